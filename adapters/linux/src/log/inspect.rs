//! `dash2sim inspect LOG [--json]`: what a log holds and what is wrong with it. A damaged
//! or truncated log is reported (exit status 0); only a file that is not a log at all is
//! an error.

use std::collections::BTreeMap;

use dash2sim_core::binlog::{Kind, Record};
use serde_json::{json, Value};

use super::{seconds, LogContents};

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

/// Camera frames in a log: how many were logged, the gaps in their sequence numbers and how
/// many frames those skipped, and how often the numbering started again (a camera restart).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Frames {
    /// `FrameMeta` records.
    pub logged: u64,
    /// Places where the frame number jumped by more than one.
    pub gaps: u64,
    /// Frames those jumps skipped.
    pub missing: u64,
    /// Places where the frame number went back.
    pub restarts: u64,
}

/// The camera frames of a log.
pub fn frames(log: &LogContents) -> Frames {
    let mut f = Frames::default();
    let mut last: Option<i64> = None;
    for r in &log.records {
        let Record::FrameMeta(m) = r else { continue };
        f.logged += 1;
        match last {
            Some(previous) if m.frame <= previous => f.restarts += 1,
            Some(previous) if m.frame > previous + 1 => {
                f.gaps += 1;
                f.missing += u64::try_from(m.frame - previous - 1).unwrap_or(0);
            }
            _ => {}
        }
        last = Some(m.frame);
    }
    f
}

/// Inputs the recorder dropped before its pipeline, as its events counted them (the largest
/// running count in "inputs dropped …" events).
pub fn dropped_inputs(log: &LogContents) -> u64 {
    let prefix = dash2sim_core::pipeline::Issue::InputsDropped.text().as_bytes();
    log.records
        .iter()
        .filter_map(|r| match r {
            Record::Event(e) if e.text.starts_with(prefix) => {
                let text = std::str::from_utf8(&e.text).ok()?;
                let count = text.rsplit('(').next()?.split_whitespace().next()?;
                count.parse::<u64>().ok()
            }
            _ => None,
        })
        .max()
        .unwrap_or(0)
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
    let f = frames(log);
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
        "frames": {"logged": f.logged, "sequence_gaps": f.gaps, "missing": f.missing, "restarts": f.restarts},
        "dropped_inputs": dropped_inputs(log),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::binlog::{EgoPose, EventRecord, FrameMeta, Header, VehicleSpeed};

    #[test]
    fn gaps_are_per_kind_and_longer_than_a_second() {
        let pose = |t_us| Record::EgoPose(EgoPose { t_us, ..EgoPose::default() });
        let speed = |t_us| Record::VehicleSpeed(VehicleSpeed { t_us, ..VehicleSpeed::default() });
        // Poses stop for 1.5 s while speeds go on: a pose gap only.
        let mut records = vec![pose(0), speed(0), pose(100_000), speed(800_000), speed(1_500_000), pose(1_600_000)];
        let header = Header { device_id: [0; 16], origin: [0; 3] };
        let bytes = crate::log::import::encode(&header, &mut records).expect("encodes");
        let log = crate::log::decode(&bytes, "test").expect("a log");
        assert_eq!(gaps(&log), vec![(Kind::EgoPose, 0.1, 1.6)]);
        let r = report(&log);
        assert_eq!((r["records"].as_u64(), r["by_type"]["EgoPose"].as_u64()), (Some(6), Some(3)), "{r}");
    }

    #[test]
    fn frames_gaps_restarts_and_drops_are_counted() {
        let frame = |t_us, frame| Record::FrameMeta(FrameMeta { t_us, frame, flags: 0 });
        let mut dropped = EventRecord { t_us: 700, level: 3, ..EventRecord::default() };
        let text = format!("{} (17 so far)", dash2sim_core::pipeline::Issue::InputsDropped.text());
        dropped.text.extend_from_slice(text.as_bytes()).expect("fits");
        // 1 2 3, then 6 (two missing), 7, then the camera restarts at 1.
        let mut records = vec![
            frame(100, 1),
            frame(200, 2),
            frame(300, 3),
            frame(600, 6),
            frame(700, 7),
            Record::Event(dropped),
            frame(900, 1),
        ];
        let header = Header { device_id: [0; 16], origin: [0; 3] };
        let bytes = crate::log::import::encode(&header, &mut records).expect("encodes");
        let log = crate::log::decode(&bytes, "test").expect("a log");
        assert_eq!(frames(&log), Frames { logged: 6, gaps: 1, missing: 2, restarts: 1 });
        assert_eq!(dropped_inputs(&log), 17);
        assert_eq!(report(&log)["frames"]["missing"], 2);
    }
}
