//! Rotations as the IMU needs them, with `libm` for every transcendental function (the
//! device's log is the host's byte for byte only if both compute the same bits).

use nalgebra::{Matrix3, Vector3};

/// The rotation roll, pitch, yaw (rad) applied yaw·pitch·roll (Z-Y-X).
pub fn from_roll_pitch_yaw(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    let (sr, cr) = libm::sincos(roll);
    let (sp, cp) = libm::sincos(pitch);
    let (sy, cy) = libm::sincos(yaw);
    Matrix3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// The rotation by the rotation vector `phi` (axis × angle, rad): Rodrigues' formula,
/// with its series near zero.
pub fn exp(phi: &Vector3<f64>) -> Matrix3<f64> {
    let angle2 = phi.norm_squared();
    let k = phi.cross_matrix();
    let (a, b) = if angle2 < 1e-12 {
        (1.0 - angle2 / 6.0, 0.5 - angle2 / 24.0)
    } else {
        let angle = libm::sqrt(angle2);
        (libm::sin(angle) / angle, (1.0 - libm::cos(angle)) / angle2)
    };
    Matrix3::identity() + k * a + k * k * b
}

/// The rotation vector of a rotation (the inverse of [`exp`] for angles below π).
///
/// The angle is taken from both its sine (`|v| = 2·sin θ`, `v` the skew part) and its cosine
/// (`trace − 1 = 2·cos θ`): from the cosine alone (`acos`, as nalgebra's `scaled_axis` does)
/// half the digits are lost near zero — 1e-8 rad on any angle — and a trace rounded above 3
/// gives NaN, which is what small relative rotations between neighbouring keyframes are.
pub fn log(r: &Matrix3<f64>) -> Vector3<f64> {
    let v = Vector3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]);
    let sin2 = libm::sqrt(v.norm_squared());
    if sin2 < 1e-12 {
        return v * 0.5;
    }
    v * (libm::atan2(sin2, r.trace() - 1.0) / sin2)
}

/// The nearest rotation to a matrix that integration has let drift from one (a first-order
/// Gram–Schmidt step: enough when applied after every few hundred updates).
pub fn renormalise(r: &Matrix3<f64>) -> Matrix3<f64> {
    let x = r.column(0).into_owned();
    let y = r.column(1).into_owned();
    let error = x.dot(&y);
    let x2 = x - y * (error * 0.5);
    let y2 = y - x * (error * 0.5);
    let z2 = x2.cross(&y2);
    Matrix3::from_columns(&[
        x2 * (0.5 * (3.0 - x2.dot(&x2))),
        y2 * (0.5 * (3.0 - y2.dot(&y2))),
        z2 * (0.5 * (3.0 - z2.dot(&z2))),
    ])
}

/// Yaw, pitch, roll (Z-Y-X) of a rotation, rad.
pub fn yaw_pitch_roll(r: &Matrix3<f64>) -> [f64; 3] {
    [libm::atan2(r[(1, 0)], r[(0, 0)]), libm::asin((-r[(2, 0)]).clamp(-1.0, 1.0)), libm::atan2(r[(2, 1)], r[(2, 2)])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_and_log_are_inverse_and_exp_is_a_rotation() {
        for phi in [Vector3::new(0.3, -0.2, 0.9), Vector3::new(1e-9, 0.0, -2e-9), Vector3::new(0.0, 2.5, 0.0)] {
            let r = exp(&phi);
            assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-12);
            assert!((log(&r) - phi).norm() < 1e-9, "{phi:?}");
        }
        let yaw = exp(&Vector3::new(0.0, 0.0, 0.5));
        assert!((yaw_pitch_roll(&yaw)[0] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_small_rotation_keeps_its_digits_and_a_trace_rounded_above_three_is_no_nan() {
        // The relative rotation of two nearby keyframes, as a product of rotations.
        let phi = Vector3::new(2e-6, -1e-6, 3e-6);
        let a = exp(&Vector3::new(0.4, -1.1, 2.0));
        let relative = exp(&phi) * a * a.transpose();
        // From the trace alone the angle would be off by ~1e-8 rad: 0.3 % of this one.
        assert!((log(&relative) - phi).norm() < 1e-6 * phi.norm(), "{:?}", log(&relative) - phi);
        let rounded_up = Matrix3::identity() * (1.0 + 4.0 * f64::EPSILON) + phi.cross_matrix();
        assert!(rounded_up.trace() > 3.0);
        assert!((log(&rounded_up) - phi).norm() < 1e-9 * phi.norm().max(1.0));
    }

    #[test]
    fn roll_pitch_yaw_round_trips() {
        let r = from_roll_pitch_yaw(0.1, -0.2, 2.0);
        let [y, p, roll] = yaw_pitch_roll(&r);
        assert!((y - 2.0).abs() < 1e-12 && (p + 0.2).abs() < 1e-12 && (roll - 0.1).abs() < 1e-12);
    }

    #[test]
    fn renormalising_pulls_a_drifted_matrix_back_to_a_rotation() {
        let drifted = exp(&Vector3::new(0.2, 0.1, -0.4)) * 1.0001 + Matrix3::from_element(1e-5);
        let r = renormalise(&drifted);
        assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-6);
        assert!((r - drifted).norm() < 1e-3);
    }
}
