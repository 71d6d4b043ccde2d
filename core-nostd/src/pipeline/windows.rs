//! The verification windows: the eased ego, a second late, and the latest tracks as agents
//! scored as nuPlan scores a log replay, one window after another; each closed window a
//! record and an event. The stage keeps its own state (the open window, the agents, the
//! ego's doubt); the anchoring tells it when the device first anchored and how far the ego
//! is in doubt, the tracking which agents it reports, and the pipeline hands it each eased
//! pose (smoothed here, [`lag`]) with the log to write to.

use embedded_io::Write;

use super::sink::LogSink;
use super::{edge, lag, verification_record, PipelineConfig, PipelineError};
use crate::binlog::{quantise, Record, Verification};
use crate::decimal::Decimal;
use crate::drivable::{Channel, Checker};
use crate::obb::Pose2;
use crate::score::{Agent, Decision, Scorer, Scores};
use crate::time::Timestamp;

/// Agents the tracker stopped reporting are scored for this long after (s): the smoothed
/// ego's lag ([`lag`]) and half a second.
const KEEP_LOST_S: f64 = 1.5;

/// At most this many of them.
const KEPT_AGENTS: usize = 16;

/// Poses a window's scorer keeps for the driving direction's one-second window: a camera's
/// frames, up to 64 fps (a log's 100 Hz needs the default 128; 1.5 KB less RAM).
const WINDOW_DIRECTION_POSES: usize = 64;

/// The first window opens this long after the device's first anchored pose, s: the
/// anchor's first corrections (its rotation and scale still settling, eased in) are its
/// own motion, not the driver's, and would be scored as jerks and speeds.
pub const SETTLE_AFTER_ANCHORED_S: f64 = 3.0;

/// The open window and the agents it scores.
#[derive(Debug)]
pub(super) struct Windows<'a, const T3: usize> {
    /// The eased ego, smoothed a second late ([`lag`]).
    lag: lag::FixedLag,
    /// The relative motion's path alone (the eased ego less its corrections), smoothed the
    /// same way beside it.
    motion_lag: lag::FixedLag,
    agents: heapless::Vec<Agent, T3>,
    /// Of `agents`, those the tracker no longer reports, and since when (s).
    lost: heapless::Vec<(u32, f64), KEPT_AGENTS>,
    agents_t: f64,
    /// Where the ego last scored was (east, north): the agents nearest it are the ones kept
    /// when there are more than the stage holds.
    scored_at: Option<(f64, f64)>,
    window: Option<Window<'a>>,
    /// The windows' latest at-fault collision, carried across a window's end ([`edge`]).
    edge_collisions: edge::EdgeCollisions,
    /// How far the ego's position is in doubt (m): the configured number of the latest
    /// anchored or carried pose's σ.
    doubt_m: f64,
    /// No window opens before this time (s): the first anchored pose's and
    /// [`SETTLE_AFTER_ANCHORED_S`]; never until the device has anchored.
    open_from: f64,
}

impl<const T3: usize> Default for Windows<'_, T3> {
    fn default() -> Self {
        Windows {
            lag: lag::FixedLag::new(),
            motion_lag: lag::FixedLag::new(),
            agents: heapless::Vec::new(),
            lost: heapless::Vec::new(),
            agents_t: 0.0,
            scored_at: None,
            window: None,
            edge_collisions: edge::EdgeCollisions::default(),
            doubt_m: 0.0,
            open_from: f64::INFINITY,
        }
    }
}

/// One verification window.
#[derive(Clone, Debug)]
struct Window<'a> {
    start: f64,
    /// The time of the last pose it scored.
    last: Timestamp,
    scorer: Scorer<'a, 'static, 1, WINDOW_DIRECTION_POSES>,
    /// The multiplier of a collision in the last second of the window before ([`edge`]).
    inherited_collision: Option<f64>,
}

impl<'a, const T3: usize> Windows<'a, T3> {
    /// The device anchored for the first time at `t` (s): the first window opens
    /// [`SETTLE_AFTER_ANCHORED_S`] later.
    pub(super) fn anchored_first_at(&mut self, t: f64) {
        self.open_from = t + SETTLE_AFTER_ANCHORED_S;
    }

    /// The ego's position is in doubt by `doubt_m` (m) from now on.
    pub(super) fn ego_in_doubt(&mut self, doubt_m: f64) {
        self.doubt_m = doubt_m;
    }

    /// The agents the tracker reports at `now` (s), `reports(id)` saying whether an id is
    /// among them: they replace the last ones; those it stopped reporting stay
    /// [`KEEP_LOST_S`] (at most [`KEPT_AGENTS`]), moved on by their velocity — the windows
    /// score the ego a second back, when the cone the car passed was still beside it (most
    /// leave the camera's view, not the road).
    ///
    /// When there are more than `T3` of them (a camera reporting as many objects as the
    /// tracker holds, and the ones just passed beside), the ones nearest the ego last scored
    /// are kept: a cone 60 m ahead of the camera is 75 m ahead of the ego being scored, the
    /// drum it just passed is beside it.
    pub(super) fn agents_reported(
        &mut self,
        now: f64,
        reports: impl Fn(u32) -> bool,
        reported: impl Iterator<Item = Agent>,
    ) {
        let dt = now - self.agents_t;
        let mut kept: heapless::Vec<(Agent, f64), KEPT_AGENTS> = heapless::Vec::new();
        for a in &self.agents {
            if reports(a.id) {
                continue;
            }
            let since = self.lost.iter().find(|(id, _)| *id == a.id).map_or(now, |l| l.1);
            if now - since <= KEEP_LOST_S {
                let mut a = *a;
                a.bbox.centre.x += a.velocity.0 * dt;
                a.bbox.centre.y += a.velocity.1 * dt;
                // At most KEPT_AGENTS kept; beyond, the rest are forgotten.
                let _ = kept.push((a, since));
            }
        }
        self.agents.clear();
        self.lost.clear();
        self.agents_t = now;
        for a in reported.chain(kept.iter().map(|(a, _)| *a)) {
            admit_nearest(&mut self.agents, a, self.scored_at);
        }
        for (a, since) in kept {
            if self.agents.iter().any(|held| held.id == a.id) {
                // Cannot fail: `lost` holds as many as `kept`.
                let _ = self.lost.push((a.id, since));
            }
        }
    }

    /// The eased ego at `t` and its relative motion alone (`motion`, [`super::ease`]): each
    /// into its smoother, and what they give out (a second back) scored together.
    pub(super) fn ego<W: Write, const BUF: usize>(
        &mut self,
        config: &PipelineConfig<'a>,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
        eased: Pose2,
        motion: Pose2,
    ) -> Result<(), PipelineError<W::Error>> {
        let motions = self.motion_lag.push(t, motion);
        for (at, smoothed) in self.lag.push(t, eased) {
            let motion = motions.iter().find(|(m, _)| *m == at).map(|(_, p)| *p);
            self.score(config, log, at, &smoothed, motion)?;
        }
        Ok(())
    }

    /// The drive ends at `t`: the poses the smoother still holds scored, the open window
    /// closed.
    pub(super) fn finish<W: Write, const BUF: usize>(
        &mut self,
        config: &PipelineConfig<'a>,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
    ) -> Result<(), PipelineError<W::Error>> {
        let motions = self.motion_lag.flush();
        for (at, smoothed) in self.lag.flush() {
            let motion = motions.iter().find(|(m, _)| *m == at).map(|(_, p)| *p);
            self.score(config, log, at, &smoothed, motion)?;
        }
        self.close(log, t)
    }

    /// One smoothed ego pose (of `t`, a second back) into the open verification window, with
    /// the relative motion's of the same time beside it for comfort: the agents moved to `t`
    /// by their velocity (back, from their latest update); a window that reached its length
    /// is closed at `t`.
    fn score<W: Write, const BUF: usize>(
        &mut self,
        config: &PipelineConfig<'a>,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
        ego: &Pose2,
        motion: Option<Pose2>,
    ) -> Result<(), PipelineError<W::Error>> {
        let Some(map) = config.map else { return Ok(()) };
        self.scored_at = Some((ego.x, ego.y));
        let ts = t.as_secs_f64();
        // A gap in the ego (a VO re-initialisation's missing frames, or a new session not yet
        // observable after the carry gave up) ends the window at its last pose: the device
        // did not see what happened in the gap, and a window verified over it would vouch
        // for it.
        if let Some(last) = self.window.as_ref().map(|w| w.last) {
            if (t - last).as_secs_f64() > lag::MAX_GAP_S {
                self.close(log, last)?;
            }
        }
        if self.window.is_none() && ts >= self.open_from {
            let checker = Checker::new(map, config.footprint);
            self.window = Some(Window {
                start: ts,
                last: t,
                scorer: Scorer::keeping_direction_poses(checker, Channel::Insensitive, config.score),
                inherited_collision: self.edge_collisions.carried_into(ts),
            });
        }
        // The latest tracks, moved by their velocity to this pose's time (in place: a copy
        // of 64 agents is 4.6 KB of a microcontroller's stack).
        let dt = ts - self.agents_t;
        for a in self.agents.iter_mut() {
            a.bbox.centre.x += a.velocity.0 * dt;
            a.bbox.centre.y += a.velocity.1 * dt;
        }
        self.agents_t = ts;
        let Some(window) = self.window.as_mut() else { return Ok(()) };
        // A refused pose (not finite, time not increasing) leaves the window as it was. The
        // ego's doubt and the agents' (as many of their σ as of the ego's) are given to it
        // and, beside, held against it: the window is decided.
        let agent_sigmas = config.window_doubt_sigmas;
        if let Ok(report) = window.scorer.step_both_ways(ts, ego, &self.agents, self.doubt_m, agent_sigmas) {
            window.last = t;
            if let Some(motion) = motion {
                window.scorer.motion_beside(ts, &motion);
            }
            if let Some(collision) = &report.collision {
                self.edge_collisions.push(ts, collision);
            }
        }
        if ts - window.start >= config.window_s {
            self.close(log, t)?;
        }
        Ok(())
    }

    /// Closes the open window: its scores with the ego's doubt given to it (the record's
    /// score, as before windows were decided) and held against it bound the window's score,
    /// and decide it (verified, rejected or undecided, as `verify --decide-at` does).
    fn close<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
    ) -> Result<(), PipelineError<W::Error>> {
        let Some(window) = self.window.take() else { return Ok(()) };
        let inherit = |own: Scores| window.inherited_collision.map_or(own, |m| edge::inherit(&own, m));
        let s = inherit(window.scorer.finish(None));
        let against = window.scorer.finish_against(None).map_or(s, inherit);
        if s.poses == 0 {
            return Ok(());
        }
        let (low, high) = (s.score.min(against.score), s.score.max(against.score));
        let decision = Decision::of_interval(low, high);
        let stats = &mut log.stats;
        stats.windows = stats.windows.saturating_add(1);
        match decision {
            Decision::Verified => stats.windows_verified = stats.windows_verified.saturating_add(1),
            Decision::Undecided => stats.windows_undecided = stats.windows_undecided.saturating_add(1),
            Decision::Rejected => {}
        }
        if s.no_at_fault_collisions < 1.0 {
            stats.collision_windows = stats.collision_windows.saturating_add(1);
        }
        let record = Verification {
            decision: decision.code(),
            score_low_e2: quantise(low, 1e-2),
            score_high_e2: quantise(high, 1e-2),
            ..verification_record(log.time(t), &s)
        };
        log.write(&Record::Verification(record))?;
        log.event(
            t,
            2,
            format_args!(
                "verification window of {} s: score {} to {}, {}",
                Decimal::new(s.duration, 1),
                Decimal::new(low, 2),
                Decimal::new(high, 2),
                decision.name()
            ),
        )
    }
}

/// `agent` into `agents`; when they are full, in place of the one farthest from `near` if it
/// is nearer than that one (without `near`, the first ones in stay). Bounded: one pass over
/// the `N` held.
fn admit_nearest<const N: usize>(agents: &mut heapless::Vec<Agent, N>, agent: Agent, near: Option<(f64, f64)>) {
    let Err(agent) = agents.push(agent) else { return };
    let Some((x, y)) = near else { return };
    let distance = |a: &Agent| libm::hypot(a.bbox.centre.x - x, a.bbox.centre.y - y);
    let farthest = agents.iter_mut().max_by(|a, b| distance(a).total_cmp(&distance(b)));
    if let Some(farthest) = farthest.filter(|f| distance(&agent) < distance(f)) {
        *farthest = agent;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obb::OrientedBox;
    use crate::score::{AgentKind, PlaceSigma};

    fn cone(id: u32, x: f64, y: f64) -> Agent {
        let bbox = OrientedBox { centre: Pose2::new(x, y, 0.0), length: 0.4, width: 0.4 };
        Agent { id, kind: AgentKind::Object, bbox, velocity: (0.0, 0.0), sigma_across: PlaceSigma::NONE }
    }

    /// Four agents held; the drum beside the ego leaves the camera's view while four cones
    /// far ahead are reported: `scored_at` the ego being scored. The ids held after.
    fn held_after_passing_a_drum(scored_at: Option<(f64, f64)>) -> heapless::Vec<u32, 4> {
        let mut windows = Windows::<'static, 4> { scored_at, ..Windows::default() };
        let first = [cone(1, 2.0, 1.5), cone(10, 50.0, 7.0), cone(11, 53.0, 7.0), cone(12, 56.0, 7.0)];
        windows.agents_reported(0.0, |id| first.iter().any(|a| a.id == id), first.into_iter());
        let next = [cone(10, 50.0, 7.0), cone(11, 53.0, 7.0), cone(12, 56.0, 7.0), cone(13, 59.0, 7.0)];
        windows.agents_reported(0.1, |id| next.iter().any(|a| a.id == id), next.into_iter());
        assert!(windows.lost.iter().all(|(id, _)| windows.agents.iter().any(|a| a.id == *id)));
        windows.agents.iter().map(|a| a.id).collect()
    }

    #[test]
    fn a_full_stage_keeps_the_agents_nearest_the_ego_scored() {
        // The drum just passed stays (in place of the cone 59 m ahead): the ego scored a
        // second back is beside it.
        let mut held = held_after_passing_a_drum(Some((0.0, 0.0)));
        held.sort_unstable();
        assert_eq!(held, [1, 10, 11, 12]);
        // Before anything was scored there is nothing to be near: the first reported stay.
        assert_eq!(held_after_passing_a_drum(None), [10, 11, 12, 13]);
    }
}
