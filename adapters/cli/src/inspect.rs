//! `dash2sim inspect`: what a 4D log holds, rendered.

use std::path::Path;

use dash2sim_core::binlog::Kind;
use dash2sim_linux::log::inspect::{dropped_inputs, events, frames, gaps, report};
use dash2sim_linux::log::read;
use dash2sim_linux::{Error, Result};
use serde_json::json;

/// `dash2sim inspect`.
pub fn run(path: &Path, with_events: bool, as_json: bool) -> Result<()> {
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
