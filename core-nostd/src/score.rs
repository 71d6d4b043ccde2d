//! The nuPlan-style closed-loop score of a replayed drive, computed streaming, one pose at
//! a time (nuPlan `planning/metrics/`, PDM's aggregation; docs/verify.md).
//!
//! score = Π multipliers × Σ wᵢ sᵢ / Σ wᵢ × 100, with
//! * multipliers: no at-fault collisions, drivable-area compliance, driving-direction
//!   compliance, ego is making progress;
//! * weighted: progress along the expert route (5), time to collision within bound (5),
//!   speed-limit compliance (4), comfort (2).
//!
//! A log is *verified* when its recorded ego, replayed against the map with the recorded
//! (non-reactive) agents, scores above [`VERIFIED_ABOVE`].
//!
//! Departures from nuPlan, all because a stream has no future and no map server:
//! * velocities are backward differences of consecutive poses; accelerations, jerks and
//!   yaw derivatives for comfort come from a quadratic Savitzky–Golay fit over a sliding
//!   window of [`COMFORT_WINDOW`] poses (nuPlan filters the whole series at once);
//! * progress is the length of the driven path, and the expert's is given to
//!   [`Scorer::finish`] (replaying the recorded ego, the expert is the ego: ratio 1);
//! * the lane the ego is in is the lane containing its footprint centre, kept while it
//!   still contains it (nuPlan's `ego_driven_route`);
//! * TTC projects both boxes step by step for every relevant agent, without nuPlan's
//!   pre-filter by elongated boxes (which only saves time); an agent's "stopped" speed
//!   and heading come from its recorded velocity and box.

use heapless::Deque;

use crate::drivable::{Channel, Checker, PoseCheck};
use crate::obb::{OrientedBox, Pose2};

/// A log is verified above this score.
pub const VERIFIED_ABOVE: f64 = 90.0;
/// Weights of progress, TTC, speed limit and comfort.
pub const WEIGHTS: [f64; 4] = [5.0, 5.0, 4.0, 2.0];
/// Poses in the comfort derivative window.
pub const COMFORT_WINDOW: usize = 7;
/// Poses kept for the driving-direction window by default (enough for 1 s at 100 Hz; a
/// scorer's `DIRECTION` parameter).
pub const DIRECTION_CAPACITY: usize = 128;
/// Agents remembered as already collided with (each collision counts once).
pub const COLLISION_CAPACITY: usize = 64;
/// An agent within this angle of the heading, seen from the rear axle, is ahead (rad).
const AHEAD_ANGLE: f64 = 30.0 * core::f64::consts::PI / 180.0;
/// An agent beyond this angle from the heading is behind (rad).
const BEHIND_ANGLE: f64 = 150.0 * core::f64::consts::PI / 180.0;

/// What kind of road user or object an agent is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AgentKind {
    /// Cars, trucks, buses: a collision scores 0.
    Vehicle,
    /// Pedestrians and cyclists (vulnerable road users): a collision scores 0.
    Vru,
    /// Static objects (cones, barriers, signs): each collision halves the multiplier.
    Object,
}

/// Another road user or object at the current time.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Agent {
    /// Track id, stable over time.
    pub id: u32,
    /// Kind.
    pub kind: AgentKind,
    /// Box in the map frame.
    pub bbox: OrientedBox,
    /// Velocity (east, north), m/s.
    pub velocity: (f64, f64),
    /// How well its place is known across the ego's path ([`PlaceSigma::NONE`]: as placed).
    /// [`Scorer::step_both_ways`] shrinks and grows its box by a multiple of it.
    pub sigma_across: PlaceSigma,
}

/// The σ of an agent's place across the ego's path, in 5 cm steps rounded up (so never
/// less than stated) up to 12.75 m: one byte, which rides in an [`Agent`]'s padding — a
/// device holds 64 agents in its windows and has no room for more.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlaceSigma(u8);

impl PlaceSigma {
    /// No σ: the agent is where it was placed.
    pub const NONE: PlaceSigma = PlaceSigma(0);
    const STEP_M: f64 = 0.05;

    /// `sigma` m, rounded up to the next 5 cm (12.75 m at most; none when not > 0 or NaN).
    pub fn from_m(sigma: f64) -> Self {
        if sigma.is_nan() || sigma <= 0.0 {
            return PlaceSigma::NONE;
        }
        PlaceSigma(libm::ceil(sigma / Self::STEP_M - 1e-9).clamp(1.0, 255.0) as u8)
    }

    /// The σ, m.
    pub fn m(self) -> f64 {
        f64::from(self.0) * Self::STEP_M
    }
}

impl Agent {
    /// The agent with its box larger by `by` m on every side (smaller when negative, down
    /// to a centimetre).
    pub fn grown(&self, by: f64) -> Agent {
        if by == 0.0 {
            return *self;
        }
        let bbox = OrientedBox {
            length: (self.bbox.length + 2.0 * by).max(0.01),
            width: (self.bbox.width + 2.0 * by).max(0.01),
            ..self.bbox
        };
        Agent { bbox, ..*self }
    }
}

/// How far a pose's position is in doubt (m, `k` of its stated σ along one axis), and
/// which way the doubt is taken ([`Scorer::step_with`]). The agents' own doubt is their
/// boxes': a caller grows each by its doubt (or shrinks it) with [`Agent::grown`] — each
/// agent has its own, and only the caller knows it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Doubt {
    /// The benefit of the doubt: the best the drive can be within it.
    For {
        /// The ego's position, m.
        ego: f64,
    },
    /// The doubt held against the ego: the worst the drive can be within it.
    Against {
        /// The ego's position, m.
        ego: f64,
    },
}

impl Doubt {
    /// No doubt: nuPlan's own scoring.
    pub const NONE: Doubt = Doubt::For { ego: 0.0 };

    /// The ego's doubt, m (≥ 0; none when not finite).
    fn ego(self) -> f64 {
        let (Doubt::For { ego } | Doubt::Against { ego }) = self;
        if ego.is_finite() {
            ego.max(0.0)
        } else {
            0.0
        }
    }
}

/// The six quantities nuPlan's comfort metric bounds — as bounds in [`ScoreConfig`], as
/// the extremes a drive reached in [`Scores`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Comfort {
    /// Longitudinal acceleration range (bounds) or min and max (extremes), m/s².
    pub lon_accel: (f64, f64),
    /// |Lateral acceleration|, m/s².
    pub lat_accel: f64,
    /// |Jerk|, m/s³.
    pub jerk: f64,
    /// |Longitudinal jerk|, m/s³.
    pub lon_jerk: f64,
    /// |Yaw rate|, rad/s.
    pub yaw_rate: f64,
    /// |Yaw acceleration|, rad/s².
    pub yaw_accel: f64,
}

impl Comfort {
    /// Extremes before anything was measured.
    const NONE: Comfort = Comfort {
        lon_accel: (f64::INFINITY, f64::NEG_INFINITY),
        lat_accel: 0.0,
        jerk: 0.0,
        lon_jerk: 0.0,
        yaw_rate: 0.0,
        yaw_accel: 0.0,
    };

    /// Whether these extremes stay strictly inside `bounds`.
    fn within(&self, bounds: &Comfort) -> bool {
        let b = bounds;
        // No window filled yet: nothing measured, nothing out of bounds.
        let measured = self.lon_accel.0 <= self.lon_accel.1;
        let lon_ok = !measured || (self.lon_accel.0 > b.lon_accel.0 && self.lon_accel.1 < b.lon_accel.1);
        lon_ok
            && self.lat_accel < b.lat_accel
            && self.jerk < b.jerk
            && self.lon_jerk < b.lon_jerk
            && self.yaw_rate < b.yaw_rate
            && self.yaw_accel < b.yaw_accel
    }
}

/// The settings of every metric; [`Default`] is nuPlan's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScoreConfig {
    /// TTC projection horizon and step, s.
    pub ttc_horizon: f64,
    /// TTC projection step, s.
    pub ttc_step: f64,
    /// TTC at or below this fails the TTC metric, s.
    pub ttc_threshold: f64,
    /// Ego at or below this speed is not checked for TTC, m/s.
    pub ttc_stopped_speed: f64,
    /// At or below this speed a vehicle counts as stopped in collision classification, m/s.
    pub stopped_speed: f64,
    /// Driving-direction window, s.
    pub direction_window: f64,
    /// Backwards progress below this per window scores 1, m.
    pub direction_compliant: f64,
    /// … below this 0.5, else 0, m.
    pub direction_violation: f64,
    /// Overspeed normaliser of the speed-limit score, m/s.
    pub overspeed_scale: f64,
    /// Progress ratio below which the ego is not making progress.
    pub min_progress_ratio: f64,
    /// Progress below this (ego or expert) counts as this, m.
    pub min_progress: f64,
    /// Comfort bounds.
    pub comfort: Comfort,
}

impl Default for ScoreConfig {
    fn default() -> Self {
        ScoreConfig {
            ttc_horizon: 3.0,
            ttc_step: 0.1,
            ttc_threshold: 0.95,
            ttc_stopped_speed: 5e-3,
            stopped_speed: 5e-2,
            direction_window: 1.0,
            direction_compliant: 2.0,
            direction_violation: 6.0,
            overspeed_scale: 2.23,
            min_progress_ratio: 0.2,
            min_progress: 2.0,
            comfort: Comfort {
                lon_accel: (-4.05, 2.40),
                lat_accel: 4.89,
                jerk: 8.37,
                lon_jerk: 4.13,
                yaw_rate: 0.95,
                yaw_accel: 1.93,
            },
        }
    }
}

/// Why a pose was refused (the scorer's state is unchanged).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ScoreError {
    /// A coordinate, heading or time is NaN or infinite.
    NotFinite,
    /// The time is not after the previous pose's.
    TimeNotIncreasing,
}

impl core::fmt::Display for ScoreError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ScoreError::NotFinite => "pose or time is not finite",
            ScoreError::TimeNotIncreasing => "time does not increase",
        })
    }
}

impl core::error::Error for ScoreError {}

/// A collision found at a step (each agent's first contact only).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Collision {
    /// The agent.
    pub id: u32,
    /// Its kind.
    pub kind: AgentKind,
    /// Whether the ego is at fault (nuPlan's classification).
    pub at_fault: bool,
}

/// What one step found.
#[derive(Clone, Debug, PartialEq)]
pub struct StepReport {
    /// The drivable-area check of the pose.
    pub check: PoseCheck,
    /// Ego speed (backward difference), m/s.
    pub speed: f64,
    /// Projected time to collision, s, if within the horizon.
    pub ttc: Option<f64>,
    /// The agent that time is to (the one collided with, at an at-fault collision).
    pub ttc_agent: Option<u32>,
    /// Progress along the lane direction over the last window, m (negative: against it).
    pub direction_progress: f64,
    /// A new collision, if any (the first of the step).
    pub collision: Option<Collision>,
    /// Whether the pose counted as on the drivable area, its doubt taken as the step was
    /// told ([`Scorer::step_with`]; without doubt, `check.compliant()`).
    pub compliant: bool,
}

/// Savitzky–Golay (quadratic) first and second derivative at the centre of a window of
/// equally spaced samples `dt` apart.
fn savitzky_golay(values: impl Iterator<Item = f64>, dt: f64) -> (f64, f64) {
    let m = (COMFORT_WINDOW / 2) as f64;
    let (mut first, mut second, mut norm1, mut norm2) = (0.0, 0.0, 0.0, 0.0);
    let mean_k2 = (1..=COMFORT_WINDOW / 2).map(|k| (k * k) as f64).sum::<f64>() * 2.0 / COMFORT_WINDOW as f64;
    for (i, y) in values.enumerate() {
        let k = i as f64 - m;
        first += k * y;
        norm1 += k * k;
        second += (k * k - mean_k2) * y;
        norm2 += (k * k - mean_k2) * (k * k - mean_k2);
    }
    (first / norm1 / dt, 2.0 * second / norm2 / (dt * dt))
}

/// Consecutive poses farther apart than this, s, leave a hole: the comfort metrics are not
/// differentiated across it (a device's window ends at such a gap; a finished log with a
/// hole is scored on either side of it, and never verified: `verify`).
pub const HOLE_S: f64 = 1.0;

/// A pose closer than this after the last one the comfort window took is left out of it, s.
/// nuPlan scores its simulations sampled at 10 Hz; the window's [`COMFORT_WINDOW`] poses at
/// a camera's 30 fps would span 0.2 s and turn centimetres of the poses' jitter into jerks
/// far past the bounds (every window of a 30 fps device failed comfort). Short of 0.1 s so
/// that a 10 Hz camera's jitter leaves none of its poses out; any frame rate above it is
/// taken at an even step (30 and 20 fps every 0.1 s, 25 fps every 0.12 s).
pub const COMFORT_STEP_S: f64 = 0.09;

/// Sliding-window comfort derivatives.
#[derive(Clone, Debug)]
struct ComfortWindow {
    /// (t, x, y, unwrapped heading).
    poses: Deque<(f64, f64, f64, f64), COMFORT_WINDOW>,
    /// (t, |a|, a_lon) at the centres of pose windows.
    accels: Deque<(f64, f64, f64), COMFORT_WINDOW>,
    extremes: Comfort,
}

impl ComfortWindow {
    fn new() -> Self {
        ComfortWindow { poses: Deque::new(), accels: Deque::new(), extremes: Comfort::NONE }
    }

    fn push(&mut self, t: f64, pose: &Pose2) {
        // A hole in the poses (a log missing a stretch of its ego) restarts the window: a
        // derivative across it would be of poses that are not there.
        if self.poses.back().is_some_and(|&(previous, ..)| t - previous > HOLE_S) {
            self.poses.clear();
            self.accels.clear();
        }
        if self.poses.back().is_some_and(|&(previous, ..)| t - previous < COMFORT_STEP_S) {
            return;
        }
        let heading = match self.poses.back() {
            Some(&(_, _, _, previous)) => previous + wrap(pose.heading - previous),
            None => pose.heading,
        };
        if self.poses.is_full() {
            self.poses.pop_front();
        }
        // Cannot fail: a slot was just freed.
        let _ = self.poses.push_back((t, pose.x, pose.y, heading));
        if !self.poses.is_full() {
            return;
        }
        let (Some(first), Some(last)) = (self.poses.front(), self.poses.back()) else { return };
        let dt = (last.0 - first.0) / (COMFORT_WINDOW - 1) as f64;
        let Some(&(tc, _, _, hc)) = self.poses.iter().nth(COMFORT_WINDOW / 2) else { return };
        let (_, ax) = savitzky_golay(self.poses.iter().map(|p| p.1), dt);
        let (_, ay) = savitzky_golay(self.poses.iter().map(|p| p.2), dt);
        let (yaw_rate, yaw_accel) = savitzky_golay(self.poses.iter().map(|p| p.3), dt);
        let (s, c) = libm::sincos(hc);
        let (lon, lat) = (ax * c + ay * s, -ax * s + ay * c);
        let e = &mut self.extremes;
        e.lon_accel = (e.lon_accel.0.min(lon), e.lon_accel.1.max(lon));
        e.lat_accel = e.lat_accel.max(libm::fabs(lat));
        e.yaw_rate = e.yaw_rate.max(libm::fabs(yaw_rate));
        e.yaw_accel = e.yaw_accel.max(libm::fabs(yaw_accel));
        if self.accels.is_full() {
            self.accels.pop_front();
        }
        let _ = self.accels.push_back((tc, libm::hypot(ax, ay), lon));
        if self.accels.is_full() {
            let (Some(a0), Some(a1)) = (self.accels.front(), self.accels.back()) else { return };
            let dt = (a1.0 - a0.0) / (COMFORT_WINDOW - 1) as f64;
            let (jerk, _) = savitzky_golay(self.accels.iter().map(|a| a.1), dt);
            let (lon_jerk, _) = savitzky_golay(self.accels.iter().map(|a| a.2), dt);
            e.jerk = e.jerk.max(libm::fabs(jerk));
            e.lon_jerk = e.lon_jerk.max(libm::fabs(lon_jerk));
        }
    }
}

/// Slack on the bounding discs of the TTC broad phase, m: far above the rounding of box
/// corners, far below anything that matters.
const DISC_MARGIN: f64 = 1e-6;

/// Half the diagonal of a box: the radius of its bounding disc.
fn half_diagonal(b: &OrientedBox) -> f64 {
    0.5 * libm::hypot(b.length, b.width)
}

/// When two discs `reach` apart at most (sum of radii) touch, their centres `relative`
/// apart and closing at `closing` (the second's velocity minus the first's): the interval
/// of times (s, may start in the past), or `None` when they never do.
fn disc_contact(relative: (f64, f64), closing: (f64, f64), reach: f64) -> Option<(f64, f64)> {
    let a = closing.0 * closing.0 + closing.1 * closing.1;
    let b = 2.0 * (relative.0 * closing.0 + relative.1 * closing.1);
    let c = relative.0 * relative.0 + relative.1 * relative.1 - reach * reach;
    if a <= f64::EPSILON {
        // No relative motion: touching now means touching throughout.
        return (c <= 0.0).then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    let discriminant = b * b - 4.0 * a * c;
    // Negative (or NaN from non-finite agents): the discs never touch.
    if discriminant.is_nan() || discriminant < 0.0 {
        return None;
    }
    let root = libm::sqrt(discriminant);
    Some(((-b - root) / (2.0 * a), (-b + root) / (2.0 * a)))
}

fn wrap(angle: f64) -> f64 {
    let a = libm::remainder(angle, core::f64::consts::TAU);
    if a.is_finite() {
        a
    } else {
        0.0
    }
}

/// What the evidence decides of a drive whose score is known only within an interval (the
/// ego's and the objects' doubt): `verify --decide-at`, `finish`'s windows and the
/// device's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize), serde(rename_all = "lowercase"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Decision {
    /// Verified anywhere within the doubt.
    Verified,
    /// Rejected anywhere within the doubt.
    Rejected,
    /// Verified somewhere within it and rejected elsewhere.
    Undecided,
}

impl Decision {
    /// Its name, as the JSON and the text say it.
    pub fn name(self) -> &'static str {
        match self {
            Decision::Verified => "verified",
            Decision::Rejected => "rejected",
            Decision::Undecided => "undecided",
        }
    }

    /// The decision of a score interval: verified when all of it is above nuPlan's 90,
    /// rejected when none of it is.
    pub fn of_interval(low: f64, high: f64) -> Self {
        if low > VERIFIED_ABOVE {
            Decision::Verified
        } else if high > VERIFIED_ABOVE {
            Decision::Undecided
        } else {
            Decision::Rejected
        }
    }

    /// The decision a `Verification` record's code says; none for 0 (a window not
    /// decided: a log before v1.7) or a code it does not know.
    pub fn of_code(code: i64) -> Option<Self> {
        match code {
            crate::binlog::DECISION_VERIFIED => Some(Decision::Verified),
            crate::binlog::DECISION_REJECTED => Some(Decision::Rejected),
            crate::binlog::DECISION_UNDECIDED => Some(Decision::Undecided),
            _ => None,
        }
    }

    /// Its code in a `Verification` record ([`crate::binlog::DECISION_VERIFIED`], …).
    pub fn code(self) -> i64 {
        match self {
            Decision::Verified => crate::binlog::DECISION_VERIFIED,
            Decision::Rejected => crate::binlog::DECISION_REJECTED,
            Decision::Undecided => crate::binlog::DECISION_UNDECIDED,
        }
    }
}

/// The final scores.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scores {
    /// No at-fault collisions: 1, 0.5 per static object hit (floored at 0), 0 after a
    /// vehicle or VRU.
    pub no_at_fault_collisions: f64,
    /// Drivable-area compliance: 1 or 0.
    pub drivable_area: f64,
    /// Driving-direction compliance: 1, 0.5 or 0.
    pub driving_direction: f64,
    /// Ego is making progress: 1 or 0.
    pub making_progress: f64,
    /// Progress along the expert route, 0..1.
    pub progress: f64,
    /// TTC within bound: 1 or 0.
    pub ttc: f64,
    /// Speed-limit compliance, 0..1.
    pub speed_limit: f64,
    /// Comfort: 1 or 0.
    pub comfort: f64,
    /// The aggregate, 0..100.
    pub score: f64,
    /// Score above [`VERIFIED_ABOVE`].
    pub verified: bool,
    /// Poses scored.
    pub poses: u32,
    /// Poses whose footprint was not compliant.
    pub noncompliant_poses: u32,
    /// Worst corner distance outside the drivable area over the drive, m.
    pub worst_corner: f64,
    /// Most negative progress along the lane direction in one window, m.
    pub min_direction_progress: f64,
    /// Smallest projected time to collision, s (infinite if none within the horizon).
    pub min_ttc: f64,
    /// At-fault collisions with vehicles or VRUs, and with objects; all collisions.
    pub collisions: (u32, u32, u32),
    /// ∫ overspeed dt, m.
    pub overspeed_integral: f64,
    /// Ego path length, m.
    pub ego_progress: f64,
    /// Duration, s.
    pub duration: f64,
    /// Comfort extremes.
    pub comfort_extremes: Comfort,
}

/// Scores a drive pose by pose. `DIRECTION` poses are kept for the driving direction's
/// one-second window: a source of more poses a second than that judges it over the last
/// `DIRECTION` (a device scoring a camera's frames needs its frame rate, not a log's 100 Hz).
#[derive(Clone, Debug)]
pub struct Scorer<'a, 's, const WORDS: usize, const DIRECTION: usize = DIRECTION_CAPACITY> {
    checker: Checker<'a>,
    channel: Channel<'s, WORDS>,
    config: ScoreConfig,
    first_t: Option<f64>,
    last: Option<(f64, Pose2)>,
    /// The map's metrics, with the ego's doubt taken the way each step says.
    map: MapTally,
    /// The collisions and times to collision with the agents as each step placed them
    /// (smaller by their doubt, [`Scorer::step_both_ways`]).
    contacts: Contacts,
    /// The map's metrics and the contacts with the doubt held against the ego, kept beside
    /// them by [`Scorer::step_both_ways`].
    against: Option<Against>,
    /// Each step's time and its progress along the lane, for `map` and for `against`.
    direction: Deque<(f64, [f64; 2]), DIRECTION>,
    comfort: ComfortWindow,
    /// The comfort of the ego's path without the corrections its anchoring eased in (the
    /// camera's own motion), where a device feeds it ([`Scorer::motion_beside`]).
    motion_comfort: Option<ComfortWindow>,
    poses: u32,
    worst_corner: f64,
    distance: f64,
}

/// The ego's contacts with the agents: the collisions nuPlan counts and the shortest time
/// to collision.
#[derive(Clone, Debug)]
struct Contacts {
    /// Agents already collided with (each collision counts once).
    collided: heapless::Vec<u32, COLLISION_CAPACITY>,
    /// At-fault collisions with vehicles and VRUs, at-fault collisions with objects, all.
    collisions: (u32, u32, u32),
    min_ttc: f64,
}

/// The ego at one step, as its contacts with the agents are judged.
#[derive(Clone, Copy)]
struct EgoStep<'c, 'a> {
    checker: &'c Checker<'a>,
    config: &'c ScoreConfig,
    pose: &'c Pose2,
    /// Its speed, m/s.
    speed: f64,
    /// Its drivable-area check (whether it is between lanes or off the road).
    check: &'c PoseCheck,
}

/// What the doubt held against the ego decides: the map's metrics and the contacts with
/// the agents grown by theirs.
#[derive(Clone, Debug)]
struct Against {
    map: MapTally,
    contacts: Contacts,
}

/// The metrics a drive's footprint on the map decides — drivable area, driving direction,
/// speed limit — with the ego's doubt taken one way. The collisions and the time to
/// collision are the objects' doubt's ([`Contacts`]); comfort is the stepped path's, or
/// with the benefit of the doubt also the motion's beside it ([`Scorer::motion_beside`]);
/// the speed and progress are taken as logged.
#[derive(Clone, Copy, Debug)]
struct MapTally {
    /// Poses whose footprint was not compliant.
    noncompliant: u32,
    /// The lane the centre was last in, and how far along it (m).
    lane: Option<(u32, f64)>,
    /// Most negative progress along the lane over one direction window, m.
    min_direction: f64,
    /// ∫ overspeed dt, m.
    overspeed: f64,
}

impl MapTally {
    const NONE: MapTally = MapTally { noncompliant: 0, lane: None, min_direction: 0.0, overspeed: 0.0 };
}

impl<'a, 's, const WORDS: usize> Scorer<'a, 's, WORDS> {
    /// A scorer for drives on `checker`'s map with `channel` as the drivable lanes, keeping
    /// [`DIRECTION_CAPACITY`] poses for the driving direction.
    pub fn new(checker: Checker<'a>, channel: Channel<'s, WORDS>, config: ScoreConfig) -> Self {
        Self::keeping_direction_poses(checker, channel, config)
    }
}

impl<'a, 's, const WORDS: usize, const DIRECTION: usize> Scorer<'a, 's, WORDS, DIRECTION> {
    /// [`Scorer::new`] keeping `DIRECTION` poses for the driving direction's window.
    pub fn keeping_direction_poses(checker: Checker<'a>, channel: Channel<'s, WORDS>, config: ScoreConfig) -> Self {
        Scorer {
            checker,
            channel,
            config,
            first_t: None,
            last: None,
            map: MapTally::NONE,
            contacts: Contacts::NONE,
            against: None,
            direction: Deque::new(),
            comfort: ComfortWindow::new(),
            motion_comfort: None,
            poses: 0,
            worst_corner: f64::NEG_INFINITY,
            distance: 0.0,
        }
    }

    /// Score the ego with its rear axle at `pose` at time `t` (s), among `agents`.
    pub fn step(&mut self, t: f64, pose: &Pose2, agents: &[Agent]) -> Result<StepReport, ScoreError> {
        self.step_with(t, pose, agents, Doubt::NONE)
    }

    /// [`Scorer::step`] for a pose whose position is in doubt by `doubt` m (a device's ego,
    /// `k` of its stated σ), given the benefit of the doubt on the map's metrics:
    /// [`Scorer::step_with`] with [`Doubt::For`]`(doubt)`. (The device's windows score both
    /// ways at once: [`Scorer::step_both_ways`].)
    pub fn step_in_doubt(
        &mut self,
        t: f64,
        pose: &Pose2,
        agents: &[Agent],
        doubt: f64,
    ) -> Result<StepReport, ScoreError> {
        self.step_with(t, pose, agents, Doubt::For { ego: doubt })
    }

    /// [`Scorer::step`] with the pose's position in doubt, taken the way `doubt` says. [`Doubt::For`] gives the ego the benefit of it: a corner breaks
    /// drivable-area compliance only when it is outside by nuPlan's 0.3 m and the ego's doubt
    /// more ([`PoseCheck::compliant_within`]); a centre in no lane heading the ego's way is
    /// taken to be in the nearest one that does within the doubt
    /// ([`Checker::lane_headed_within`]), for the driving direction and the speed limit.
    /// [`Doubt::Against`] holds it against the ego: the footprint must also be compliant
    /// moved its doubt to either side. The agents come as the caller placed them: each
    /// smaller by its own doubt on every side for the ego, larger against it
    /// ([`Agent::grown`]). Run once each way over a drive, the two scores
    /// ([`Scorer::finish`]) bound the drive's score for an ego moved sideways within its
    /// doubt and objects anywhere within theirs; the ego's speed, path shape and progress are
    /// taken as logged. The report's check is the pose's own; a doubt ≤ 0 or not finite is
    /// none.
    pub fn step_with(
        &mut self,
        t: f64,
        pose: &Pose2,
        agents: &[Agent],
        doubt: Doubt,
    ) -> Result<StepReport, ScoreError> {
        self.step_sides(t, pose, agents, (doubt, None), 0.0)
    }

    /// [`Scorer::step_in_doubt`] with each agent smaller by `agent_sigmas` of its
    /// [`Agent::sigma_across`] on every side, and beside it the same doubts held against the
    /// ego ([`Doubt::Against`], each agent larger by as much): one pass gives the drive's
    /// score both ways ([`Scorer::finish`], [`Scorer::finish_against`]) where two scorers
    /// would hold two of everything (a device's windows decide so, in 1.3 KB more than one
    /// scorer). The report is the benefit of the doubt's.
    pub fn step_both_ways(
        &mut self,
        t: f64,
        pose: &Pose2,
        agents: &[Agent],
        doubt: f64,
        agent_sigmas: f64,
    ) -> Result<StepReport, ScoreError> {
        let sides = (Doubt::For { ego: doubt }, Some(Doubt::Against { ego: doubt }));
        self.step_sides(t, pose, agents, sides, agent_sigmas)
    }

    /// One step with the ego's doubt taken `sides.0`'s way and, when there is a second,
    /// that way too beside it; each agent smaller by `agent_sigmas` of its σ for the first
    /// side and larger by as much for the second.
    fn step_sides(
        &mut self,
        t: f64,
        pose: &Pose2,
        agents: &[Agent],
        sides: (Doubt, Option<Doubt>),
        agent_sigmas: f64,
    ) -> Result<StepReport, ScoreError> {
        let (doubt, against) = sides;
        if !(t.is_finite() && pose.is_finite()) {
            return Err(ScoreError::NotFinite);
        }
        let (speed, dt) = match self.last {
            Some((t0, _)) if t <= t0 => return Err(ScoreError::TimeNotIncreasing),
            Some((t0, p0)) => {
                let step = libm::hypot(pose.x - p0.x, pose.y - p0.y);
                self.distance += step;
                (step / (t - t0), t - t0)
            }
            None => (0.0, 0.0),
        };
        self.first_t.get_or_insert(t);
        self.last = Some((t, *pose));
        self.poses += 1;

        let check = self.checker.check(pose, self.channel, self.map.lane.map(|(l, _)| l));
        self.worst_corner = self.worst_corner.max(check.worst());
        let (map, compliant, progress) = self.map_step(self.map, pose, &check, doubt, speed, dt);
        let against = against.map(|doubt| {
            let tally = self.against.as_ref().map_or(MapTally::NONE, |a| a.map);
            self.map_step(tally, pose, &check, doubt, speed, dt)
        });
        self.map = map;

        // Driving direction: progress along the lane the centre stays in, over the window.
        if self.direction.is_full() {
            self.direction.pop_front();
        }
        let _ = self.direction.push_back((t, [progress, against.map_or(0.0, |(_, _, p)| p)]));
        let horizon = t - self.config.direction_window - 1e-6;
        while self.direction.front().is_some_and(|&(t0, _)| t0 < horizon) {
            self.direction.pop_front();
        }
        let sum = |side: usize| -> f64 { self.direction.iter().map(|(_, p)| p[side]).sum() };
        let direction_progress = sum(0);
        self.map.min_direction = self.map.min_direction.min(direction_progress);
        if let Some((mut tally, _, _)) = against {
            tally.min_direction = tally.min_direction.min(sum(1));
            self.against.get_or_insert(Against { map: tally, contacts: Contacts::NONE }).map = tally;
        }

        self.comfort.push(t, pose);
        let moving = self.poses > 1 && speed > self.config.ttc_stopped_speed;
        let ego = EgoStep { checker: &self.checker, config: &self.config, pose, speed, check: &check };
        let (collision, ttc) = self.contacts.step(&ego, moving, agents, -agent_sigmas);
        if let (Some(_), Some(held)) = (against, self.against.as_mut()) {
            held.contacts.step(&ego, moving, agents, agent_sigmas);
        }
        Ok(StepReport {
            check,
            speed,
            ttc: ttc.map(|(t, _)| t),
            ttc_agent: ttc.map(|(_, id)| id),
            direction_progress,
            collision,
            compliant,
        })
    }

    /// One pose's map metrics added to `tally` with the ego's doubt taken `doubt`'s way:
    /// the tally, whether the footprint counts as compliant, and the progress along the
    /// lane the centre is in (m). [`Doubt::For`] gives the ego the benefit of it: a corner
    /// breaks drivable-area compliance only when it is outside by nuPlan's 0.3 m and the
    /// ego's doubt more ([`PoseCheck::compliant_within`]); a centre in no lane heading the
    /// ego's way is taken to be in the nearest one that does within the doubt
    /// ([`Checker::lane_headed_within`]), for the driving direction and the speed limit.
    /// [`Doubt::Against`] holds it against the ego: the footprint must also be compliant
    /// moved its doubt to either side.
    fn map_step(
        &self,
        mut tally: MapTally,
        pose: &Pose2,
        check: &PoseCheck,
        doubt: Doubt,
        speed: f64,
        dt: f64,
    ) -> (MapTally, bool, f64) {
        let ego_doubt = doubt.ego();
        let compliant = match doubt {
            Doubt::For { .. } => check.compliant_within(ego_doubt),
            Doubt::Against { .. } => check.compliant() && (ego_doubt == 0.0 || self.compliant_aside(pose, ego_doubt)),
        };
        if !compliant {
            tally.noncompliant += 1;
        }
        let lenient = matches!(doubt, Doubt::For { .. }) && ego_doubt > 0.0;
        let centre_lane = match check.centre_lane {
            Some(c) if !lenient || libm::cos(c.heading - pose.heading) > 0.0 => Some(c),
            own if lenient => self.checker.lane_headed_within(pose, ego_doubt).or(own),
            own => own,
        };
        let progress = match (centre_lane, tally.lane) {
            (Some(now), Some((lane, along))) if now.lane == lane => now.along - along,
            _ => 0.0,
        };
        tally.lane = centre_lane.map(|c| (c.lane, c.along));
        // Speed limit of the lane the centre is in.
        if let Some(limit) = centre_lane.and_then(|c| c.speed_limit) {
            tally.overspeed += (speed - limit).max(0.0) * dt;
        }
        (tally, compliant, progress)
    }

    /// Whether the footprint stays compliant moved `by` m to its left and to its right.
    fn compliant_aside(&self, pose: &Pose2, by: f64) -> bool {
        [by, -by].iter().all(|&left| {
            let (x, y) = pose.offset(0.0, left);
            self.checker.check(&Pose2::new(x, y, pose.heading), self.channel, self.map.lane.map(|(l, _)| l)).compliant()
        })
    }

    /// Beside the step at `t`, the ego's pose as its own motion alone put it (a device's
    /// VO path, without the corrections its anchoring eased in): with the benefit of the
    /// doubt the drive is comfortable when this path is or the stepped one is.
    pub fn motion_beside(&mut self, t: f64, pose: &Pose2) {
        self.motion_comfort.get_or_insert_with(ComfortWindow::new).push(t, pose);
    }

    /// The scores of the drive so far. `expert_progress` is the expert's path length
    /// (m); `None` when the replayed ego is the expert.
    pub fn finish(&self, expert_progress: Option<f64>) -> Scores {
        self.scores(&self.map, &self.contacts, expert_progress, true)
    }

    /// The scores of the drive so far with the ego's doubt held against it, where it was
    /// scored [`Scorer::step_both_ways`]; `None` otherwise.
    pub fn finish_against(&self, expert_progress: Option<f64>) -> Option<Scores> {
        self.against.as_ref().map(|a| self.scores(&a.map, &a.contacts, expert_progress, false))
    }

    fn scores(&self, map: &MapTally, contacts: &Contacts, expert_progress: Option<f64>, lenient: bool) -> Scores {
        let cfg = &self.config;
        let duration = match (self.first_t, self.last) {
            (Some(t0), Some((t1, _))) => t1 - t0,
            _ => 0.0,
        };
        let no_at_fault_collisions =
            if contacts.collisions.0 > 0 { 0.0 } else { (1.0 - 0.5 * f64::from(contacts.collisions.1)).max(0.0) };
        let drivable_area = if map.noncompliant == 0 { 1.0 } else { 0.0 };
        let backwards = -map.min_direction;
        let driving_direction = if backwards < cfg.direction_compliant {
            1.0
        } else if backwards < cfg.direction_violation {
            0.5
        } else {
            0.0
        };
        let expert = expert_progress.unwrap_or(self.distance);
        let progress = (self.distance.max(cfg.min_progress) / expert.max(cfg.min_progress)).min(1.0);
        let making_progress = if progress >= cfg.min_progress_ratio { 1.0 } else { 0.0 };
        let ttc = if contacts.min_ttc > cfg.ttc_threshold { 1.0 } else { 0.0 };
        let speed_limit =
            if duration > 0.0 { (1.0 - map.overspeed / (cfg.overspeed_scale * duration)).max(0.0) } else { 1.0 };
        let motion_comfortable =
            lenient && self.motion_comfort.as_ref().is_some_and(|m| m.extremes.within(&cfg.comfort));
        let comfort = if self.comfort.extremes.within(&cfg.comfort) || motion_comfortable { 1.0 } else { 0.0 };
        let weighted = (WEIGHTS[0] * progress + WEIGHTS[1] * ttc + WEIGHTS[2] * speed_limit + WEIGHTS[3] * comfort)
            / WEIGHTS.iter().sum::<f64>();
        let score = 100.0 * no_at_fault_collisions * drivable_area * driving_direction * making_progress * weighted;
        Scores {
            no_at_fault_collisions,
            drivable_area,
            driving_direction,
            making_progress,
            progress,
            ttc,
            speed_limit,
            comfort,
            score,
            verified: score > VERIFIED_ABOVE,
            poses: self.poses,
            noncompliant_poses: map.noncompliant,
            worst_corner: self.worst_corner,
            min_direction_progress: map.min_direction,
            min_ttc: contacts.min_ttc,
            collisions: contacts.collisions,
            overspeed_integral: map.overspeed,
            ego_progress: self.distance,
            duration,
            comfort_extremes: self.comfort.extremes,
        }
    }
}

impl Contacts {
    const NONE: Contacts = Contacts { collided: heapless::Vec::new(), collisions: (0, 0, 0), min_ttc: f64::INFINITY };

    /// The ego's contacts at one step with `agents`, each larger by `grow_sigmas` of its
    /// [`Agent::sigma_across`] (smaller when negative): the step's first new collision, and
    /// its time to collision (0 at an at-fault collision; projected only while `moving`)
    /// with the agent it is to.
    fn step(
        &mut self,
        ego: &EgoStep<'_, '_>,
        moving: bool,
        agents: &[Agent],
        grow_sigmas: f64,
    ) -> (Option<Collision>, Option<(f64, u32)>) {
        let placed = |a: &Agent| a.grown(grow_sigmas * a.sigma_across.m());
        let collision = self.collide(ego, agents.iter().map(placed));
        let ttc = match collision {
            // nuPlan: an at-fault collision is a TTC of 0.
            Some(c) if c.at_fault => Some((0.0, c.id)),
            _ if moving => self.ttc(ego, agents.iter().map(placed)),
            _ => None,
        };
        if let Some((ttc, _)) = ttc {
            self.min_ttc = self.min_ttc.min(ttc);
        }
        (collision, ttc)
    }

    /// nuPlan's collision classification for each agent's first contact.
    fn collide(&mut self, step: &EgoStep<'_, '_>, agents: impl Iterator<Item = Agent>) -> Option<Collision> {
        let EgoStep { checker, config, pose, speed, check } = *step;
        let ego = checker.footprint().at(pose);
        let mut first = None;
        for agent in agents {
            if self.collided.contains(&agent.id) || !ego.overlaps(&agent.bbox) {
                continue;
            }
            // Full: later contacts with further agents count again, never fewer.
            let _ = self.collided.push(agent.id);
            let stopped = libm::hypot(agent.velocity.0, agent.velocity.1) <= config.stopped_speed;
            let at_fault = if speed <= config.stopped_speed {
                false
            } else if agent.kind == AgentKind::Object || stopped || agent.bbox.touches_segment(ego.front_edge()) {
                true
            } else if agent.bbox.touches_segment(ego.rear_edge()) {
                false
            } else {
                // Lateral: the ego's fault while changing lanes or off the drivable area.
                check.occupied.len() > 1 || !check.compliant()
            };
            self.collisions.2 += 1;
            if at_fault {
                match agent.kind {
                    AgentKind::Object => self.collisions.1 += 1,
                    AgentKind::Vehicle | AgentKind::Vru => self.collisions.0 += 1,
                }
            }
            first.get_or_insert(Collision { id: agent.id, kind: agent.kind, at_fault });
        }
        first
    }

    /// Constant-velocity projection of ego and agents: the first time their boxes meet.
    /// As nuPlan: agents ahead (within 30° of the heading, seen from the rear axle) count;
    /// agents beside count too while the ego is between lanes or off the drivable area;
    /// agents behind (beyond 150°) and agents already collided with never do. Each agent
    /// moves along its heading at its speed. The time and the agent it is to.
    fn ttc(&self, step: &EgoStep<'_, '_>, agents: impl Iterator<Item = Agent>) -> Option<(f64, u32)> {
        let EgoStep { checker, config, pose, speed, check } = *step;
        let ego = checker.footprint().at(pose);
        let (s, c) = libm::sincos(pose.heading);
        let between_lanes = check.occupied.len() != 1 || !check.compliant();
        // The horizon itself is excluded, as numpy's arange(step, horizon, step).
        let steps = libm::ceil(config.ttc_horizon / config.ttc_step - 1e-9).clamp(1.0, 1000.0) as u32 - 1;
        let mut best: Option<(f64, u32)> = None;
        for agent in agents {
            let (dx, dy) = (agent.bbox.centre.x - pose.x, agent.bbox.centre.y - pose.y);
            let distance = libm::hypot(dx, dy);
            let cos_angle = if distance > 1e-9 { (dx * c + dy * s) / distance } else { 1.0 };
            let ahead = cos_angle > libm::cos(AHEAD_ANGLE);
            let behind = cos_angle < libm::cos(BEHIND_ANGLE);
            if self.collided.contains(&agent.id) || !(ahead || (between_lanes && !behind)) {
                continue;
            }
            let agent_speed = libm::hypot(agent.velocity.0, agent.velocity.1);
            let (sa, ca) = libm::sincos(agent.bbox.centre.heading);
            // Broad phase: the boxes can only meet while their bounding discs do; the exact
            // test runs on those steps alone, in the same order, so the result is the same.
            let relative = (agent.bbox.centre.x - ego.centre.x, agent.bbox.centre.y - ego.centre.y);
            let closing = (agent_speed * ca - speed * c, agent_speed * sa - speed * s);
            let reach = half_diagonal(&ego) + half_diagonal(&agent.bbox) + DISC_MARGIN;
            let Some((enter, leave)) = disc_contact(relative, closing, reach) else { continue };
            let step = config.ttc_step;
            let first = (libm::floor(enter / step).clamp(1.0, f64::from(steps.max(1))) as u32).max(1);
            let last = libm::ceil(leave / step).clamp(0.0, f64::from(steps)) as u32;
            for k in first..=last {
                let tk = f64::from(k) * config.ttc_step;
                if best.is_some_and(|(b, _)| tk >= b) {
                    break;
                }
                let e = ego.translated(speed * c * tk, speed * s * tk);
                let a = agent.bbox.translated(agent_speed * ca * tk, agent_speed * sa * tk);
                if e.overlaps(&a) {
                    best = Some((tk, agent.id));
                    break;
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn savitzky_golay_is_exact_on_quadratics() {
        // y = 3 + 2t + 1.5t², sampled 0.1 s apart around t = 0.
        let dt = 0.1;
        let values = (0..COMFORT_WINDOW).map(|i| {
            let t = (i as f64 - 3.0) * dt;
            3.0 + 2.0 * t + 1.5 * t * t
        });
        let (d1, d2) = savitzky_golay(values, dt);
        assert!((d1 - 2.0).abs() < 1e-9 && (d2 - 3.0).abs() < 1e-9, "{d1} {d2}");
    }

    #[test]
    fn comfort_sees_a_hard_brake_and_not_a_steady_cruise() {
        let mut cruise = ComfortWindow::new();
        let mut brake = ComfortWindow::new();
        for i in 0..40 {
            let t = f64::from(i) * 0.1;
            cruise.push(t, &Pose2::new(15.0 * t, 0.0, 0.0));
            // Brake at 6 m/s² from 20 m/s.
            brake.push(t, &Pose2::new(20.0 * t - 3.0 * t * t, 0.0, 0.0));
        }
        let bounds = ScoreConfig::default().comfort;
        assert!(cruise.extremes.within(&bounds), "{:?}", cruise.extremes);
        assert!(!brake.extremes.within(&bounds));
        assert!((brake.extremes.lon_accel.0 - -6.0).abs() < 1e-6, "{:?}", brake.extremes);
    }

    /// A steady cruise whose poses jitter by up to a centimetre (a camera's anchored poses),
    /// and a hard brake, sampled at `fps`: (the cruise's extremes, the brake's).
    fn jittery_drives(fps: u32) -> (Comfort, Comfort) {
        let (mut cruise, mut brake) = (ComfortWindow::new(), ComfortWindow::new());
        let mut state = 12_345u32;
        let mut jitter = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (f64::from(state >> 8) / f64::from(1u32 << 24) - 0.5) * 0.02
        };
        for i in 0..4 * fps {
            let t = f64::from(i) / f64::from(fps);
            let (dx, dy) = (jitter(), jitter());
            cruise.push(t, &Pose2::new(15.0 * t + dx, dy, 0.0));
            brake.push(t, &Pose2::new(20.0 * t - 3.0 * t * t + dx, dy, 0.0));
        }
        (cruise.extremes, brake.extremes)
    }

    #[test]
    fn comfort_is_judged_at_nuplans_10_hz_whatever_the_camera_rate() {
        let bounds = ScoreConfig::default().comfort;
        for fps in [10, 20, 25, 30] {
            let (cruise, brake) = jittery_drives(fps);
            assert!(cruise.within(&bounds), "{fps} fps: a steady cruise {cruise:?}");
            assert!(!brake.within(&bounds), "{fps} fps: a hard brake {brake:?}");
        }
    }
}
