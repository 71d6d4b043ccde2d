//! The dashcam's inertial sensor (a G-sensor with a gyro beside it): its samples, the checks
//! they must pass, and what the device makes of them.
//!
//! A sample is the sensor's own reading on its own axes: the angular rate (rad/s) and the
//! **specific force** (m/s²: what an accelerometer measures, acceleration minus gravity, so
//! a sensor at rest reads 9.81 m/s² *upwards*). Where the sensor sits is configuration,
//! [`ImuMount`]: the rotation from its axes to the camera's, as calibrated for the housing
//! (for comma's EON the identity: the IMU's axes are the camera's, forward, right, down).
//! Through the camera's mount the samples reach the **body** frame (x forward, y left,
//! z up), where everything below works:
//!
//! * [`attitude`]: the body's attitude — gyro-propagated, its tilt held to gravity (the
//!   specific force less the acceleration the wheels and the turn rate explain); pitch and
//!   roll from the sensor instead of from the VO;
//! * [`bias`]: the gyro's bias, at standstill (the wheels say when) and in motion (the
//!   GNSS course says how fast the car really turns);
//! * [`dead_reckoning`]: gyro + wheels as the relative motion, a trajectory in a frame of
//!   its own with its z vertical, anchored as a VO trajectory is;
//! * [`forward`]: the car's forward axis in the body frame, from its braking and speeding
//!   up — how far the housing (and the camera in it) is turned on the car;
//! * [`preintegrate`]: what the log keeps — the samples preintegrated over a short
//!   interval (Δ angle, Δ velocity), raw, so that offline finishing can redo everything;
//! * [`impact`]: the G-sensor's trigger, a specific-force spike past a threshold;
//! * [`lsm6dso`]: a driver for a consumer MEMS IMU over embedded-hal 1.0 I²C.
//!
//! [`check`] refuses what cannot be a sample (not finite, beyond any consumer sensor's full
//! scale); [`UnitCheck`] refuses a stream whose gravity says its units or axes are not the
//! ones configured (specific force in g, the sensor's axes swapped against its mount).

pub mod attitude;
pub mod bias;
pub mod dead_reckoning;
pub mod forward;
pub mod impact;
pub mod lsm6dso;
pub mod preintegrate;
pub mod so3;

use nalgebra::{Matrix3, Vector3};

/// Standard gravity, m/s².
pub const GRAVITY: f64 = 9.806_65;
/// The largest angular rate a sample may have, rad/s: a consumer sensor's widest full
/// scale is ±2000 °/s (34.9 rad/s); anything beyond is not a reading.
pub const MAX_RATE_RAD_S: f64 = 40.0;
/// The largest specific force a sample may have, m/s²: ±16 g full scale, and a margin.
pub const MAX_SPECIFIC_FORCE: f64 = 20.0 * GRAVITY;

/// One reading of the sensor, on its own axes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuSample {
    /// Angular rate about the sensor's x, y, z, rad/s.
    pub gyro: [f64; 3],
    /// Specific force along the sensor's x, y, z, m/s² (at rest: 9.81 m/s² up).
    pub accel: [f64; 3],
}

/// Why a sample was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Refusal {
    /// A value is NaN or infinite.
    NotFinite,
    /// An angular rate or a specific force beyond any consumer sensor's full scale (rates
    /// in °/s read as rad/s, or a corrupted sample).
    BeyondFullScale,
}

/// Whether a sample can be a reading at all.
pub fn check(s: &ImuSample) -> Result<(), Refusal> {
    if !s.gyro.iter().chain(&s.accel).all(|v| v.is_finite()) {
        return Err(Refusal::NotFinite);
    }
    let rate = Vector3::from(s.gyro).norm();
    let force = Vector3::from(s.accel).norm();
    if rate > MAX_RATE_RAD_S || force > MAX_SPECIFIC_FORCE {
        return Err(Refusal::BeyondFullScale);
    }
    Ok(())
}

/// The sensor's axes on the camera: the rotation sensor → camera as roll, pitch, yaw (rad;
/// applied yaw·pitch·roll, as [`CameraMount`](crate::pipeline::CameraMount)'s). Calibrated
/// for the housing, not assumed: a dashcam's IMU is soldered at whatever angle its board
/// allowed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImuMount {
    /// Sensor → camera rotation, rad.
    pub roll_pitch_yaw: [f64; 3],
}

impl ImuMount {
    /// Sensor → camera rotation.
    pub fn rotation(&self) -> Matrix3<f64> {
        let [r, p, y] = self.roll_pitch_yaw;
        so3::from_roll_pitch_yaw(r, p, y)
    }
}

/// What a stream's first second of gravity says about it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UnitVerdict {
    /// Not enough quiet samples yet.
    Undecided,
    /// Gravity as configured: magnitude about 9.8 m/s², pointing up the body's z.
    Consistent,
    /// The specific force's magnitude at rest is about 1: given in g, not m/s².
    InG,
    /// Gravity points this far (rad) from the body's up: the sensor's axes or its mount
    /// are not as configured.
    AxesOff(f64),
}

/// Checks a stream's units and axes from gravity: over samples that do not turn (the
/// gyro near zero), the mean specific force in the body frame must be about 9.8 m/s² and
/// point within [`UnitCheck::MAX_TILT_RAD`] of up (a car on a road is never tilted more).
#[derive(Clone, Copy, Debug, Default)]
pub struct UnitCheck {
    sum: [f64; 3],
    n: u32,
    verdict: Option<UnitVerdict>,
}

impl UnitCheck {
    /// Quiet samples the verdict rests on (about a second at 100 Hz).
    pub const SAMPLES: u32 = 100;
    /// Largest tilt of gravity from the body's up, rad (25°: steeper than any road).
    pub const MAX_TILT_RAD: f64 = 0.436;

    /// A sample already in the body frame; the verdict so far.
    pub fn push(&mut self, gyro_body: &Vector3<f64>, force_body: &Vector3<f64>) -> UnitVerdict {
        if let Some(v) = self.verdict {
            return v;
        }
        // Turning samples carry centripetal force; leave them out.
        if gyro_body.norm() > 0.1 {
            return UnitVerdict::Undecided;
        }
        for (s, f) in self.sum.iter_mut().zip(force_body.iter()) {
            *s += f;
        }
        self.n += 1;
        if self.n < Self::SAMPLES {
            return UnitVerdict::Undecided;
        }
        let mean = Vector3::from(self.sum) / f64::from(self.n);
        let magnitude = mean.norm();
        let verdict = if (0.5..2.0).contains(&magnitude) {
            UnitVerdict::InG
        } else {
            let tilt =
                if magnitude > 0.0 { libm::acos((mean.z / magnitude).clamp(-1.0, 1.0)) } else { core::f64::consts::PI };
            if tilt > Self::MAX_TILT_RAD || !(0.5 * GRAVITY..1.5 * GRAVITY).contains(&magnitude) {
                UnitVerdict::AxesOff(tilt)
            } else {
                UnitVerdict::Consistent
            }
        };
        self.verdict = Some(verdict);
        verdict
    }

    /// The verdict, once there is one.
    pub fn verdict(&self) -> Option<UnitVerdict> {
        self.verdict
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_beyond_full_scale_or_not_finite_is_refused() {
        let good = ImuSample { gyro: [0.1, -0.2, 0.3], accel: [0.5, 0.1, 9.8] };
        assert_eq!(check(&good), Ok(()));
        let nan = ImuSample { gyro: [f64::NAN, 0.0, 0.0], ..good };
        assert_eq!(check(&nan), Err(Refusal::NotFinite));
        // 90 °/s given as a number of degrees.
        let degrees = ImuSample { gyro: [0.0, 0.0, 90.0], ..good };
        assert_eq!(check(&degrees), Err(Refusal::BeyondFullScale));
        let slam = ImuSample { accel: [250.0, 0.0, 9.8], ..good };
        assert_eq!(check(&slam), Err(Refusal::BeyondFullScale));
    }

    fn verdict_of(force: Vector3<f64>) -> UnitVerdict {
        let mut c = UnitCheck::default();
        let mut v = UnitVerdict::Undecided;
        for _ in 0..UnitCheck::SAMPLES {
            v = c.push(&Vector3::zeros(), &force);
        }
        v
    }

    #[test]
    fn gravity_tells_units_in_g_and_swapped_axes() {
        assert_eq!(verdict_of(Vector3::new(0.3, 0.1, 9.79)), UnitVerdict::Consistent);
        assert_eq!(verdict_of(Vector3::new(0.03, 0.01, 0.998)), UnitVerdict::InG);
        // The sensor's z mounted forward: gravity along the body's x.
        assert!(matches!(verdict_of(Vector3::new(9.8, 0.0, 0.2)), UnitVerdict::AxesOff(t) if t > 1.5));
        // Upside down.
        assert!(matches!(verdict_of(Vector3::new(0.0, 0.0, -9.8)), UnitVerdict::AxesOff(_)));
    }

    #[test]
    fn turning_samples_do_not_count_and_the_verdict_stays() {
        let mut c = UnitCheck::default();
        for _ in 0..1000 {
            assert_eq!(c.push(&Vector3::new(0.0, 0.0, 0.5), &Vector3::new(0.0, 3.0, 9.8)), UnitVerdict::Undecided);
        }
        assert_eq!(verdict_of(Vector3::new(0.0, 0.0, 9.8)), UnitVerdict::Consistent);
        for _ in 0..UnitCheck::SAMPLES {
            c.push(&Vector3::zeros(), &Vector3::new(0.0, 0.0, 9.8));
        }
        assert_eq!(c.verdict(), Some(UnitVerdict::Consistent));
        assert_eq!(c.push(&Vector3::zeros(), &Vector3::new(0.0, 0.0, 1.0)), UnitVerdict::Consistent);
    }
}
