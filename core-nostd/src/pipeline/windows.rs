//! The verification windows: the eased ego, a second late, and the latest tracks as agents
//! scored as nuPlan scores a log replay, one window after another; each closed window a
//! record and an event.

use embedded_io::Write;

use super::{edge, lag, verification_record, PipelineError, State};
use crate::binlog::{quantise, Record, Verification};
use crate::decimal::Decimal;
use crate::drivable::{Channel, Checker};
use crate::obb::Pose2;
use crate::score::{Agent, Decision, Scorer, Scores};
use crate::time::Timestamp;

/// Agents the tracker stopped reporting are scored for this long after (s): the smoothed
/// ego's lag ([`lag`]) and half a second.
pub(super) const KEEP_LOST_S: f64 = 1.5;

/// At most this many of them.
pub(super) const KEPT_AGENTS: usize = 16;

/// The first window opens this long after the device's first anchored pose, s: the
/// anchor's first corrections (its rotation and scale still settling, eased in) are its
/// own motion, not the driver's, and would be scored as jerks and speeds.
pub const SETTLE_AFTER_ANCHORED_S: f64 = 3.0;

/// The open window and the agents it scores.
#[derive(Debug)]
pub(super) struct Windows<'a, const T3: usize> {
    pub(super) agents: heapless::Vec<Agent, T3>,
    /// Of `agents`, those the tracker no longer reports, and since when (s).
    pub(super) lost: heapless::Vec<(u32, f64), KEPT_AGENTS>,
    pub(super) agents_t: f64,
    pub(super) window: Option<Window<'a>>,
    /// The windows' latest at-fault collision, carried across a window's end ([`edge`]).
    pub(super) edge_collisions: edge::EdgeCollisions,
    /// How far the ego's position is in doubt (m): the configured number of the latest
    /// anchored or carried pose's σ.
    pub(super) doubt_m: f64,
    /// No window opens before this time (s): the first anchored pose's and
    /// [`SETTLE_AFTER_ANCHORED_S`]; never until the device has anchored.
    pub(super) open_from: f64,
}

impl<const T3: usize> Default for Windows<'_, T3> {
    fn default() -> Self {
        Windows {
            agents: heapless::Vec::new(),
            lost: heapless::Vec::new(),
            agents_t: 0.0,
            window: None,
            edge_collisions: edge::EdgeCollisions::default(),
            doubt_m: 0.0,
            open_from: f64::INFINITY,
        }
    }
}

/// One verification window.
#[derive(Clone, Debug)]
pub(super) struct Window<'a> {
    pub(super) start: f64,
    /// The time of the last pose it scored.
    pub(super) last: Timestamp,
    pub(super) scorer: Scorer<'a, 'static, 1>,
    /// The multiplier of a collision in the last second of the window before ([`edge`]).
    pub(super) inherited_collision: Option<f64>,
}

impl<W: Write, const T3: usize, const T2: usize, const BUF: usize> State<'_, W, T3, T2, BUF> {
    /// One smoothed ego pose (of `t`, a second back) into the open verification window: the
    /// agents moved to `t` by their velocity (back, from their latest update); a window
    /// that reached its length is closed at `t`.
    pub(super) fn score(&mut self, t: Timestamp, ego: &Pose2) -> Result<(), PipelineError<W::Error>> {
        let Some(map) = self.config.map else { return Ok(()) };
        let ts = t.as_secs_f64();
        // A gap in the ego (a VO re-initialisation's missing frames, or a new session not yet
        // observable after the carry gave up) ends the window at its last pose: the device did not see what happened in the gap, and a
        // window verified over it would vouch for it.
        if let Some(last) = self.windows.window.as_ref().map(|w| w.last) {
            if (t - last).as_secs_f64() > lag::MAX_GAP_S {
                self.close_window(last)?;
            }
        }
        if self.windows.window.is_none() && ts >= self.windows.open_from {
            let checker = Checker::new(map, self.config.footprint);
            self.windows.window = Some(Window {
                start: ts,
                last: t,
                scorer: Scorer::new(checker, Channel::Insensitive, self.config.score),
                inherited_collision: self.windows.edge_collisions.carried_into(ts),
            });
        }
        // The latest tracks, moved by their velocity to this pose's time (in place: a copy
        // of 64 agents is 4.6 KB of a microcontroller's stack).
        let dt = ts - self.windows.agents_t;
        for a in self.windows.agents.iter_mut() {
            a.bbox.centre.x += a.velocity.0 * dt;
            a.bbox.centre.y += a.velocity.1 * dt;
        }
        self.windows.agents_t = ts;
        let Some(window) = self.windows.window.as_mut() else { return Ok(()) };
        // A refused pose (not finite, time not increasing) leaves the window as it was. The
        // ego's doubt is given to it and, beside, held against it: the window is decided.
        if let Ok(report) = window.scorer.step_both_ways(ts, ego, &self.windows.agents, self.windows.doubt_m) {
            window.last = t;
            if let Some(collision) = &report.collision {
                self.windows.edge_collisions.push(ts, collision);
            }
        }
        if ts - window.start >= self.config.window_s {
            self.close_window(t)?;
        }
        Ok(())
    }

    /// Closes the open window: its scores with the ego's doubt given to it (the record's
    /// score, as before windows were decided) and held against it bound the window's score,
    /// and decide it (verified, rejected or undecided, as `verify --decide-at` does).
    pub(super) fn close_window(&mut self, t: Timestamp) -> Result<(), PipelineError<W::Error>> {
        let Some(window) = self.windows.window.take() else { return Ok(()) };
        let inherit = |own: Scores| window.inherited_collision.map_or(own, |m| edge::inherit(&own, m));
        let s = inherit(window.scorer.finish(None));
        let against = window.scorer.finish_against(None).map_or(s, inherit);
        if s.poses == 0 {
            return Ok(());
        }
        let (low, high) = (s.score.min(against.score), s.score.max(against.score));
        let decision = Decision::of_interval(low, high);
        let stats = &mut self.log.stats;
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
            ..verification_record(self.log.time(t), &s)
        };
        self.log.write(&Record::Verification(record))?;
        self.log.event(
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
