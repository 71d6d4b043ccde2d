//! Visual odometry as a monocular camera would give it: the true motion seen through a
//! similarity whose scale and yaw drift with time (the scale of monocular VO is unknown
//! and wanders), plus noise on every frame-to-frame increment.

use dash2sim_core::nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use dash2sim_core::sim3::{rotation_z, Pose};
use rand::Rng;

use super::gauss;
use crate::trajectory::Trajectory;

/// How the VO track is made from the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoModel {
    /// Metres per VO unit at t = 0.
    pub scale: f64,
    /// VO → ENU rotation at t = 0.
    pub rotation: Matrix3<f64>,
    /// Relative scale drift per minute (0.01 = 1 %).
    pub scale_drift_per_min: f64,
    /// Yaw drift, degrees per minute.
    pub yaw_drift_deg_per_min: f64,
}

impl VoModel {
    /// An arbitrary 3D orientation and scale 3.7 with 1 %/min scale and 1°/min yaw drift.
    pub fn arbitrary() -> Self {
        let axis = Unit::new_normalize(Vector3::new(0.4, -0.7, 0.6));
        VoModel {
            scale: 3.7,
            rotation: *Rotation3::from_axis_angle(&axis, 2.3).matrix(),
            scale_drift_per_min: 0.01,
            yaw_drift_deg_per_min: 1.0,
        }
    }

    /// A gravity-aligned VO frame (visual-inertial odometry, or VO levelled by the
    /// dashcam's accelerometer): z is up, the heading is arbitrary (2.3 rad), scale 3.7,
    /// with 1 %/min scale and 1°/min yaw drift. Anchor it with `--mode gravity`.
    pub fn gravity_aligned() -> Self {
        VoModel { rotation: rotation_z(2.3), ..VoModel::arbitrary() }
    }

    /// The true VO → ENU scale at `t` seconds from the start.
    pub fn scale_at(&self, t: f64) -> f64 {
        self.scale * (1.0 + self.scale_drift_per_min * t / 60.0)
    }

    fn rotation_at(&self, t: f64) -> Matrix3<f64> {
        rotation_z((self.yaw_drift_deg_per_min * t / 60.0).to_radians()) * self.rotation
    }

    /// VO poses: truth increments mapped back through the drifting similarity, and the
    /// truth orientations seen from the drifting VO frame.
    pub fn make_vo(&self, truth: &Trajectory) -> Trajectory {
        let t0 = truth.stamps[0];
        let mut vo = Trajectory::default();
        let mut x = Vector3::zeros();
        for (k, (&t, pose)) in truth.stamps.iter().zip(&truth.poses).enumerate() {
            if k > 0 {
                let dp = pose.translation - truth.poses[k - 1].translation;
                let tau = t - t0;
                x += self.rotation_at(tau).transpose() * dp / self.scale_at(tau);
            }
            vo.stamps.push(t);
            let rotation = self.rotation_at(t - t0).transpose() * pose.rotation;
            vo.poses.push(Pose { rotation, translation: x });
        }
        vo
    }
}

/// Perturb every increment of `vo` by Gaussian noise of `relative` × its length per axis
/// (the error accumulates, as VO's does).
pub fn add_increment_noise(vo: &mut Trajectory, rng: &mut impl Rng, relative: f64) {
    let mut offset = Vector3::zeros();
    let mut previous = None;
    for pose in &mut vo.poses {
        let original = pose.translation;
        if let Some(p) = previous {
            let step: Vector3<f64> = original - p;
            let sigma = relative * step.norm();
            offset += Vector3::new(gauss(rng, sigma), gauss(rng, sigma), gauss(rng, sigma));
        }
        previous = Some(original);
        pose.translation += offset;
    }
}
