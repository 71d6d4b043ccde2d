//! `dash2sim inspect`: what a 4D log holds, rendered.

use std::path::Path;

use dash2sim_core::binlog::signature::key_id;
use dash2sim_core::binlog::Kind;
use dash2sim_linux::log::inspect::{dropped_inputs, events, frames, gaps, report};
use dash2sim_linux::log::{read, signing};
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
    if log.stats.signatures > 0 {
        println!(
            "  signatures  {} of {} segments carry one (`--verify-key PUB` checks them)",
            log.stats.signatures, log.stats.segments
        );
    }
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
    if let Some(imu) = &r.imu {
        println!("  IMU         {} samples in {} intervals ({:.1} Hz)", imu.samples, imu.intervals, imu.rate_hz);
        if let Some(e) = &imu.last_estimate {
            let [bx, by, bz] = e.gyro_bias_rad_s;
            println!(
                "              last estimate at {:.1} s: pitch {:.2}°, roll {:.2}°; gyro bias ({bx:.5}, {by:.5}, {bz:.5}) rad/s, ± {:.5} about the vertical, from {} standstills and {} GNSS course intervals",
                e.t_s, e.pitch_deg, e.roll_deg, e.bias_sigma_rad_s, e.standstills, e.courses
            );
        }
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

/// `dash2sim inspect --verify-key`: each segment's signature, per file (a folder's files
/// in recording order, one chain); fails when a segment is not trusted.
pub fn verify_key(path: &Path, key: &str, as_json: bool) -> Result<()> {
    let public = signing::read_public(key)?;
    let files = if path.is_dir() { recorded_files(path)? } else { vec![(path.to_path_buf(), false)] };
    let logs = files.iter().map(|(f, _)| read(f).map_err(Error::other)).collect::<Result<Vec<_>>>()?;
    let names: Vec<String> = files.iter().map(|(f, _)| f.display().to_string()).collect();
    let checked = names.iter().zip(&logs).zip(&files).map(|((name, log), (_, after_deleted))| signing::Checked {
        name,
        signing: &log.signing,
        after_deleted: *after_deleted,
    });
    let seals = signing::check(&public, checked)?;
    let untrusted: usize = seals.iter().map(|f| f.segments.len() - f.trusted()).sum();
    if as_json {
        println!("{}", json!({ "key_id": signing::hex(&key_id(&public)), "files": seals, "untrusted": untrusted }));
    } else {
        println!("signatures against key {} ({} files)", signing::hex(&key_id(&public)), seals.len());
        for file in &seals {
            println!("  {}: {} of {} segments ok", file.file, file.trusted(), file.segments.len());
            for s in file.segments.iter().filter(|s| !s.trusted || s.verdict != "ok") {
                let key = s.other_key.as_ref().map(|id| format!(" (key id {id})")).unwrap_or_default();
                println!("    segment {:>4}  {}{key}", s.seq, s.verdict);
            }
        }
    }
    if untrusted > 0 {
        return Err(Error::invalid(format!("{untrusted} segments are not signed by the key, unaltered and in order")));
    }
    Ok(())
}

/// A recording folder's present log files, oldest first, each with whether the file
/// before it was deleted by loop recording (by the index when it has one, else by name,
/// which is the start time).
fn recorded_files(dir: &Path) -> Result<Vec<(std::path::PathBuf, bool)>> {
    if let Ok(index) = read_index(dir) {
        let mut previous_deleted = false;
        let mut files = Vec::new();
        for e in &index.segments {
            if e.deleted.is_none() {
                files.push((dir.join(&e.file), previous_deleted));
            }
            previous_deleted = e.deleted.is_some();
        }
        return Ok(files);
    }
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .map_err(|e| Error::file(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "d2slog"))
        .collect();
    files.sort();
    Ok(files.into_iter().map(|f| (f, false)).collect())
}

/// `dash2sim keygen -o PREFIX`.
pub fn keygen(prefix: &Path) -> Result<()> {
    let (secret, public, key) = signing::keygen(prefix)?;
    println!("secret key {} (give it to `record --key`; keep it on the device)", secret.display());
    println!("public key {} ({})", public.display(), signing::hex(&key));
    println!("key id     {}", signing::hex(&key_id(&key)));
    Ok(())
}
