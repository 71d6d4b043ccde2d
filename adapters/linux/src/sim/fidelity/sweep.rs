//! `dash2sim scenario sweep`: many generated drives, each on the product's path — generate,
//! `record` from the device's files, `finish`, `verify` the truth, the online and the
//! finished log in both channel modes — in parallel, one row per drive (`runs.csv`,
//! `runs.jsonl`), the statistics over them (`summary.json`, printed) and a picture
//! (`sweep.png`).

use std::fmt::Write as _;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use dash2sim_core::geo::Geodetic;
use dash2sim_core::pipeline::RelativeMotion;
use rayon::prelude::*;
use serde::Serialize;

use super::drive::{assess, Anchors, Assessment, Recorded, WindowPair};
use super::summary::Summary;
use crate::log;
use crate::record::{self, Setup};
use crate::sim::scenario::command::{config, MAX_DURATION_S};
use crate::sim::scenario::profile::{Profile, Receiver};
use crate::sim::scenario::write::{road_tile, write_scenario};
use crate::sim::scenario::{generate, Driver, Drivers};
use crate::verify::decide::{decision_or_point, Decision, DoubtSettings};
use crate::verify::VerifyReport;
use crate::{Error, Result};
use dash2sim_core::binlog::Record;

/// A sweep (`dash2sim scenario sweep`).
#[derive(Debug, Clone)]
pub struct SweepRequest {
    /// Seeds, both ends included ([`parse_seeds`] reads `A-B` or `A`).
    pub seeds: RangeInclusive<u64>,
    /// Drive each seed careful, careless or both.
    pub driver: Drivers,
    /// How far the sensors are from ideal.
    pub profile: Profile,
    /// The GNSS receiver.
    pub receiver: Receiver,
    /// Finishing's anchors: street (simulated from the true path every 50 m) or none.
    pub anchors: Anchors,
    /// Hand finishing the receiver's true latency instead of letting it estimate one: an
    /// oracle that bounds what a better latency estimate could gain. Its figures are a
    /// bound, never the product's (the summary says so).
    pub oracle_latency: bool,
    /// Where the device's relative motion comes from: the camera's VO, or (a camera that
    /// publishes no VO at all) gyro + wheels dead reckoning; the drives' VO is then not
    /// recorded.
    pub relative_motion: RelativeMotion,
    /// How much doubt the logs' decisions allow (`--decide-at`, `--object-sigma`).
    pub doubt: DoubtSettings,
    /// Length of each drive, s.
    pub duration: f64,
    /// Drives run at once (default: one per core).
    pub jobs: Option<usize>,
    /// Output folder: runs.csv, runs.jsonl, summary.json, sweep.png.
    pub output: PathBuf,
    /// Keep each drive's files (generated streams, logs, anchors) under `OUTPUT/drives/`.
    pub keep: bool,
}

/// `A-B` or `A` as an inclusive range of seeds.
pub fn parse_seeds(text: &str) -> Result<RangeInclusive<u64>> {
    let number = |s: &str| -> Result<u64> {
        s.trim().parse().map_err(|_| Error::invalid(format!("`{s}` is not a seed (a whole number ≥ 0); give A-B or A")))
    };
    let (a, b) = match text.split_once('-') {
        Some((a, b)) => (number(a)?, number(b)?),
        None => {
            let a = number(text)?;
            (a, a)
        }
    };
    if a > b {
        return Err(Error::invalid(format!("{text}: the first seed is after the last (give A-B with A ≤ B)")));
    }
    Ok(a..=b)
}

/// One drive's verdict in one channel mode.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// nuPlan-style score, 0–100.
    pub score: f64,
    /// Score > 90.
    pub verified: bool,
    /// nuPlan's names of the metrics below 1.
    pub failed: Vec<String>,
    /// With the log's doubt (`verify --decide-at 2`): verified, rejected or undecided (the
    /// truth's, which has none, is its point verdict).
    pub decision: Decision,
    /// The score's interval within the doubt.
    pub score_interval: [f64; 2],
    /// Each metric that could flip within the doubt, in words.
    pub in_doubt: Vec<String>,
}

impl Verdict {
    fn of(report: &VerifyReport) -> Self {
        let failed =
            report.metrics.named().into_iter().filter(|(_, x)| *x < 1.0).map(|(name, _)| name.to_owned()).collect();
        let (decision, score_interval) = decision_or_point(report.decided.as_ref(), report.score);
        let in_doubt = report.decided.as_ref().map_or_else(Vec::new, |d| d.in_doubt.clone());
        Verdict { score: report.score, verified: report.verified, failed, decision, score_interval, in_doubt }
    }
}

/// A verdict in both channel modes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdicts {
    /// Every lane drivable (as the device verifies).
    pub insensitive: Verdict,
    /// Only the lanes along the route.
    pub sensitive: Verdict,
}

impl Verdicts {
    fn of(b: &super::drive::BothModes) -> Self {
        Verdicts { insensitive: Verdict::of(&b.insensitive), sensitive: Verdict::of(&b.sensitive) }
    }
}

/// What a drive came to: one row of the sweep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Row {
    /// The drive's seed.
    pub seed: u64,
    /// `careful` or `careless`.
    pub driver: &'static str,
    /// Sensor profile.
    pub profile: &'static str,
    /// GNSS receiver.
    pub receiver: &'static str,
    /// Finishing's anchors.
    pub anchors: &'static str,
    /// Finishing was told the receiver's true latency (`--oracle-latency`): this row is a
    /// bound, not the product's.
    pub oracle_latency: bool,
    /// Why the drive did not come through the product (then nothing else is filled).
    pub error: Option<String>,
    /// The true drive's verification.
    pub truth: Option<Verdicts>,
    /// The device's log's (none when it never anchored: nothing verified).
    pub online: Option<Verdicts>,
    /// The finished log's.
    pub finished: Option<Verdicts>,
    /// The online ego verified against the true objects (its tracks set aside).
    pub online_ego_true_agents: Option<Verdicts>,
    /// The finished ego verified against the true objects.
    pub finished_ego_true_agents: Option<Verdicts>,
    /// Online horizontal ego APE (RMSE over anchored frames), m; none when never anchored.
    pub online_ape_m: Option<f64>,
    /// Finished ego APE (RMSE), m.
    pub finished_ape_m: Option<f64>,
    /// The same two as a user measures them: each pose at its UTC stamp against the truth
    /// at that instant, m.
    pub online_ape_utc_m: Option<f64>,
    /// See `online_ape_utc_m`.
    pub finished_ape_utc_m: Option<f64>,
    /// The device's log's UTC against the drive's (median over its frames), s.
    pub online_clock_error_s: Option<f64>,
    /// The finished log's, s.
    pub finished_clock_error_s: Option<f64>,
    /// Online scale error at the last observable estimate (relative); none without VO.
    pub online_scale_error: Option<f64>,
    /// Finished scale against the VO's mean true scale (relative); none without VO.
    pub finished_scale_error: Option<f64>,
    /// MOTA of the online 3D tracks against the truth.
    pub online_mota: Option<f64>,
    /// IDF1 of the online 3D tracks.
    pub online_idf1: Option<f64>,
    /// MOTA of the finished tracks.
    pub finished_mota: Option<f64>,
    /// IDF1 of the finished tracks.
    pub finished_idf1: Option<f64>,
    /// Seconds from the first frame to the device's first anchored pose.
    pub first_anchor_s: Option<f64>,
    /// VO sessions in the drive (1: no re-initialisation).
    pub vo_sessions: u32,
    /// The device's camera mount at the end of the drive against the true one: the larger
    /// of the yaw and pitch errors, degrees (none when it wrote no estimate).
    pub mount_error_deg: Option<f64>,
    /// The device called its mount calibrated by the end of the drive.
    pub mount_calibrated: bool,
    /// The finished mount's yaw against the true one, degrees: what its objects were placed
    /// with.
    pub finished_mount_yaw_error_deg: Option<f64>,
    /// The device's poses stating a σ, and those of them within 2σ of the truth.
    pub online_sigma_poses: usize,
    /// See `online_sigma_poses`.
    pub online_within_2sigma: usize,
    /// Mean horizontal NEES of the device's poses (2 when their σ is right).
    pub online_nees: Option<f64>,
    /// Finished poses stating a σ, and those of them within 2σ of the truth.
    pub finished_sigma_poses: usize,
    /// See `finished_sigma_poses`.
    pub finished_within_2sigma: usize,
    /// Mean horizontal NEES of the finished poses (2 when their σ is right).
    pub finished_nees: Option<f64>,
    /// `finish`'s GNSS latency against the receiver's true one, s.
    pub latency_error_s: Option<f64>,
    /// The device's (its last observable anchor estimate's) against the true one, s.
    pub online_latency_error_s: Option<f64>,
    /// The horizontal length of the fixes' mean error over the drive (weighted by their
    /// stated σ, multipath left out), m: about what an estimate resting on these fixes
    /// alone for its position can expect, since errors correlated for up to 30 s do not
    /// average out within a drive (judged; never shown to the estimators).
    pub gnss_mean_error_m: Option<f64>,
    /// `finish`'s wheel factor (true distance / odometer distance) against the true one
    /// (the inverse of the wheels' scale error), relative.
    pub wheel_factor_error: Option<f64>,
    /// The device's 15 s windows beside the truth's.
    pub windows: Vec<WindowPair>,
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl Row {
    pub(super) fn empty(seed: u64, driver: Driver, args: &SweepRequest) -> Self {
        Row {
            seed,
            driver: driver.name(),
            profile: args.profile.name(),
            receiver: args.receiver.name(),
            anchors: args.anchors.name(),
            oracle_latency: args.oracle_latency,
            error: None,
            truth: None,
            online: None,
            finished: None,
            online_ego_true_agents: None,
            finished_ego_true_agents: None,
            online_ape_m: None,
            finished_ape_m: None,
            online_ape_utc_m: None,
            finished_ape_utc_m: None,
            online_clock_error_s: None,
            finished_clock_error_s: None,
            online_scale_error: None,
            finished_scale_error: None,
            online_mota: None,
            online_idf1: None,
            finished_mota: None,
            finished_idf1: None,
            first_anchor_s: None,
            vo_sessions: 0,
            mount_error_deg: None,
            finished_mount_yaw_error_deg: None,
            mount_calibrated: false,
            online_sigma_poses: 0,
            online_within_2sigma: 0,
            online_nees: None,
            finished_sigma_poses: 0,
            finished_within_2sigma: 0,
            finished_nees: None,
            latency_error_s: None,
            online_latency_error_s: None,
            gnss_mean_error_m: None,
            wheel_factor_error: None,
            windows: Vec::new(),
        }
    }

    fn with_assessment(mut self, a: &Assessment, facts: &DriveFacts) -> Self {
        let ape = |j: &crate::sim::scenario::judge::LogJudgement| (!j.ego_errors.is_empty()).then_some(j.ego_rmse);
        self.truth = Some(Verdicts::of(&a.truth));
        self.online = a.online.verification.as_ref().map(Verdicts::of);
        self.finished = a.finished.verification.as_ref().map(Verdicts::of);
        self.online_ego_true_agents = a.online.ego_with_true_agents.as_ref().map(Verdicts::of);
        self.finished_ego_true_agents = a.finished.ego_with_true_agents.as_ref().map(Verdicts::of);
        self.online_ape_m = ape(&a.online.judgement);
        self.finished_ape_m = ape(&a.finished.judgement);
        self.online_ape_utc_m = finite(a.online.judgement.ego_rmse_utc);
        self.finished_ape_utc_m = finite(a.finished.judgement.ego_rmse_utc);
        self.online_clock_error_s = a.online.judgement.clock_error_s;
        self.finished_clock_error_s = a.finished.judgement.clock_error_s;
        // A scale is the VO's; a dead-reckoned path's is the wheels' (the wheel factor's row).
        if facts.vo_recorded {
            self.online_scale_error = a.online_scale.map(|(_, e)| e);
            self.finished_scale_error = finite(a.finished_scale.2);
        }
        self.online_mota = finite(a.online.judgement.tracks.0);
        self.online_idf1 = finite(a.online.judgement.tracks.1);
        self.finished_mota = finite(a.finished.judgement.tracks.0);
        self.finished_idf1 = finite(a.finished.judgement.tracks.1);
        self.first_anchor_s = a.online.judgement.first_anchored_s;
        self.vo_sessions = facts.vo_sessions;
        self.mount_error_deg = facts.mount_error_deg;
        self.mount_calibrated = facts.mount_calibrated;
        self.finished_mount_yaw_error_deg = facts.finished_mount_yaw_error_deg;
        let sigma = a.online.judgement.sigma;
        self.online_sigma_poses = sigma.poses;
        self.online_within_2sigma = sigma.within_2sigma;
        self.online_nees = finite(sigma.nees());
        let sigma = a.finished.judgement.sigma;
        self.finished_sigma_poses = sigma.poses;
        self.finished_within_2sigma = sigma.within_2sigma;
        self.finished_nees = finite(sigma.nees());
        let anchoring = &a.finish_report.anchoring;
        self.latency_error_s = finite(anchoring.gnss_latency_s).map(|l| l - facts.true_latency_s);
        self.online_latency_error_s = a.online_latency_s.map(|l| l - facts.true_latency_s);
        self.gnss_mean_error_m = facts.gnss_mean_error_m;
        self.wheel_factor_error = finite(anchoring.wheel_factor).map(|w| w * facts.true_wheel_scale - 1.0);
        self.windows = a.windows.clone();
        self
    }
}

/// Generate drive `seed` with `driver`, record it from its files, judge it; its row.
fn run_drive(seed: u64, driver: Driver, args: &SweepRequest, work: &Path) -> Row {
    let row = Row::empty(seed, driver, args);
    match try_drive(seed, driver, args, work) {
        Ok((assessment, facts)) => row.with_assessment(&assessment, &facts),
        Err(e) => Row { error: Some(e.to_string()), ..row },
    }
}

/// What a drive's row takes from the scenario and the device's log besides the assessment.
struct DriveFacts {
    vo_sessions: u32,
    /// The camera's VO was recorded (not `--relative-motion imu-wheels`).
    vo_recorded: bool,
    mount_error_deg: Option<f64>,
    mount_calibrated: bool,
    finished_mount_yaw_error_deg: Option<f64>,
    /// The receiver's latency and the wheels' scale as the generator drew them (what the
    /// estimates are judged against; never shown to them).
    true_latency_s: f64,
    true_wheel_scale: f64,
    gnss_mean_error_m: Option<f64>,
}

/// The horizontal length of the fixes' mean error (fix − the true camera position at the
/// fix's time: the fixes describe the camera, as the scenario makes them), weighted by the
/// receiver's stated σ as a solve weighs them, the multipath fixes left out as a solve's
/// gate would, m; `None` without such fixes.
fn gnss_mean_error(scenario: &crate::sim::scenario::Scenario) -> Option<f64> {
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
fn mount_error(scenario: &crate::sim::scenario::Scenario, records: &[Record]) -> Option<(f64, f64, bool)> {
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
        crate::sim::scenario::ScenarioConfig { driver, ..config(seed, args.duration, args.profile, args.receiver)? };
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
finished_decision,finished_score_low,finished_score_high,online_decision";

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
        "{},{},{},{},{},{},{error},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
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
        return Err(Error::invalid(format!(
            "--duration {} must be between 10 and {MAX_DURATION_S} seconds",
            args.duration
        )));
    }
    if args.jobs == Some(0) {
        return Err(Error::invalid("--jobs must be at least 1"));
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_are_a_range_or_one_and_a_backward_range_is_refused() {
        assert_eq!(parse_seeds("3-7").ok(), Some(3..=7));
        assert_eq!(parse_seeds("12").ok(), Some(12..=12));
        let e = parse_seeds("5-2").expect_err("backwards").to_string();
        assert!(e.contains("first seed is after the last"), "{e}");
        assert!(parse_seeds("a-3").expect_err("not a number").to_string().contains("not a seed"));
        assert!(parse_seeds("-3").is_err());
    }
}
