//! `dash2sim inspect`: what a 4D log holds, rendered.

use std::path::Path;

use dash2sim_core::binlog::Kind;
use dash2sim_linux::log::inspect::{dropped_inputs, frames, gaps, report};
use dash2sim_linux::log::read;
use serde_json::Value;

/// `dash2sim inspect`.
pub fn run(path: &Path, as_json: bool) -> Result<(), String> {
    let log = read(path).map_err(|e| e.to_string())?;
    let r = report(&log);
    if as_json {
        println!("{r}");
        return Ok(());
    }
    println!("log {} ({} bytes, format v1)", path.display(), log.bytes);
    match &r["header"] {
        Value::Null => println!("  header      damaged"),
        h => println!("  header      device {}, origin {}, {}", h["device_id"], h["origin"]["lat"], h["origin"]["lon"]),
    }
    if let (Some(a), Some(b)) = (r["t_start"].as_f64(), r["t_end"].as_f64()) {
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
    Ok(())
}
