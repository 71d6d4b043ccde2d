//! Online calibration of how the camera sits on the car, from the VO alone.
//!
//! Nobody measures the yaw and pitch of a dashcam stuck behind a windscreen, and a few
//! degrees matter: a camera pitched by 2° places an object 30 m ahead a metre off the
//! ground, and its yaw turns the ego's heading and every detection. openpilot's answer is
//! to watch the direction of travel: on a straight, level road a car moves along its own
//! forward axis, so the VO's frame-to-frame motion, expressed in the camera frame, *is*
//! the car's forward axis as the camera sees it. Its yaw and pitch against the camera's
//! axes are the mount's yaw and pitch. The VO's own orientation error cancels (the motion
//! and the orientation are in the same VO frame); its scale does not matter (only the
//! direction is used).
//!
//! Each VO pose gives a sample — the chord of the camera's path over the last
//! [`CalibrationConfig::baseline_s`], seen from the camera's orientation halfway along it (a
//! chord is ten frames' noise averaged, and on a gentle bend the halfway orientation is the
//! chord's tangent) — when the car is moving (the chord is at least half the session's
//! typical one) and going straight (the camera turned less than
//! [`CalibrationConfig::max_turn_rate`] along the chord);
//! the estimate is the samples' mean, weighed against the nominal mount as a prior
//! ([`CalibrationConfig::prior_sigma`]). Its σ comes from the samples' own spread — nothing
//! is told how noisy the VO is — counting [`CalibrationConfig::correlated_samples`] samples
//! as one, as a VO's errors are correlated over a second or so. The roll is the nominal
//! mount's: the direction of travel says nothing about it. Without VO the pitch is taken
//! from where the detected objects stand instead ([`super::ground`]).

use nalgebra::{Matrix3, Vector3};

use super::ground::GroundPitch;
use super::mount::CameraMount;
use crate::sim3::Pose;
use crate::track3d::Detection3d;

/// Orientations kept to measure the turn over the baseline (1.6 s at 10 Hz).
const HISTORY: usize = 16;

/// How the mount is calibrated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationConfig {
    /// A sample is taken only when the camera turned slower than this over the baseline,
    /// rad/s. On a bend the camera (ahead of the rear axle) moves sideways by turn rate ×
    /// lever arm: 1°/s at 10 m/s with the camera 1.8 m ahead is 0.18°.
    pub max_turn_rate: f64,
    /// The turn is measured over this long, s (a single frame's orientation jitter would
    /// swamp it).
    pub baseline_s: f64,
    /// Samples further than this from the nominal mount are not a car going forward
    /// (reversing, a VO glitch), rad.
    pub max_deviation: f64,
    /// σ of the nominal mount as a prior, rad.
    pub prior_sigma: f64,
    /// Calibrated once this many samples are in …
    pub min_samples: u32,
    /// … and both σ are below this, rad.
    pub max_sigma: f64,
    /// Consecutive samples counted as one independent sample.
    pub correlated_samples: f64,
    /// The pitch from where the detected objects stand ([`super::ground`]) instead of the
    /// direction of travel: for a camera whose motion nobody measures (gyro + wheels,
    /// whose dead-reckoned camera is pitched as gravity says).
    pub pitch_from_ground: bool,
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        CalibrationConfig {
            max_turn_rate: 1.0_f64.to_radians(),
            baseline_s: 1.0,
            max_deviation: 10.0_f64.to_radians(),
            prior_sigma: 5.0_f64.to_radians(),
            min_samples: 100,
            max_sigma: 0.1_f64.to_radians(),
            correlated_samples: 10.0,
            pitch_from_ground: false,
        }
    }
}

/// The calibrated mount and how well it is known.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MountEstimate {
    /// The mount: the nominal position and roll, the estimated pitch and yaw.
    pub mount: CameraMount,
    /// 1-σ of the yaw and the pitch, rad.
    pub sigma: [f64; 2],
    /// Samples taken.
    pub samples: u32,
    /// Enough samples and a small enough σ.
    pub calibrated: bool,
}

/// One kept pose: time, camera → VO rotation, position.
#[derive(Clone, Copy, Debug)]
struct Kept {
    t: f64,
    rotation: Matrix3<f64>,
    position: Vector3<f64>,
}

/// Running mean and spread of one angle (Welford).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Running {
    mean: f64,
    m2: f64,
}

impl Running {
    fn push(&mut self, n: u32, x: f64) {
        let delta = x - self.mean;
        self.mean += delta / f64::from(n);
        self.m2 += delta * (x - self.mean);
    }
}

/// The calibrator: feed it every VO pose ([`MountCalibration::push`]).
#[derive(Clone, Debug)]
pub struct MountCalibration {
    config: CalibrationConfig,
    nominal: CameraMount,
    session: Option<u32>,
    history: heapless::Deque<Kept, HISTORY>,
    /// Mean length of the session's chords (VO units), exponentially weighted.
    typical_chord: f64,
    samples: u32,
    /// Samples refused as too far from the nominal mount.
    outliers: u32,
    yaw: Running,
    pitch: Running,
    ground: GroundPitch,
}

impl MountCalibration {
    /// A calibrator starting from the nominal mount.
    pub const fn new(nominal: CameraMount, config: CalibrationConfig) -> Self {
        MountCalibration {
            config,
            nominal,
            session: None,
            history: heapless::Deque::new(),
            typical_chord: 0.0,
            samples: 0,
            outliers: 0,
            yaw: Running { mean: 0.0, m2: 0.0 },
            pitch: Running { mean: 0.0, m2: 0.0 },
            ground: GroundPitch::new(nominal.roll_pitch_yaw[1]),
        }
    }

    /// A 3D detection (camera frame), when the pitch is taken from the ground
    /// ([`CalibrationConfig::pitch_from_ground`]). Returns whether it was counted.
    pub fn push_detection(&mut self, d: &Detection3d) -> bool {
        self.config.pitch_from_ground && self.ground.push(&self.nominal, d)
    }

    /// The VO pose (camera → VO frame) of VO session `session` at `t` s. Poses must come
    /// in time order; a new session starts the motion afresh (its increments are not
    /// comparable with the old one's), the estimate carries on. Returns whether the pose
    /// gave a sample.
    pub fn push(&mut self, t: f64, session: u32, pose: &Pose) -> bool {
        if !(t.is_finite() && pose.is_finite()) {
            return false;
        }
        if self.session != Some(session) {
            self.session = Some(session);
            self.history.clear();
            self.typical_chord = 0.0;
        }
        if self.history.back().is_some_and(|k| t <= k.t) {
            return false;
        }
        if self.history.is_full() {
            self.history.pop_front();
        }
        // Room was made above.
        let _ = self.history.push_back(Kept { t, rotation: pose.rotation, position: pose.translation });
        let Some(sample) = self.sample() else { return false };
        let [_, pitch0, yaw0] = self.nominal.roll_pitch_yaw;
        let (yaw, pitch) = sample;
        let limit = self.config.max_deviation;
        if (yaw - yaw0).abs() > limit || (pitch - pitch0).abs() > limit {
            self.outliers = self.outliers.saturating_add(1);
            return false;
        }
        self.samples = self.samples.saturating_add(1);
        self.yaw.push(self.samples, yaw);
        self.pitch.push(self.samples, pitch);
        true
    }

    /// The yaw and pitch the chord ending at the latest pose gives, if the car moved
    /// straight along it.
    fn sample(&mut self) -> Option<(f64, f64)> {
        let n = self.history.len();
        let latest = *self.history.back()?;
        let start =
            (0..n).rev().find(|&k| self.history.get(k).is_some_and(|o| latest.t - o.t >= self.config.baseline_s))?;
        let (old, middle) = (self.history.get(start)?, self.history.get((start + n - 1) / 2)?);
        let chord = latest.position - old.position;
        let length = chord.norm();
        if !(length > 0.0 && length.is_finite()) {
            return None;
        }
        let moving = length >= 0.5 * self.typical_chord;
        self.typical_chord = if self.typical_chord > 0.0 { 0.9 * self.typical_chord + 0.1 * length } else { length };
        let relative = old.rotation.transpose() * latest.rotation;
        let turn = libm::acos(((relative.trace() - 1.0) * 0.5).clamp(-1.0, 1.0));
        let straight = turn <= self.config.max_turn_rate * (latest.t - old.t);
        if !(moving && straight) {
            return None;
        }
        self.forward_angles(&(middle.rotation.transpose() * chord / length))
    }

    /// The mount's yaw and pitch that make the camera-frame unit vector `forward` the
    /// body's forward axis, with the nominal roll. The mount rotation is yaw·pitch·roll
    /// (camera → body), so `Rz(yaw)·Ry(pitch)·(Rx(roll)·forward) = x̂`:
    /// `Rx(roll)·forward = (cos p cos y, −sin y, sin p cos y)`.
    fn forward_angles(&self, forward: &Vector3<f64>) -> Option<(f64, f64)> {
        let (s, c) = libm::sincos(self.nominal.roll_pitch_yaw[0]);
        let u = Vector3::new(forward.x, c * forward.y - s * forward.z, s * forward.y + c * forward.z);
        if u.x.is_nan() || u.x <= 0.0 {
            return None;
        }
        Some((libm::asin((-u.y).clamp(-1.0, 1.0)), libm::atan2(u.z, u.x)))
    }

    /// The current estimate: the nominal mount as the prior, the samples' mean as the
    /// measurement.
    pub fn estimate(&self) -> MountEstimate {
        let c = &self.config;
        let [roll, pitch0, yaw0] = self.nominal.roll_pitch_yaw;
        let prior = 1.0 / (c.prior_sigma * c.prior_sigma);
        let n = f64::from(self.samples);
        let independent = (n / c.correlated_samples.max(1.0)).max(1.0);
        let fuse = |running: &Running, nominal: f64| {
            if self.samples < 2 {
                return (nominal, c.prior_sigma);
            }
            let spread = (running.m2 / (n - 1.0)).max(1e-12);
            let measured = independent / spread;
            let information = prior + measured;
            ((prior * nominal + measured * running.mean) / information, libm::sqrt(1.0 / information))
        };
        let (yaw, sigma_yaw) = fuse(&self.yaw, yaw0);
        let (pitch, sigma_pitch) = match (c.pitch_from_ground, self.ground.estimate()) {
            (false, _) => fuse(&self.pitch, pitch0),
            (true, Some(measured)) => measured,
            (true, None) => (pitch0, c.prior_sigma),
        };
        MountEstimate {
            mount: CameraMount { position: self.nominal.position, roll_pitch_yaw: [roll, pitch, yaw] },
            sigma: [sigma_yaw, sigma_pitch],
            samples: self.samples,
            calibrated: self.samples >= c.min_samples && sigma_yaw <= c.max_sigma && sigma_pitch <= c.max_sigma,
        }
    }

    /// Forget the samples and start again from the nominal mount: what the poses said
    /// before no longer holds (the dead-reckoned camera was turned once the car's forward
    /// axis was found).
    pub fn restart(&mut self) {
        // Where the objects stand does not depend on the camera's yaw.
        let ground = core::mem::replace(&mut self.ground, GroundPitch::new(0.0));
        *self = MountCalibration { ground, ..MountCalibration::new(self.nominal, self.config) };
    }

    /// Samples refused as too far from the nominal mount.
    pub fn outliers(&self) -> u32 {
        self.outliers
    }

    /// The nominal mount it started from.
    pub fn nominal(&self) -> &CameraMount {
        &self.nominal
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim3::rotation_z;

    /// A camera on `mount` of a car driving east at 10 m/s for `seconds` at 10 Hz, then
    /// turning left at 10°/s: its VO poses (VO = ENU scaled by 1/3, rotated by 0.7 rad).
    fn drive(mount: &CameraMount, straight_s: f64, turning_s: f64) -> impl Iterator<Item = (f64, Pose)> {
        let vo_from_enu = rotation_z(-0.7);
        let m = mount.rotation();
        let lever = Vector3::from(mount.position);
        let (mut x, mut y, mut heading) = (0.0, 0.0, 0.0);
        let frames = ((straight_s + turning_s) * 10.0) as usize;
        (0..frames).map(move |k| {
            let t = k as f64 * 0.1;
            if k > 0 {
                x += libm::cos(heading);
                y += libm::sin(heading);
                if t > straight_s {
                    heading += 1.0_f64.to_radians();
                }
            }
            let body = rotation_z(heading);
            let camera = Vector3::new(x, y, 0.0) + body * lever;
            let rotation = vo_from_enu * body * m;
            (t, Pose { rotation, translation: vo_from_enu * camera / 3.0 })
        })
    }

    #[test]
    fn the_yaw_and_pitch_of_the_mount_come_back_from_straight_driving() {
        let truth = CameraMount { position: [1.8, 0.0, 1.3], roll_pitch_yaw: [0.0, -0.04, 0.05] };
        let mut c = MountCalibration::new(CameraMount::default(), CalibrationConfig::default());
        let samples = drive(&truth, 30.0, 0.0).filter(|(t, p)| c.push(*t, 0, p)).count();
        let e = c.estimate();
        assert!(samples > 250, "{samples} samples");
        assert!((e.mount.roll_pitch_yaw[2] - 0.05).abs() < 1e-6, "{e:?}");
        assert!((e.mount.roll_pitch_yaw[1] + 0.04).abs() < 1e-6, "{e:?}");
        assert!(e.calibrated && e.samples as usize == samples);
    }

    #[test]
    fn comma_axes_roll_is_kept_and_the_angles_still_come_back() {
        let nominal = CameraMount { position: [1.5, 0.0, 1.2], roll_pitch_yaw: [core::f64::consts::PI, 0.0, 0.0] };
        let truth = CameraMount { roll_pitch_yaw: [core::f64::consts::PI, 0.03, -0.02], ..nominal };
        let mut c = MountCalibration::new(nominal, CalibrationConfig::default());
        for (t, p) in drive(&truth, 20.0, 0.0) {
            c.push(t, 0, &p);
        }
        let [roll, pitch, yaw] = c.estimate().mount.roll_pitch_yaw;
        assert!(
            (roll - core::f64::consts::PI).abs() < 1e-12 && (pitch - 0.03).abs() < 1e-6 && (yaw + 0.02).abs() < 1e-6
        );
    }

    #[test]
    fn a_drive_that_never_goes_straight_keeps_the_nominal_mount() {
        let truth = CameraMount { roll_pitch_yaw: [0.0, 0.05, 0.05], ..CameraMount::default() };
        let mut c = MountCalibration::new(CameraMount::default(), CalibrationConfig::default());
        // Turning from the start (after one second, the baseline, of straight driving).
        let taken = drive(&truth, 0.0, 30.0).filter(|(t, p)| c.push(*t, 0, p)).count();
        let e = c.estimate();
        assert_eq!(taken, 0);
        assert_eq!(e.mount, CameraMount::default());
        assert!(!e.calibrated && e.sigma == [5.0_f64.to_radians(); 2]);
    }

    #[test]
    fn a_new_session_restarts_the_motion_but_keeps_the_estimate() {
        let truth = CameraMount { roll_pitch_yaw: [0.0, 0.02, -0.03], ..CameraMount::default() };
        let mut c = MountCalibration::new(CameraMount::default(), CalibrationConfig::default());
        let poses: heapless::Vec<(f64, Pose), 400> = drive(&truth, 40.0, 0.0).collect();
        for (t, p) in &poses[..200] {
            c.push(*t, 0, p);
        }
        let before = c.estimate().samples;
        // The new session's VO is somewhere else entirely: without the restart its first
        // increment would be a wild sample (an outlier at best).
        let jumped =
            |p: &Pose| Pose { rotation: p.rotation, translation: p.translation * 0.5 + Vector3::new(90.0, -40.0, 3.0) };
        let (t, p) = &poses[200];
        assert!(!c.push(*t, 1, &jumped(p)), "the first pose of a session gives no sample");
        for (t, p) in &poses[201..] {
            c.push(*t, 1, &jumped(p));
        }
        let e = c.estimate();
        assert!(e.samples > before && c.outliers() == 0);
        assert!((e.mount.roll_pitch_yaw[2] + 0.03).abs() < 1e-6);
    }

    #[test]
    fn standing_still_and_bad_poses_give_no_sample() {
        let mut c = MountCalibration::new(CameraMount::default(), CalibrationConfig::default());
        let still = Pose { rotation: Matrix3::identity(), translation: Vector3::new(1.0, 2.0, 3.0) };
        for k in 0..50 {
            assert!(!c.push(f64::from(k) * 0.1, 0, &still));
        }
        let nan = Pose { rotation: Matrix3::identity(), translation: Vector3::new(f64::NAN, 0.0, 0.0) };
        assert!(!c.push(5.0, 0, &nan));
        assert!(!c.push(f64::INFINITY, 0, &still));
        assert_eq!(c.estimate().samples, 0);
    }
}
