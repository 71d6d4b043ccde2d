//! Metric scale from wheel speed.
//!
//! Over a short window, distance travelled by the wheels divided by VO path length is
//! the VO→metre scale — far more precise than what a few metres of GNSS noise allow.
//! Wheel speed itself is biased (tyre wear, pressure; about −0.85 % on the comma2k19
//! car), so its factor is calibrated online against the GNSS path: chords of accepted
//! fixes at least [`CALIBRATION_BASELINE_S`] apart, summed, over the odometer distance
//! between the same instants. GNSS errors telescope in that sum, so the calibration
//! error falls as 1/path length.

use nalgebra::Vector3;

use crate::time::Timestamp;

/// Minimum time between the two fixes of one calibration chord: long enough that
/// fix-to-fix noise is small against the chord, short enough that chord ≈ arc.
pub(crate) const CALIBRATION_BASELINE_S: f64 = 1.0;
/// Longest gap accepted inside one chord (a GNSS outage breaks the chain).
const CALIBRATION_MAX_GAP_S: f64 = 5.0;
/// Below this speed (m/s) the VO and wheel distances are dominated by noise.
const MIN_SPEED_MPS: f64 = 1.0;

/// Wheel-speed scale estimation state.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct WheelScale {
    /// Exponentially windowed VO path length (VO units).
    vo_path: f64,
    /// Exponentially windowed odometer distance over the same frames (m).
    wheel_path: f64,
    last_frame: Option<(Timestamp, Vector3<f64>, f64)>,
    /// Σ GNSS chord lengths and Σ odometer distances over the same chords.
    gnss_path_m: f64,
    odometer_path_m: f64,
    chord_start: Option<(Timestamp, Vector3<f64>, f64)>,
}

impl WheelScale {
    /// The VO started again: its path so far is in another scale; the calibration against
    /// GNSS (wheels against the world) still holds.
    pub fn new_vo_session(&mut self) {
        *self = WheelScale { vo_path: 0.0, wheel_path: 0.0, last_frame: None, ..*self };
    }

    /// A VO frame with the odometer reading at its time.
    pub fn push_frame(&mut self, t: Timestamp, position: &Vector3<f64>, odometer_m: f64, time_constant_s: f64) {
        if let Some((t0, p0, o0)) = self.last_frame {
            let dt = (t - t0).as_secs_f64();
            let wheel = odometer_m - o0;
            if dt > 0.0 && wheel > MIN_SPEED_MPS * dt {
                let keep = libm::exp(-dt / time_constant_s);
                self.vo_path = self.vo_path * keep + (position - p0).norm();
                self.wheel_path = self.wheel_path * keep + wheel;
            }
        }
        self.last_frame = Some((t, *position, odometer_m));
    }

    /// An accepted GNSS fix (ENU) with the odometer reading at the instant it describes.
    pub fn push_fix(&mut self, t: Timestamp, enu: &Vector3<f64>, odometer_m: f64) {
        match self.chord_start {
            Some((t0, p0, o0)) => {
                let dt = (t - t0).as_secs_f64();
                if dt > CALIBRATION_MAX_GAP_S || dt <= 0.0 {
                    self.chord_start = Some((t, *enu, odometer_m));
                } else if dt >= CALIBRATION_BASELINE_S {
                    let wheel = odometer_m - o0;
                    if wheel > MIN_SPEED_MPS * dt {
                        self.gnss_path_m += (enu - p0).norm();
                        self.odometer_path_m += wheel;
                    }
                    self.chord_start = Some((t, *enu, odometer_m));
                }
            }
            None => self.chord_start = Some((t, *enu, odometer_m)),
        }
    }

    /// The calibrated wheel factor (true distance / odometer distance) and the GNSS
    /// path length it rests on.
    pub fn calibration(&self) -> Option<(f64, f64)> {
        (self.odometer_path_m > 0.0 && self.gnss_path_m > 0.0)
            .then(|| (self.gnss_path_m / self.odometer_path_m, self.gnss_path_m))
    }

    /// Metres per VO unit over the recent window, with the calibration applied.
    pub fn scale(&self) -> Option<f64> {
        let (factor, _) = self.calibration()?;
        (self.vo_path > 0.0 && self.wheel_path > 0.0).then(|| factor * self.wheel_path / self.vo_path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ts(s: f64) -> Timestamp {
        Timestamp::from_secs_f64(s).expect("finite")
    }

    #[test]
    fn calibrates_a_biased_odometer_and_scales_vo() {
        let mut w = WheelScale::default();
        // Truth: 20 m/s along x. Odometer reads 1 % low. VO is in units of 0.5 m.
        for k in 0..200 {
            let t = k as f64 * 0.05;
            let truth = 20.0 * t;
            w.push_frame(ts(t), &Vector3::new(truth / 0.5, 0.0, 0.0), truth * 0.99, 5.0);
            if k % 2 == 0 {
                w.push_fix(ts(t), &Vector3::new(truth, 0.0, 0.0), truth * 0.99);
            }
        }
        let (factor, path) = w.calibration().expect("calibrated");
        assert!((factor - 1.0 / 0.99).abs() < 1e-9, "{factor}");
        assert!((path - 180.0).abs() < 1e-6, "{path}");
        assert!((w.scale().expect("scale") - 0.5).abs() < 1e-9);
    }

    #[test]
    fn standing_still_teaches_nothing() {
        let mut w = WheelScale::default();
        for k in 0..100 {
            w.push_frame(ts(k as f64 * 0.05), &Vector3::zeros(), 0.0, 5.0);
            w.push_fix(ts(k as f64 * 0.05), &Vector3::new(0.3 * (k % 3) as f64, 0.0, 0.0), 0.0);
        }
        assert_eq!(w.calibration(), None);
        assert_eq!(w.scale(), None);
    }
}
