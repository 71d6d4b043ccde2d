//! `dash2sim inspect LOG [--json]`: what a log holds and what is wrong with it. A damaged
//! or truncated log is reported (exit status 0); only a file that is not a log at all is
//! an error.

use std::collections::BTreeMap;

use dash2sim_core::binlog::{Kind, Record};
use serde::Serialize;

use super::{seconds, LogContents};

/// One of the log's own messages: what the device said went wrong (or right) and when
/// (`inspect --events`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LogEvent {
    /// Time, s (UTC once the log knows it).
    pub t_s: f64,
    /// `debug`, `info`, `warning`, `error`, `fatal` (as `foxglove.Log`), or `unknown`.
    pub level: &'static str,
    /// The text (invalid UTF-8 replaced).
    pub text: String,
}

/// The log's events in log order.
pub fn events(log: &LogContents) -> Vec<LogEvent> {
    const LEVELS: [&str; 6] = ["unknown", "debug", "info", "warning", "error", "fatal"];
    log.records
        .iter()
        .filter_map(|r| match r {
            Record::Event(e) => Some(LogEvent {
                t_s: seconds(e.t_us),
                level: LEVELS.get(usize::from(e.level)).copied().unwrap_or("unknown"),
                text: String::from_utf8_lossy(&e.text).into_owned(),
            }),
            _ => None,
        })
        .collect()
}

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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Frames {
    /// `FrameMeta` records.
    pub logged: u64,
    /// Places where the frame number jumped by more than one.
    #[serde(rename = "sequence_gaps")]
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

/// What a log says of its IMU (`inspect`'s IMU line): how much it kept, and what the
/// device last made of it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImuReport {
    /// Preintegrated intervals (`ImuDelta`).
    pub intervals: u64,
    /// Samples in them.
    pub samples: u64,
    /// Samples per second over the intervals' time, Hz.
    pub rate_hz: f64,
    /// The device's last estimate (`ImuEstimate`), if it made one.
    pub last_estimate: Option<ImuEstimateReport>,
}

/// The device's estimate of its IMU at one time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ImuEstimateReport {
    /// When, s.
    pub t_s: f64,
    /// The body's pitch (positive nose down), degrees.
    pub pitch_deg: f64,
    /// The body's roll, degrees.
    pub roll_deg: f64,
    /// The gyro's bias about the body's x, y, z, rad/s.
    pub gyro_bias_rad_s: [f64; 3],
    /// 1-σ of the bias about the vertical, rad/s.
    pub bias_sigma_rad_s: f64,
    /// Standstills the bias rests on.
    pub standstills: i64,
    /// GNSS course intervals it rests on.
    pub courses: i64,
}

/// The log's IMU, if it has one.
pub fn imu(log: &LogContents) -> Option<ImuReport> {
    let (mut intervals, mut samples, mut time_us, mut last) = (0u64, 0u64, 0i64, None);
    for record in &log.records {
        match record {
            Record::ImuDelta(d) => {
                intervals += 1;
                samples += u64::try_from(d.samples).unwrap_or(0);
                time_us = time_us.saturating_add(d.dt_us);
            }
            Record::ImuEstimate(e) => last = Some(e),
            _ => {}
        }
    }
    if intervals == 0 && last.is_none() {
        return None;
    }
    let last_estimate = last.map(|e| ImuEstimateReport {
        t_s: seconds(e.t_us),
        pitch_deg: (e.pitch_e6 as f64 * 1e-6).to_degrees(),
        roll_deg: (e.roll_e6 as f64 * 1e-6).to_degrees(),
        gyro_bias_rad_s: [e.bias_x_e7, e.bias_y_e7, e.bias_z_e7].map(|b| b as f64 * 1e-7),
        bias_sigma_rad_s: e.bias_sigma_e7 as f64 * 1e-7,
        standstills: e.standstills,
        courses: e.courses,
    });
    let rate_hz = if time_us > 0 { samples as f64 / seconds(time_us) } else { 0.0 };
    Some(ImuReport { intervals, samples, rate_hz, last_estimate })
}

/// What a log holds (`dash2sim inspect --json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// The header, if it survived.
    pub header: Option<HeaderReport>,
    /// The file's length.
    pub bytes: u64,
    /// Records decoded.
    pub records: u64,
    /// Records per kind (kinds with none left out).
    pub by_type: BTreeMap<&'static str, u64>,
    /// Bytes per kind, and per record.
    pub bytes_by_type: BTreeMap<&'static str, KindBytes>,
    /// Segments.
    pub segments: u64,
    /// Damaged stretches.
    pub damaged: u64,
    /// Bytes in them.
    pub damaged_bytes: u64,
    /// Each damaged stretch.
    pub damage: Vec<Damage>,
    /// Records lost with the damage.
    pub lost: u64,
    /// Records of kinds this reader does not know.
    pub unknown: u64,
    /// The first record's time, s.
    pub t_start: Option<f64>,
    /// The last record's time, s.
    pub t_end: Option<f64>,
    /// Gaps longer than [`GAP_S`] between records of one kind.
    pub gaps: Vec<Gap>,
    /// The camera frames.
    pub frames: Frames,
    /// Inputs the recorder dropped before its pipeline.
    pub dropped_inputs: u64,
    /// The IMU, if the log has one.
    pub imu: Option<ImuReport>,
}

/// A log's header as the report gives it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeaderReport {
    /// The device's name.
    pub device_id: String,
    /// The ENU origin.
    pub origin: Origin,
    /// The format's version.
    pub version: &'static str,
}

/// A geodetic origin: degrees, metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Origin {
    /// Latitude, degrees.
    pub lat: f64,
    /// Longitude, degrees.
    pub lon: f64,
    /// Height, m.
    pub height: f64,
}

/// The bytes of one kind of record.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct KindBytes {
    /// Bytes in all.
    pub bytes: u64,
    /// Bytes per record.
    pub per_record: f64,
}

/// A damaged stretch of the file.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Damage {
    /// Where it starts.
    pub offset: u64,
    /// Its length.
    pub len: u64,
}

/// A gap between records of one kind.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Gap {
    /// The kind.
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// The record before it, s.
    pub from: f64,
    /// The record after it, s.
    pub to: f64,
}

/// The report on `log`.
pub fn report(log: &LogContents) -> Report {
    let s = &log.stats;
    let kinds = || Kind::ALL.iter().zip(s.records.iter().zip(s.bytes)).filter(|(_, (n, _))| **n > 0);
    let header = log.header.map(|h| HeaderReport {
        device_id: String::from_utf8_lossy(&h.device_id).trim_end_matches('\0').to_owned(),
        origin: Origin {
            lat: f64::from(h.origin[0]) * 1e-7,
            lon: f64::from(h.origin[1]) * 1e-7,
            height: f64::from(h.origin[2]) * 1e-3,
        },
        version: "1",
    });
    Report {
        header,
        bytes: log.bytes,
        records: s.total(),
        by_type: kinds().map(|(k, (n, _))| (k.name(), *n)).collect(),
        bytes_by_type: kinds()
            .map(|(k, (n, b))| (k.name(), KindBytes { bytes: b, per_record: b as f64 / *n as f64 }))
            .collect(),
        segments: s.segments,
        damaged: s.damaged,
        damaged_bytes: s.damaged_bytes,
        damage: log.damage.iter().map(|&(offset, len)| Damage { offset, len }).collect(),
        lost: s.lost,
        unknown: s.unknown,
        t_start: s.time_span.map(|(a, _)| seconds(a)),
        t_end: s.time_span.map(|(_, b)| seconds(b)),
        gaps: gaps(log).into_iter().map(|(k, from, to)| Gap { kind: k.name(), from, to }).collect(),
        frames: frames(log),
        dropped_inputs: dropped_inputs(log),
        imu: imu(log),
    }
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
        assert_eq!((r.records, r.by_type.get("EgoPose")), (6, Some(&3)), "{r:?}");
        let json = serde_json::to_value(&r).expect("serialises");
        assert_eq!((json["records"].as_u64(), json["gaps"][0]["type"].as_str()), (Some(6), Some("EgoPose")), "{json}");
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
        let json = serde_json::to_value(report(&log)).expect("serialises");
        assert_eq!((json["frames"]["missing"].as_u64(), json["frames"]["sequence_gaps"].as_u64()), (Some(2), Some(1)));
    }

    #[test]
    fn the_imu_line_counts_samples_over_the_intervals_time_and_reads_the_last_estimate() {
        use dash2sim_core::binlog::{ImuDelta, ImuEstimate};
        let delta = |t_us| Record::ImuDelta(ImuDelta { t_us, dt_us: 100_000, samples: 10, ..ImuDelta::default() });
        let estimate = |t_us, bias_z_e7| {
            Record::ImuEstimate(ImuEstimate { t_us, pitch_e6: 17_453, bias_z_e7, courses: 4, ..ImuEstimate::default() })
        };
        let header = Header { device_id: [0; 16], origin: [0; 3] };
        let mut records =
            vec![delta(100_000), delta(200_000), estimate(200_000, 1_000), delta(300_000), estimate(300_000, 2_000)];
        let log =
            crate::log::decode(&crate::log::import::encode(&header, &mut records).expect("encodes"), "t").expect("log");
        let imu = imu(&log).expect("an IMU");
        assert_eq!((imu.intervals, imu.samples), (3, 30));
        assert!((imu.rate_hz - 100.0).abs() < 1e-9, "{}", imu.rate_hz);
        let e = imu.last_estimate.expect("an estimate");
        assert_eq!((e.t_s, e.courses), (0.3, 4));
        assert!((e.gyro_bias_rad_s[2] - 2e-4).abs() < 1e-12, "{:?}", e.gyro_bias_rad_s);
        assert!((e.pitch_deg - 1.0).abs() < 1e-3, "{}", e.pitch_deg);
        // A log without an IMU says nothing of one.
        let mut none = vec![Record::FrameMeta(FrameMeta { t_us: 1, frame: 1, flags: 0 })];
        let log =
            crate::log::decode(&crate::log::import::encode(&header, &mut none).expect("encodes"), "t").expect("log");
        assert_eq!(report(&log).imu, None);
    }
}
