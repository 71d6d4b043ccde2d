//! The body's attitude from the gyro, its tilt held to gravity.
//!
//! The gyro (bias removed, body axes) turns the attitude sample by sample; alone it drifts.
//! Gravity is the one direction the car always knows: at rest the specific force is 9.81
//! m/s² up. Driving adds the car's own acceleration — along the road, the wheel speed's
//! change; across it, the speed times the turn rate — and once that is taken out, what is
//! left is gravity. Each sample pulls the attitude's up towards that measured up with a
//! time constant of [`TILT_TIME_CONSTANT_S`] (a complementary filter), less when the
//! specific force's magnitude says something unexplained is going on (a pothole, braking
//! the wheels did not see). The correction is perpendicular to up, so it never touches the
//! heading: yaw is the gyro's alone (the anchorer finds where it points).
//!
//! A gyro bias about a horizontal axis tilts the attitude steadily, and a proportional
//! pull alone would leave it tilted by bias × time constant (0.035 rad/s × 2 s = 4° on
//! comma's EON). The correction is therefore also integrated into an estimate of that
//! bias (Mahony, Hamel and Pflimlin's complementary filter on SO(3), 2008), with a time
//! constant of [`TILT_BIAS_TIME_CONSTANT_S`]: the horizontal bias is gravity's to find, the
//! vertical one is the course's ([`super::bias`]).

use nalgebra::{Matrix3, Vector3};

use super::{so3, GRAVITY};

/// Time constant with which the tilt follows gravity, s.
pub const TILT_TIME_CONSTANT_S: f64 = 2.0;
/// For this long after it is levelled (s), the tilt follows gravity faster
/// ([`SETTLING_TIME_CONSTANT_S`]) and no bias is integrated: the first level is taken from
/// one sample, whatever the car was doing then.
pub const SETTLING_S: f64 = 5.0;
/// The tilt's time constant while settling, s.
pub const SETTLING_TIME_CONSTANT_S: f64 = 0.5;
/// Time constant with which the horizontal gyro bias follows the tilt correction, s.
pub const TILT_BIAS_TIME_CONSTANT_S: f64 = 5.0;
/// A sample whose compensated specific force is this far from 1 g (m/s²) does not correct.
const MAX_FORCE_ERROR: f64 = 2.0;
/// Updates between renormalisations of the rotation.
const RENORMALISE_EVERY: u32 = 256;

/// The body's attitude: body → a level frame (z up) whose yaw is wherever the gyro took it.
#[derive(Clone, Copy, Debug)]
pub struct Attitude {
    rotation: Matrix3<f64>,
    /// The gyro's bias about the horizontal axes the tilt correction has found (body axes).
    tilt_bias: Vector3<f64>,
    initialised: bool,
    /// Time since it was levelled, s (counted up to [`SETTLING_S`]).
    age_s: f64,
    updates: u32,
}

impl Default for Attitude {
    fn default() -> Self {
        Attitude {
            rotation: Matrix3::identity(),
            tilt_bias: Vector3::zeros(),
            initialised: false,
            age_s: 0.0,
            updates: 0,
        }
    }
}

/// The acceleration the car's own motion gives the body (x forward, y left, z up), m/s²:
/// the wheel speed's change along the road, speed × turn rate across it.
pub fn motion_acceleration(speed_mps: f64, accel_mps2: f64, gyro_body: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(accel_mps2, speed_mps * gyro_body.z, -speed_mps * gyro_body.y)
}

impl Attitude {
    /// The attitude so far (body → level frame).
    pub fn rotation(&self) -> &Matrix3<f64> {
        &self.rotation
    }

    /// The gyro's bias about the horizontal axes, as the tilt correction found it (body
    /// axes, rad/s).
    pub fn tilt_bias(&self) -> &Vector3<f64> {
        &self.tilt_bias
    }

    /// Forget the horizontal bias (another estimate, a standstill's, has all of it).
    pub fn reset_tilt_bias(&mut self) {
        self.tilt_bias = Vector3::zeros();
    }

    /// How long since it was levelled, s (counted up to [`SETTLING_S`]).
    pub fn levelled_for_s(&self) -> f64 {
        self.age_s
    }

    /// Whether a first sample has levelled it.
    pub fn is_initialised(&self) -> bool {
        self.initialised
    }

    /// The body's pitch and roll (Z-Y-X, rad), as [`so3::yaw_pitch_roll`] gives them.
    pub fn pitch_roll(&self) -> [f64; 2] {
        let [_, pitch, roll] = so3::yaw_pitch_roll(&self.rotation);
        [pitch, roll]
    }

    /// One sample over `dt` s: the rate (bias removed) and specific force in the body
    /// frame, and the acceleration the car's motion explains ([`motion_acceleration`]).
    pub fn update(&mut self, dt: f64, gyro: &Vector3<f64>, force: &Vector3<f64>, motion: &Vector3<f64>) {
        let gravity = force - motion;
        let magnitude = gravity.norm();
        if !self.initialised {
            if magnitude > 0.5 * GRAVITY {
                self.rotation = level(&(gravity / magnitude));
                self.initialised = true;
            }
            return;
        }
        if !(dt > 0.0 && dt.is_finite()) {
            return;
        }
        self.rotation *= so3::exp(&((gyro - self.tilt_bias) * dt));
        let settling = self.age_s < SETTLING_S;
        self.age_s = (self.age_s + dt).min(SETTLING_S);
        let error = (magnitude - GRAVITY).abs();
        if error < MAX_FORCE_ERROR && magnitude > 0.0 {
            let measured_up = gravity / magnitude;
            let predicted_up = self.rotation.transpose() * Vector3::z();
            let trust = 1.0 - error / MAX_FORCE_ERROR;
            let tau = if settling { SETTLING_TIME_CONSTANT_S } else { TILT_TIME_CONSTANT_S };
            let gain = (dt / tau).clamp(0.0, 1.0) * trust;
            let tilt_error = measured_up.cross(&predicted_up);
            self.rotation *= so3::exp(&(tilt_error * gain));
            if !settling {
                // Steady state: (bias − estimate) = kP·e, so the estimate moves by kI·e.
                let integral = dt * trust / (TILT_TIME_CONSTANT_S * TILT_BIAS_TIME_CONSTANT_S);
                self.tilt_bias -= tilt_error * integral;
            }
        }
        self.updates += 1;
        if self.updates.is_multiple_of(RENORMALISE_EVERY) {
            self.rotation = so3::renormalise(&self.rotation);
        }
    }
}

/// The body → level rotation with yaw 0 for a body whose up (in body axes) is `up`.
fn level(up: &Vector3<f64>) -> Matrix3<f64> {
    // In the level frame the body's axes are the rows' transposes: the third row is up.
    let pitch = libm::asin((-up.x).clamp(-1.0, 1.0));
    let roll = libm::atan2(up.y, up.z);
    so3::from_roll_pitch_yaw(roll, pitch, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn force_at(pitch: f64, roll: f64) -> Vector3<f64> {
        so3::from_roll_pitch_yaw(roll, pitch, 0.0).transpose() * Vector3::new(0.0, 0.0, GRAVITY)
    }

    #[test]
    fn at_rest_the_tilt_is_gravity_s() {
        let mut a = Attitude::default();
        let f = force_at(0.05, -0.02);
        a.update(0.01, &Vector3::zeros(), &f, &Vector3::zeros());
        let [p, r] = a.pitch_roll();
        assert!((p - 0.05).abs() < 1e-12 && (r + 0.02).abs() < 1e-12);
    }

    #[test]
    fn braking_the_wheels_explain_does_not_tilt_the_car() {
        let (pitch, roll) = (0.03, 0.01);
        let mut with = Attitude::default();
        let mut without = Attitude::default();
        for k in 0..1000 {
            // Braking at 4 m/s² for ten seconds: the specific force leans forward.
            let decel = if k > 0 { -4.0 } else { 0.0 };
            let f = force_at(pitch, roll) + Vector3::new(decel, 0.0, 0.0);
            let motion = motion_acceleration(20.0, decel, &Vector3::zeros());
            with.update(0.01, &Vector3::zeros(), &f, &motion);
            without.update(0.01, &Vector3::zeros(), &f, &Vector3::zeros());
        }
        let [p, r] = with.pitch_roll();
        assert!((p - pitch).abs() < 1e-6 && (r - roll).abs() < 1e-6, "{p} {r}");
        // The uncompensated filter takes the braking for a nose-down slope.
        assert!((without.pitch_roll()[0] - pitch).abs() > 0.1);
    }

    #[test]
    fn a_turn_keeps_its_heading_from_the_gyro_and_its_tilt_from_gravity() {
        let mut a = Attitude::default();
        let rate = Vector3::new(0.0, 0.0, 0.2);
        for _ in 0..=500 {
            // 15 m/s round a bend at 0.2 rad/s: 3 m/s² to the left.
            let f = Vector3::new(0.0, 3.0, GRAVITY);
            let motion = motion_acceleration(15.0, 0.0, &rate);
            a.update(0.01, &rate, &f, &motion);
        }
        let [yaw, pitch, roll] = so3::yaw_pitch_roll(a.rotation());
        assert!((yaw - 1.0).abs() < 1e-9, "{yaw}");
        assert!(pitch.abs() < 1e-9 && roll.abs() < 1e-9, "{pitch} {roll}");
    }

    #[test]
    fn a_horizontal_gyro_bias_is_found_and_no_longer_tilts_the_car() {
        let bias = Vector3::new(0.01, -0.035, 0.0);
        let mut with = Attitude::default();
        for _ in 0..12_000 {
            with.update(0.01, &bias, &force_at(0.0, 0.0), &Vector3::zeros());
        }
        assert!((with.tilt_bias() - bias).norm() < 1e-4, "{:?}", with.tilt_bias());
        let [p, r] = with.pitch_roll();
        assert!(p.abs() < 1e-4 && r.abs() < 1e-4, "{p} {r}");
        with.reset_tilt_bias();
        assert_eq!(with.tilt_bias(), &Vector3::zeros());
    }

    #[test]
    fn a_wrong_start_is_pulled_to_gravity_within_a_few_time_constants() {
        let mut a = Attitude::default();
        a.update(0.01, &Vector3::zeros(), &force_at(0.2, 0.0), &Vector3::zeros());
        for _ in 0..6000 {
            a.update(0.01, &Vector3::zeros(), &force_at(0.0, 0.0), &Vector3::zeros());
        }
        // The bias integrator takes part of the start for a bias and gives it back over its
        // own time constant: after a minute, under 1 % of 0.2 rad is left.
        assert!(a.pitch_roll()[0].abs() < 0.2 * 0.01, "{:?}", a.pitch_roll());
    }
}
