//! `dash2sim scenario sweep`: many generated drives, each on the product's path — generate,
//! `record` from the device's files, `finish`, `verify` the truth, the online and the
//! finished log in both channel modes — in parallel, one row per drive (`runs.csv`,
//! `runs.jsonl`), the statistics over them (`summary.json`, printed) and a picture
//! (`sweep.png`).

use std::fmt::Write as _;
use std::path::Path;

use dash2sim_core::geo::Geodetic;
use dash2sim_core::pipeline::RelativeMotion;
use rayon::prelude::*;

use super::drive::{assess, Assessment, Recorded, WindowPair};
use super::rows::{finite, DriveFacts, Row, SweepRequest, Verdict};
use super::summary::Summary;
use crate::scenario::command::{config, MAX_DURATION_S};
use crate::scenario::write::{road_tile, write_scenario};
use crate::scenario::{generate, Driver};
use crate::{Error, Field, Result};
use dash2sim_core::binlog::Record;
use dash2sim_linux::log;
use dash2sim_linux::record::{self, Setup};

/// Generate drive `seed` with `driver`, record it from its files, judge it; its row.
fn run_drive(seed: u64, driver: Driver, args: &SweepRequest, work: &Path) -> Row {
    let row = Row::empty(seed, driver, args);
    match try_drive(seed, driver, args, work) {
        Ok((assessment, facts)) => row.with_assessment(&assessment, &facts),
        Err(e) => Row { error: Some(e.to_string()), ..row },
    }
}

/// The horizontal length of the fixes' mean error (fix − the true camera position at the
/// fix's time: the fixes describe the camera, as the scenario makes them), weighted by the
/// receiver's stated σ as a solve weighs them, the multipath fixes left out as a solve's
/// gate would, m; `None` without such fixes.
fn gnss_mean_error(scenario: &crate::scenario::Scenario) -> Option<f64> {
    let frames = &scenario.frames;
    let [forward, left, _] = scenario.config.camera.true_mount().position;
    let mut sum = [0.0; 3];
    for g in scenario.gnss.iter().filter(|g| !g.multipath) {
        let k = frames.partition_point(|f| f.ego.t < g.t_fix - 1e-6);
        let Some(frame) = frames.get(k).filter(|f| (f.ego.t - g.t_fix).abs() < 1e-6) else { continue };
        let ego = &frame.ego;
        let (sin, cos) = ego.heading.sin_cos();
        let camera = [ego.x + forward * cos - left * sin, ego.y + forward * sin + left * cos];
        let w = g.reported_sigma.powi(-2);
        sum = [sum[0] + w * (g.enu[0] - camera[0]), sum[1] + w * (g.enu[1] - camera[1]), sum[2] + w];
    }
    (sum[2] > 0.0).then(|| (sum[0] / sum[2]).hypot(sum[1] / sum[2]))
}

/// A log's last mount estimate against the scenario's true mount: its yaw and pitch
/// errors, degrees, and whether it was called calibrated.
fn mount_error(scenario: &crate::scenario::Scenario, records: &[Record]) -> Option<(f64, f64, bool)> {
    let m = records.iter().rev().find_map(|r| match r {
        Record::MountEstimate(m) => Some(*m),
        _ => None,
    })?;
    let truth = scenario.config.camera.true_mount().roll_pitch_yaw;
    let yaw = (m.yaw_e6 as f64 * 1e-6 - truth[2]).to_degrees().abs();
    let pitch = (m.pitch_e6 as f64 * 1e-6 - truth[1]).to_degrees().abs();
    Some((yaw, pitch, m.calibrated == 1))
}

fn try_drive(seed: u64, driver: Driver, args: &SweepRequest, work: &Path) -> Result<(Assessment, DriveFacts)> {
    let config =
        crate::scenario::ScenarioConfig { driver, ..config(seed, args.duration, args.profile, args.receiver)? };
    let scenario = generate(&config);
    let drive_dir = work.join("drive");
    write_scenario(&scenario, &drive_dir).map_err(|e| Error::file(&drive_dir, e))?;
    let [lat, lon, height] = config.origin;
    let origin = Geodetic::new(lat, lon, height).map_err(Error::other)?;
    let tile = road_tile(&drive_dir, origin)?;
    // The demo's device: the same setup, so that a row equals `demo --offline`'s summary.
    let setup = Setup {
        relative_motion: args.relative_motion,
        ..Setup::work_zone(origin, Some(tile.clone()), *b"dash2sim-demo\0\0\0")
    };
    let mut sources = record::Sources::scenario(&drive_dir);
    if args.relative_motion == RelativeMotion::ImuWheels {
        sources.vo = None;
    }
    let (stream, _) = record::read_sources(&sources)?;
    let recording = record::run_stream(&stream, &setup)?;
    let log_path = work.join("drive.d2slog");
    std::fs::write(&log_path, &recording.log).map_err(|e| Error::file(&log_path, e))?;
    let log = log::read(&log_path).map_err(Error::other)?;
    let log_name = log_path.display().to_string();
    let recorded = Recorded {
        scenario: &scenario,
        drive_dir: &drive_dir,
        log: &log,
        log_name: &log_name,
        tile: &tile,
        setup: &setup,
    };
    let told_latency_s = args.oracle_latency.then_some(config.gnss.latency_s);
    let assessment = assess(&recorded, args.anchors, &work.join("anchors.csv"), told_latency_s, args.doubt)?;
    if args.keep {
        let finished = work.join("finished.d2slog");
        std::fs::write(&finished, &assessment.finished_bytes).map_err(|e| Error::file(&finished, e))?;
    }
    let device_mount = mount_error(&scenario, &log.records);
    let finished = log::decode(&assessment.finished_bytes, "finished").map_err(Error::other)?;
    let facts = DriveFacts {
        vo_sessions: scenario.vo.reinits() + 1,
        vo_recorded: args.relative_motion == RelativeMotion::Vo,
        mount_error_deg: device_mount.map(|(yaw, pitch, _)| yaw.max(pitch)),
        mount_calibrated: device_mount.is_some_and(|m| m.2),
        finished_mount_yaw_error_deg: mount_error(&scenario, &finished.records).map(|m| m.0),
        true_latency_s: config.gnss.latency_s,
        true_wheel_scale: config.wheel.scale,
        gnss_mean_error_m: gnss_mean_error(&scenario),
    };
    Ok((assessment, facts))
}

/// The columns of `runs.csv`.
const CSV_HEADER: &str = "seed,driver,profile,receiver,anchors,oracle_latency,error,\
truth_score,truth_verified,truth_failed,online_score,online_verified,online_failed,finished_score,finished_verified,finished_failed,\
truth_score_cs,truth_verified_cs,online_score_cs,online_verified_cs,finished_score_cs,finished_verified_cs,finished_failed_cs,\
online_ape_m,finished_ape_m,online_ape_utc_m,finished_ape_utc_m,online_clock_error_s,finished_clock_error_s,online_scale_error,finished_scale_error,online_mota,online_idf1,finished_mota,finished_idf1,\
first_anchor_s,vo_sessions,mount_error_deg,mount_calibrated,finished_mount_yaw_error_deg,online_within_2sigma,online_nees,finished_within_2sigma,finished_nees,latency_error_s,online_latency_error_s,gnss_mean_error_m,wheel_factor_error,windows,device_windows_verified,truth_windows_verified,\
finished_decision,finished_score_low,finished_score_high,online_decision,device_window_decisions";

fn csv_row(r: &Row) -> String {
    let opt = |x: Option<f64>| x.map_or_else(String::new, |v| format!("{v:.6}"));
    let verdict = |v: Option<&Verdict>| match v {
        Some(v) => format!("{:.4},{},{}", v.score, u8::from(v.verified), v.failed.join(" ")),
        None => ",,".to_owned(),
    };
    let short = |v: Option<&Verdict>| match v {
        Some(v) => format!("{:.4},{}", v.score, u8::from(v.verified)),
        None => ",".to_owned(),
    };
    let marks = |f: fn(&WindowPair) -> bool| r.windows.iter().map(|w| if f(w) { '1' } else { '0' }).collect::<String>();
    let decided = |v: Option<&Verdict>| match v {
        Some(v) => format!("{},{:.4},{:.4}", v.decision.name(), v.score_interval[0], v.score_interval[1]),
        None => ",,".to_owned(),
    };
    let error = r.error.as_deref().map_or_else(String::new, |e| format!("\"{}\"", e.replace('"', "'")));
    format!(
        "{},{},{},{},{},{},{error},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
        r.seed,
        r.driver,
        r.profile,
        r.receiver,
        r.anchors,
        u8::from(r.oracle_latency),
        verdict(r.truth.as_ref().map(|v| &v.insensitive)),
        verdict(r.online.as_ref().map(|v| &v.insensitive)),
        verdict(r.finished.as_ref().map(|v| &v.insensitive)),
        short(r.truth.as_ref().map(|v| &v.sensitive)),
        short(r.online.as_ref().map(|v| &v.sensitive)),
        verdict(r.finished.as_ref().map(|v| &v.sensitive)),
        opt(r.online_ape_m),
        opt(r.finished_ape_m),
        opt(r.online_ape_utc_m),
        opt(r.finished_ape_utc_m),
        opt(r.online_clock_error_s),
        opt(r.finished_clock_error_s),
        opt(r.online_scale_error),
        opt(r.finished_scale_error),
        opt(r.online_mota),
        opt(r.online_idf1),
        opt(r.finished_mota),
        opt(r.finished_idf1),
        opt(r.first_anchor_s),
        r.vo_sessions,
        opt(r.mount_error_deg),
        u8::from(r.mount_calibrated),
        opt(r.finished_mount_yaw_error_deg),
        opt(finite(r.online_within_2sigma as f64 / r.online_sigma_poses as f64)),
        opt(r.online_nees),
        opt(finite(r.finished_within_2sigma as f64 / r.finished_sigma_poses as f64)),
        opt(r.finished_nees),
        opt(r.latency_error_s),
        opt(r.online_latency_error_s),
        opt(r.gnss_mean_error_m),
        opt(r.wheel_factor_error),
        r.windows.len(),
        marks(|w| w.device_verified),
        marks(|w| w.truth_verified),
        decided(r.finished.as_ref().map(|v| &v.insensitive)),
        r.online.as_ref().map_or("", |v| v.insensitive.decision.name()),
        // Per window: v verified, r rejected, u undecided, - not decided.
        r.windows
            .iter()
            .map(|w| w.device_decision.map_or('-', |d| d.name().chars().next().unwrap_or('-')))
            .collect::<String>(),
    )
}

fn write(path: &Path, contents: impl AsRef<[u8]>) -> Result<()> {
    std::fs::write(path, contents).map_err(|e| Error::file(path, e))
}

/// Run the sweep `args` describes: its rows (in seed, driver order) and summary, written to
/// the output folder. `progress` is told, as each drive ends (from the worker threads), how
/// many have ended and how many there are.
pub fn sweep(args: &SweepRequest, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<(Vec<Row>, Summary)> {
    if !(args.duration.is_finite() && (10.0..=MAX_DURATION_S).contains(&args.duration)) {
        return Err(Error::request(
            Field::Duration,
            format!("{} s must be between 10 and {MAX_DURATION_S} seconds", args.duration),
        ));
    }
    if args.jobs == Some(0) {
        return Err(Error::request(Field::Jobs, "at least 1 is needed"));
    }
    let out = &args.output;
    std::fs::create_dir_all(out)
        .map_err(|e| Error::refused(format!("cannot create the output folder {}", out.display()), e))?;
    // Fail now, not after the drives, when the folder cannot be written.
    write(&out.join("runs.csv"), format!("{CSV_HEADER}\n"))?;
    let work_root = if args.keep { out.join("drives") } else { out.join(".work") };
    let drives: Vec<(u64, Driver)> =
        args.seeds.clone().flat_map(|seed| args.driver.list().iter().map(move |d| (seed, *d))).collect();
    let ended = std::sync::atomic::AtomicUsize::new(0);
    let jobs = args.jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(jobs).build().map_err(Error::other)?;
    let rows: Vec<Row> = pool.install(|| {
        drives
            .par_iter()
            .map(|&(seed, driver)| {
                let work = work_root.join(format!("{seed:05}-{}", driver.name()));
                let row = run_drive(seed, driver, args, &work);
                if !args.keep {
                    let _ = std::fs::remove_dir_all(&work);
                }
                progress(ended.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, drives.len());
                row
            })
            .collect()
    });
    if !args.keep {
        let _ = std::fs::remove_dir(&work_root);
    }
    let mut csv = format!("{CSV_HEADER}\n");
    let mut lines = String::new();
    for row in &rows {
        let _ = writeln!(csv, "{}", csv_row(row));
        let _ = writeln!(lines, "{}", serde_json::to_string(row).map_err(Error::other)?);
    }
    write(&out.join("runs.csv"), csv)?;
    write(&out.join("runs.jsonl"), lines)?;
    let summary = Summary::of(args, &rows);
    let text = serde_json::to_string_pretty(&summary).map_err(Error::other)?;
    write(&out.join("summary.json"), text)?;
    // The picture needs the `plot` feature; without it the tables are all there is.
    #[cfg(feature = "plot")]
    super::plot::draw(&rows, &summary, &out.join("sweep.png"))?;
    Ok((rows, summary))
}
