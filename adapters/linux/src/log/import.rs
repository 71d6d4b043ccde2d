//! `dash2sim import`: existing recordings → a 4D log, in time order.
//!
//! * an NMEA 0183 capture → GNSS fixes (the core's epoch assembly, as `nmea decode`); an
//!   offset moves their UTC times onto the other sources' clock;
//! * a candump capture (and DBC files) → vehicle speeds from NMEA 2000 SOG, J1939 CCVS1,
//!   OBD-II PID 0x0D, and a DBC signal in its unit;
//! * a TUM trajectory → ego poses in the log's ENU frame (x east, y north; heading from the
//!   body x axis);
//! * the objects CSV → 3D tracks.
//!
//! The header's origin is the one given, else the first GNSS fix.

use std::path::{Path, PathBuf};

use dash2sim_core::binlog::{
    EgoPose, GnssFix, Header, Record, Track3d, Tracks3d, VehicleSpeed, Writer, WriterConfig, MAX_TRACKS,
};
use dash2sim_core::nmea::{Event as NmeaEvent, Stream, StreamEvent};

use super::quantise;
use crate::ingest::can::{SignalName, SpeedUnit};
use crate::trajectory::{Format, Trajectory};
use crate::{Error, Field, Result};

/// What to import.
#[derive(Clone, Debug, Default)]
pub struct ImportRequest {
    /// Output log.
    pub output: PathBuf,
    /// NMEA 0183 capture.
    pub nmea: Option<PathBuf>,
    /// Added to NMEA times, s.
    pub nmea_offset_s: f64,
    /// candump capture.
    pub can: Option<PathBuf>,
    /// DBC files.
    pub dbc: Vec<PathBuf>,
    /// The DBC signal carrying vehicle speed.
    pub speed_signal: Option<SignalName>,
    /// That signal's unit.
    pub speed_unit: SpeedUnit,
    /// TUM trajectory.
    pub traj: Option<PathBuf>,
    /// Objects CSV.
    pub objects: Option<PathBuf>,
    /// The log's ENU origin (else the first GNSS fix).
    pub origin: Option<dash2sim_core::geo::Geodetic>,
}

/// Records from one source (as `import` reads it).
pub fn nmea_records(
    path: &Path,
    offset_s: f64,
    out: &mut Vec<Record>,
    problem: &mut dyn FnMut(&str),
) -> Result<Option<[f64; 3]>> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    let mut stream: Stream = Stream::new();
    let mut first = None;
    let mut push = |fix: &dash2sim_core::nmea::GnssFix, out: &mut Vec<Record>| {
        let (Some(t), Some(lat), Some(lon)) = (fix.time(), fix.lat, fix.lon) else { return };
        let alt = fix.alt_hae().or(fix.alt_msl).unwrap_or(0.0);
        first.get_or_insert([lat, lon, alt]);
        out.push(Record::GnssFix(GnssFix {
            t_us: t.micros() + quantise(offset_s, 1e-6),
            lat_e7: quantise(lat, 1e-7),
            lon_e7: quantise(lon, 1e-7),
            alt_mm: quantise(alt, 1e-3),
            speed_mm_s: quantise(fix.speed_mps.unwrap_or(0.0), 1e-3),
            track_e4: quantise(fix.track_deg.unwrap_or(0.0).to_radians(), 1e-4),
            hdop_e2: quantise(fix.hdop.unwrap_or(0.0), 1e-2),
            satellites: i64::from(fix.satellites_used.unwrap_or(0)),
            mode: i64::from(fix.mode.gpsd()),
        }));
    };
    let name = path.display();
    for (index, line) in bytes.split_inclusive(|&b| b == b'\n').enumerate() {
        stream.feed(line, |event| match event {
            StreamEvent::Sentence(NmeaEvent::Message { fix: Some(fix), .. }) => push(fix, out),
            StreamEvent::Sentence(NmeaEvent::BadSentence(e)) => problem(&format!("{name}:{}: {e}", index + 1)),
            StreamEvent::Sentence(NmeaEvent::BadFields(e)) => problem(&format!("{name}:{}: {e}", index + 1)),
            StreamEvent::Dropped(e) => problem(&format!("{name}:{}: {e}", index + 1)),
            StreamEvent::Sentence(NmeaEvent::Message { .. }) => {}
        });
    }
    if let Some(fix) = stream.decoder.finish() {
        push(&fix, out);
    }
    Ok(first)
}

fn can_records(
    request: &ImportRequest,
    path: &Path,
    out: &mut Vec<Record>,
    problem: &mut dyn FnMut(&str),
) -> Result<()> {
    let (table, warnings) = crate::ingest::can::load_tables(&request.dbc)?;
    warnings.iter().for_each(|w| problem(w));
    let to_mps = request.speed_unit.to_mps();
    let file = std::fs::File::open(path).map_err(|e| Error::file(path, e))?;
    let mut source = dash2sim_can::candump::CandumpReader::new(std::io::BufReader::new(file));
    let mut decoder = crate::ingest::can::CanDecoder::new(table);
    let name = path.display();
    let mut problems = 0u64;
    crate::ingest::can::decode_source(
        &mut source,
        &mut decoder,
        |m| {
            let Some(t) = m["t"].as_f64() else { return Ok(()) };
            let f = &m["fields"];
            let found = if m["message"].as_str().is_some() {
                match &request.speed_signal {
                    Some(SignalName { message, signal }) if m["message"].as_str() == Some(message) => {
                        f[signal.as_str()].as_f64().map(|v| (v * to_mps, 3))
                    }
                    _ => None,
                }
            } else if m["pgn"] == 65265 {
                f["Wheel-Based Vehicle Speed"].as_f64().map(|v| (v, 1))
            } else if m["pid"] == 13 {
                f["Vehicle Speed"].as_f64().map(|v| (v / 3.6, 2))
            } else if m["pgn"] == 129_026 {
                f["SOG"].as_f64().map(|v| (v, 4))
            } else {
                None
            };
            if let Some((speed, source)) = found {
                out.push(Record::VehicleSpeed(VehicleSpeed {
                    t_us: quantise(t, 1e-6),
                    speed_mm_s: quantise(speed, 1e-3),
                    source,
                }));
            }
            Ok(())
        },
        |line, text| {
            problems += 1;
            if problems <= 10 {
                problem(&format!("{name}:{line}: {text}"));
            }
        },
    )
    .map_err(|e| Error::file(path, e))?;
    if problems > 10 {
        problem(&format!("{name}: … and {} more problems", problems - 10));
    }
    Ok(())
}

/// Records from one source (as `import` reads it).
pub fn traj_records(path: &Path, out: &mut Vec<Record>) -> Result<()> {
    let traj = Trajectory::read(path, Format::Tum).map_err(Error::other)?;
    for (t, p) in traj.stamps.iter().zip(&traj.poses) {
        out.push(Record::EgoPose(EgoPose {
            t_us: quantise(*t, 1e-6),
            x_mm: quantise(p.translation.x, 1e-3),
            y_mm: quantise(p.translation.y, 1e-3),
            z_mm: quantise(p.translation.z, 1e-3),
            yaw_e4: quantise(p.rotation[(1, 0)].atan2(p.rotation[(0, 0)]), 1e-4),
            sigma_mm: 0,
        }));
    }
    Ok(())
}

/// Records from one source (as `import` reads it).
pub fn object_records(path: &Path, out: &mut Vec<Record>) -> Result<()> {
    // One batch per time (split into records of at most MAX_TRACKS).
    let mut by_time: std::collections::BTreeMap<i64, Vec<Track3d>> = std::collections::BTreeMap::new();
    for row in crate::ingest::objects::read(path)? {
        by_time.entry(quantise(row.t, 1e-6)).or_default().push(Track3d {
            id: i64::from(row.id),
            class: dash2sim_core::class::code_of(&row.class),
            x_mm: quantise(row.centre[0], 1e-3),
            y_mm: quantise(row.centre[1], 1e-3),
            z_mm: quantise(row.centre[2], 1e-3),
            l_mm: quantise(row.size[0], 1e-3),
            w_mm: quantise(row.size[1], 1e-3),
            h_mm: quantise(row.size[2], 1e-3),
            yaw_e4: quantise(row.yaw, 1e-4),
            vx_mm_s: quantise(row.velocity[0], 1e-3),
            vy_mm_s: quantise(row.velocity[1], 1e-3),
            is_static: i64::from(row.is_static),
        });
    }
    for (t_us, tracks) in by_time {
        for chunk in tracks.chunks(MAX_TRACKS) {
            let mut batch = Tracks3d { t_us, ..Tracks3d::default() };
            for track in chunk {
                // A chunk never exceeds MAX_TRACKS.
                let _ = batch.tracks.push(*track);
            }
            out.push(Record::Tracks3d(batch));
        }
    }
    Ok(())
}

/// Encode `records` (sorted by time here) as a log with `header`.
pub fn encode(header: &Header, records: &mut [Record]) -> Result<Vec<u8>> {
    records.sort_by_key(Record::t_us);
    encode_in_order(header, records)
}

/// Encode `records` as a log with `header`, in the order given.
pub fn encode_in_order<R: std::borrow::Borrow<Record>>(
    header: &Header,
    records: impl IntoIterator<Item = R>,
) -> Result<Vec<u8>> {
    let mut writer: Box<Writer<Vec<u8>, 65_536>> =
        Box::new(Writer::new(Vec::new(), header, WriterConfig::default()).map_err(Error::other)?);
    for r in records {
        let r = r.borrow();
        writer.write(r).map_err(|e| Error::refused(format!("{} record at {} µs", r.kind().name(), r.t_us()), e))?;
    }
    writer.finish().map_err(Error::other)
}

/// What [`import`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// Records written.
    pub records: usize,
    /// Records by kind (name → count), in name order.
    pub by_kind: std::collections::BTreeMap<&'static str, u64>,
    /// From the first record to the last, s.
    pub span_s: f64,
    /// The log's size, bytes.
    pub bytes: usize,
}

/// `dash2sim import`: the sources of `request` into one log; `problem` hears each line of
/// a capture that could not be read (the import goes on) and the DBC files' warnings.
pub fn import(request: &ImportRequest, problem: &mut dyn FnMut(&str)) -> Result<Imported> {
    let mut records = Vec::new();
    let mut origin = request.origin.map(|g| [g.lat_deg, g.lon_deg, g.height_m]);
    if let Some(path) = &request.nmea {
        let first = nmea_records(path, request.nmea_offset_s, &mut records, problem)?;
        origin = origin.or(first);
    }
    if let Some(path) = &request.can {
        can_records(request, path, &mut records, problem)?;
    }
    if let Some(path) = &request.traj {
        if origin.is_none() {
            return Err(Error::request(
                Field::Origin,
                "a trajectory is placed in the log's ENU frame: give its origin, or an NMEA capture to take it from",
            ));
        }
        traj_records(path, &mut records)?;
    }
    if let Some(path) = &request.objects {
        object_records(path, &mut records)?;
    }
    if records.is_empty() {
        return Err(Error::request(
            Field::ImportSources,
            "nothing to import: give an NMEA or CAN capture, a trajectory or objects (with records in them)",
        ));
    }
    // Say where the log came from, as its first event.
    let sources: Vec<String> =
        [("nmea", &request.nmea), ("can", &request.can), ("traj", &request.traj), ("objects", &request.objects)]
            .iter()
            .filter_map(|(name, path)| path.as_ref().map(|p| format!("{name}={}", p.display())))
            .collect();
    let first = records.iter().map(Record::t_us).min().unwrap_or(0);
    records.push(super::event(first, 2, &format!("dash2sim import: {}", sources.join(" "))));
    let [lat, lon, h] = origin.unwrap_or([0.0; 3]);
    let header = Header {
        device_id: *b"dash2sim-import\0",
        origin: [quantise(lat, 1e-7) as i32, quantise(lon, 1e-7) as i32, quantise(h, 1e-3) as i32],
    };
    let bytes = encode(&header, &mut records)?;
    std::fs::write(&request.output, &bytes).map_err(|e| Error::file(&request.output, e))?;
    let span_s = match (records.first(), records.last()) {
        (Some(a), Some(b)) => (b.t_us() - a.t_us()) as f64 * 1e-6,
        _ => 0.0,
    };
    let mut by_kind = std::collections::BTreeMap::new();
    for r in &records {
        *by_kind.entry(r.kind().name()).or_insert(0u64) += 1;
    }
    Ok(Imported { records: records.len(), by_kind, span_s, bytes: bytes.len() })
}
