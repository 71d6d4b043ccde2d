//! CSS Electronics' CANedge drive (`css-electronics-canedge/` of the data folder): 40
//! minutes of a car in Denmark, logged as five candump files. GNSS arrives over CAN from a
//! CANmod.gps module (DBC-defined frames on can1, read through `canmod-gps.dbc` as
//! [`GnssSignals`](dash2sim_core::pipeline::GnssSignals)), the speed as OBD-II PID 0x0D
//! responses on can0. There is no camera: the log carries GNSS and speed only — no VO, so
//! no anchoring, no ego poses and no verification (and the data has no map of Denmark).
//! What can be measured: every fix and every speed reaches the log (against cantools'
//! decoding), the logger's clock against GNSS time, and the fixes against the OBD speed.

use std::path::{Path, PathBuf};

use dash2sim_core::binlog::Record;
use dash2sim_core::geo::Geodetic;
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::pipeline::Issue;
use serde::Serialize;

use super::{write, OutputFile};
use crate::{Error, Result};
use dash2sim_linux::log;
use dash2sim_linux::record::{self, RecordRequest};

/// The session's candump files start with this.
pub const SPLITS: &str = "candump/3BA199E2_00000164_";

/// The files the drive needs besides its candump splits, relative to its folder.
pub const REQUIRED: [&str; 4] = [
    "dbc/canmod-gps.dbc",
    "expected/3BA199E2_session164.gnss_pos.csv",
    "expected/3BA199E2_session164.gnss_odo.csv",
    "expected/3BA199E2_session164.obd_pid0d_speed.csv",
];

/// CANmod.gps's position and time as `record --gnss-signals` takes them.
pub const GNSS_SIGNALS: &str = "lat=gnss_pos.Latitude,lon=gnss_pos.Longitude,valid=gnss_pos.PositionValid,\
accuracy=gnss_pos.PositionAccuracy,time=gnss_time.Epoch";

/// The session's candump files in order (their names sort by split number).
pub fn splits(dir: &Path) -> Vec<PathBuf> {
    let (folder, prefix) = SPLITS.split_once('/').unwrap_or(("", SPLITS));
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join(folder))
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with(prefix) && n.ends_with(".log"))
        })
        .collect();
    files.sort();
    files
}

/// A reference CSV with a header: its rows split into cells, and a column's index by name.
struct Csv {
    path: PathBuf,
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Csv {
    fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
        let mut lines = text.lines().map(|l| l.split(',').map(str::to_owned).collect::<Vec<_>>());
        let header = lines.next().unwrap_or_default();
        Ok(Csv { path: path.to_path_buf(), header, rows: lines.collect() })
    }

    fn column(&self, name: &str) -> Result<usize> {
        self.header.iter().position(|h| h == name).ok_or_else(|| Error::file(&self.path, format!("no column {name}")))
    }

    /// Rows whose `name` column is `value`.
    fn count(&self, name: &str, value: &str) -> Result<usize> {
        let i = self.column(name)?;
        Ok(self.rows.iter().filter(|r| r.get(i).map(String::as_str) == Some(value)).count())
    }
}

/// The module's own trip odometer at the end (the last valid `DistanceTrip`), m.
fn odometer_m(odo: &Csv) -> Result<Option<f64>> {
    let (valid, trip) = (odo.column("DistanceValid")?, odo.column("DistanceTrip")?);
    Ok(odo
        .rows
        .iter()
        .rev()
        .find_map(|r| (r.get(valid).map(String::as_str) == Some("1")).then(|| r.get(trip)?.parse().ok()).flatten()))
}

/// Pearson correlation.
fn correlation(pairs: &[(f64, f64)]) -> f64 {
    let n = pairs.len() as f64;
    let (ma, mb) = (pairs.iter().map(|p| p.0).sum::<f64>() / n, pairs.iter().map(|p| p.1).sum::<f64>() / n);
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (a, b) in pairs {
        ab += (a - ma) * (b - mb);
        aa += (a - ma) * (a - ma);
        bb += (b - mb) * (b - mb);
    }
    ab / (aa * bb).sqrt()
}

/// The fixes' own speed (distance between consecutive fixes over their time, at the
/// midpoint) against the OBD speeds of the log, interpolated at the OBD times: pairs of
/// (fixes, OBD) in km/h. `fixes` are (UTC s, ENU) in log order.
fn speed_pairs(records: &[Record], fixes: &[(f64, Vector3<f64>)]) -> Vec<(f64, f64)> {
    let from_fixes: Vec<(f64, f64)> = fixes
        .windows(2)
        .filter_map(|w| {
            let ((t0, p0), (t, p)) = (w[0], w[1]);
            // Only fixes a second or so apart: a gap is not a speed.
            (0.5..=1.5).contains(&(t - t0)).then(|| (0.5 * (t + t0), (p - p0).norm() / (t - t0) * 3.6))
        })
        .collect();
    let mut pairs = Vec::new();
    for r in records {
        let Record::VehicleSpeed(v) = r else { continue };
        let t = v.t_us as f64 * 1e-6;
        let k = from_fixes.partition_point(|(s, _)| *s < t);
        let (Some(a), Some(b)) = (k.checked_sub(1).and_then(|i| from_fixes.get(i)), from_fixes.get(k)) else {
            continue;
        };
        if b.0 - a.0 <= 1.5 {
            pairs.push((a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0), v.speed_mm_s as f64 * 3.6e-3));
        }
    }
    pairs
}

/// What `run` measured on the drive (`demo --data`'s summary of it).
#[derive(Debug, Serialize)]
pub struct Report {
    /// `css`.
    pub name: &'static str,
    /// What the recording is.
    pub what: &'static str,
    /// Why there is no VO.
    pub vo: &'static str,
    /// candump files read.
    pub candump_files: usize,
    /// CAN frames they held.
    pub can_frames: u64,
    /// What the device recorded, against cantools' decoding.
    pub recording: RecordingReport,
    /// The drive by its fixes, against the module's odometer.
    pub drive: Drive,
    /// The logger's clock against GNSS time.
    pub clock: Clock,
    /// The fixes' own speed against OBD speed.
    pub speed_check: SpeedCheck,
    /// The files written.
    pub files: Vec<OutputFile>,
}

/// What the device recorded, beside cantools' counts of the same frames.
#[derive(Debug, Serialize)]
pub struct RecordingReport {
    /// The pipeline's summary (`record --json`).
    pub pipeline: record::Summary,
    /// Fixes logged.
    pub fixes: u64,
    /// Position frames cantools decodes as valid.
    pub fixes_valid_by_cantools: usize,
    /// Position frames refused for having no fix.
    pub positions_without_fix: u64,
    /// Position frames cantools decodes as invalid.
    pub positions_without_fix_by_cantools: usize,
    /// Speeds logged.
    pub speeds: u64,
    /// OBD speed responses in the reference.
    pub speeds_in_reference: usize,
    /// The log's size.
    pub log_bytes: u64,
    /// The log's size per minute of driving.
    pub bytes_per_minute: f64,
}

/// The drive by its fixes.
#[derive(Debug, Serialize)]
pub struct Drive {
    /// From the first fix to the last, s.
    pub duration_s: f64,
    /// Along the fixes, km.
    pub distance_km: f64,
    /// The module's own trip odometer, km.
    pub module_odometer_km: Option<f64>,
}

/// Logger time minus GNSS time over the drive (the log's clock-offset records), s.
#[derive(Debug, Serialize)]
pub struct Clock {
    /// The first offset.
    pub logger_minus_gnss_first_s: Option<f64>,
    /// The last offset.
    pub logger_minus_gnss_last_s: Option<f64>,
    /// The smallest.
    pub logger_minus_gnss_min_s: Option<f64>,
    /// The largest.
    pub logger_minus_gnss_max_s: Option<f64>,
    /// Clock-offset records.
    pub offset_records: usize,
}

/// Speed from consecutive fixes against OBD speed.
#[derive(Debug, Serialize)]
pub struct SpeedCheck {
    /// Pairs compared.
    pub pairs: usize,
    /// Mean absolute difference, km/h.
    pub mean_abs_diff_kmh: f64,
    /// Their correlation.
    pub correlation: f64,
    /// How the pairs were made.
    pub what: &'static str,
}

/// The drive through the product into `out`: recorded from its candump splits, exported,
/// and measured. The summary.
pub fn run(dir: &Path, out: &Path) -> Result<Report> {
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, e))?;
    let files = splits(dir);
    if files.is_empty() {
        return Err(Error::file(dir, format!("no candump files {SPLITS}*.log")));
    }
    let sources = record::Sources { can: files.clone(), ..record::Sources::default() };
    let log_path = out.join("css.d2slog");
    let args = RecordRequest {
        dbc: vec![dir.join("dbc/canmod-gps.dbc")],
        gnss_signals: Some(GNSS_SIGNALS.parse()?),
        speed_source: record::SpeedMessage::Obd,
        ..RecordRequest::from_files(&log_path, sources)
    };
    let (recording, counts) = record::record_files(&args)?;
    write(&log_path, &recording.log)?;
    let log = log::read(&log_path).map_err(Error::other)?;
    let header = log.header.ok_or_else(|| Error::invalid("the recorded log has no header"))?;
    let frame = log::frame(&header).ok_or_else(|| Error::invalid("the log's origin is not a position"))?;

    let offsets: Vec<f64> = log
        .records
        .iter()
        .filter_map(|r| if let Record::ClockOffset(c) = r { Some(-(c.offset_us as f64) * 1e-6) } else { None })
        .collect();
    let fixes: Vec<(f64, Vector3<f64>)> = log
        .records
        .iter()
        .filter_map(|r| match r {
            Record::GnssFix(f) => Geodetic::new(f.lat_e7 as f64 * 1e-7, f.lon_e7 as f64 * 1e-7, 0.0)
                .ok()
                .map(|g| (f.t_us as f64 * 1e-6, frame.geodetic_to_enu(&g))),
            _ => None,
        })
        .collect();
    let distance_m: f64 = fixes.windows(2).map(|w| (w[1].1 - w[0].1).norm()).sum();
    let span_s = fixes.last().map_or(0.0, |l| l.0) - fixes.first().map_or(0.0, |f| f.0);
    let pairs = speed_pairs(&log.records, &fixes);
    let mean_abs = pairs.iter().map(|(a, b)| (a - b).abs()).sum::<f64>() / pairs.len().max(1) as f64;

    write(&out.join("drive.geojson"), dash2sim_export::geojson::geojson(&log)?.to_string())?;
    dash2sim_export::mcap::write(&log, None, &out.join("drive.mcap"), None)?;

    let expected = |name: &str| Csv::read(&dir.join("expected").join(format!("3BA199E2_session164.{name}.csv")));
    let (positions, odo) = (expected("gnss_pos")?, expected("gnss_odo")?);
    let file = |what, name| OutputFile::new(what, out, name);
    Ok(Report {
        name: "css",
        what: "CSS Electronics' CANedge: 40 minutes of a car in Denmark; GNSS over CAN (CANmod.gps, DBC-defined), speed as OBD-II PID 0x0D",
        vo: "none: the log carries GNSS and speed only (no anchoring, no ego poses, no verification — and no map of Denmark in the data)",
        candump_files: files.len(),
        can_frames: counts.can_frames,
        recording: RecordingReport {
            pipeline: record::summary(&recording),
            fixes: recording.stats.fixes,
            fixes_valid_by_cantools: positions.count("PositionValid", "1")?,
            positions_without_fix: recording.issues.get(Issue::GnssNoPosition),
            positions_without_fix_by_cantools: positions.count("PositionValid", "0")?,
            speeds: recording.stats.speeds,
            speeds_in_reference: expected("obd_pid0d_speed")?.rows.len(),
            log_bytes: log.bytes,
            bytes_per_minute: log.bytes as f64 / (span_s / 60.0),
        },
        drive: Drive {
            duration_s: span_s,
            distance_km: distance_m * 1e-3,
            module_odometer_km: odometer_m(&odo)?.map(|m| m * 1e-3),
        },
        clock: Clock {
            logger_minus_gnss_first_s: offsets.first().copied(),
            logger_minus_gnss_last_s: offsets.last().copied(),
            logger_minus_gnss_min_s: offsets.iter().copied().reduce(f64::min),
            logger_minus_gnss_max_s: offsets.iter().copied().reduce(f64::max),
            offset_records: offsets.len(),
        },
        speed_check: SpeedCheck {
            pairs: pairs.len(),
            mean_abs_diff_kmh: mean_abs,
            correlation: correlation(&pairs),
            what: "speed from consecutive fixes vs OBD PID 0x0D, both from the log (UTC), OBD times",
        },
        files: vec![
            file("the device's 4D log (GNSS and speed)", "css.d2slog"),
            file("GeoJSON for QGIS (the GNSS track)", "drive.geojson"),
            file("MCAP for Foxglove", "drive.mcap"),
        ],
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use dash2sim_core::pipeline::GnssSignals;

    use super::GNSS_SIGNALS;
    use dash2sim_linux::record::{gnss_signals, RecordRequest, Sources};

    #[test]
    fn gnss_signals_from_canmods_dbc_are_the_cores_canmod_preset() {
        // gnss_time and gnss_pos as CSS's canmod-gps.dbc has them.
        let dbc = "VERSION \"\"\n\nBS_:\n\nBU_:\n\n\
            BO_ 3 gnss_pos: 8 Vector__XXX\n SG_ PositionAccuracy : 58|6@1+ (1,0) [0|63] \"m\" Vector__XXX\n \
            SG_ Latitude : 1|28@1+ (1e-06,-90) [-90|90] \"deg\" Vector__XXX\n \
            SG_ Longitude : 29|29@1+ (1e-06,-180) [-180|180] \"deg\" Vector__XXX\n \
            SG_ PositionValid : 0|1@1+ (1,0) [0|1] \"\" Vector__XXX\n\n\
            BO_ 2 gnss_time: 6 Vector__XXX\n SG_ TimeValid : 0|1@1+ (1,0) [0|1] \"\" Vector__XXX\n \
            SG_ TimeConfirmed : 1|1@1+ (1,0) [0|1] \"\" Vector__XXX\n \
            SG_ Epoch : 8|40@1+ (0.001,1577840400) [1577840400|2677352027] \"sec\" Vector__XXX\n";
        let path = std::env::temp_dir().join(format!("dash2sim-canmod-{}.dbc", std::process::id()));
        std::fs::write(&path, dbc).expect("write");
        let args = RecordRequest {
            dbc: vec![path.clone()],
            gnss_signals: Some(GNSS_SIGNALS.parse().expect("names")),
            ..RecordRequest::from_files(Path::new("out.d2slog"), Sources::default())
        };
        let from_dbc =
            dash2sim_linux::ingest::can::load_tables(&args.dbc).and_then(|(table, _)| gnss_signals(&args, &table));
        let _ = std::fs::remove_file(&path);
        assert_eq!(from_dbc.expect("signals"), GnssSignals::canmod_gps());
    }
}
