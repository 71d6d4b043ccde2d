//! The ego carried across a VO re-initialisation until the new session is anchored.
//!
//! When the VO loses track and starts again, the new session's similarity to the world is
//! unknown until the anchorer has seen enough GNSS fixes along it (5–25 s on a typical
//! drive). The car has not gone anywhere unknown in the meantime: where the old session
//! last put the camera, the car's speed from the wheels, and the VO's own motion in the new
//! session say where it is. [`Carry`] makes a provisional similarity from them — the new
//! session's first camera orientation is the old session's last turned by what the gyro
//! measured over the gap (or not turned, without one: the car turns little in a second or
//! two), its first position the last one moved on by the wheel speed over the gap along the
//! heading, its scale the wheel distance over the VO path length since — and the pipeline
//! places the ego and the detections through it,
//! flagged by events, until the anchorer's own estimate takes over, for at most
//! [`MAX_CARRY_S`]. Its error grows with the turn during the gap and the wheel factor's
//! error; the anchorer's is bounded.
//!
//! The same carried attitude is the anchorer's prior on the new session's rotation
//! ([`rotation_prior`]): with it the fixes need only a few seconds of a straight road to
//! anchor the session, instead of a bend.
//!
//! How far the car turned during the gap comes from the gyro when the dashcam has one (its
//! heading, bias removed, is good to a few hundredths of a degree over a second or two);
//! without it, from the ego's turn rate before the gap, extrapolated ([`Turn`]).

use nalgebra::{Matrix3, Vector3};

use crate::sim3::{rotation_z, Pose, Sim3};
use crate::track3d::wrap_angle;

/// Wheel distance the scale is taken over before the first carried pose, m.
const MIN_WHEEL_DISTANCE_M: f64 = 2.0;
/// The ego is carried at most this long after the old session's last anchored pose, s:
/// the turn during the gap, uncorrected, takes the carried pose off sideways by the distance
/// driven times its angle (on the typical profile's sweep the online APE's 90th percentile
/// went from 3.3 m to 3.6 m with the carry unbounded).
pub const MAX_CARRY_S: f64 = 10.0;
/// Growth of a carried pose's σ, m per second since the last anchored pose: the wheels'
/// few per cent of distance and the VO's heading over the gap (as `finish` bridges one).
pub const CARRY_SPEED_SIGMA: f64 = 0.5;

/// Attitude error of one VO frame beyond what the anchorer knew of the old session's
/// rotation, rad (0.5°): the floor of the carried rotation's σ.
const FIRST_FRAME_SIGMA_RAD: f64 = 0.5 * core::f64::consts::PI / 180.0;
/// Time constant of the ego's turn rate as [`TurnRate`] smooths it, s.
const TURN_RATE_TIME_CONSTANT_S: f64 = 1.0;
/// Anchored frames farther apart than this start the turn rate afresh, s.
const TURN_RATE_MAX_STEP_S: f64 = 1.0;

/// The ego's turn rate over its latest anchored frames (rad/s, smoothed over about a
/// second): how far the car will have turned during a VO gap.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TurnRate {
    last: Option<(f64, f64)>,
    rate: f64,
}

impl TurnRate {
    /// The anchored ego's heading (rad) at `t` s.
    pub fn push(&mut self, t: f64, heading: f64) {
        if let Some((t0, h0)) = self.last {
            let dt = t - t0;
            if dt > 0.0 && dt <= TURN_RATE_MAX_STEP_S {
                let rate = wrap_angle(heading - h0) / dt;
                self.rate += (rate - self.rate) * (dt / TURN_RATE_TIME_CONSTANT_S).min(1.0);
            } else {
                self.rate = 0.0;
            }
        }
        if t.is_finite() && heading.is_finite() && self.rate.is_finite() {
            self.last = Some((t, heading));
        } else {
            *self = TurnRate::default();
        }
    }

    /// The smoothed turn rate, rad/s (left positive).
    pub fn rate(&self) -> f64 {
        self.rate
    }
}

/// How far the car turned about the vertical during a VO gap (rad, left positive), and
/// how sure that is (1-σ, rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Turn {
    /// The turn, rad.
    pub angle: f64,
    /// Its 1-σ error, rad.
    pub sigma: f64,
}

impl Turn {
    /// The ego's `turn_rate` before the gap, extrapolated over `gap_s`: its error is taken
    /// as half the turn.
    pub fn extrapolated(turn_rate: f64, gap_s: f64) -> Self {
        let angle = turn_rate * gap_s.max(0.0);
        Turn { angle, sigma: 0.5 * libm::fabs(angle) }
    }
}

/// The new session's rotation (VO → ENU) as the carry sees it, and its 1-σ error (rad):
/// the camera's world attitude `from` at the old session's last anchored frame, turned on
/// about the vertical by the `turn` during the gap, through the new session's `first` VO
/// pose. The error adds, to the old session's rotation σ, the turn's and one frame's
/// attitude error.
pub fn rotation_prior(from: &Pose, turn: Turn, first: &Pose, old_sigma_rad: f64) -> (Matrix3<f64>, f64) {
    let rotation = rotation_z(turn.angle) * from.rotation * first.rotation.transpose();
    let sigma = libm::sqrt(
        old_sigma_rad * old_sigma_rad + turn.sigma * turn.sigma + FIRST_FRAME_SIGMA_RAD * FIRST_FRAME_SIGMA_RAD,
    );
    (rotation, sigma)
}

/// The provisional similarity of a new VO session.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Carry {
    /// The camera's world pose at the old session's last anchored frame, and its time (s).
    from: Pose,
    from_t: f64,
    /// The ego's heading then, rad.
    heading: f64,
    /// The new session's first VO pose and its time, and the turn (rad) since `from`.
    first: Option<(f64, Pose, f64)>,
    /// Where the camera was at the new session's first pose (world).
    first_world: Vector3<f64>,
    /// The latest VO position and time of the new session.
    last: Option<(f64, Vector3<f64>)>,
    /// Wheel distance (m) and VO path length (VO units) since the session's first pose.
    wheel_m: f64,
    vo_path: f64,
}

impl Carry {
    /// Carry from the camera's world pose `from` at `t` s, the ego heading `heading`.
    pub fn new(from: Pose, t: f64, heading: f64) -> Self {
        Carry {
            from,
            from_t: t,
            heading,
            first: None,
            first_world: from.translation,
            last: None,
            wheel_m: 0.0,
            vo_path: 0.0,
        }
    }

    /// The new session's VO pose at `t` s, the car's speed then (m/s, wheel factor
    /// applied) and how far it has turned since the old session's last anchored frame
    /// (rad; the gyro's, or 0 without one — only the first pose's is used): the provisional
    /// similarity, once the wheels have gone far enough to give the scale.
    pub fn push(&mut self, t: f64, pose: &Pose, speed_mps: f64, turn: f64) -> Option<Sim3> {
        if !(t.is_finite() && pose.is_finite() && speed_mps.is_finite()) || t - self.from_t > MAX_CARRY_S {
            return None;
        }
        let Some((_, first, first_turn)) = self.first else {
            let gap = (t - self.from_t).max(0.0);
            let turn = if turn.is_finite() { turn } else { 0.0 };
            // Along the arc's chord: the mean heading over the gap.
            let (s, c) = libm::sincos(self.heading + 0.5 * turn);
            self.first_world = self.from.translation + Vector3::new(c, s, 0.0) * speed_mps * gap;
            self.first = Some((t, *pose, turn));
            self.last = Some((t, pose.translation));
            return None;
        };
        if let Some((t0, p0)) = self.last.filter(|(t0, _)| t > *t0) {
            self.wheel_m += speed_mps.abs() * (t - t0);
            self.vo_path += (pose.translation - p0).norm();
            self.last = Some((t, pose.translation));
        }
        if !(self.wheel_m >= MIN_WHEEL_DISTANCE_M && self.vo_path > 0.0) {
            return None;
        }
        let scale = self.wheel_m / self.vo_path;
        let rotation = rotation_z(first_turn) * self.from.rotation * first.rotation.transpose();
        let translation = self.first_world - rotation * first.translation * scale;
        Some(Sim3 { rotation, scale, translation })
    }

    /// When the carry began (the old session's last anchored frame), s.
    pub fn since(&self) -> f64 {
        self.from_t
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Matrix3;

    use super::*;
    use crate::sim3::rotation_z;

    #[test]
    fn a_new_session_is_placed_where_the_car_went_on() {
        // The car drives east at 10 m/s; the old session last saw the camera at (100, 5, 1.3)
        // at t = 10 s; after a 1 s gap the new VO frame is turned by 2 rad and scaled by 1/4.
        let to_vo = rotation_z(-2.0);
        let camera = |t: f64| Vector3::new(100.0 + 10.0 * (t - 10.0), 5.0, 1.3);
        let from = Pose { rotation: rotation_z(0.0), translation: camera(10.0) };
        let mut carry = Carry::new(from, 10.0, 0.0);
        let vo = |t: f64| Pose { rotation: to_vo, translation: to_vo * (camera(t) - camera(11.0)) * 4.0 };
        assert_eq!(carry.push(11.0, &vo(11.0), 10.0, 0.0), None, "no scale from one pose");
        assert_eq!(carry.push(11.1, &vo(11.1), 10.0, 0.0), None, "1 m of wheels is not enough");
        let mut s = None;
        for k in 2..10 {
            let t = 11.0 + 0.1 * f64::from(k);
            s = carry.push(t, &vo(t), 10.0, 0.0).or(s);
        }
        let s = s.unwrap_or_else(|| unreachable!("2 m of wheels give the scale"));
        assert!((s.scale - 0.25).abs() < 1e-9, "{s:?}");
        let p = s.transform_point(&vo(12.5).translation);
        assert!((p - camera(12.5)).norm() < 1e-9, "{p:?}");
        assert!((s.rotation * to_vo - Matrix3::identity()).norm() < 1e-12);
        assert_eq!(carry.since(), 10.0);
        assert_eq!(carry.push(20.5, &vo(20.5), 10.0, 0.0), None, "not carried beyond MAX_CARRY_S");
    }

    #[test]
    fn the_turn_during_the_gap_turns_the_carried_session() {
        // The car heads east until the gap; during its 2 s it turns left by 0.2 rad, which
        // the gyro measured. The new VO frame is the world turned by 2 rad: through the
        // carry, the new session's camera heads 0.2 rad left of east, as the car does.
        let to_vo = rotation_z(-2.0);
        let from = Pose { rotation: rotation_z(0.0), translation: Vector3::new(100.0, 5.0, 1.3) };
        let mut carry = Carry::new(from, 10.0, 0.0);
        let heading: f64 = 0.2;
        let direction = Vector3::new(libm::cos(heading), libm::sin(heading), 0.0);
        let camera = |t: f64| Vector3::new(100.0, 5.0, 1.3) + direction * 10.0 * (t - 10.0);
        let vo = |t: f64| Pose { rotation: to_vo * rotation_z(heading), translation: to_vo * camera(t) * 4.0 };
        let mut s = None;
        for k in 0..10 {
            let t = 12.0 + 0.1 * f64::from(k);
            s = carry.push(t, &vo(t), 10.0, heading).or(s);
        }
        let s = s.unwrap_or_else(|| unreachable!("2 m of wheels give the scale"));
        let world = s.rotation * vo(12.5).rotation;
        let carried = libm::atan2(world[(1, 0)], world[(0, 0)]);
        assert!((carried - heading).abs() < 1e-9, "carried heading {carried}");
        // Without the gyro's turn, the 0.2 rad of the gap would be the carried ego's error.
        let mut blind = Carry::new(from, 10.0, 0.0);
        let mut b = None;
        for k in 0..10 {
            let t = 12.0 + 0.1 * f64::from(k);
            b = blind.push(t, &vo(t), 10.0, 0.0).or(b);
        }
        let w = b.unwrap_or_else(|| unreachable!("a scale")).rotation * vo(12.5).rotation;
        assert!((libm::atan2(w[(1, 0)], w[(0, 0)]) - heading).abs() > 0.19);
    }

    #[test]
    fn the_turn_rate_follows_the_heading_and_restarts_after_a_gap() {
        let mut turn = TurnRate::default();
        // 0.2 rad/s to the left across ±π, frames at 10 Hz, for 10 s (ten time constants).
        for k in 0..100 {
            let t = 0.1 * f64::from(k);
            turn.push(t, wrap_angle(3.0 + 0.2 * t));
        }
        assert!((turn.rate() - 0.2).abs() < 1e-3, "{}", turn.rate());
        turn.push(16.0, 0.0);
        assert_eq!(turn.rate(), 0.0, "frames 6 s apart say nothing of the rate");
        turn.push(f64::NAN, 0.0);
        turn.push(16.1, 0.01);
        assert_eq!(turn.rate(), 0.0, "a non-finite input starts afresh");
    }

    #[test]
    fn the_carried_rotation_turns_on_over_the_gap_and_says_how_sure_it_is() {
        // The new VO frame is the world turned by 2 rad; the car turned at 0.1 rad/s, the
        // gap 1 s: the camera's first attitude in the new frame maps to the world through
        // the prior, with the turn extrapolated.
        let to_vo = rotation_z(-2.0);
        let from = Pose { rotation: rotation_z(0.5), translation: Vector3::zeros() };
        let first = Pose { rotation: to_vo * rotation_z(0.6), translation: Vector3::zeros() };
        let (rotation, sigma) = rotation_prior(&from, Turn::extrapolated(0.1, 1.0), &first, 0.01);
        assert!((rotation * to_vo - Matrix3::identity()).norm() < 1e-12, "{rotation}");
        let expected = (0.01f64 * 0.01 + 0.05 * 0.05 + FIRST_FRAME_SIGMA_RAD * FIRST_FRAME_SIGMA_RAD).sqrt();
        assert!((sigma - expected).abs() < 1e-15);
        let (_, straight) = rotation_prior(&from, Turn::extrapolated(0.0, 1.0), &first, 0.0);
        assert_eq!(straight, FIRST_FRAME_SIGMA_RAD);
        // A gyro's turn is as sure as the gyro says.
        let (_, gyro) = rotation_prior(&from, Turn { angle: 0.1, sigma: 0.001 }, &first, 0.0);
        assert!((gyro - (1e-6 + FIRST_FRAME_SIGMA_RAD * FIRST_FRAME_SIGMA_RAD).sqrt()).abs() < 1e-15);
    }
}
