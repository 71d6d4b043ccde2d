//! Similarity transforms and rigid poses.
//!
//! A visual-odometry trajectory lives in a frame with an unknown origin, orientation and
//! scale; a [`Sim3`] maps it into a metric ENU frame. [`Pose`] is a rigid-body pose stored
//! the way evo stores it — a raw rotation matrix and a translation, never silently
//! re-orthonormalised — so that trajectory metrics reproduce evo's numbers exactly.
//!
//! [`umeyama`] estimates a `Sim3` from point correspondences using accumulated moments.

pub mod umeyama;

use nalgebra::{Matrix3, Matrix4, Vector3};

pub use umeyama::{AlignError, AlignMode, Moments};

/// A similarity transform `p ↦ s·R·p + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sim3 {
    /// Rotation (orthonormal, det +1 when produced by this crate).
    pub rotation: Matrix3<f64>,
    /// Translation, in the target frame.
    pub translation: Vector3<f64>,
    /// Scale factor, > 0.
    pub scale: f64,
}

/// A rigid-body pose: `rotation` maps body-frame vectors to the world frame and
/// `translation` is the body origin in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Body → world rotation.
    pub rotation: Matrix3<f64>,
    /// Body origin in the world frame.
    pub translation: Vector3<f64>,
}

impl Default for Sim3 {
    fn default() -> Self {
        Sim3::identity()
    }
}

impl Sim3 {
    /// The identity transform.
    pub fn identity() -> Self {
        Sim3 { rotation: Matrix3::identity(), translation: Vector3::zeros(), scale: 1.0 }
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Sim3) -> Sim3 {
        Sim3 {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation * self.scale + self.translation,
            scale: self.scale * other.scale,
        }
    }

    /// The inverse transform (uses `Rᵀ` as the inverse rotation).
    pub fn inverse(&self) -> Sim3 {
        let rt = self.rotation.transpose();
        Sim3 { rotation: rt, translation: -(rt * self.translation) / self.scale, scale: 1.0 / self.scale }
    }

    /// Map a point.
    pub fn transform_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p * self.scale + self.translation
    }

    /// Map a pose: its position is transformed as a point, its orientation is rotated.
    /// This is what evo's `scale(s)` followed by `transform(se3(R, t))` does.
    pub fn transform_pose(&self, pose: &Pose) -> Pose {
        Pose { rotation: self.rotation * pose.rotation, translation: self.transform_point(&pose.translation) }
    }

    /// True when every component is finite and the scale is positive.
    pub fn is_valid(&self) -> bool {
        self.rotation.iter().all(|v| v.is_finite())
            && self.translation.iter().all(|v| v.is_finite())
            && self.scale.is_finite()
            && self.scale > 0.0
    }
}

impl Pose {
    /// The identity pose.
    pub fn identity() -> Self {
        Pose { rotation: Matrix3::identity(), translation: Vector3::zeros() }
    }

    /// From a unit (or not quite unit) quaternion `w, x, y, z` and a position.
    ///
    /// The quaternion is normalised inside the formula exactly as evo's
    /// `transformations.quaternion_matrix` does, so TUM files give bit-for-bit the same
    /// matrices; a zero quaternion gives the identity rotation as it does there.
    pub fn from_quaternion_wxyz(q: [f64; 4], translation: Vector3<f64>) -> Self {
        let n = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
        if n < 4.0 * f64::EPSILON {
            return Pose { rotation: Matrix3::identity(), translation };
        }
        let k = libm::sqrt(2.0 / n);
        let [w, x, y, z] = [q[0] * k, q[1] * k, q[2] * k, q[3] * k];
        #[rustfmt::skip]
        let rotation = Matrix3::new(
            1.0 - y * y - z * z, x * y - z * w,       x * z + y * w,
            x * y + z * w,       1.0 - x * x - z * z, y * z - x * w,
            x * z - y * w,       y * z + x * w,       1.0 - x * x - y * y,
        );
        Pose { rotation, translation }
    }

    /// The inverse pose, `(Rᵀ, −Rᵀt)`, as evo's `se3_inverse` computes it.
    pub fn inverse(&self) -> Pose {
        let rt = self.rotation.transpose();
        Pose { rotation: rt, translation: -(rt * self.translation) }
    }

    /// `self · other` as 4×4 homogeneous matrices.
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// `self⁻¹ · other`: the pose of `other` seen from `self` (evo's `relative_se3`).
    pub fn relative_to(&self, other: &Pose) -> Pose {
        self.inverse().compose(other)
    }

    /// The 4×4 homogeneous matrix.
    pub fn to_matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }

    /// True when every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.rotation.iter().chain(self.translation.iter()).all(|v| v.is_finite())
    }
}

/// Rotation about the z axis by `yaw` radians.
pub fn rotation_z(yaw: f64) -> Matrix3<f64> {
    let (s, c) = (libm::sin(yaw), libm::cos(yaw));
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Sim3 {
        Sim3 { rotation: rotation_z(0.7), translation: Vector3::new(1.0, -2.0, 3.0), scale: 2.5 }
    }

    #[test]
    fn inverse_undoes_the_transform() {
        let t = sample();
        let p = Vector3::new(4.0, 5.0, -6.0);
        let back = t.inverse().transform_point(&t.transform_point(&p));
        assert!((back - p).norm() < 1e-12);
        let id = t.compose(&t.inverse());
        assert!((id.rotation - Matrix3::identity()).norm() < 1e-12);
        assert!(id.translation.norm() < 1e-12 && (id.scale - 1.0).abs() < 1e-12);
    }

    #[test]
    fn compose_applies_right_operand_first() {
        let a = sample();
        let b = Sim3 { rotation: rotation_z(-0.2), translation: Vector3::new(0.0, 1.0, 0.0), scale: 0.5 };
        let p = Vector3::new(1.0, 2.0, 3.0);
        let direct = a.transform_point(&b.transform_point(&p));
        assert!((a.compose(&b).transform_point(&p) - direct).norm() < 1e-12);
    }

    #[test]
    fn quaternion_matches_rotation_about_z() {
        let yaw: f64 = 0.3;
        let q = [libm::cos(yaw / 2.0), 0.0, 0.0, libm::sin(yaw / 2.0)];
        let pose = Pose::from_quaternion_wxyz(q, Vector3::zeros());
        assert!((pose.rotation - rotation_z(yaw)).norm() < 1e-15);
        // Not normalised on input: same rotation.
        let scaled = Pose::from_quaternion_wxyz(q.map(|v| v * 3.0), Vector3::zeros());
        assert!((scaled.rotation - pose.rotation).norm() < 1e-15);
        assert_eq!(Pose::from_quaternion_wxyz([0.0; 4], Vector3::zeros()).rotation, Matrix3::identity());
    }

    #[test]
    fn relative_pose_of_itself_is_identity() {
        let p = Pose { rotation: rotation_z(1.0), translation: Vector3::new(3.0, 4.0, 5.0) };
        let r = p.relative_to(&p);
        assert!((r.to_matrix() - Matrix4::identity()).norm() < 1e-12);
    }
}
