//! `dash2sim inspect LOG [--json]`: what a log holds and what is wrong with it. A damaged
//! or truncated log is reported (exit status 0); only a file that is not a log at all is
//! an error.

use std::collections::BTreeMap;
use std::path::Path;

use dash2sim_core::binlog::Kind;
use serde_json::{json, Value};

use super::{read, seconds, LogContents};

/// A gap longer than this between records of one kind is reported, s.
pub const GAP_S: f64 = 1.0;

/// Gaps per kind: (kind, from s, to s) where consecutive records are more than [`GAP_S`]
/// apart.
pub fn gaps(log: &LogContents) -> Vec<(Kind, f64, f64)> {
    let mut last: BTreeMap<Kind, i64> = BTreeMap::new();
    let mut out = Vec::new();
    for r in &log.records {
        let t = r.t_us();
        if let Some(previous) = last.insert(r.kind(), t) {
            if seconds(t - previous) > GAP_S {
                out.push((r.kind(), seconds(previous), seconds(t)));
            }
        }
    }
    out
}

/// The JSON report.
pub fn report(log: &LogContents) -> Value {
    let s = &log.stats;
    let by_type: serde_json::Map<String, Value> =
        Kind::ALL.iter().zip(s.records).filter(|(_, n)| *n > 0).map(|(k, n)| (k.name().to_owned(), json!(n))).collect();
    let bytes_by_type: serde_json::Map<String, Value> = Kind::ALL
        .iter()
        .zip(s.records.iter().zip(s.bytes))
        .filter(|(_, (n, _))| **n > 0)
        .map(|(k, (n, b))| (k.name().to_owned(), json!({"bytes": b, "per_record": b as f64 / *n as f64})))
        .collect();
    let (t_start, t_end) =
        s.time_span.map_or((Value::Null, Value::Null), |(a, b)| (json!(seconds(a)), json!(seconds(b))));
    let header = log.header.map(|h| {
        json!({
            "device_id": String::from_utf8_lossy(&h.device_id).trim_end_matches('\0'),
            "origin": {"lat": f64::from(h.origin[0]) * 1e-7, "lon": f64::from(h.origin[1]) * 1e-7, "height": f64::from(h.origin[2]) * 1e-3},
            "version": "1",
        })
    });
    json!({
        "header": header,
        "bytes": log.bytes,
        "records": s.total(),
        "by_type": by_type,
        "bytes_by_type": bytes_by_type,
        "segments": s.segments,
        "damaged": s.damaged,
        "damaged_bytes": s.damaged_bytes,
        "damage": log.damage.iter().map(|(o, l)| json!({"offset": o, "len": l})).collect::<Vec<_>>(),
        "lost": s.lost,
        "unknown": s.unknown,
        "t_start": t_start,
        "t_end": t_end,
        "gaps": gaps(log).iter().map(|(k, a, b)| json!({"type": k.name(), "from": a, "to": b})).collect::<Vec<_>>(),
    })
}

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
    for (offset, len) in log.damage.iter().take(10) {
        println!("    {len} bytes at offset {offset}");
    }
    for (kind, a, b) in gaps(&log).iter().take(10) {
        println!("  gap         {} {a:.3} … {b:.3} s", kind.name());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::binlog::{EgoPose, Header, Record, VehicleSpeed};

    #[test]
    fn gaps_are_per_kind_and_longer_than_a_second() {
        let pose = |t_us| Record::EgoPose(EgoPose { t_us, ..EgoPose::default() });
        let speed = |t_us| Record::VehicleSpeed(VehicleSpeed { t_us, ..VehicleSpeed::default() });
        // Poses stop for 1.5 s while speeds go on: a pose gap only.
        let mut records = vec![pose(0), speed(0), pose(100_000), speed(800_000), speed(1_500_000), pose(1_600_000)];
        let header = Header { device_id: [0; 16], origin: [0; 3] };
        let bytes = crate::logfile::import::encode(&header, &mut records).expect("encodes");
        let log = crate::logfile::decode(&bytes, "test").expect("a log");
        assert_eq!(gaps(&log), vec![(Kind::EgoPose, 0.1, 1.6)]);
        let r = report(&log);
        assert_eq!((r["records"].as_u64(), r["by_type"]["EgoPose"].as_u64()), (Some(6), Some(3)), "{r}");
    }
}
