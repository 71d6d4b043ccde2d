//! The ego the device's verification windows score: the VO's motion at once, the
//! anchorer's corrections eased in. The detections are placed through it too, so that the
//! windows score the ego and the agents it saw in one frame: through the anchored pose, a
//! cone seen ahead was placed with one fix's error and passed with another's, and the
//! difference put it in the ego's path. (The log's `EgoPose` records keep the anchored pose
//! — eased, it arrives late at real corrections — and its tracks are moved onto it with
//! [`Reframe`].)
//!
//! The anchored ego is the anchor similarity applied to the VO pose. The similarity changes
//! at every GNSS fix, and a change of a tenth of a degree in its rotation moves a pose
//! hundreds of metres from the VO origin by decimetres between two frames: replayed, such a
//! step is a speed spike and a jerk far beyond nuPlan's comfort bounds, and the device's
//! verification windows failed comfort and speed-limit compliance on nearly every drive of
//! the typical profile while the true drive passed (docs/fidelity.md).
//!
//! [`Ease`] splits the pose's change between frames in two. The VO's own motion — this
//! frame's pose against the previous frame's, both through the *current* similarity —
//! passes at once: it is what the car did. The rest — the correction, the anchored pose
//! against where that motion puts the eased ego — is followed by a critically damped second
//! order system of time constant `ease_s`, so that a correction moves the ego with a
//! continuous velocity and a bounded acceleration (a step of `d` metres: at most
//! `d / (e·ease_s)` m/s and `d / ease_s²` m/s²). Nothing waits: the eased ego is the anchored
//! one as soon as the corrections stop, with no lag on the VO's motion, so the windows keep
//! scoring the agents of the same instant (a fixed-lag smoother would have to keep the
//! tracks of the lag too, several kilobytes the microcontroller does not have).
//!
//! A correction larger than [`SNAP_M`] (or [`SNAP_RAD`]), a gap in the poses longer than
//! [`MAX_GAP_S`], or the first pose start the eased ego afresh at the anchored one.
//!
//! Beside the eased ego the ease keeps the VO's motion alone ([`Ease::motion`]): the same
//! steps without the corrections. Its path shape is the camera's own, which the windows'
//! comfort is given the benefit of (`Scorer::motion_beside`): a window whose eased ego fails
//! comfort only through the corrections eased into it is not rejected for it.

use crate::obb::Pose2;

/// A correction this large (m) is taken at once: easing it in would drive the ego
/// somewhere at a speed of its own.
pub const SNAP_M: f64 = 10.0;
/// The same for the heading, rad (20°).
pub const SNAP_RAD: f64 = 0.35;
/// Poses further apart than this (s) start afresh.
pub const MAX_GAP_S: f64 = 1.0;

/// Moves what was placed relative to one ego pose to the same place relative to another
/// (the tracks, from the eased ego onto the anchored one for the log).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reframe {
    from: Pose2,
    to: Pose2,
    turn: f64,
    sin: f64,
    cos: f64,
}

impl Reframe {
    /// From pose `from` onto pose `to`.
    pub fn new(from: Pose2, to: Pose2) -> Self {
        let turn = wrap(to.heading - from.heading);
        let (sin, cos) = libm::sincos(turn);
        Reframe { from, to, turn, sin, cos }
    }

    /// A point (east, north, m).
    pub fn point(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.from.x, y - self.from.y);
        (self.to.x + self.cos * dx - self.sin * dy, self.to.y + self.sin * dx + self.cos * dy)
    }

    /// A heading, rad.
    pub fn heading(&self, heading: f64) -> f64 {
        wrap(heading + self.turn)
    }

    /// A vector (a velocity: east, north).
    pub fn vector(&self, x: f64, y: f64) -> (f64, f64) {
        (self.cos * x - self.sin * y, self.sin * x + self.cos * y)
    }
}

/// The eased ego of the previous frame.
#[derive(Clone, Copy, Debug, PartialEq)]
struct State {
    t: f64,
    anchored: Pose2,
    eased: Pose2,
    /// The VO's motion alone accumulated since the ease started afresh: the eased ego less
    /// the corrections eased in.
    motion: Pose2,
    /// The correction's rate: east, north (m/s) and heading (rad/s).
    rate: [f64; 3],
}

/// The anchored ego with the anchorer's corrections eased in (see the module).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ease {
    /// Time constant, s (0: no easing, the anchored pose passes unchanged).
    ease_s: f64,
    state: Option<State>,
}

fn wrap(a: f64) -> f64 {
    let two_pi = 2.0 * core::f64::consts::PI;
    a - two_pi * libm::floor((a + core::f64::consts::PI) / two_pi)
}

impl Ease {
    /// Corrections followed with time constant `ease_s` seconds (0 or not finite: none).
    pub const fn new(ease_s: f64) -> Self {
        Ease { ease_s, state: None }
    }

    /// Forget the previous frame: the next pose starts afresh.
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// The eased ego at `t` s: `anchored` is this frame's anchored pose, `moved_from` the
    /// previous frame's VO pose through the same similarity (`None` when there is none of
    /// the same VO session: the anchored pose's change since the previous frame is then
    /// taken as the motion, all of it).
    pub fn push(&mut self, t: f64, anchored: Pose2, moved_from: Option<Pose2>) -> Pose2 {
        let ease = self.ease_s.is_finite() && self.ease_s > 0.0;
        let Some(previous) = self.state.filter(|s| ease && t > s.t && t - s.t <= MAX_GAP_S) else {
            self.state = Some(State { t, anchored, eased: anchored, motion: anchored, rate: [0.0; 3] });
            return anchored;
        };
        let dt = t - previous.t;
        // Where the VO's motion since the previous frame takes the eased ego.
        let from = moved_from.unwrap_or(previous.anchored);
        let predicted = Pose2::new(
            previous.eased.x + (anchored.x - from.x),
            previous.eased.y + (anchored.y - from.y),
            wrap(previous.eased.heading + wrap(anchored.heading - from.heading)),
        );
        let error = [anchored.x - predicted.x, anchored.y - predicted.y, wrap(anchored.heading - predicted.heading)];
        if libm::hypot(error[0], error[1]) > SNAP_M || error[2].abs() > SNAP_RAD {
            self.state = Some(State { t, anchored, eased: anchored, motion: anchored, rate: [0.0; 3] });
            return anchored;
        }
        let m = previous.motion;
        let motion = Pose2::new(
            m.x + (anchored.x - from.x),
            m.y + (anchored.y - from.y),
            wrap(m.heading + wrap(anchored.heading - from.heading)),
        );
        // Critically damped: rate' = ω² e − 2ω rate, integrated semi-implicitly (stable for
        // any dt; a step longer than the time constant is followed in one go).
        let omega = 1.0 / self.ease_s;
        let mut rate = previous.rate;
        let mut eased = [predicted.x, predicted.y, predicted.heading];
        let damping = (1.0 + dt * omega) * (1.0 + dt * omega);
        for ((r, e), p) in rate.iter_mut().zip(error).zip(eased.iter_mut()) {
            *r = (*r + dt * omega * omega * e) / damping;
            let step = *r * dt;
            // Never past the anchored pose.
            *p += if step.abs() > e.abs() { e } else { step };
        }
        let eased = Pose2::new(eased[0], eased[1], wrap(eased[2]));
        self.state = Some(State { t, anchored, eased, motion, rate });
        eased
    }

    /// The VO's motion alone since the ease last started afresh, as of the last pose: the
    /// eased ego less the corrections eased in (none before the first pose).
    pub fn motion(&self) -> Option<Pose2> {
        self.state.map(|s| s.motion)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reframing_keeps_what_was_placed_where_it_stood_to_the_ego() {
        // A cone 10 m ahead and 2 m left of the eased ego (heading north); the anchored ego is
        // 1 m east of it and turned 0.1 rad left.
        let eased = Pose2::new(5.0, 5.0, core::f64::consts::FRAC_PI_2);
        let anchored = Pose2::new(6.0, 5.0, core::f64::consts::FRAC_PI_2 + 0.1);
        let to_log = Reframe::new(eased, anchored);
        let (x, y) = to_log.point(3.0, 15.0);
        let (forward, left) = anchored.offset(10.0, 2.0);
        assert!((x - forward).abs() < 1e-12 && (y - left).abs() < 1e-12, "{x} {y} vs {forward} {left}");
        assert!((to_log.heading(core::f64::consts::PI) - (-core::f64::consts::PI + 0.1)).abs() < 1e-12);
        let (vx, vy) = to_log.vector(0.0, 1.0);
        assert!((vx + libm::sin(0.1)).abs() < 1e-12 && (vy - libm::cos(0.1)).abs() < 1e-12);
        let same = Reframe::new(eased, eased);
        assert_eq!(same.point(3.0, 15.0), (3.0, 15.0));
    }

    /// A car at 10 m/s due east, 10 Hz, whose anchored pose jumps 0.5 m north at 1 s.
    fn drive(ease: &mut Ease) -> ([f64; 60], f64) {
        let mut north = [0.0; 60];
        let mut max_speed_north: f64 = 0.0;
        let mut last = 0.0;
        for (k, n) in north.iter_mut().enumerate() {
            let t = k as f64 * 0.1;
            let jump = if t >= 1.0 { 0.5 } else { 0.0 };
            let anchored = Pose2::new(10.0 * t, jump, 0.0);
            // The previous frame's VO pose through this frame's similarity.
            let moved_from = Pose2::new(10.0 * (t - 0.1), jump, 0.0);
            let p = ease.push(t, anchored, (k > 0).then_some(moved_from));
            assert!((p.x - 10.0 * t).abs() < 1e-9, "the VO's motion passes at once");
            *n = p.y;
            if k > 0 {
                max_speed_north = max_speed_north.max((p.y - last) / 0.1);
            }
            last = p.y;
        }
        (north, max_speed_north)
    }

    #[test]
    fn a_correction_is_eased_in_and_the_motion_is_not() {
        let (north, max_speed) = drive(&mut Ease::new(1.0));
        assert_eq!(north[9], 0.0);
        assert!(north[10] < 0.1, "a step does not pass at once: {}", north[10]);
        // Critically damped: 1 − 2/e of the way (0.13 m) after a time constant.
        assert!(north[20] > 0.1 && north[20] < 0.2, "a quarter of the way after a time constant: {}", north[20]);
        assert!((north[59] - 0.5).abs() < 0.05, "there after five: {}", north[59]);
        assert!(north.windows(2).all(|w| w[1] >= w[0] && w[1] <= 0.5), "monotone, never past");
        // A 0.5 m step at once is 5 m/s between two frames; eased, at most d/(e·τ) ≈ 0.18.
        assert!(max_speed < 0.25, "{max_speed}");
    }

    #[test]
    fn the_motion_alone_is_the_eased_ego_less_the_corrections() {
        let mut ease = Ease::new(1.0);
        assert_eq!(ease.motion(), None);
        for k in 0..30 {
            let t = k as f64 * 0.1;
            // 10 m/s east; the anchored pose jumps 0.5 m north at 1 s.
            let jump = if t >= 1.0 { 0.5 } else { 0.0 };
            let moved_from = Pose2::new(10.0 * (t - 0.1), jump, 0.0);
            let eased = ease.push(t, Pose2::new(10.0 * t, jump, 0.0), (k > 0).then_some(moved_from));
            let motion = ease.motion().expect("a pose was pushed");
            assert!((motion.x - 10.0 * t).abs() < 1e-9, "the VO's motion: {motion:?}");
            assert_eq!(motion.y, 0.0, "no correction in it, at {t} s (eased {eased:?})");
        }
        let eased_at_end = ease.push(3.0, Pose2::new(30.0, 0.5, 0.0), Some(Pose2::new(29.0, 0.5, 0.0)));
        assert!(eased_at_end.y > 0.3, "the eased ego took most of the correction: {eased_at_end:?}");
        // A correction taken at once (the similarity moved 12 m north, the VO 1 m east)
        // starts it afresh at the anchored pose.
        let far = Pose2::new(31.0, 12.5, 0.0);
        ease.push(3.1, far, Some(Pose2::new(30.0, 12.5, 0.0)));
        assert_eq!(ease.motion(), Some(far));
    }

    #[test]
    fn without_easing_and_after_a_gap_or_a_large_correction_the_anchored_pose_passes() {
        let (north, _) = drive(&mut Ease::new(0.0));
        assert_eq!(north[10], 0.5);
        let mut ease = Ease::new(2.0);
        ease.push(0.0, Pose2::new(0.0, 0.0, 0.0), None);
        assert_eq!(ease.push(0.1, Pose2::new(1.0, 0.3, 0.0), None).y, 0.3, "no VO motion: the anchored change");
        assert_eq!(ease.push(1.5, Pose2::new(15.0, 0.3, 0.0), None).y, 0.3, "after a gap: afresh");
        let far = Pose2::new(16.0, 12.0, 0.0);
        assert_eq!(ease.push(1.6, far, Some(Pose2::new(15.0, 0.3, 0.0))), far, "a 12 m correction at once");
        let turned = Pose2::new(17.0, 12.0, 0.5);
        assert_eq!(ease.push(1.7, turned, Some(Pose2::new(16.0, 12.0, 0.0))), turned, "so is a 29° one");
    }

    #[test]
    fn headings_ease_across_the_wrap() {
        let mut ease = Ease::new(1.0);
        let pi = core::f64::consts::PI;
        ease.push(0.0, Pose2::new(0.0, 0.0, pi - 0.01), None);
        // The anchored heading crosses ±π by a 0.02 rad correction: eased by the short way.
        let p = ease.push(0.1, Pose2::new(0.0, 0.0, -pi + 0.01), Some(Pose2::new(0.0, 0.0, pi - 0.01)));
        assert!(p.heading > pi - 0.011 || p.heading < -pi + 0.011, "{}", p.heading);
    }
}
