//! The batch problem as the solve is given it and gives it back: the VO samples, fixes and
//! anchors of one session, the settings (the σ and walks it assumes, the latency search),
//! and the solution with its uncertainty.

use dash2sim_core::nalgebra::{Matrix3, Vector3};

/// A VO sample: the camera in the VO frame.
#[derive(Clone, Copy, Debug)]
pub struct VoSample {
    /// Time, s (log time).
    pub t: f64,
    /// The VO session (a solve is given one session's samples).
    pub session: u32,
    /// Camera position, VO units.
    pub position: Vector3<f64>,
    /// Camera → VO rotation.
    pub rotation: Matrix3<f64>,
    /// How uncertain the path's rise is per metre travelled: 0 for a camera's VO (its σ is
    /// [`Settings::vo_sigma`] on every axis); a dead-reckoned path's height integrates the
    /// grade its attitude shows and is left to the fixes where they disagree
    /// ([`crate::reckon`]).
    pub grade_sigma: f64,
    /// Dead-reckoned from the gyro: its heading drifts at the rate of the gyro's bias that
    /// the device's estimate left, one rate for the drive, which the solve finds
    /// ([`Settings::heading_drift_sigma`]). A camera's VO drifts as a random walk only.
    pub reckoned: bool,
}

/// A GNSS fix in the log's ENU frame.
#[derive(Clone, Copy, Debug)]
pub struct Fix {
    /// Time of the fix, s.
    pub t: f64,
    /// Antenna (taken at the camera) position, m.
    pub enu: Vector3<f64>,
    /// 1-σ horizontal error, m.
    pub sigma_h: f64,
    /// 1-σ vertical error, m.
    pub sigma_v: f64,
}

/// Where an external anchor is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AnchorAt {
    /// The rear axle at this time, s.
    Time(f64),
    /// This point of the VO frame.
    VoPoint(Vector3<f64>),
}

/// An external anchor in the log's ENU frame.
#[derive(Clone, Copy, Debug)]
pub struct Anchor {
    /// What is anchored.
    pub at: AnchorAt,
    /// Where it is, m.
    pub enu: Vector3<f64>,
    /// 1-σ, m (every axis).
    pub sigma: f64,
}

/// Everything the solve reads.
#[derive(Clone, Copy, Debug)]
pub struct Inputs<'a> {
    /// VO samples in time order.
    pub vo: &'a [VoSample],
    /// GNSS fixes in time order.
    pub fixes: &'a [Fix],
    /// Vehicle speed samples (time s, m/s) in time order.
    pub speeds: &'a [(f64, f64)],
    /// External anchors.
    pub anchors: &'a [Anchor],
    /// Rear axle in the camera frame (the mount's lever arm).
    pub lever: Vector3<f64>,
}

/// Model and solver constants.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Spacing of keyframes, s.
    pub keyframe_s: f64,
    /// The VO frame's z axis is vertical: only yaw varies.
    pub gravity_aligned: bool,
    /// GNSS error correlation time, s.
    pub gnss_correlation_s: f64,
    /// Random walk of the log-scale, per √s.
    pub scale_walk: f64,
    /// Random walk of the rotation, rad per √s.
    pub rotation_walk: f64,
    /// The two random walks when external anchors take part. Without them the similarity
    /// is left looser so that it also absorbs the GNSS's slowly wandering error (on the
    /// comma2k19 minute: ATE 1.26 m against 1.75 m with the tighter walks, whose latency
    /// estimate collapses to 7 ms); with them it only has to follow the VO's drift and must
    /// not follow the anchors' noise. This is the tightest of the walks `finish` tries with
    /// anchors; it keeps the one that predicts held-out anchors best ([`crate::walk`],
    /// `docs/finishing.md`).
    pub anchored_walk: (f64, f64),
    /// VO chord error: metres plus a fraction of the chord.
    pub vo_sigma: (f64, f64),
    /// Odometer distance error over a segment: a fraction plus metres.
    pub wheel_sigma: (f64, f64),
    /// Prior σ of the log wheel factor.
    pub wheel_factor_sigma: f64,
    /// Prior mean and σ of the GNSS latency, s.
    pub latency_prior: (f64, f64),
    /// Cauchy scale, σ.
    pub robust: f64,
    /// A residual beyond this many σ is rejected.
    pub gate: f64,
    /// Gauss–Newton iterations at most.
    pub max_iterations: usize,
    /// Latencies tried before the solve (first, last, step), s; none when step ≤ 0.
    pub latency_search: (f64, f64, f64),
    /// Prior σ of a dead-reckoned path's heading drift rate, rad/s: the gyro bias about the
    /// vertical that the device's estimate left. The rotation's random walk cannot follow a
    /// steady drift (on comma2k19's minute with the phone's fixes, 1.5 mrad/s left a
    /// cross-track bow of 8 m); a rate shared by the whole drive can.
    pub heading_drift_sigma: f64,
}

impl Settings {
    /// These settings with the GNSS latency held at `latency_s`: no search, and a prior
    /// tight enough that the solve does not move it.
    pub fn with_latency_held(self, latency_s: f64) -> Self {
        Settings { latency_prior: (latency_s, 1e-4), latency_search: (0.0, -1.0, 0.0), ..self }
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            keyframe_s: 0.5,
            gravity_aligned: false,
            gnss_correlation_s: 2.0,
            scale_walk: 0.001,
            rotation_walk: 0.002,
            anchored_walk: (0.0003, 0.0007),
            vo_sigma: (0.02, 0.002),
            wheel_sigma: (0.01, 0.05),
            wheel_factor_sigma: 0.02,
            latency_prior: (0.05, 0.1),
            robust: 3.0,
            gate: 6.0,
            max_iterations: 50,
            latency_search: (0.0, 0.2, 0.05),
            heading_drift_sigma: 0.01,
        }
    }
}

/// Why a drive could not be re-anchored.
#[derive(Clone, Debug, PartialEq)]
pub enum SolveError {
    /// Fewer than two VO samples.
    NoVo,
    /// Neither GNSS fixes nor anchors within the VO's time span.
    NothingToAnchorTo,
    /// The fixes and anchors do not determine a first alignment.
    Degenerate(String),
    /// The normal equations could not be factored.
    Singular,
}

impl std::fmt::Display for SolveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SolveError::NoVo => f.write_str("fewer than two VO poses: there is no trajectory to re-anchor"),
            SolveError::NothingToAnchorTo => f.write_str(
                "nothing to anchor to: no GNSS fix and no anchor falls within the VO poses' time span (anchors from street \
                 imagery would give some)",
            ),
            SolveError::Degenerate(why) => write!(f, "the fixes and anchors do not determine an alignment: {why}"),
            SolveError::Singular => f.write_str("the least-squares problem is singular"),
        }
    }
}

/// The re-anchored drive.
#[derive(Clone, Debug)]
pub struct Solution {
    /// Keyframe times, s.
    pub keyframe_t: Vec<f64>,
    /// VO index of each keyframe.
    pub(super) keyframe_vo: Vec<usize>,
    /// Camera positions at the keyframes, m.
    pub positions: Vec<Vector3<f64>>,
    /// Log-scale of each segment (the last repeats the one before).
    pub log_scale: Vec<f64>,
    /// Rotation of each segment.
    pub rotation: Vec<Matrix3<f64>>,
    /// GNSS latency, s.
    pub latency_s: f64,
    /// The latency the solve started from (the latency search's pick), s.
    pub start_latency_s: f64,
    /// Wheel factor (true distance / odometer distance).
    pub wheel_factor: f64,
    /// A dead-reckoned path's heading drift rate, rad/s (0 for a camera's VO).
    pub heading_drift: f64,
    /// Per fix: used (within the VO span and the gate).
    pub fix_used: Vec<bool>,
    /// Per anchor: used.
    pub anchor_used: Vec<bool>,
    /// Gauss–Newton iterations run.
    pub iterations: usize,
    /// A-posteriori variance factor (χ² / redundancy).
    pub sigma0_sq: f64,
    /// 1-σ of the drive's mean scale, relative.
    pub scale_sigma: f64,
    /// RMS 1-σ of the camera positions, m (from keyframes sampled along the drive).
    pub position_sigma_m: f64,
    /// Horizontal 1-σ (DRMS, m) of the camera position at up to 32 keyframes along the
    /// drive, by time: [`Solution::horizontal_sigma_at`] interpolates it.
    pub horizontal_sigma: Vec<(f64, f64)>,
    /// The least 1-σ of the camera's heading at those keyframes, rad: how well the
    /// session's fixes and anchors fix which way its VO path points where they fix it best.
    pub heading_sigma_rad: f64,
    /// RMS horizontal residual of the used fixes, m.
    pub gnss_rms_m: f64,
}
