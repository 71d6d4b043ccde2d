//! One recorded drive judged against the truth its generator knows: finished (with or
//! without street-imagery anchors), verified three ways (the true drive, the online log,
//! the finished log; both channel modes), the device's verification windows set against
//! the truth's over the same stretches, the anchoring's error and scale, the tracks'
//! MOTA/IDF1. `dash2sim demo` and `dash2sim scenario sweep` both judge their drives here, so
//! a sweep's row and a demo's summary of the same drive agree.

use std::path::Path;

use dash2sim_core::binlog::{Record, FRAME_DEAD_RECKONED};
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{Pose2, PACIFICA};

use crate::scenario::judge::{judge_log, LogJudgement};
use crate::scenario::street::street_anchors;
use crate::scenario::write::START_UNIX_S;
use crate::scenario::Scenario;
use crate::{Error, Result};
use dash2sim_finish::FinishReport;
use dash2sim_linux::ingest::map_tile::fine_index;
use dash2sim_linux::log::{self, LogContents};
use dash2sim_linux::record::Setup;
use dash2sim_verify::decide::{Decision, DoubtSettings};
use dash2sim_verify::{AgentsByTime, Metrics, StatedUncertainty, VerifyReport};

/// Which street-imagery anchors finishing is given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Anchors {
    /// Every 50 m of the drive, simulated from the true path under the profile's anchor
    /// model (σ 0.3 m per axis; wrong matches in the typical and hard profiles).
    #[default]
    Street,
    /// None: finishing has GNSS and wheel speed only.
    None,
}

impl Anchors {
    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Anchors::Street => "street",
            Anchors::None => "none",
        }
    }
}

/// Street-imagery anchors are simulated this far apart along the drive, m.
pub const ANCHOR_SPACING_M: f64 = 50.0;

/// Every metric of `verify` on an ego trajectory, channel-insensitive and channel-sensitive
/// (`verify --json`'s objects).
#[derive(Clone, Debug)]
pub struct BothModes {
    /// Every lane drivable, as the device verifies.
    pub insensitive: VerifyReport,
    /// Only the lanes along the driven route.
    pub sensitive: VerifyReport,
}

impl BothModes {
    /// nuPlan's verdicts of `ego` among `agents`.
    fn of(map: MapView<'_>, ego: &[(f64, Pose2)], agents: &AgentsByTime) -> Result<Self> {
        Self::in_doubt(map, ego, &StatedUncertainty::default(), agents, None)
    }

    /// The same, and with `doubt` the verdicts with the doubt of the ego's and the objects'
    /// stated `sigmas` ([`dash2sim_verify::decide`]).
    fn in_doubt(
        map: MapView<'_>,
        ego: &[(f64, Pose2)],
        sigmas: &StatedUncertainty,
        agents: &AgentsByTime,
        doubt: Option<DoubtSettings>,
    ) -> Result<Self> {
        let index = fine_index::for_checks(&map, 2 * dash2sim_verify::checks_in_doubt(ego.len()));
        let checker = fine_index::checker(map, PACIFICA, index.as_ref());
        let mode = |sensitive| -> Result<VerifyReport> {
            let v = dash2sim_verify::replay_in_doubt(checker, ego, sigmas, agents, sensitive, doubt)?;
            Ok(dash2sim_verify::report(&v, sensitive))
        };
        Ok(BothModes { insensitive: mode(false)?, sensitive: mode(true)? })
    }
}

/// The truth of a drive written to `drive_dir` ([`crate::scenario::write::write_scenario`])
/// verified both ways on its own road, among its true objects: what a driver kind's
/// [`Expectation`](crate::scenario::Expectation) holds.
pub fn verify_truth(scenario: &Scenario, drive_dir: &Path) -> Result<BothModes> {
    let [lat, lon, height] = scenario.config.origin;
    let origin = dash2sim_core::geo::Geodetic::new(lat, lon, height).map_err(Error::other)?;
    let tile = crate::scenario::write::road_tile(drive_dir, origin)?;
    let map = MapView::parse(&tile).map_err(|e| Error::refused("map", e))?;
    let agents = dash2sim_verify::read_objects(&drive_dir.join("objects.csv"))?;
    BothModes::of(map, &truth_ego(scenario), &agents)
}

/// A log judged: against the truth, and verified both ways.
#[derive(Clone, Debug)]
pub struct Judged {
    /// Ego error and tracks against the truth.
    pub judgement: LogJudgement,
    /// Its verification; none when the log has no ego pose (the device never anchored):
    /// nothing to verify, so nothing verified.
    pub verification: Option<BothModes>,
    /// Its ego verified against the true objects instead of its tracks: where this agrees
    /// with the truth and `verification` does not, the tracks made the difference.
    pub ego_with_true_agents: Option<BothModes>,
}

/// One of the device's verification windows and the truth's over the same stretch.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WindowPair {
    /// Drive time of its first and last pose, s from the first frame.
    pub start_s: f64,
    /// See `start_s`.
    pub end_s: f64,
    /// The device's score and verdict (channel-insensitive).
    pub device_score: f64,
    /// See `device_score`.
    pub device_verified: bool,
    /// The device's decision with the ego's doubt (none from a device that did not decide
    /// its windows).
    pub device_decision: Option<Decision>,
    /// The device's metrics below 1 (what its verdict rests on).
    pub device_failed: Vec<&'static str>,
    /// The true drive's score and verdict over the frames of the same stretch.
    pub truth_score: f64,
    /// See `truth_score`.
    pub truth_verified: bool,
    /// Whether the truth's window has an at-fault collision.
    pub truth_collision: bool,
    /// The truth's metrics below 1.
    pub truth_failed: Vec<&'static str>,
}

/// What a recorded drive came to.
#[derive(Debug)]
pub struct Assessment {
    /// The true drive verified against the true objects.
    pub truth: BothModes,
    /// The device's log.
    pub online: Judged,
    /// The finished log.
    pub finished: Judged,
    /// The anchors CSV finishing was given, if any.
    pub anchors_text: Option<String>,
    /// `finish`'s report.
    pub finish_report: FinishReport,
    /// The finished log.
    pub finished_log: LogContents,
    /// Its bytes.
    pub finished_bytes: Vec<u8>,
    /// The device's anchor scale at its last observable estimate, and its error against the
    /// VO's true scale then.
    pub online_scale: Option<(f64, f64)>,
    /// The GNSS latency of the device's last observable anchor estimate, s (0 when it had
    /// none to give).
    pub online_latency_s: Option<f64>,
    /// The finished scale, the VO's true scale averaged over its poses, and the error.
    pub finished_scale: (f64, f64, f64),
    /// The device's windows against the truth's.
    pub windows: Vec<WindowPair>,
}

/// The drive time (s from its first frame) of log time `t_us`, through the camera's frame
/// numbers; a log without camera frames (gyro + wheels: its frames are the dead reckoning's)
/// through its UTC clock, which the generated receiver sets to the drive's start at
/// [`START_UNIX_S`] (within the clock's tens of milliseconds).
pub fn drive_time(log: &LogContents, t_us: i64) -> Option<f64> {
    let first = log.records.iter().find_map(|r| match r {
        Record::FrameMeta(f) if f.frame == 1 && f.flags & FRAME_DEAD_RECKONED == 0 => Some(f.t_us),
        _ => None,
    });
    match first {
        Some(first) => Some((t_us - first) as f64 * 1e-6),
        None => Some(t_us as f64 * 1e-6 - START_UNIX_S),
    }
}

/// The VO's true scale at drive time `t` (the pose of the nearest earlier tracked frame).
fn true_scale_at(scenario: &Scenario, t: f64) -> Option<f64> {
    let frame = (t * scenario.config.frame_rate_hz).round() as usize;
    let k = scenario.vo.samples.partition_point(|s| s.frame <= frame);
    scenario.vo.samples.get(k.checked_sub(1)?).map(|s| s.scale)
}

/// The online anchor's scale at the end of the drive against the VO's true scale then.
fn online_scale(scenario: &Scenario, log: &LogContents) -> Option<(f64, f64)> {
    let (t_us, scale) = log.records.iter().rev().find_map(|r| match r {
        Record::AnchorEstimate(a) if a.observability == 2 => Some((a.t_us, a.scale_e6 as f64 * 1e-6)),
        _ => None,
    })?;
    let truth = true_scale_at(scenario, drive_time(log, t_us)?)?;
    Some((scale, scale / truth - 1.0))
}

/// The GNSS latency of the device's last observable anchor estimate, s.
fn online_latency(log: &LogContents) -> Option<f64> {
    log.records.iter().rev().find_map(|r| match r {
        Record::AnchorEstimate(a) if a.observability == 2 => Some(a.latency_us as f64 * 1e-6),
        _ => None,
    })
}

/// The true ego of every frame, as `verify` replays it.
pub fn truth_ego(scenario: &Scenario) -> Vec<(f64, Pose2)> {
    scenario.frames.iter().map(|f| (f.ego.t, Pose2::new(f.ego.x, f.ego.y, f.ego.heading))).collect()
}

/// The device's verification windows beside the truth's over the same stretches: window k
/// holds the ego poses (anchored or carried) after window k − 1's last, up to its own
/// record's time, so it starts at the first of them — after a gap in the ego, the window
/// the gap ended is not stretched over it.
fn window_pairs(
    scenario: &Scenario,
    log: &LogContents,
    map: MapView<'_>,
    agents: &AgentsByTime,
) -> Result<Vec<WindowPair>> {
    let truth = truth_ego(scenario);
    let mut previous_end = f64::NEG_INFINITY;
    let poses: Vec<f64> = log
        .records
        .iter()
        .filter_map(|r| match r {
            Record::EgoPose(p) => drive_time(log, p.t_us),
            _ => None,
        })
        .collect();
    // The device's first window opens a settling time after its first anchored pose.
    let first_open = poses.first().map(|t| t + dash2sim_core::pipeline::SETTLE_AFTER_ANCHORED_S);
    let mut pairs = Vec::new();
    for record in &log.records {
        let Record::Verification(v) = record else { continue };
        let Some(end) = drive_time(log, v.t_us) else { continue };
        let after = first_open.map_or(previous_end, |open| previous_end.max(open - 2e-6));
        let start = poses.iter().copied().find(|t| *t > after + 1e-6).unwrap_or(end).min(end);
        previous_end = end;
        let stretch: Vec<(f64, Pose2)> =
            truth.iter().copied().filter(|(t, _)| *t >= start - 1e-6 && *t <= end + 1e-6).collect();
        if stretch.is_empty() {
            continue;
        }
        let s = dash2sim_verify::replay(map, &stretch, agents, false, PACIFICA)?.scores;
        pairs.push(WindowPair {
            start_s: start,
            end_s: end,
            device_score: v.score_e2 as f64 / 100.0,
            device_verified: v.score_e2 > 9000,
            device_decision: Decision::of_code(v.decision),
            device_failed: Metrics::of_record(v).failed(),
            truth_score: s.score,
            truth_verified: s.verified,
            truth_collision: s.no_at_fault_collisions < 1.0,
            truth_failed: Metrics::of(&s).failed(),
        });
    }
    Ok(pairs)
}

fn judge(
    scenario: &Scenario,
    log: &LogContents,
    name: &str,
    map: MapView<'_>,
    true_agents: &AgentsByTime,
    doubt: DoubtSettings,
) -> Result<Judged> {
    let judgement = judge_log(scenario, log);
    if !log.records.iter().any(|r| matches!(r, Record::EgoPose(_))) {
        return Ok(Judged { judgement, verification: None, ego_with_true_agents: None });
    }
    let (ego, agents) = dash2sim_verify::from_contents(log, name, &map)?;
    let sigmas = StatedUncertainty::of(log);
    // The true objects are on the drive's clock (0 at the first frame), the log's ego on
    // the log's: move the objects onto the log's clock.
    let first_frame_ms = drive_time(log, 0).map_or(0, |t| (-t * 1000.0).round() as i64);
    let true_agents: AgentsByTime = true_agents.iter().map(|(ms, a)| (ms + first_frame_ms, a.clone())).collect();
    Ok(Judged {
        judgement,
        verification: Some(BothModes::in_doubt(map, &ego, &sigmas, &agents, Some(doubt))?),
        ego_with_true_agents: Some(BothModes::of(map, &ego, &true_agents)?),
    })
}

/// A generated drive and the device's log of it.
#[derive(Clone, Copy, Debug)]
pub struct Recorded<'a> {
    /// The drive, with its truth.
    pub scenario: &'a Scenario,
    /// Where its files were written (`objects.csv` is the truth verify reads).
    pub drive_dir: &'a Path,
    /// The device's log.
    pub log: &'a LogContents,
    /// The log's name in messages.
    pub log_name: &'a str,
    /// The map tile of its road.
    pub tile: &'a [u8],
    /// The device setup it was recorded with (finishing takes its mount and UERE).
    pub setup: &'a Setup,
}

/// Judge a recorded drive: finish it with `anchors` (the anchors CSV written to
/// `anchors_path`), verify the truth, the online and the finished log on the drive's map
/// tile, and set the device's windows against the truth's. `told_latency_s`, when given, is
/// the receiver's latency handed to finishing in place of its own estimate (the sweep's
/// `--oracle-latency`, a bound; the product never has it). The logs' decisions allow
/// `doubt`.
pub fn assess(
    recorded: &Recorded<'_>,
    anchors: Anchors,
    anchors_path: &Path,
    told_latency_s: Option<f64>,
    doubt: DoubtSettings,
) -> Result<Assessment> {
    let Recorded { scenario, drive_dir, log, log_name, tile, setup } = *recorded;
    let map = MapView::parse(tile).map_err(Error::other)?;
    let anchors_text = match anchors {
        Anchors::Street => {
            let text = street_anchors(scenario, log, ANCHOR_SPACING_M, scenario.config.seed);
            std::fs::write(anchors_path, &text).map_err(|e| Error::file(anchors_path, e))?;
            Some(text)
        }
        Anchors::None => None,
    };
    let anchor_file = anchors_text
        .as_deref()
        .map(dash2sim_finish::anchors::parse)
        .transpose()
        .map_err(|(line, why)| Error::line(anchors_path, line, why))?;
    let anchors_name = anchors_path.display().to_string();
    let settings = dash2sim_finish::solve::Settings { gravity_aligned: true, ..Default::default() };
    let settings = match told_latency_s {
        Some(latency) => settings.with_latency_held(latency),
        None => settings,
    };
    let finished = dash2sim_finish::finish(
        &log.compact(),
        log_name,
        anchor_file.as_ref().map(|f| (anchors_name.as_str(), f)),
        Some(tile),
        setup.mount,
        settings,
        setup.gnss.uere_m,
    )?;
    let header = log.header.ok_or_else(|| Error::invalid("the recorded log has no header"))?;
    let finished_bytes = log::import::encode_in_order(&header, finished.records.iter())?;
    let finished_log = log::decode(&finished_bytes, "finished").map_err(Error::other)?;

    let truth_agents = dash2sim_verify::read_objects(&drive_dir.join("objects.csv"))?;
    let truth = BothModes::of(map, &truth_ego(scenario), &truth_agents)?;
    let online = judge(scenario, log, "the online log", map, &truth_agents, doubt)?;
    let finished_judged = judge(scenario, &finished_log, "the finished log", map, &truth_agents, doubt)?;
    let windows = window_pairs(scenario, log, map, &truth_agents)?;

    let samples = &scenario.vo.samples;
    let true_mean_scale = samples.iter().map(|s| s.scale).sum::<f64>() / samples.len().max(1) as f64;
    let scale = finished.report.anchoring.scale;
    Ok(Assessment {
        truth,
        online_scale: online_scale(scenario, log),
        online_latency_s: online_latency(log),
        online,
        finished: finished_judged,
        anchors_text,
        finish_report: finished.report,
        finished_log,
        finished_bytes,
        finished_scale: (scale, true_mean_scale, scale / true_mean_scale - 1.0),
        windows,
    })
}
