//! The gyro's bias, estimated online.
//!
//! A consumer MEMS gyro's zero-rate offset is ±1–4 °/s at turn-on and wanders; integrated
//! over a minute, 1 °/s is a full turn the car never made. Two things show it:
//!
//! * **standstill** — when the wheels say the car stands, the gyro should read zero on
//!   every axis: the mean of what it reads is the bias ([`GyroBias::push`] with a speed
//!   of 0; at least [`STANDSTILL_S`] of it);
//! * **the GNSS course** — in motion (above [`MIN_COURSE_SPEED_MPS`]) the course over
//!   ground turns as fast as the car does: its rate between two fixes against the gyro's
//!   rate about the vertical over the same interval measures the bias along the vertical
//!   (a scalar Kalman filter, the bias a random walk; [`GyroBias::push_course`]).
//!
//! The same comparison measures the gyro's **scale**: a rate given in °/s instead of rad/s
//! turns 57 times faster than the course ([`GyroBias::scale`]).

use nalgebra::Vector3;

/// The car stands when the wheels read below this, m/s.
pub const STANDSTILL_MPS: f64 = 0.01;
/// Standstill this long (s) before its mean is taken as the bias.
pub const STANDSTILL_S: f64 = 0.5;
/// The course is compared from this speed on (below it a course is noise), m/s.
pub const MIN_COURSE_SPEED_MPS: f64 = 5.0;
/// σ of the GNSS velocity behind the course, m/s (a consumer receiver's Doppler speed).
const COURSE_VELOCITY_SIGMA_MPS: f64 = 0.2;
/// Prior σ of the bias, rad/s (a consumer gyro's turn-on bias is up to ±4 °/s).
const PRIOR_SIGMA_RAD_S: f64 = 0.1;
/// How fast the bias may wander, rad/s per √s (bias instability of a consumer MEMS gyro).
const RANDOM_WALK_RAD_S_PER_SQRT_S: f64 = 1e-4;
/// Innovations beyond this many σ are passed over (a course jump, a fix gone wrong).
const GATE_SIGMA: f64 = 5.0;
/// Course intervals compared: between 0.05 s and this, s.
const MAX_COURSE_INTERVAL_S: f64 = 3.0;
/// Σ (course rate² · Δt) from which the scale is judged, rad²/s (a turn at 0.1 rad/s for
/// five seconds).
const SCALE_EVIDENCE: f64 = 0.05;
/// The scale compares turns over at least this long, s (the course's noise over 0.1 s
/// would swamp it).
const SCALE_INTERVAL_S: f64 = 1.0;

/// The estimator's state.
#[derive(Clone, Copy, Debug)]
pub struct GyroBias {
    bias: Vector3<f64>,
    /// Variance of the bias along the vertical, (rad/s)².
    variance: f64,
    /// Standstill so far: its length, s, and the rate summed over it.
    standstill_s: f64,
    standstill_sum: Vector3<f64>,
    standstill_n: u32,
    /// Gyro rate about the vertical integrated since the last course, rad.
    turned: f64,
    turned_s: f64,
    last_course: Option<(f64, f64)>,
    /// The scale's longer interval: its start (time, course) and the gyro's turn since.
    scale_start: Option<(f64, f64)>,
    scale_turned: f64,
    /// The gyro's raw rate y against the course's x over the scale's intervals, weighted by
    /// their length: Σw, Σx, Σy, Σxy, Σxx (a line with an intercept: the bias is unknown).
    sums: [f64; 5],
    standstills: u32,
    courses: u32,
}

impl Default for GyroBias {
    fn default() -> Self {
        GyroBias {
            bias: Vector3::zeros(),
            variance: PRIOR_SIGMA_RAD_S * PRIOR_SIGMA_RAD_S,
            standstill_s: 0.0,
            standstill_sum: Vector3::zeros(),
            standstill_n: 0,
            turned: 0.0,
            turned_s: 0.0,
            last_course: None,
            scale_start: None,
            scale_turned: 0.0,
            sums: [0.0; 5],
            standstills: 0,
            courses: 0,
        }
    }
}

impl GyroBias {
    /// The bias so far, body axes, rad/s.
    pub fn bias(&self) -> &Vector3<f64> {
        &self.bias
    }

    /// 1-σ of the bias along the vertical, rad/s.
    pub fn sigma(&self) -> f64 {
        libm::sqrt(self.variance)
    }

    /// Standstills and course intervals the estimate rests on.
    pub fn evidence(&self) -> (u32, u32) {
        (self.standstills, self.courses)
    }

    /// The gyro's rate over the course's (1 for a gyro in rad/s), once the drive has
    /// turned enough to tell.
    pub fn scale(&self) -> Option<f64> {
        let [w, x, y, xy, xx] = self.sums;
        let spread = xx - x * x / w;
        (w > 0.0 && spread >= SCALE_EVIDENCE).then(|| (xy - x * y / w) / spread)
    }

    /// One raw gyro sample (body axes, rad/s) over `dt` s, with the body's up (body axes)
    /// and the wheels' speed (None: not known). True when a standstill just ended and its
    /// mean became the bias on every axis.
    pub fn push(&mut self, dt: f64, gyro: &Vector3<f64>, up: &Vector3<f64>, speed_mps: Option<f64>) -> bool {
        if !(dt > 0.0 && dt.is_finite()) {
            return false;
        }
        self.variance += RANDOM_WALK_RAD_S_PER_SQRT_S * RANDOM_WALK_RAD_S_PER_SQRT_S * dt;
        self.turned += gyro.dot(up) * dt;
        self.turned_s += dt;
        self.scale_turned += gyro.dot(up) * dt;
        if speed_mps.is_some_and(|v| v.abs() < STANDSTILL_MPS) {
            self.standstill_s += dt;
            self.standstill_sum += gyro;
            self.standstill_n = self.standstill_n.saturating_add(1);
            false
        } else {
            self.end_standstill()
        }
    }

    /// The car moved: a standstill long enough gives the bias (true when it did).
    fn end_standstill(&mut self) -> bool {
        let taken = self.standstill_s >= STANDSTILL_S && self.standstill_n > 0;
        if taken {
            self.bias = self.standstill_sum / f64::from(self.standstill_n);
            // The mean of ≥ 50 samples of a 0.005 rad/s-noise gyro: well below the course's.
            self.variance = self.variance.min(1e-8);
            self.standstills = self.standstills.saturating_add(1);
        }
        self.standstill_s = 0.0;
        self.standstill_sum = Vector3::zeros();
        self.standstill_n = 0;
        taken
    }

    /// A GNSS course (rad, clockwise from north) at time `t` (s) and the speed it was
    /// measured at; `up` the body's up (body axes) as now.
    pub fn push_course(&mut self, t: f64, course_rad: f64, speed_mps: f64, up: &Vector3<f64>) {
        let fast = speed_mps.is_finite() && speed_mps >= MIN_COURSE_SPEED_MPS && course_rad.is_finite();
        let previous = self.last_course.replace((t, course_rad)).filter(|_| fast);
        let (turned, turned_s) = (self.turned, self.turned_s);
        self.turned = 0.0;
        self.turned_s = 0.0;
        if !fast {
            self.last_course = None;
            self.scale_start = None;
            return;
        }
        self.compare_scale(t, course_rad);
        let Some((t0, c0)) = previous else { return };
        let dt = t - t0;
        if !(0.05..=MAX_COURSE_INTERVAL_S).contains(&dt) || turned_s <= 0.0 {
            return;
        }
        // Counter-clockwise from above, as the gyro's rate about up.
        let course_rate = -wrap(course_rad - c0) / dt;
        let gyro_rate = turned / turned_s;
        let measured = gyro_rate - course_rate;
        let noise = core::f64::consts::SQRT_2 * COURSE_VELOCITY_SIGMA_MPS / speed_mps / dt;
        let current = self.bias.dot(up);
        let innovation = measured - current;
        let s = self.variance + noise * noise;
        if innovation * innovation > GATE_SIGMA * GATE_SIGMA * s {
            return;
        }
        let gain = self.variance / s;
        self.bias += up * (gain * innovation);
        self.variance *= 1.0 - gain;
        self.courses = self.courses.saturating_add(1);
    }
}

impl GyroBias {
    /// The gyro's turn (bias removed) against the course's over [`SCALE_INTERVAL_S`].
    fn compare_scale(&mut self, t: f64, course_rad: f64) {
        let Some((t0, c0)) = self.scale_start else {
            self.scale_start = Some((t, course_rad));
            self.scale_turned = 0.0;
            return;
        };
        let dt = t - t0;
        if dt < SCALE_INTERVAL_S {
            return;
        }
        let course_rate = -wrap(course_rad - c0) / dt;
        if dt <= 2.0 * MAX_COURSE_INTERVAL_S {
            let gyro_rate = self.scale_turned / dt;
            let [w, x, y, xy, xx] = &mut self.sums;
            *w += dt;
            *x += course_rate * dt;
            *y += gyro_rate * dt;
            *xy += course_rate * gyro_rate * dt;
            *xx += course_rate * course_rate * dt;
        }
        self.scale_start = Some((t, course_rad));
        self.scale_turned = 0.0;
    }
}

/// An angle into (−π, π].
fn wrap(a: f64) -> f64 {
    let tau = core::f64::consts::TAU;
    a - tau * libm::round(a / tau)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_standstill_gives_the_bias_on_every_axis() {
        let mut b = GyroBias::default();
        let truth = Vector3::new(0.01, -0.02, 0.068);
        for k in 0..100 {
            let noise = if k % 2 == 0 { 0.003 } else { -0.003 };
            b.push(0.01, &(truth + Vector3::repeat(noise)), &Vector3::z(), Some(0.0));
        }
        assert!(b.push(0.01, &truth, &Vector3::z(), Some(3.0)), "the car moved: the standstill is taken");
        assert!((b.bias() - truth).norm() < 1e-4, "{:?}", b.bias());
        assert_eq!(b.evidence(), (1, 0));
    }

    #[test]
    fn a_short_stop_is_not_a_standstill() {
        let mut b = GyroBias::default();
        for _ in 0..20 {
            b.push(0.01, &Vector3::new(0.0, 0.0, 0.05), &Vector3::z(), Some(0.0));
        }
        assert!(!b.push(0.01, &Vector3::zeros(), &Vector3::z(), Some(1.0)));
        assert_eq!(b.bias(), &Vector3::zeros());
    }

    /// A car driving a slalom at 20 m/s, its gyro off by 0.068 rad/s: the course finds it.
    fn drive(gyro_scale: f64) -> GyroBias {
        let mut b = GyroBias::default();
        let bias = 0.068;
        let mut course = 0.3;
        let dt = 0.01;
        for k in 0..6000 {
            let t = f64::from(k) * dt;
            let rate = 0.15 * libm::sin(t * 0.5);
            course -= rate * dt;
            b.push(dt, &Vector3::new(0.0, 0.0, rate * gyro_scale + bias), &Vector3::z(), Some(20.0));
            if k % 10 == 0 {
                b.push_course(t, course, 20.0, &Vector3::z());
            }
        }
        b
    }

    #[test]
    fn the_course_in_motion_finds_the_vertical_bias_and_the_scale() {
        let b = drive(1.0);
        assert!((b.bias().z - 0.068).abs() < 1e-3, "{:?}", b.bias());
        // Ten courses a second at 20 m/s, each of 0.2 m/s velocity noise: σ ~ 6e-3 rad/s after a minute.
        assert!(b.sigma() < 1e-2 && b.sigma() < GyroBias::default().sigma() / 10.0, "{}", b.sigma());
        assert!(b.scale().is_some_and(|s| (s - 1.0).abs() < 0.02), "{:?}", b.scale());
        assert!(b.evidence().1 > 500);
    }

    #[test]
    fn a_gyro_in_degrees_shows_in_its_scale() {
        let b = drive(180.0 / core::f64::consts::PI);
        assert!(b.scale().is_some_and(|s| s > 10.0), "{:?}", b.scale());
    }

    #[test]
    fn slow_or_far_apart_courses_are_not_compared() {
        let mut b = GyroBias::default();
        for k in 0..100 {
            b.push(0.01, &Vector3::new(0.0, 0.0, 0.05), &Vector3::z(), Some(2.0));
            if k % 10 == 0 {
                b.push_course(f64::from(k) * 0.01, f64::from(k), 2.0, &Vector3::z());
            }
        }
        b.push_course(10.0, 0.0, 20.0, &Vector3::z());
        b.push_course(20.0, 0.5, 20.0, &Vector3::z());
        assert_eq!(b.evidence(), (0, 0));
    }
}
