//! The fixed-lag smoother of the ego the device's verification windows score.
//!
//! A monocular VO's frame-to-frame motion is noisy: on the typical profile (1 % of each
//! increment per axis) the anchored ego's accelerations, taken as nuPlan's comfort metric
//! takes them (a Savitzky–Golay fit over 0.6 s), have a median of 1.5–3 m/s² and peaks far
//! beyond the comfort bounds on a drive the true ego passes with ease. The smoother holds
//! the last [`SPAN`] poses and gives out the one [`LAG`] frames back, fitted by a quadratic
//! in time over the poses within [`LAG`] frames either side of it: the windows are judged
//! one second late, on an ego whose noise is averaged over two. The agents are moved back
//! to the smoothed pose's time by their velocity (`Pipeline::score`), so the tracks of the
//! lag need not be kept; what it costs is the buffer, [`SPAN`] poses of 32 bytes (the
//! windows keep two: the eased ego's and its relative motion's, [`super::ease`]).
//!
//! A gap longer than [`MAX_GAP_S`] between two poses gives out the poses still held (each
//! fitted over the ones either side of it that there are) and starts afresh.

use heapless::Deque;
use nalgebra::{Matrix3, Vector3};

use crate::obb::Pose2;
use crate::time::Timestamp;

/// Frames the smoothed ego is given out late.
pub const LAG: usize = 10;
/// Poses held: the lag either side of the one given out.
pub const SPAN: usize = 2 * LAG + 1;
/// Poses further apart than this (s) are not fitted together: a hole in the ego, as the
/// score defines it (and `verify` reports it in a finished log); a window ends there too.
pub const MAX_GAP_S: f64 = crate::score::HOLE_S;

/// Poses given out by one [`FixedLag::push`] or [`FixedLag::flush`]: at most the lag and
/// one.
pub type Out = heapless::Vec<(Timestamp, Pose2), { LAG + 1 }>;

/// The last [`SPAN`] poses and how many of them have been given out.
#[derive(Clone, Debug, Default)]
pub struct FixedLag {
    poses: Deque<(Timestamp, Pose2), SPAN>,
    given: usize,
}

fn wrap(a: f64) -> f64 {
    let two_pi = 2.0 * core::f64::consts::PI;
    a - two_pi * libm::floor((a + core::f64::consts::PI) / two_pi)
}

impl FixedLag {
    /// An empty smoother.
    pub const fn new() -> Self {
        FixedLag { poses: Deque::new(), given: 0 }
    }

    /// The pose at `t` in; out, the smoothed pose [`LAG`] frames back once there is one
    /// (after a gap, first the poses held from before it). A pose not later than the last
    /// one is refused (nothing out).
    pub fn push(&mut self, t: Timestamp, pose: Pose2) -> Out {
        let mut out = Out::new();
        if let Some(&(last, _)) = self.poses.back() {
            if t <= last || !pose.is_finite() {
                return out;
            }
            if (t - last).as_secs_f64() > MAX_GAP_S {
                out = self.flush();
            }
        }
        if self.poses.is_full() {
            self.poses.pop_front();
            self.given = self.given.saturating_sub(1);
        }
        // Not full after the pop: the push always succeeds.
        let _ = self.poses.push_back((t, pose));
        if self.poses.len() > LAG + self.given {
            if let Some(p) = self.fit(self.given) {
                let _ = out.push(p);
            }
            self.given += 1;
        }
        out
    }

    /// The poses not yet given out, smoothed over those either side that there are; the
    /// smoother is empty afterwards.
    pub fn flush(&mut self) -> Out {
        let mut out = Out::new();
        for k in self.given..self.poses.len() {
            if let Some(p) = self.fit(k) {
                let _ = out.push(p);
            }
        }
        self.poses.clear();
        self.given = 0;
        out
    }

    /// Pose `k` of those held, fitted by a quadratic in time over the poses within [`LAG`]
    /// of it (the pose itself when fewer than three, or when the fit is singular).
    fn fit(&self, k: usize) -> Option<(Timestamp, Pose2)> {
        let &(tc, centre) = self.poses.iter().nth(k)?;
        let near = self.poses.iter().skip(k.saturating_sub(LAG)).take(k.min(LAG) + LAG + 1);
        let (mut normal, mut rhs) = (Matrix3::<f64>::zeros(), [Vector3::<f64>::zeros(); 3]);
        let mut n = 0;
        for &(t, p) in near {
            let dt = (t - tc).as_secs_f64();
            let basis = Vector3::new(1.0, dt, dt * dt);
            normal += basis * basis.transpose();
            let values = [p.x - centre.x, p.y - centre.y, wrap(p.heading - centre.heading)];
            for (r, v) in rhs.iter_mut().zip(values) {
                *r += basis * v;
            }
            n += 1;
        }
        let inverse = normal.try_inverse().filter(|_| n >= 3);
        let Some(inverse) = inverse else { return Some((tc, centre)) };
        let [x, y, h] = rhs.map(|r| (inverse * r).x);
        let smoothed = Pose2::new(centre.x + x, centre.y + y, wrap(centre.heading + h));
        Some((tc, if smoothed.is_finite() { smoothed } else { centre }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(k: usize) -> Timestamp {
        Timestamp::from_micros(k as i64 * 100_000)
    }

    /// A car braking at 2 m/s² from 15 m/s, turning at 0.1 rad/s, with ±5 cm of noise.
    fn pose(k: usize) -> (Pose2, Pose2) {
        let t = k as f64 * 0.1;
        let truth = Pose2::new(15.0 * t - t * t, 0.0, wrap(3.0 + 0.1 * t));
        let noise = if k.is_multiple_of(2) { 0.05 } else { -0.05 };
        (truth, Pose2::new(truth.x + noise, truth.y - noise, wrap(truth.heading + noise * 0.1)))
    }

    #[test]
    fn gives_out_each_pose_once_lag_frames_late_and_quadratic_motion_unchanged() {
        let mut lag = FixedLag::new();
        let mut out = heapless::Vec::<(Timestamp, Pose2), 64>::new();
        for k in 0..40 {
            let given = lag.push(at(k), pose(k).1);
            assert_eq!(given.len(), usize::from(k >= LAG), "frame {k}");
            out.extend(given);
        }
        out.extend(lag.flush());
        assert_eq!(out.len(), 40);
        for (k, (t, p)) in out.iter().enumerate() {
            assert_eq!(*t, at(k));
            let truth = pose(k).0;
            // The alternating noise averages out; a quadratic is fitted exactly.
            let tolerance = if (LAG..40 - LAG).contains(&k) { 0.006 } else { 0.03 };
            assert!((p.x - truth.x).abs() < tolerance && (p.y - truth.y).abs() < tolerance, "{k}: {p:?} {truth:?}");
            assert!(wrap(p.heading - truth.heading).abs() < 0.01, "{k}: across ±π too");
        }
    }

    #[test]
    fn a_gap_gives_out_what_is_held_and_old_or_broken_poses_are_refused() {
        let mut lag = FixedLag::new();
        for k in 0..5 {
            assert!(lag.push(at(k), pose(k).1).is_empty());
        }
        assert!(lag.push(at(4), pose(5).1).is_empty(), "not later");
        assert!(lag.push(at(5), Pose2::new(f64::NAN, 0.0, 0.0)).is_empty(), "not finite");
        let after_gap = lag.push(at(30), pose(30).1);
        assert_eq!(after_gap.iter().map(|p| p.0).collect::<heapless::Vec<_, 8>>(), [0, 1, 2, 3, 4].map(at));
        assert_eq!(lag.flush().as_slice(), [(at(30), pose(30).1)], "one pose alone passes unchanged");
        assert!(lag.flush().is_empty());
    }
}
