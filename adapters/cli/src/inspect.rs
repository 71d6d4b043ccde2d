//! `dash2sim inspect`: what a 4D log holds, rendered.

use std::path::Path;

use dash2sim_core::binlog::Kind;
use dash2sim_linux::log::inspect::{dropped_inputs, events, frames, gaps, report};
use dash2sim_linux::log::read;
use dash2sim_linux::record::storage::{read_index, INDEX_FILE};
use dash2sim_linux::{Error, Result};
use serde_json::json;

/// `dash2sim inspect`: a log, or a live recording's folder (its index).
pub fn run(path: &Path, with_events: bool, as_json: bool) -> Result<()> {
    if path.is_dir() {
        return folder(path, as_json);
    }
    let log = read(path).map_err(Error::other)?;
    let r = report(&log);
    if as_json {
        // Through `Value`, whose keys are sorted: the output's order is the JSON's, not the
        // struct's.
        let mut out = crate::render::json_of(&r)?;
        if with_events {
            out["events"] = crate::render::json_of(&events(&log))?;
        }
        println!("{out}");
        return Ok(());
    }
    println!("log {} ({} bytes, format v1)", path.display(), log.bytes);
    match &r.header {
        None => println!("  header      damaged"),
        // Rendered as JSON values, as the report gives them.
        Some(h) => {
            println!(
                "  header      device {}, origin {}, {}",
                json!(h.device_id),
                json!(h.origin.lat),
                json!(h.origin.lon)
            )
        }
    }
    if let (Some(a), Some(b)) = (r.t_start, r.t_end) {
        println!("  time        {a:.6} … {b:.6} s ({:.1} s), {} segments", b - a, log.stats.segments);
    }
    println!("  records     {}", log.stats.total());
    for (kind, (n, bytes)) in Kind::ALL.iter().zip(log.stats.records.iter().zip(log.stats.bytes)) {
        if *n > 0 {
            println!("    {:<16} {n:>8}  {bytes:>9} bytes  {:>6.2} per record", kind.name(), bytes as f64 / *n as f64);
        }
    }
    println!(
        "  damage      {} stretches, {} bytes; {} records lost with them; {} of unknown kinds",
        log.stats.damaged, log.stats.damaged_bytes, log.stats.lost, log.stats.unknown
    );
    let f = frames(&log);
    if f.logged > 0 {
        println!(
            "  frames      {} logged, {} sequence gaps ({} frames missing), {} restarts; {} inputs dropped",
            f.logged,
            f.gaps,
            f.missing,
            f.restarts,
            dropped_inputs(&log)
        );
    }
    for (offset, len) in log.damage.iter().take(10) {
        println!("    {len} bytes at offset {offset}");
    }
    for (kind, a, b) in gaps(&log).iter().take(10) {
        println!("  gap         {} {a:.3} … {b:.3} s", kind.name());
    }
    if with_events {
        let events = events(&log);
        println!("  events      {}", events.len());
        for e in &events {
            println!("    {:.3} s  {:<7}  {}", e.t_s, e.level, e.text);
        }
    }
    Ok(())
}

/// A recording folder: every file its index names, with its time span, size, protection
/// and, if it was deleted, why.
fn folder(dir: &Path, as_json: bool) -> Result<()> {
    let index = read_index(dir).map_err(|e| {
        Error::invalid(format!("{}: a folder, but not a live recording's ({INDEX_FILE}: {e})", dir.display()))
    })?;
    if as_json {
        println!("{}", crate::render::json_of(&index)?);
        return Ok(());
    }
    let utc = |ms: u64| dash2sim_linux::utc::iso8601(i64::try_from(ms).unwrap_or(i64::MAX / 1000) * 1000);
    let (mut kept, mut bytes) = (0, 0);
    println!("recording folder {} ({} files named in {INDEX_FILE})", dir.display(), index.segments.len());
    for e in &index.segments {
        let span = match e.ended_ms {
            Some(end) => format!(
                "{} … {} ({:.0} s)",
                utc(e.started_ms),
                utc(end),
                (end.saturating_sub(e.started_ms)) as f64 / 1000.0
            ),
            None => format!("{} …, being recorded", utc(e.started_ms)),
        };
        let state = match (&e.deleted, &e.protected) {
            (Some(why), Some(kept)) => format!("deleted ({why}; it was kept: {kept})"),
            (Some(why), None) => format!("deleted ({why})"),
            (None, Some(why)) => format!("kept: {why}"),
            (None, None) => String::new(),
        };
        if e.deleted.is_none() {
            bytes += e.bytes;
            kept += usize::from(e.protected.is_some());
        }
        println!("  {}  {span}  {} bytes  {state}", e.file, e.bytes);
    }
    let present = index.segments.iter().filter(|e| e.deleted.is_none()).count();
    println!(
        "  {present} files present ({bytes} bytes), {kept} of them kept; {} deleted",
        index.segments.len() - present
    );
    Ok(())
}
