//! Where the dashcam sits on the car, and how what it sees is placed in the world.
//!
//! Frames (all right-handed):
//! * **body**: the ego vehicle's rear axle on the ground, x forward, y left, z up (nuPlan
//!   places the ego's pose there);
//! * **camera**: the frame the VO poses and the 3D detections are given in, at the
//!   camera. [`CameraMount`] is its pose in the body frame. A detector that reports
//!   boxes in a levelled camera frame (x forward, y left, z up, REP 103) has a mount with
//!   no rotation; one that follows the camera's own axes (comma's x forward, y right,
//!   z down) has a roll of π.
//!
//! The dashcam's GNSS receiver is taken to be at the camera (it is inside the same
//! housing): the anchorer aligns camera positions to the fixes, and the rear axle
//! follows through the mount.

use nalgebra::{Matrix2, Matrix3, Vector3};

use crate::box3d::Box3d;
use crate::obb::Pose2;
use crate::sim3::{Pose, Sim3};
use crate::track3d::Detection3d;

/// The camera's pose on the vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraMount {
    /// Camera position in the body frame (forward, left, up from the rear axle on the
    /// ground), m.
    pub position: [f64; 3],
    /// Camera → body rotation as roll, pitch, yaw (rad; applied yaw·pitch·roll).
    pub roll_pitch_yaw: [f64; 3],
}

impl Default for CameraMount {
    /// A windscreen dashcam: 1.8 m ahead of the rear axle, 1.3 m up, levelled axes.
    fn default() -> Self {
        CameraMount { position: [1.8, 0.0, 1.3], roll_pitch_yaw: [0.0; 3] }
    }
}

impl CameraMount {
    /// Camera → body rotation.
    pub fn rotation(&self) -> Matrix3<f64> {
        let [r, p, y] = self.roll_pitch_yaw;
        crate::imu::so3::from_roll_pitch_yaw(r, p, y)
    }

    /// The ego's world pose (rear axle) when the camera is at `camera` (ENU), as a body
    /// rotation and the rear axle's position.
    pub fn body_pose(&self, camera: &Pose) -> Pose {
        let rotation = camera.rotation * self.rotation().transpose();
        let translation = camera.translation - rotation * Vector3::from(self.position);
        Pose { rotation, translation }
    }

    /// A detection in the camera frame, in the body frame (box centre, heading about the
    /// vertical, horizontal covariance). Pitch and roll of the car itself are ignored:
    /// near the vehicle the ground is taken to be flat.
    pub fn to_body(&self, d: &Detection3d) -> Detection3d {
        let r = self.rotation();
        let b = &d.bbox;
        let centre = r * Vector3::new(b.x, b.y, b.z) + Vector3::from(self.position);
        let (s, c) = libm::sincos(b.yaw);
        let forward = r * Vector3::new(c, s, 0.0);
        let yaw = libm::atan2(forward.y, forward.x);
        let a = Matrix2::new(r[(0, 0)], r[(0, 1)], r[(1, 0)], r[(1, 1)]);
        Detection3d {
            bbox: Box3d { x: centre.x, y: centre.y, z: centre.z, yaw, ..*b },
            position_covariance: d.position_covariance.map(|cov| transform_covariance(&a, cov)),
            ..*d
        }
    }
}

/// `A C Aᵀ` for a 2×2 covariance stored as (xx, xy, yy).
fn transform_covariance(a: &Matrix2<f64>, [xx, xy, yy]: [f64; 3]) -> [f64; 3] {
    let c = Matrix2::new(xx, xy, xy, yy);
    let out = a * c * a.transpose();
    [out[(0, 0)], 0.5 * (out[(0, 1)] + out[(1, 0)]), out[(1, 1)]]
}

/// Heading of a body rotation: the forward axis's direction in the ground plane.
pub fn heading(rotation: &Matrix3<f64>) -> f64 {
    libm::atan2(rotation[(1, 0)], rotation[(0, 0)])
}

/// The camera pose in ENU: the anchor applied to the VO pose (its scale only moves
/// positions; a rotation stays a rotation).
pub fn camera_in_world(anchor: &Sim3, vo: &Pose) -> Pose {
    Pose { rotation: anchor.rotation * vo.rotation, translation: anchor.transform_point(&vo.translation) }
}

/// A detection in the body frame placed in the world through the ego's planar pose:
/// x, y and heading in ENU, z kept as the height above the ego's ground (so that the
/// tracker's ground prior holds wherever the road is).
pub fn to_world(ego: &Pose2, d: &Detection3d) -> Detection3d {
    let (s, c) = libm::sincos(ego.heading);
    let b = &d.bbox;
    let a = Matrix2::new(c, -s, s, c);
    Detection3d {
        bbox: Box3d {
            x: ego.x + c * b.x - s * b.y,
            y: ego.y + s * b.x + c * b.y,
            yaw: crate::track3d::wrap_angle(b.yaw + ego.heading),
            ..*b
        },
        position_covariance: d.position_covariance.map(|cov| transform_covariance(&a, cov)),
        ..*d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim3::rotation_z;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn a_levelled_mount_shifts_and_a_rolled_mount_flips_y_and_z() {
        let d = Detection3d {
            position_covariance: Some([4.0, 1.0, 0.25]),
            ..Detection3d::new(0, Box3d { x: 10.0, y: 2.0, z: -0.8, yaw: 0.3, l: 4.0, w: 2.0, h: 1.5 }, 0.9)
        };
        let levelled = CameraMount::default().to_body(&d);
        assert!(close(levelled.bbox.x, 11.8) && close(levelled.bbox.y, 2.0) && close(levelled.bbox.z, 0.5));
        assert!(close(levelled.bbox.yaw, 0.3));
        assert_eq!(levelled.position_covariance, Some([4.0, 1.0, 0.25]));
        // comma's camera axes: y right, z down.
        let rolled = CameraMount { position: [0.0; 3], roll_pitch_yaw: [core::f64::consts::PI, 0.0, 0.0] };
        let b = rolled.to_body(&d);
        assert!(close(b.bbox.y, -2.0) && close(b.bbox.z, 0.8) && close(b.bbox.yaw, -0.3));
        let [xx, xy, yy] = b.position_covariance.unwrap_or_default();
        assert!(close(xx, 4.0) && close(xy, -1.0) && close(yy, 0.25));
    }

    #[test]
    fn the_rear_axle_is_behind_and_below_the_camera() {
        let mount = CameraMount::default();
        let camera =
            Pose { rotation: rotation_z(core::f64::consts::FRAC_PI_2), translation: Vector3::new(5.0, 5.0, 1.3) };
        let body = mount.body_pose(&camera);
        assert!(close(body.translation.x, 5.0) && close(body.translation.y, 3.2) && close(body.translation.z, 0.0));
        assert!(close(heading(&body.rotation), core::f64::consts::FRAC_PI_2));
        let placed = to_world(
            &Pose2::new(5.0, 3.2, core::f64::consts::FRAC_PI_2),
            &Detection3d::new(0, Box3d { x: 10.0, y: 0.0, z: 0.5, yaw: 0.0, l: 1.0, w: 1.0, h: 1.0 }, 1.0),
        );
        assert!(close(placed.bbox.x, 5.0) && close(placed.bbox.y, 13.2) && close(placed.bbox.z, 0.5));
    }
}
