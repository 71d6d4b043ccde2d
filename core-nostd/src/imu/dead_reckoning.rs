//! Gyro + wheels as the relative motion: where the camera publishes no VO (a dashcam without
//! the compute for it, or a VO outage) the car's own trajectory is still known up to a
//! similarity — the attitude from the gyro ([`Attitude`]), the distance from the wheels.
//!
//! The body's origin moves along its own heading at the wheels' speed (a car does not
//! slide sideways); integrated, that is a trajectory in a frame of its own whose z is up
//! (the attitude is levelled by gravity) and whose scale is the wheels' — the same kind of
//! thing a VO gives, anchored the same way: its scale is the wheel factor, its drift the
//! gyro's heading drift and the wheels' slip.
//!
//! The trajectory stays in the horizontal plane: the sensor's forward axis is not the car's
//! direction of travel in pitch (comma's EON looks 3.8° below it), and integrating along it
//! sank the comma2k19 minute by 66 m in a kilometre, which no gravity-aligned similarity
//! can take out. The height is left to the anchors until the mount's pitch is calibrated
//! against the drive (issue #54).

use nalgebra::{Matrix3, Vector3};

use super::attitude::Attitude;
use crate::sim3::Pose;

/// The dead-reckoned body.
#[derive(Clone, Copy, Debug, Default)]
pub struct DeadReckoning {
    position: Vector3<f64>,
}

impl DeadReckoning {
    /// Move by `speed_mps` over `dt` s along the body's heading as `attitude` has it (its
    /// forward axis projected on the horizontal).
    pub fn advance(&mut self, dt: f64, speed_mps: f64, attitude: &Attitude) {
        if !(dt > 0.0 && dt.is_finite() && speed_mps.is_finite()) {
            return;
        }
        let mut forward = attitude.rotation().column(0).into_owned();
        forward.z = 0.0;
        let n = forward.norm();
        if n < 0.5 {
            return;
        }
        self.position += forward * (speed_mps * dt / n);
    }

    /// The pose of a camera mounted at `position` (body frame, m) with rotation
    /// `camera_to_body`: what the pipeline anchors in place of a VO pose.
    pub fn camera_pose(&self, attitude: &Attitude, camera_to_body: &Matrix3<f64>, position: &Vector3<f64>) -> Pose {
        let r = attitude.rotation();
        Pose { rotation: r * camera_to_body, translation: self.position + r * position }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imu::attitude::motion_acceleration;
    use crate::imu::GRAVITY;

    #[test]
    fn a_pitched_sensor_moves_the_car_along_the_road_not_into_it() {
        let (speed, dt) = (20.0, 0.01);
        let mut attitude = Attitude::default();
        // Gravity as a sensor pitched 4° nose down reads it.
        let pitch = 4f64.to_radians();
        let force = crate::imu::so3::from_roll_pitch_yaw(0.0, pitch, 0.0).transpose() * Vector3::new(0.0, 0.0, GRAVITY);
        let mut dr = DeadReckoning::default();
        for _ in 0..1000 {
            attitude.update(dt, &Vector3::zeros(), &force, &Vector3::zeros());
            dr.advance(dt, speed, &attitude);
        }
        let p = dr.camera_pose(&attitude, &Matrix3::identity(), &Vector3::zeros()).translation;
        assert!((p.x - 200.0).abs() < 1e-6 && p.y.abs() < 1e-9 && p.z.abs() < 1e-9, "{p:?}");
    }

    #[test]
    fn a_quarter_circle_at_constant_speed_ends_where_geometry_says() {
        let (speed, rate, dt) = (10.0, 0.1, 0.01);
        let mut attitude = Attitude::default();
        let mut dr = DeadReckoning::default();
        let gyro = Vector3::new(0.0, 0.0, rate);
        let force = Vector3::new(0.0, speed * rate, GRAVITY);
        attitude.update(dt, &gyro, &force, &motion_acceleration(speed, 0.0, &gyro));
        let steps = (core::f64::consts::FRAC_PI_2 / rate / dt) as usize;
        for _ in 0..steps {
            attitude.update(dt, &gyro, &force, &motion_acceleration(speed, 0.0, &gyro));
            dr.advance(dt, speed, &attitude);
        }
        // A quarter of a circle of radius 100 m, from east to north.
        let p = dr.camera_pose(&attitude, &Matrix3::identity(), &Vector3::zeros()).translation;
        assert!((p.x - 100.0).abs() < 0.6 && (p.y - 100.0).abs() < 0.6 && p.z.abs() < 1e-9, "{p:?}");
        let camera = dr.camera_pose(&attitude, &Matrix3::identity(), &Vector3::new(1.8, 0.0, 1.3));
        assert!((camera.translation - (p + Vector3::new(-0.0, 1.8, 1.3))).norm() < 0.02, "{:?}", camera.translation);
    }
}
