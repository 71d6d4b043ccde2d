//! `dash2sim verify`: replay a recorded ego trajectory against a map tile, with the
//! recorded objects as non-reactive agents, and score it as nuPlan would
//! (`dash2sim_core::score`).
//!
//! Inputs: a TUM trajectory in the map's ENU frame (x east, y north, the pose at the rear
//! axle, heading from the quaternion's body x axis) and optionally an objects CSV in the
//! scenario format (`frame,t_s,id,class,x,y,z,yaw,l,w,h,vx,vy,static,visible`); the
//! objects of the frame nearest each pose (within [`OBJECT_TIME_TOLERANCE`]) are its agents.
//!
//! The crate `dash2sim-verify` (issue #56: verification out of the host library); `plot`
//! draws a drive with its verification.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod anchoring;
pub mod decide;
pub mod evaluate;
pub mod mot;
#[cfg(feature = "plot")]
pub mod plot;

use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use dash2sim_core::class;
use dash2sim_core::drivable::{Channel, Checker, LaneSet};
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{Footprint, OrientedBox, Pose2};
use dash2sim_core::score::{Agent, AgentKind, Doubt, PlaceSigma, ScoreConfig, Scorer, Scores, StepReport};
use dash2sim_linux::ingest::map_tile::fine_index;
use dash2sim_linux::{Error, Result};
use decide::{Decided, DoubtSettings, NearestPass, OffRoadInDoubt};

/// Objects farther in time than this from a pose are not its agents, s.
pub const OBJECT_TIME_TOLERANCE: f64 = 0.05;
/// Words of the channel lane set: maps of up to 32 × 8192 = 262 144 lanes.
const CHANNEL_WORDS: usize = 8192;

/// What `verify` was asked.
#[derive(Clone, Debug)]
pub struct VerifyRequest<'a> {
    /// The map tile.
    pub map: &'a Path,
    /// Where the ego comes from.
    pub ego: EgoSource<'a>,
    /// Objects CSV.
    pub objects: Option<&'a Path>,
    /// Only lanes near the driven route are drivable.
    pub channel_sensitive: bool,
    /// The ego's outline.
    pub footprint: Footprint,
    /// Per-pose CSV to write.
    pub poses: Option<&'a Path>,
    /// Only the poses within this time window, s (a nuPlan scenario's, for the cross-check).
    pub window: (f64, f64),
    /// How much doubt the decision allows (`--decide-at`, `--object-sigma`).
    pub doubt: DoubtSettings,
}

/// Agents by time (ms).
pub type AgentsByTime = BTreeMap<i64, Vec<Agent>>;

/// A log's ego poses (time, rear-axle pose), its agents, and the σ it states.
pub type LoggedDrive = (Vec<(f64, Pose2)>, AgentsByTime, StatedUncertainty);

/// The uncertainty a log states: each ego pose's horizontal σ (DRMS, m; in
/// [`from_contents`]'s order, 0 where it states none) and the covariance of each track's
/// place relative to the ego that states one (`TrackCovariance`: xx, xy, yy, m²), by id.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StatedUncertainty {
    /// Each ego pose's σ.
    pub ego: Vec<f64>,
    /// Each track's covariance, by id.
    pub tracks: BTreeMap<u32, [f64; 3]>,
}

impl StatedUncertainty {
    /// What `log` states.
    pub fn of(log: &dash2sim_linux::log::LogContents) -> Self {
        let ego = dash2sim_linux::log::views::ego_poses(log).map(|p| p.sigma_mm.max(0) as f64 * 1e-3).collect();
        let tracks = log
            .records
            .iter()
            .filter_map(|r| match r {
                dash2sim_core::binlog::Record::TrackCovariance(c) => Some((
                    u32::try_from(c.id).ok()?,
                    [c.cov_xx_mm2, c.cov_xy_mm2, c.cov_yy_mm2].map(|v| v as f64 * 1e-6),
                )),
                _ => None,
            })
            .collect();
        StatedUncertainty { ego, tracks }
    }

    /// The same tracks', the ego's of the poses in `poses` only.
    pub fn of_poses(&self, poses: std::ops::Range<usize>) -> Self {
        StatedUncertainty { ego: self.ego.get(poses).unwrap_or(&[]).to_vec(), tracks: self.tracks.clone() }
    }
}

/// The recorded drive to replay.
#[derive(Clone, Copy, Debug)]
pub enum EgoSource<'a> {
    /// A TUM trajectory of the rear axle in the map's ENU frame.
    Tum(&'a Path),
    /// A 4D log: its ego poses, and its 3D tracks as agents.
    Log(&'a Path),
}

/// Ego poses and agents from a 4D log, moved from the log's ENU frame into the map's
/// (through geodetic coordinates when the origins differ; headings are kept — the frames
/// of nearby origins differ by well under a milliradian per kilometre).
/// A damaged log's stretches are skipped, and `warn` told so.
/// With them, the σ the log states ([`StatedUncertainty`]).
pub fn from_log(path: &Path, map: &MapView<'_>, warn: &mut dyn FnMut(&str)) -> Result<LoggedDrive> {
    let log = dash2sim_linux::log::read(path).map_err(Error::other)?;
    if log.stats.damaged > 0 {
        warn(&format!("{}: {} damaged stretches skipped", path.display(), log.stats.damaged));
    }
    let (poses, agents) = from_contents(&log, &path.display().to_string(), map)?;
    Ok((poses, agents, StatedUncertainty::of(&log)))
}

/// [`from_log`] on a log already read (`name` for messages).
pub fn from_contents(
    log: &dash2sim_linux::log::LogContents,
    name: &str,
    map: &MapView<'_>,
) -> Result<(Vec<(f64, Pose2)>, AgentsByTime)> {
    use dash2sim_core::geo::{Geodetic, LocalFrame};
    use dash2sim_core::nalgebra::Vector3;
    use dash2sim_linux::log::views::{ego_enu, ego_poses, standing_objects, tracks};
    let header = log.header.ok_or_else(|| Error::invalid(format!("{name}: the header is damaged (no origin)")))?;
    let log_frame =
        dash2sim_linux::log::frame(&header).ok_or_else(|| Error::invalid(format!("{name}: invalid origin")))?;
    let [lat, lon, h] = map.header().origin;
    let map_frame = LocalFrame::new(Geodetic::new(lat, lon, h).map_err(|e| Error::refused("map origin", e))?);
    let same = (f64::from(header.origin[0]) * 1e-7 - lat).abs() < 1e-7
        && (f64::from(header.origin[1]) * 1e-7 - lon).abs() < 1e-7;
    let to_map = |v: Vector3<f64>| -> (f64, f64) {
        if same {
            return (v.x, v.y);
        }
        match log_frame.enu_to_geodetic(&v) {
            Ok(g) => {
                let m = map_frame.geodetic_to_enu(&g);
                (m.x, m.y)
            }
            Err(_) => (f64::NAN, f64::NAN),
        }
    };
    let poses: Vec<(f64, Pose2)> = ego_poses(log)
        .map(|p| {
            let (v, yaw) = ego_enu(p);
            let (x, y) = to_map(v);
            (p.t_us as f64 * 1e-6, Pose2::new(x, y, yaw))
        })
        .collect();
    if poses.is_empty() {
        return Err(Error::invalid(format!(
            "{name}: no ego poses to verify (a log of GNSS and speed only has none: record it with VO (from a file \
             or the camera process), finish it, or verify a trajectory file as the ego instead)"
        )));
    }
    let mut agents: BTreeMap<i64, Vec<Agent>> = BTreeMap::new();
    let at =
        |t: &dash2sim_core::binlog::Track3d| to_map(Vector3::new(t.x_mm as f64, t.y_mm as f64, t.z_mm as f64) * 1e-3);
    for (t_us, t) in tracks(log) {
        agents.entry((t_us as f64 / 1000.0).round() as i64).or_default().push(agent_of(t, at(t)));
    }
    // Static objects stand where they were seen after the camera lost them.
    for (last_us, standing) in standing_objects(log).into_values() {
        let agent = agent_of(&standing, at(&standing));
        let last_ms = (last_us as f64 / 1000.0).round() as i64;
        for frame in agents.range_mut(last_ms + 1..).map(|(_, a)| a) {
            if !frame.iter().any(|a| a.id == agent.id) {
                frame.push(agent);
            }
        }
    }
    Ok((poses, agents))
}

/// The agent a logged track state is, its centre at `at` in the map's frame; a track the
/// log reports static stands still ([`dash2sim_linux::log::views::track_velocity`]).
fn agent_of(t: &dash2sim_core::binlog::Track3d, at: (f64, f64)) -> Agent {
    Agent {
        id: u32::try_from(t.id).unwrap_or(u32::MAX),
        kind: class::by_code(t.class).map_or(AgentKind::Object, |c| c.kind),
        bbox: OrientedBox {
            centre: Pose2::new(at.0, at.1, t.yaw_e4 as f64 * 1e-4),
            length: t.l_mm as f64 * 1e-3,
            width: t.w_mm as f64 * 1e-3,
        },
        velocity: dash2sim_linux::log::views::track_velocity(t),
        sigma_across: PlaceSigma::NONE,
    }
}

/// Objects by time (ms), from an objects CSV (`dash2sim_linux::ingest::objects`).
pub fn read_objects(path: &Path) -> Result<BTreeMap<i64, Vec<Agent>>> {
    let mut by_time: BTreeMap<i64, Vec<Agent>> = BTreeMap::new();
    for row in dash2sim_linux::ingest::objects::read(path)? {
        let agent = Agent {
            id: row.id,
            kind: class::kind_of(&row.class),
            bbox: OrientedBox {
                centre: Pose2::new(row.centre[0], row.centre[1], row.yaw),
                length: row.size[0],
                width: row.size[1],
            },
            velocity: (row.velocity[0], row.velocity[1]),
            sigma_across: PlaceSigma::NONE,
        };
        by_time.entry((row.t * 1000.0).round() as i64).or_default().push(agent);
    }
    Ok(by_time)
}

/// The agents of the object frame nearest `t`, if within [`OBJECT_TIME_TOLERANCE`].
fn agents_at(objects: &BTreeMap<i64, Vec<Agent>>, t: f64) -> &[Agent] {
    let ms = (t * 1000.0).round() as i64;
    let tolerance = (OBJECT_TIME_TOLERANCE * 1000.0) as i64;
    objects
        .range(ms - tolerance..=ms + tolerance)
        .min_by_key(|(k, _)| (**k - ms).abs())
        .map_or(&[], |(_, agents)| agents.as_slice())
}

/// The outcome of a replay.
#[derive(Debug)]
pub struct Verification {
    /// Final scores.
    pub scores: Scores,
    /// Per-pose reports, with the pose's time and rear-axle pose.
    pub steps: Vec<(f64, Pose2, StepReport)>,
    /// Lanes on the channel (channel-sensitive mode).
    pub channel_lanes: Option<usize>,
    /// The verdict with its doubt ([`replay_in_doubt`]); none from [`replay`].
    pub decided: Option<Decided>,
}

/// Replay `poses` (time, rear-axle pose) on `map`: nuPlan's score.
pub fn replay(
    map: MapView<'_>,
    poses: &[(f64, Pose2)],
    objects: &BTreeMap<i64, Vec<Agent>>,
    channel_sensitive: bool,
    footprint: Footprint,
) -> Result<Verification> {
    let index = fine_index::for_checks(&map, poses.len());
    let checker = fine_index::checker(map, footprint, index.as_ref());
    replay_in_doubt(checker, poses, &StatedUncertainty::default(), objects, channel_sensitive, None)
}

/// How many footprint checks replaying `poses` in doubt costs in one channel mode: nuPlan's
/// score and, with a doubt, the two bounds ([`fine_index::for_checks`]).
pub fn checks_in_doubt(poses: usize) -> usize {
    3 * poses
}

/// [`replay`], and with `doubt` the verdict with its doubt ([`decide`]): the drive scored
/// again with `k` of each pose's σ and of each object's across the ego's path (`sigmas`:
/// what the log states; an object that states none has `--object-sigma`'s) for the ego,
/// and once more against it. `checker` holds the map and the ego's footprint (and the map's
/// fine index where one pays, [`fine_index::for_checks`]).
pub fn replay_in_doubt(
    checker: Checker<'_>,
    poses: &[(f64, Pose2)],
    sigmas: &StatedUncertainty,
    objects: &BTreeMap<i64, Vec<Agent>>,
    channel_sensitive: bool,
    doubt: Option<DoubtSettings>,
) -> Result<Verification> {
    let (map, footprint) = (*checker.map(), *checker.footprint());
    let mut channel_set: Box<LaneSet<CHANNEL_WORDS>> = Box::default();
    if channel_sensitive {
        if map.header().lanes as usize > LaneSet::<CHANNEL_WORDS>::capacity() {
            return Err(Error::invalid(format!(
                "the map has more than {} lanes",
                LaneSet::<CHANNEL_WORDS>::capacity()
            )));
        }
        for (_, pose) in poses {
            channel_set.add_route_pose(&map, &footprint, pose);
        }
    }
    let channel = if channel_sensitive { Channel::Sensitive(&*channel_set) } else { Channel::Insensitive };
    let mut scorer = Scorer::new(checker, channel, ScoreConfig::default());
    // With a doubt: the drive scored with it for the ego and against it, beside nuPlan's.
    let mut bounds = doubt.map(|_| {
        (Scorer::new(checker, channel, ScoreConfig::default()), Scorer::new(checker, channel, ScoreConfig::default()))
    });
    let mut steps = Vec::with_capacity(poses.len());
    let mut off_road: Option<OffRoadInDoubt> = None;
    let mut nearest: Option<NearestPass> = None;
    let (mut smaller, mut larger) = (Vec::new(), Vec::new());
    for (k, (t, pose)) in poses.iter().enumerate() {
        let agents = agents_at(objects, *t);
        let refused = |e| Error::refused(format!("pose {}", k + 1), e);
        let report = scorer.step(*t, pose, agents).map_err(refused)?;
        if let (Some((lenient, strict)), Some(settings)) = (bounds.as_mut(), doubt) {
            // A log states the horizontal σ as DRMS (both axes together); a corner leaves the
            // road along one of them, whose σ is DRMS / √2.
            let ego = settings.decide_at * sigmas.ego.get(k).copied().unwrap_or(0.0) / std::f64::consts::SQRT_2;
            smaller.clear();
            larger.clear();
            let ego_box = footprint.at(pose);
            for agent in agents {
                let by = decide::object_doubt(settings, sigmas.tracks.get(&agent.id), pose.heading);
                smaller.push(agent.grown(-by));
                larger.push(agent.grown(by));
                if let Some(pass) = NearestPass::of(*t, &ego_box, agent, by) {
                    if nearest.is_none_or(|n| pass.nearer_than(&n)) {
                        nearest = Some(pass);
                    }
                }
            }
            lenient.step_with(*t, pose, &smaller, Doubt::For { ego }).map_err(refused)?;
            let against = strict.step_with(*t, pose, &larger, Doubt::Against { ego }).map_err(refused)?;
            if !against.compliant && off_road.is_none() {
                off_road = Some(OffRoadInDoubt { t: *t, worst_corner_m: report.check.worst(), ego_doubt_m: ego });
            }
        }
        steps.push((*t, *pose, report));
    }
    let scores = scorer.finish(None);
    let decided = bounds.zip(doubt).map(|((lenient, strict), settings)| {
        decide::decided(
            &scores,
            &lenient.finish(None),
            &strict.finish(None),
            settings,
            sigmas,
            off_road.unwrap_or_default(),
            nearest,
            decide::holes(poses.iter().map(|(t, _)| *t)),
        )
    });
    Ok(Verification { scores, steps, channel_lanes: channel_sensitive.then(|| channel_set.len()), decided })
}

fn poses_csv(steps: &[(f64, Pose2, StepReport)]) -> String {
    let mut out = String::from(
        "t_s,x,y,heading,front_left_m,front_right_m,rear_right_m,rear_left_m,compliant,occupied_lanes,centre_lane,speed_mps,ttc_s,ttc_agent,direction_progress_m,collision_agent\n",
    );
    for (t, p, r) in steps {
        let corner = |c: Option<f64>| c.map_or_else(|| "inf".to_owned(), |d| format!("{d:.4}"));
        let occupied: Vec<String> = r.check.occupied.iter().map(u32::to_string).collect();
        let _ = writeln!(
            out,
            "{t:.3},{:.3},{:.3},{:.5},{},{},{},{},{},{},{},{:.3},{},{},{:.3},{}",
            p.x,
            p.y,
            p.heading,
            corner(r.check.corners[0]),
            corner(r.check.corners[1]),
            corner(r.check.corners[2]),
            corner(r.check.corners[3]),
            u8::from(r.check.compliant()),
            occupied.join(" "),
            r.check.centre_lane.map_or_else(String::new, |c| c.lane.to_string()),
            r.speed,
            r.ttc.map_or_else(String::new, |v| format!("{v:.1}")),
            r.ttc_agent.map_or_else(String::new, |id| id.to_string()),
            r.direction_progress,
            r.collision.as_ref().map_or_else(String::new, |c| c.id.to_string())
        );
    }
    out
}

/// The eight metrics, by nuPlan's names.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Multiplier.
    pub no_at_fault_collisions: f64,
    /// Multiplier.
    pub drivable_area_compliance: f64,
    /// Multiplier.
    pub driving_direction_compliance: f64,
    /// Multiplier.
    pub ego_is_making_progress: f64,
    /// Weight 5.
    pub ego_progress_along_expert_route: f64,
    /// Weight 5.
    pub time_to_collision_within_bound: f64,
    /// Weight 4.
    pub speed_limit_compliance: f64,
    /// Weight 2.
    pub ego_is_comfortable: f64,
}

impl Metrics {
    /// The metrics of `s`.
    pub fn of(s: &Scores) -> Self {
        Metrics {
            no_at_fault_collisions: s.no_at_fault_collisions,
            drivable_area_compliance: s.drivable_area,
            driving_direction_compliance: s.driving_direction,
            ego_is_making_progress: s.making_progress,
            ego_progress_along_expert_route: s.progress,
            time_to_collision_within_bound: s.ttc,
            speed_limit_compliance: s.speed_limit,
            ego_is_comfortable: s.comfort,
        }
    }

    /// The metrics a device's window record states.
    pub fn of_record(v: &dash2sim_core::binlog::Verification) -> Self {
        let m = |e4: i64| e4 as f64 * 1e-4;
        Metrics {
            no_at_fault_collisions: m(v.collisions_e4),
            drivable_area_compliance: m(v.drivable_e4),
            driving_direction_compliance: m(v.direction_e4),
            ego_is_making_progress: m(v.making_progress_e4),
            ego_progress_along_expert_route: m(v.progress_e4),
            time_to_collision_within_bound: m(v.ttc_e4),
            speed_limit_compliance: m(v.speed_limit_e4),
            ego_is_comfortable: m(v.comfort_e4),
        }
    }

    /// The names of the metrics below 1 (failed or reduced), in `named`'s order.
    pub fn failed(&self) -> Vec<&'static str> {
        self.named().into_iter().filter(|(_, v)| *v < 1.0).map(|(n, _)| n).collect()
    }

    /// Each metric with its name, the names in alphabetical order (the JSON's).
    pub fn named(&self) -> [(&'static str, f64); 8] {
        [
            ("drivable_area_compliance", self.drivable_area_compliance),
            ("driving_direction_compliance", self.driving_direction_compliance),
            ("ego_is_comfortable", self.ego_is_comfortable),
            ("ego_is_making_progress", self.ego_is_making_progress),
            ("ego_progress_along_expert_route", self.ego_progress_along_expert_route),
            ("no_at_fault_collisions", self.no_at_fault_collisions),
            ("speed_limit_compliance", self.speed_limit_compliance),
            ("time_to_collision_within_bound", self.time_to_collision_within_bound),
        ]
    }
}

/// `dash2sim verify --json`: the score, the metrics and what lies behind them.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VerifyReport {
    /// The eight metrics.
    pub metrics: Metrics,
    /// The score, 0–100.
    pub score: f64,
    /// Score > 90.
    pub verified: bool,
    /// Whether only the lanes along the route were drivable.
    pub channel_sensitive: bool,
    /// Those lanes, when channel-sensitive.
    pub channel_lanes: Option<usize>,
    /// Ego poses scored.
    pub poses: u32,
    /// Their span, s.
    pub duration_s: f64,
    /// What lies behind the metrics.
    pub details: Details,
    /// The verdict with the log's doubt: verified, rejected or undecided, the score's
    /// interval, and each metric that could flip (none when not asked for).
    pub decided: Option<Decided>,
}

/// What lies behind the metrics (non-finite values are null in JSON).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Details {
    /// Poses off the drivable area.
    pub noncompliant_poses: u32,
    /// The farthest a footprint corner got outside, m.
    pub worst_corner_outside_m: f64,
    /// The least progress along the lane's direction, m.
    pub min_progress_along_lane_direction_m: f64,
    /// The least time to collision, s.
    pub min_ttc_s: f64,
    /// At-fault collisions.
    pub collisions: Collisions,
    /// Speed over the limit, integrated, m.
    pub overspeed_integral_m: f64,
    /// The ego's progress, m.
    pub ego_progress_m: f64,
    /// The comfort extremes.
    pub comfort: ComfortReport,
}

/// Collisions.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Collisions {
    /// With agents, at fault.
    pub at_fault_agents: u32,
    /// With objects, at fault.
    pub at_fault_objects: u32,
    /// All.
    pub all: u32,
}

/// The comfort extremes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ComfortReport {
    /// Least and greatest longitudinal acceleration, m/s².
    pub lon_accel_mps2: [f64; 2],
    /// Greatest |lateral acceleration|, m/s².
    pub max_abs_lat_accel_mps2: f64,
    /// Greatest |jerk|, m/s³.
    pub max_abs_jerk_mps3: f64,
    /// Greatest |longitudinal jerk|, m/s³.
    pub max_abs_lon_jerk_mps3: f64,
    /// Greatest |yaw rate|, rad/s.
    pub max_abs_yaw_rate_radps: f64,
    /// Greatest |yaw acceleration|, rad/s².
    pub max_abs_yaw_accel_radps2: f64,
}

/// The report of `v` (`dash2sim verify --json`).
pub fn report(v: &Verification, channel_sensitive: bool) -> VerifyReport {
    let s = &v.scores;
    let e = &s.comfort_extremes;
    VerifyReport {
        metrics: Metrics::of(s),
        score: s.score,
        verified: s.verified,
        channel_sensitive,
        channel_lanes: v.channel_lanes,
        poses: s.poses,
        duration_s: s.duration,
        decided: v.decided.clone(),
        details: Details {
            noncompliant_poses: s.noncompliant_poses,
            worst_corner_outside_m: s.worst_corner,
            min_progress_along_lane_direction_m: s.min_direction_progress,
            min_ttc_s: s.min_ttc,
            collisions: Collisions {
                at_fault_agents: s.collisions.0,
                at_fault_objects: s.collisions.1,
                all: s.collisions.2,
            },
            overspeed_integral_m: s.overspeed_integral,
            ego_progress_m: s.ego_progress,
            comfort: ComfortReport {
                lon_accel_mps2: [e.lon_accel.0, e.lon_accel.1],
                max_abs_lat_accel_mps2: e.lat_accel,
                max_abs_jerk_mps3: e.jerk,
                max_abs_lon_jerk_mps3: e.lon_jerk,
                max_abs_yaw_rate_radps: e.yaw_rate,
                max_abs_yaw_accel_radps2: e.yaw_accel,
            },
        },
    }
}

/// Replay the request's ego trajectory against its map (the command line and the Python
/// package's `verify`): the verification, and the ego's source for messages.
pub fn evaluate<'a>(request: &VerifyRequest<'a>, warn: &mut dyn FnMut(&str)) -> Result<(Verification, &'a Path)> {
    let bytes = std::fs::read(request.map).map_err(|e| Error::file(request.map, e))?;
    let map = MapView::parse(&bytes).map_err(|e| Error::file(request.map, e))?;
    let (poses, mut objects, sigmas, name) = match request.ego {
        EgoSource::Tum(path) => {
            (dash2sim_linux::ingest::ego::read_ego(path)?, BTreeMap::new(), StatedUncertainty::default(), path)
        }
        EgoSource::Log(path) => {
            let (poses, agents, sigmas) = from_log(path, &map, warn)?;
            (poses, agents, sigmas, path)
        }
    };
    if let Some(path) = request.objects {
        objects = read_objects(path)?;
    }
    let (from, to) = request.window;
    let sigma_of = |k: usize| sigmas.ego.get(k).copied().unwrap_or(0.0);
    let (poses, ego_sigmas): (Vec<(f64, Pose2)>, Vec<f64>) = poses
        .into_iter()
        .enumerate()
        .filter(|(_, (t, _))| *t >= from && *t <= to)
        .map(|(k, pose)| (pose, sigma_of(k)))
        .unzip();
    let sigmas = StatedUncertainty { ego: ego_sigmas, tracks: sigmas.tracks };
    if poses.is_empty() {
        return Err(Error::file(name, format!("no ego poses between {from} and {to} s")));
    }
    let index = fine_index::for_checks(&map, checks_in_doubt(poses.len()));
    let checker = fine_index::checker(map, request.footprint, index.as_ref());
    let v = replay_in_doubt(checker, &poses, &sigmas, &objects, request.channel_sensitive, Some(request.doubt))?;
    if let Some(path) = request.poses {
        std::fs::write(path, poses_csv(&v.steps)).map_err(|e| Error::file(path, e))?;
    }
    Ok((v, name))
}

#[cfg(test)]
mod tests {
    use super::{agent_of, Metrics};
    use dash2sim_core::binlog::Track3d;

    /// A cone the log reports static is replayed standing still whatever its filtered
    /// velocity; a moving car keeps its velocity.
    #[test]
    fn a_static_track_stands_still_and_a_moving_one_moves() {
        let cone = Track3d { id: 7, class: 6, vx_mm_s: 400, vy_mm_s: -300, is_static: 1, ..Track3d::default() };
        assert_eq!(agent_of(&cone, (1.0, 2.0)).velocity, (0.0, 0.0));
        let car = Track3d { id: 8, class: 0, vx_mm_s: 15_000, vy_mm_s: -300, is_static: 0, ..Track3d::default() };
        let agent = agent_of(&car, (1.0, 2.0));
        assert_eq!(agent.velocity, (15.0, -0.3));
        assert_eq!((agent.id, agent.bbox.centre.x, agent.bbox.centre.y), (8, 1.0, 2.0));
    }

    /// `named` is what the sweep lists failed metrics from: the JSON's names, in its order.
    #[test]
    fn named_metrics_are_the_json_ones_in_its_order() {
        let m = Metrics {
            no_at_fault_collisions: 1.0,
            drivable_area_compliance: 0.0,
            driving_direction_compliance: 0.5,
            ego_is_making_progress: 1.0,
            ego_progress_along_expert_route: 0.9,
            time_to_collision_within_bound: 1.0,
            speed_limit_compliance: 0.8,
            ego_is_comfortable: 1.0,
        };
        let json = serde_json::to_value(m).expect("serialises");
        let keys: Vec<&str> = json.as_object().expect("an object").keys().map(String::as_str).collect();
        let named = m.named();
        assert_eq!(keys, named.iter().map(|(n, _)| *n).collect::<Vec<_>>());
        for (name, value) in named {
            assert_eq!(json[name].as_f64(), Some(value), "{name}");
        }
    }
}
