//! comma2k19's minute (`comma2k19/` of the data folder) in the forms a dashcam sees: the
//! real u-blox fixes as the NMEA a receiver would send (from comma's CSV: UTC, position,
//! speed, course, stamped with the device's receive time `t_boot`), the real Toyota CAN
//! through its DBC (0xB4 SPEED), and VO made from comma's fused camera poses through an
//! unknown Sim(3) with drift ([`VoModel::arbitrary`]) — the recording has no VO of its
//! own. Recorded, finished, and measured against the fused poses.

use std::path::{Path, PathBuf};

use dash2sim_core::binlog::Record;
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::sim3::{AlignMode, Moments};
use serde::Serialize;
use serde_json::Value;

use super::{device_times, write, OutputFile};
use crate::scenario::vo::VoModel;
use crate::{Error, Result};
use dash2sim_core::geo::Geodetic;
use dash2sim_core::pipeline::CameraMount;
use dash2sim_linux::log::{self, LogContents};
use dash2sim_linux::record::{self, Device, RecordRequest, VoFrame};
use dash2sim_linux::trajectory::{Format, Trajectory};
use rand::SeedableRng;

/// The files the minute needs, relative to its folder.
pub const REQUIRED: [&str; 5] = [
    "expected/global_pose_camera_enu.tum",
    "expected/live_gnss_ublox.csv",
    "expected/evo_ape_gnss_vs_pose.json",
    "raw_can.candump.log",
    "opendbc-toyota/_toyota_2017.dbc",
];

/// The ENU origin of comma's poses.
pub const ORIGIN: [f64; 3] = [37.721000009, -122.472299089, 31.6392];

/// HDOP 0.9 × 2.78 m = the anchoring test's σ of 2.5 m.
pub const UERE: f64 = 2.5 / 0.9;

/// The mount for these poses: the camera's axes (x forward, y right, z down), and the ego
/// taken at the camera so that positions compare with the poses.
pub fn mount() -> CameraMount {
    CameraMount { position: [0.0; 3], roll_pitch_yaw: [std::f64::consts::PI, 0.0, 0.0] }
}

/// The minute's ENU origin.
pub fn origin() -> Result<Geodetic> {
    let [lat, lon, h] = ORIGIN;
    Geodetic::new(lat, lon, h).map_err(|e| Error::refused("the minute's origin", e))
}

fn nmea_line(body: &str) -> String {
    let checksum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{checksum:02X}\r\n")
}

fn angle(deg: f64, width: usize, hemispheres: [char; 2]) -> (String, char) {
    let a = deg.abs();
    let whole = a.floor();
    let minutes = (a - whole) * 60.0;
    (format!("{:0width$}{minutes:09.6}", whole as u32), if deg >= 0.0 { hemispheres[0] } else { hemispheres[1] })
}

/// A receiver's fixes as NMEA.
#[derive(Debug)]
pub struct ReceiverNmea {
    /// The raw NMEA text, as the receiver sends it.
    pub raw: String,
    /// The same as a serial capture: `(t_boot) sentence` per line.
    pub stamped: String,
    /// Boot time − UTC of the first fix, s.
    pub offset_s: f64,
    /// Fixes (CSV rows).
    pub fixes: usize,
}

/// comma's u-blox CSV as GGA + RMC sentences (UTC from its millisecond stamps, HDOP 0.9).
pub fn ublox_nmea(csv: &Path) -> Result<ReceiverNmea> {
    receiver_nmea(csv, 0.9)
}

/// One of comma's receiver CSVs (`t_boot_s,lat_deg,lon_deg,speed_mps,utc_timestamp_ms,
/// alt_m,bearing_deg`) as GGA + RMC sentences with this HDOP.
pub fn receiver_nmea(csv: &Path, hdop: f64) -> Result<ReceiverNmea> {
    let text = std::fs::read_to_string(csv).map_err(|e| Error::file(csv, e))?;
    let (mut raw, mut stamped) = (String::new(), String::new());
    let (mut offset, mut fixes) = (None, 0);
    for (n, line) in text.lines().enumerate().skip(1) {
        let at = |message: String| Error::line(csv, n + 1, message);
        let v: Vec<f64> = line
            .split(',')
            .map(|x| x.trim().parse())
            .collect::<Result<_, _>>()
            .map_err(|e: std::num::ParseFloatError| at(e.to_string()))?;
        let [t_boot, lat, lon, speed, utc_ms, alt, bearing] = v[..] else {
            return Err(at(format!("expected 7 columns, found {}", v.len())));
        };
        offset.get_or_insert(t_boot - utc_ms / 1000.0);
        let secs = utc_ms / 1000.0;
        let tod = secs - (secs / 86_400.0).floor() * 86_400.0;
        let hms = format!("{:02}{:02}{:05.2}", (tod / 3600.0) as u32, ((tod % 3600.0) / 60.0) as u32, tod % 60.0);
        let (la, ns) = angle(lat, 2, ['N', 'S']);
        let (lo, ew) = angle(lon, 3, ['E', 'W']);
        // 2018-08-02 (the drive's date), as ddmmyy.
        for sentence in [
            nmea_line(&format!("GPGGA,{hms},{la},{ns},{lo},{ew},1,10,{hdop:.1},{alt:.2},M,0.0,M,,")),
            nmea_line(&format!("GPRMC,{hms},A,{la},{ns},{lo},{ew},{:.3},{bearing:.2},020818,,,A", speed / 0.514_444)),
        ] {
            stamped += &format!("({t_boot:.6}) {sentence}");
            raw += &sentence;
        }
        fixes += 1;
    }
    let offset_s = offset.ok_or_else(|| Error::file(csv, "no fixes"))?;
    Ok(ReceiverNmea { raw, stamped, offset_s, fixes })
}

/// The minute recorded by the on-device pipeline.
#[derive(Debug)]
pub struct RecordedMinute {
    /// comma's fused camera poses (ENU around [`ORIGIN`]).
    pub truth: Trajectory,
    /// The log file.
    pub path: PathBuf,
    /// The log as read.
    pub log: LogContents,
    /// Device time of every record (see [`device_times`]).
    pub device: Vec<f64>,
    /// The pipeline's summary (`record --json`).
    pub summary: record::Summary,
    /// u-blox fixes the CSV holds.
    pub fixes_in_csv: usize,
}

/// Record the minute from `dir` into `work` (`vo.csv`, `ublox.serial.log`, `comma.d2slog`)
/// with VO made by `model`, its noise drawn from `noise_seed` (a model without noise draws
/// nothing: the seed does not matter then).
pub fn record_minute(dir: &Path, work: &Path, model: &VoModel, noise_seed: u64) -> Result<RecordedMinute> {
    let truth = Trajectory::read(&dir.join("expected/global_pose_camera_enu.tum"), Format::Tum)
        .map_err(|e| Error::refused("comma2k19 poses", e))?;
    let vo = model.generate(&truth, &mut rand_chacha::ChaCha8Rng::seed_from_u64(noise_seed));
    let vo_path = work.join("vo.csv");
    let mut text = Vec::new();
    crate::scenario::write::write_vo_csv(&mut text, &vo).map_err(Error::other)?;
    write(&vo_path, &text)?;
    let nmea = ublox_nmea(&dir.join("expected/live_gnss_ublox.csv"))?;
    let nmea_path = work.join("ublox.serial.log");
    write(&nmea_path, &nmea.stamped)?;
    let sources = record::Sources {
        vo: Some(vo_path),
        nmea: Some(nmea_path),
        can: vec![dir.join("raw_can.candump.log")],
        ..record::Sources::default()
    };
    let args = RecordRequest {
        dbc: vec![dir.join("opendbc-toyota/_toyota_2017.dbc")],
        speed_signal: Some("SPEED.SPEED".parse()?),
        origin: Some(origin()?),
        device: Device { mount: mount(), mode: VoFrame::Full, uere: UERE, ..Device::default() },
        ..RecordRequest::from_files(&work.join("comma.d2slog"), sources)
    };
    let (recording, _) = record::record_files(&args)?;
    write(&args.output, &recording.log)?;
    let log = log::read(&args.output).map_err(Error::other)?;
    let device = device_times(&log.records)?;
    Ok(RecordedMinute {
        truth,
        path: args.output,
        log,
        device,
        summary: record::summary(&recording),
        fixes_in_csv: nmea.fixes,
    })
}

/// The fused camera position at `t`, interpolated between the poses around it (None
/// outside them or across a gap of more than 0.1 s).
pub fn truth_at(truth: &Trajectory, t: f64) -> Option<Vector3<f64>> {
    let k = truth.stamps.partition_point(|s| *s < t);
    let (b, tb) = (truth.poses.get(k)?, *truth.stamps.get(k)?);
    if (tb - t).abs() < 1e-6 {
        return Some(b.translation);
    }
    let (a, ta) = (truth.poses.get(k.checked_sub(1)?)?, *truth.stamps.get(k - 1)?);
    if tb - ta > 0.1 {
        return None;
    }
    Some(a.translation + (b.translation - a.translation) * ((t - ta) / (tb - ta)))
}

/// How a log's ego track compares with the fused poses.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Compared {
    /// Ego poses with a fused pose at their time.
    #[serde(rename = "ego_poses_compared")]
    pub matched: usize,
    /// Seconds from the first fused pose to the first ego pose.
    #[serde(rename = "observable_after_s")]
    pub first_s: f64,
    /// Absolute position error (no alignment), RMS and largest, m.
    #[serde(rename = "ape_rmse_m")]
    pub ape_rmse: f64,
    /// See `ape_rmse`.
    #[serde(rename = "ape_max_m")]
    pub ape_max: f64,
    /// The horizontal part of `ape_rmse`, m: what the receiver's heights (a phone's
    /// wander by metres) do not reach.
    #[serde(rename = "ape_horizontal_rmse_m")]
    pub ape_horizontal: f64,
    /// The same after the best Sim(3) alignment, m.
    #[serde(rename = "ape_after_sim3_m")]
    pub ape_aligned: f64,
    /// Scale of that Sim(3) minus one.
    pub scale_error: f64,
}

/// The ego poses of `records` (at device times `device`) against the fused poses.
pub fn compare(records: &[Record], device: &[f64], truth: &Trajectory) -> Result<Compared> {
    compare_from(records, device, truth, f64::NEG_INFINITY)
}

/// [`compare`] over the ego poses at or after device time `from` only (s): another track
/// compared over the same stretch.
pub fn compare_from(records: &[Record], device: &[f64], truth: &Trajectory, from: f64) -> Result<Compared> {
    let t0 = *truth.stamps.first().ok_or_else(|| Error::invalid("no fused poses"))?;
    let mut pairs = Vec::new();
    let mut first = None;
    for (r, &t) in records.iter().zip(device).filter(|(_, t)| **t >= from) {
        if let Record::EgoPose(p) = r {
            if let Some(x) = truth_at(truth, t) {
                first.get_or_insert(t - t0);
                pairs.push((Vector3::new(p.x_mm as f64, p.y_mm as f64, p.z_mm as f64) * 1e-3, x));
            }
        }
    }
    let mut moments = Moments::default();
    for (x, y) in &pairs {
        moments.push(x, y, 1.0).map_err(|e| Error::refused("alignment", e))?;
    }
    let sim3 = moments.align(AlignMode::Sim3).map_err(|e| Error::refused("alignment", e))?;
    let rms = |e: &mut dyn Iterator<Item = f64>| {
        let (s, n) = e.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (s / n.max(1) as f64).sqrt()
    };
    Ok(Compared {
        matched: pairs.len(),
        first_s: first.unwrap_or(f64::NAN),
        ape_rmse: rms(&mut pairs.iter().map(|(x, y)| (x - y).norm())),
        ape_max: pairs.iter().map(|(x, y)| (x - y).norm()).fold(0.0, f64::max),
        ape_horizontal: rms(&mut pairs.iter().map(|(x, y)| (x - y).xy().norm())),
        ape_aligned: rms(&mut pairs.iter().map(|(x, y)| (sim3.transform_point(x) - y).norm())),
        scale_error: sim3.scale - 1.0,
    })
}

/// What `run` measured on the minute (`demo --data`'s summary of it).
#[derive(Debug, Serialize)]
pub struct Report {
    /// `comma2k19`.
    pub name: &'static str,
    /// What the recording is.
    pub what: &'static str,
    /// Where the VO came from.
    pub vo: &'static str,
    /// The fused poses' span, s.
    pub duration_s: f64,
    /// What the device recorded.
    pub recording: RecordingReport,
    /// The u-blox fixes' own error, as evo measured it.
    pub gnss_alone: GnssAlone,
    /// The device's log against the fused poses.
    pub online: Online,
    /// The finished log against the fused poses.
    pub finished: Finished,
    /// The files written.
    pub files: Vec<OutputFile>,
}

/// What the device recorded.
#[derive(Debug, Serialize)]
pub struct RecordingReport {
    /// The pipeline's summary (`record --json`).
    pub pipeline: record::Summary,
    /// u-blox fixes the CSV holds (every one should reach the log).
    pub fixes_in_csv: usize,
    /// The log's size.
    pub log_bytes: u64,
    /// The log's size per minute of driving.
    pub bytes_per_minute: f64,
}

/// The u-blox fixes against the fused poses, no alignment (evo's figures).
#[derive(Debug, Serialize)]
pub struct GnssAlone {
    /// APE RMSE, m.
    pub ape_rmse_m: Option<f64>,
    /// Largest APE, m.
    pub ape_max_m: Option<f64>,
    /// Where the figures come from.
    pub source: &'static str,
}

/// The device's log against the fused poses.
#[derive(Debug, Serialize)]
pub struct Online {
    /// Its ego track.
    pub compared: Compared,
    /// The last full anchor's scale over the true one, minus one.
    pub anchor_scale_error_at_end: Option<f64>,
}

/// The finished log against the fused poses, and what finishing estimated.
#[derive(Debug, Serialize)]
pub struct Finished {
    /// Its ego track.
    pub compared: Compared,
    /// The same over the stretch the device had anchored (from its first ego pose on).
    pub compared_where_online: Compared,
    /// The scale's relative σ.
    pub scale_sigma_relative: f64,
    /// The GNSS latency estimated, s.
    pub gnss_latency_s: f64,
    /// The wheel-speed factor estimated.
    pub wheel_factor: f64,
}

/// The minute through the product into `out`: recorded, finished (GNSS and wheel speed,
/// no anchors), exported, and compared with the fused poses. The summary.
pub fn run(dir: &Path, out: &Path) -> Result<Report> {
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, e))?;
    let model = VoModel::arbitrary();
    let minute = record_minute(dir, out, &model, 1)?;
    let (log, truth) = (&minute.log, &minute.truth);
    let online = compare(&log.records, &minute.device, truth)?;
    let t0 = truth.stamps.first().copied().unwrap_or_default();
    let online_scale = log.records.iter().zip(&minute.device).rev().find_map(|(r, t)| match r {
        Record::AnchorEstimate(a) if a.observability == 2 => {
            Some(a.scale_e6 as f64 * 1e-6 / model.scale_at(t - t0) - 1.0)
        }
        _ => None,
    });

    let name = minute.path.display().to_string();
    let finished = dash2sim_finish::finish(&log.compact(), &name, None, None, mount(), Default::default(), UERE)?;
    let finished_records = finished.records.to_vec();
    let finished_device = device_times(&finished_records)?;
    let finished_compared = compare(&finished_records, &finished_device, truth)?;
    let online_from =
        log.records.iter().zip(&minute.device).find_map(|(r, t)| matches!(r, Record::EgoPose(_)).then_some(*t));
    let compared_where_online =
        compare_from(&finished_records, &finished_device, truth, online_from.unwrap_or(f64::INFINITY))?;
    let header = log.header.ok_or_else(|| Error::invalid("the recorded log has no header"))?;
    let finished_bytes = log::import::encode_in_order(&header, &finished_records)?;
    let finished_path = out.join("finished.d2slog");
    write(&finished_path, &finished_bytes)?;
    let finished_log = log::decode(&finished_bytes, "finished").map_err(Error::other)?;

    write(&out.join("ego.tum"), dash2sim_export::tum::tum(log))?;
    write(&out.join("finished.tum"), dash2sim_export::tum::tum(&finished_log))?;
    write(&out.join("drive.geojson"), dash2sim_export::geojson::geojson(&finished_log)?.to_string())?;
    dash2sim_export::mcap::write(&finished_log, None, &out.join("finished.mcap"), None)?;

    let evo_path = dir.join("expected/evo_ape_gnss_vs_pose.json");
    let evo: Value = serde_json::from_str(&std::fs::read_to_string(&evo_path).map_err(|e| Error::file(&evo_path, e))?)
        .map_err(|e| Error::file(&evo_path, e))?;
    let gnss_alone = &evo["cases"]["maxdiff0.01_none"]["ape_translation_stats"];
    let span = truth.stamps.last().copied().unwrap_or_default() - t0;
    let a = &finished.report.anchoring;
    let file = |what, name| OutputFile::new(what, out, name);
    Ok(Report {
        name: "comma2k19",
        what: "one minute of a Toyota RAV4 in San Francisco: real u-blox NMEA and Toyota CAN (0xB4 SPEED through opendbc)",
        vo: "none recorded: VO made from comma's fused camera poses through an unknown Sim(3) (scale 3.7, arbitrary rotation) with 1 %/min scale and 1°/min yaw drift",
        duration_s: span,
        recording: RecordingReport {
            pipeline: minute.summary,
            fixes_in_csv: minute.fixes_in_csv,
            log_bytes: log.bytes,
            bytes_per_minute: log.bytes as f64 / (span / 60.0),
        },
        gnss_alone: GnssAlone {
            ape_rmse_m: gnss_alone["rmse"].as_f64(),
            ape_max_m: gnss_alone["max"].as_f64(),
            source: "evo 1.38.1, u-blox fixes vs fused poses, no alignment (expected/evo_ape_gnss_vs_pose.json)",
        },
        online: Online { compared: online, anchor_scale_error_at_end: online_scale },
        finished: Finished {
            compared: finished_compared,
            compared_where_online,
            scale_sigma_relative: a.scale_sigma_relative,
            gnss_latency_s: a.gnss_latency_s,
            wheel_factor: a.wheel_factor,
        },
        files: vec![
            file("VO made from the fused poses (frame, pose, VO session)", "vo.csv"),
            file("the u-blox fixes as a serial capture", "ublox.serial.log"),
            file("the device's 4D log", "comma.d2slog"),
            file("the finished 4D log", "finished.d2slog"),
            file("TUM for evo (the device's log)", "ego.tum"),
            file("TUM for evo (finished)", "finished.tum"),
            file("GeoJSON for QGIS (finished)", "drive.geojson"),
            file("MCAP for Foxglove (finished)", "finished.mcap"),
        ],
    })
}
