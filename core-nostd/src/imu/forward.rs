//! Where the car's forward axis lies in the IMU stage's body frame.
//!
//! That frame is the sensor's through its nominal mounts, the housing's as it was told. A
//! dashcam stuck behind a windscreen sits turned on the car by a few degrees, so the car's
//! forward axis is off the frame's x by as much. Gravity cannot see a yaw; the car's own
//! accelerations can: braking and speeding up on a straight road push the sensor along the
//! car's forward axis and nowhere else.
//!
//! Over straight driving the horizontal specific force, less the turn's share (speed × turn
//! rate, across), is `a·(cos δ, sin δ)` plus the accelerometer's bias and gravity's share
//! of the frame's tilt, both constant: the slope of its lateral against its longitudinal
//! component — a line fitted with an intercept, so neither bias nor tilt matters — is
//! `tan δ`. The samples are averaged over short bins first, so that the vibration's noise in
//! the longitudinal component (the regressor) does not flatten the slope.

use nalgebra::Vector3;

/// Averaging bin, s.
const BIN_S: f64 = 0.25;
/// Turning faster than this (rad/s) is not straight driving: the lever arm's and the
/// turn's forces would enter.
const MAX_TURN_RATE: f64 = 0.03;
/// Slower than this (m/s) the wheels' speed and the turn mean little.
const MIN_SPEED_MPS: f64 = 3.0;
/// The spread of the longitudinal force the estimate needs, Σ (x − x̄)² over the bins,
/// (m/s²)²: 20 bins (5 s) 1 m/s² away from the mean — one firm braking.
const MIN_SPREAD: f64 = 10.0;

/// The estimator: feed it every sample ([`ForwardAxis::push`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct ForwardAxis {
    /// The open bin: Σ f_x dt, Σ lateral dt, time, and the turn rate at its start.
    bin: [f64; 4],
    /// Over the closed bins: n, Σx, Σy, Σx², Σxy.
    sums: [f64; 5],
}

impl ForwardAxis {
    /// A sample of `dt` s: the specific force on the body's axes (m/s²), the car's speed
    /// (m/s, the wheels') and the turn rate about the body's vertical (rad/s, the gyro's,
    /// bias removed), with the sensor `ahead_m` metres ahead of the rear axle: a change of
    /// turn rate pushes it sideways by `ω̇ × ahead` (a lane change while braking would
    /// otherwise read as a turned sensor). Samples while turning or nearly standing end
    /// the open bin unused.
    pub fn push(&mut self, dt: f64, force: &Vector3<f64>, speed_mps: f64, turn_rate: f64, ahead_m: f64) {
        let usable = dt > 0.0
            && dt.is_finite()
            && speed_mps >= MIN_SPEED_MPS
            && turn_rate.abs() <= MAX_TURN_RATE
            && force.iter().all(|f| f.is_finite());
        if !usable {
            self.bin = [0.0; 4];
            return;
        }
        if self.bin[2] == 0.0 {
            self.bin[3] = turn_rate;
        }
        let lateral = force.y - speed_mps * turn_rate;
        self.bin[0] += force.x * dt;
        self.bin[1] += lateral * dt;
        self.bin[2] += dt;
        if self.bin[2] >= BIN_S {
            let turn_change = (turn_rate - self.bin[3]) / self.bin[2];
            let (x, y) = (self.bin[0] / self.bin[2], self.bin[1] / self.bin[2] - turn_change * ahead_m);
            let s = &mut self.sums;
            s[0] += 1.0;
            s[1] += x;
            s[2] += y;
            s[3] += x * x;
            s[4] += x * y;
            self.bin = [0.0; 4];
        }
    }

    /// The car's forward axis as an angle from the body's x about its z (rad, positive to
    /// the left), once the drive has braked or sped up enough to show it.
    pub fn yaw(&self) -> Option<f64> {
        let [n, sx, sy, sxx, sxy] = self.sums;
        if n < 3.0 {
            return None;
        }
        let spread = sxx - sx * sx / n;
        // NaN is not enough spread either.
        if spread.is_nan() || spread < MIN_SPREAD {
            return None;
        }
        let slope = (sxy - sx * sy / n) / spread;
        slope.is_finite().then(|| libm::atan(slope))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brake at 1.5 m/s² for 5 s, cruise, speed up again: the force along the car's forward
    /// axis turned `yaw` on the body, with a constant bias and a tilt's share of gravity.
    fn drive(yaw: f64, turn: f64) -> ForwardAxis {
        let mut f = ForwardAxis::default();
        let dt = 0.01;
        let mut noise = 0.37f64;
        for k in 0..3000 {
            let t = k as f64 * dt;
            let a = if t < 5.0 {
                -1.5
            } else if t < 15.0 {
                0.0
            } else if t < 20.0 {
                1.5
            } else {
                0.0
            };
            let speed = 20.0;
            // A deterministic wobble for vibration, ±0.2 m/s².
            noise = (noise * 3.9 * (1.0 - noise)).clamp(0.01, 0.99);
            let wobble = 0.4 * (noise - 0.5);
            let force = Vector3::new(
                a * libm::cos(yaw) + 0.15 + wobble,
                a * libm::sin(yaw) - 0.2 + speed * turn - wobble,
                9.81,
            );
            f.push(dt, &force, speed, turn, 1.8);
        }
        f
    }

    #[test]
    fn braking_and_speeding_up_show_the_car_s_forward_axis_whatever_the_bias() {
        for yaw_deg in [-3.0f64, 0.0, 2.0] {
            let yaw = drive(yaw_deg.to_radians(), 0.0).yaw().expect("braked enough");
            assert!((yaw.to_degrees() - yaw_deg).abs() < 0.1, "{} vs {yaw_deg}", yaw.to_degrees());
        }
        // A turn's force across the car is taken out by the turn rate; a sharper turn is
        // not used at all.
        let gentle = drive(2f64.to_radians(), 0.02).yaw().expect("straight enough");
        assert!((gentle.to_degrees() - 2.0).abs() < 0.1, "{}", gentle.to_degrees());
        assert_eq!(drive(2f64.to_radians(), 0.05).yaw(), None);
    }

    #[test]
    fn cruising_alone_shows_nothing() {
        let mut f = ForwardAxis::default();
        for _ in 0..10_000 {
            f.push(0.01, &Vector3::new(0.1, -0.1, 9.81), 20.0, 0.0, 1.8);
        }
        assert_eq!(f.yaw(), None);
        f.push(f64::NAN, &Vector3::new(0.1, -0.1, 9.81), 20.0, 0.0, 1.8);
        assert_eq!(f.yaw(), None);
    }
}
