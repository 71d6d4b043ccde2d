//! What the log keeps of the IMU: its samples preintegrated over a short interval — the
//! rotation the gyro measured (a rotation vector) and the velocity change the specific
//! force gave (in the interval's first sensor frame), on the sensor's own axes, raw (no
//! bias removed, gravity included). That is what a factor-graph smoother takes between two
//! states (Forster et al.'s preintegrated measurements, to first order), so `finish` can
//! redo attitude, bias and dead reckoning offline; at 10 Hz it costs about a tenth of the
//! samples' bytes.

use nalgebra::{Matrix3, Vector3};

use super::so3;

/// One interval's preintegrated samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Delta {
    /// Length of the interval, s.
    pub dt: f64,
    /// Rotation over the interval (sensor frame at its start → at its end), rotation vector, rad.
    pub dtheta: Vector3<f64>,
    /// Velocity change from the specific force, in the sensor frame at the interval's start, m/s.
    pub dv: Vector3<f64>,
    /// Samples in it.
    pub samples: u32,
}

/// The running interval.
#[derive(Clone, Copy, Debug)]
pub struct Preintegrator {
    rotation: Matrix3<f64>,
    dv: Vector3<f64>,
    dt: f64,
    samples: u32,
}

impl Default for Preintegrator {
    fn default() -> Self {
        Preintegrator { rotation: Matrix3::identity(), dv: Vector3::zeros(), dt: 0.0, samples: 0 }
    }
}

impl Preintegrator {
    /// One sample (sensor axes) held for `dt` s.
    pub fn push(&mut self, dt: f64, gyro: &Vector3<f64>, force: &Vector3<f64>) {
        if !(dt > 0.0 && dt.is_finite()) {
            self.samples = self.samples.saturating_add(1);
            return;
        }
        self.dv += self.rotation * force * dt;
        self.rotation *= so3::exp(&(gyro * dt));
        self.dt += dt;
        self.samples = self.samples.saturating_add(1);
    }

    /// Time in the interval so far, s.
    pub fn elapsed(&self) -> f64 {
        self.dt
    }

    /// The interval so far, and a new one begins.
    pub fn take(&mut self) -> Delta {
        let delta = Delta { dt: self.dt, dtheta: so3::log(&self.rotation), dv: self.dv, samples: self.samples };
        *self = Preintegrator::default();
        delta
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_turn_and_push_preintegrate_to_their_totals() {
        let mut p = Preintegrator::default();
        let gyro = Vector3::new(0.0, 0.0, 0.5);
        let force = Vector3::new(1.0, 0.0, 9.8);
        for _ in 0..10 {
            p.push(0.01, &gyro, &force);
        }
        assert!((p.elapsed() - 0.1).abs() < 1e-12);
        let d = p.take();
        assert!((d.dtheta - Vector3::new(0.0, 0.0, 0.05)).norm() < 1e-12);
        assert_eq!(d.samples, 10);
        // The forward push turns with the sensor: the mean heading over the interval is 0.0225 rad.
        let expected: Vector3<f64> = (0..10).map(|k| so3::exp(&(gyro * (0.01 * f64::from(k)))) * force * 0.01).sum();
        assert!((d.dv - expected).norm() < 1e-12);
        assert!(d.dv.y > 0.0);
        assert_eq!(p.take().samples, 0, "a new interval begins");
    }
}
