//! Metric scale from wheel speed.
//!
//! Over a short window, distance travelled by the wheels divided by VO path length is
//! the VO→metre scale — far more precise than what a few metres of GNSS noise allow.
//! Wheel speed itself is biased (tyre wear, pressure; about −0.85 % on the comma2k19
//! car, within a few per cent on any car), so its factor is calibrated online against
//! GNSS: the straight-line distance between two accepted fixes (a chord) over the
//! odometer distance between the same instants, summed over chords.
//!
//! Two things bias that ratio, and each chord is built to avoid them:
//!
//! * **Noise lengthens a chord.** A chord of length d between fixes of σ (per axis) reads
//!   on average about d·(1 + (σ/d)²) long: with 5 m fixes a second apart it was 20 % too
//!   long, and the device's scale with it. A chord therefore spans at least
//!   [`CHORD_LENGTH_SIGMAS`] times the fixes' σ of wheel travel (under 0.2 % bias).
//! * **A bend shortens it.** The wheels measure the arc, the fixes the chord. The VO,
//!   whatever its scale, sees the same shape: its chord over its path length between the
//!   same instants is the factor the arc is shortened by.
//!
//! Until the chords say otherwise the factor is 1 ± [`PRIOR_REL_SIGMA`] (a speed signal is
//! good to a few per cent); chords and prior are fused by inverse variance.

use nalgebra::Vector3;

use crate::time::Timestamp;

/// Minimum time between the two fixes of one calibration chord.
pub(crate) const CALIBRATION_BASELINE_S: f64 = 1.0;
/// Wheel travel of one chord in multiples of the fixes' stated σ: its noise then
/// lengthens the chord by about (1/40)² = 0.06 % (0.25 % were the σ understated 2×).
const CHORD_LENGTH_SIGMAS: f64 = 40.0;
/// Longest gap between fixes inside one chord (a GNSS outage breaks the chain).
const CALIBRATION_MAX_GAP_S: f64 = 5.0;
/// Below this speed (m/s) the VO and wheel distances are dominated by noise.
const MIN_SPEED_MPS: f64 = 1.0;
/// Relative σ of an uncalibrated wheel factor: tyres and speed signals are good to a few
/// per cent.
pub(crate) const PRIOR_REL_SIGMA: f64 = 0.03;
/// A chord whose VO chord is shorter than this fraction of the VO path went round too
/// sharp a bend for its correction to be trusted; it is not used.
const MIN_STRAIGHTNESS: f64 = 0.8;

/// One end of a calibration chord.
#[derive(Clone, Copy, Debug)]
struct ChordEnd {
    t: Timestamp,
    enu: Vector3<f64>,
    odometer_m: f64,
    vo: Vector3<f64>,
    vo_arc: f64,
}

/// Wheel-speed scale estimation state.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct WheelScale {
    /// Exponentially windowed VO path length (VO units).
    vo_path: f64,
    /// Exponentially windowed odometer distance over the same frames (m).
    wheel_path: f64,
    last_frame: Option<(Timestamp, Vector3<f64>, f64)>,
    /// VO path length of this session while moving (VO units).
    vo_arc: f64,
    /// Σ GNSS chord lengths and Σ odometer distances over the same chords (each shortened
    /// by its bend).
    gnss_path_m: f64,
    odometer_path_m: f64,
    /// Σ 2σ² over the chords: the variance their ends add to Σ chord lengths, m².
    chord_noise_m2: f64,
    chord_start: Option<ChordEnd>,
    last_fix: Option<Timestamp>,
}

impl WheelScale {
    /// The VO started again: its path so far is in another scale and a chord may not
    /// span the two sessions; the calibration against GNSS (wheels against the world)
    /// still holds.
    pub fn new_vo_session(&mut self) {
        *self = WheelScale { vo_path: 0.0, wheel_path: 0.0, last_frame: None, vo_arc: 0.0, chord_start: None, ..*self };
    }

    /// The VO positions kept in other coordinates, p → `r`·p (lengths are unchanged).
    pub fn turn(&mut self, r: &nalgebra::Matrix3<f64>) {
        if let Some((_, p, _)) = &mut self.last_frame {
            *p = r * *p;
        }
        if let Some(c) = &mut self.chord_start {
            c.vo = r * c.vo;
        }
    }

    /// A VO frame with the odometer reading at its time.
    pub fn push_frame(&mut self, t: Timestamp, position: &Vector3<f64>, odometer_m: f64, time_constant_s: f64) {
        if let Some((t0, p0, o0)) = self.last_frame {
            let dt = (t - t0).as_secs_f64();
            let wheel = odometer_m - o0;
            if dt > 0.0 && wheel > MIN_SPEED_MPS * dt {
                let keep = libm::exp(-dt / time_constant_s);
                let step = (position - p0).norm();
                self.vo_path = self.vo_path * keep + step;
                self.wheel_path = self.wheel_path * keep + wheel;
                self.vo_arc += step;
            }
        }
        self.last_frame = Some((t, *position, odometer_m));
    }

    /// An accepted GNSS fix (ENU, stated σ) with the odometer reading and the VO position
    /// at the instant it describes.
    pub fn push_fix(&mut self, t: Timestamp, enu: &Vector3<f64>, sigma_m: f64, odometer_m: f64, vo: &Vector3<f64>) {
        // The VO path length at the fix's instant: the latest frame's, less the stretch
        // since (a latency's worth, straight).
        let vo_arc = self.last_frame.map_or(self.vo_arc, |(_, p, _)| (self.vo_arc - (p - vo).norm()).max(0.0));
        let here = ChordEnd { t, enu: *enu, odometer_m, vo: *vo, vo_arc };
        let gap = self.last_fix.map(|last| (t - last).as_secs_f64());
        self.last_fix = Some(t);
        let Some(start) = self.chord_start.filter(|_| gap.is_some_and(|g| g > 0.0 && g <= CALIBRATION_MAX_GAP_S))
        else {
            self.chord_start = Some(here);
            return;
        };
        let dt = (t - start.t).as_secs_f64();
        let wheel = odometer_m - start.odometer_m;
        if dt < CALIBRATION_BASELINE_S || wheel < CHORD_LENGTH_SIGMAS * sigma_m {
            return;
        }
        let vo_arc = here.vo_arc - start.vo_arc;
        let straightness = if vo_arc > 0.0 { (here.vo - start.vo).norm() / vo_arc } else { 0.0 };
        if wheel > MIN_SPEED_MPS * dt && (MIN_STRAIGHTNESS..=1.0).contains(&straightness) {
            self.gnss_path_m += (enu - start.enu).norm();
            self.odometer_path_m += wheel * straightness;
            self.chord_noise_m2 += 2.0 * sigma_m * sigma_m;
        }
        self.chord_start = Some(here);
    }

    /// The wheel factor (true distance / odometer distance) and its relative variance:
    /// the chords' ratio fused with the prior 1 ± 3 %. `variance_factor` scales the
    /// fixes' stated σ² (the anchorer's a-posteriori estimate of how far to trust it).
    pub fn calibration(&self, variance_factor: f64) -> (f64, f64) {
        let prior_var = PRIOR_REL_SIGMA * PRIOR_REL_SIGMA;
        let Some(measured) = self.measured() else { return (1.0, prior_var) };
        // Each chord's ends err independently at this spacing: Σ 2σ² on Σ chord lengths.
        let measured_var = variance_factor * self.chord_noise_m2 / (self.gnss_path_m * self.gnss_path_m);
        if !(measured_var.is_finite() && measured_var > 0.0) {
            return (1.0, prior_var);
        }
        let var = 1.0 / (1.0 / prior_var + 1.0 / measured_var);
        ((1.0 / prior_var + measured / measured_var) * var, var)
    }

    /// The chords' own ratio (true distance / odometer distance), once there is one.
    pub fn measured(&self) -> Option<f64> {
        let ratio = self.gnss_path_m / self.odometer_path_m;
        (self.odometer_path_m > 0.0 && self.gnss_path_m > 0.0 && ratio.is_finite()).then_some(ratio)
    }

    /// Metres per VO unit over the recent window, before the wheel factor.
    pub fn uncalibrated_scale(&self) -> Option<f64> {
        (self.vo_path > 0.0 && self.wheel_path > 0.0).then(|| self.wheel_path / self.vo_path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ts(s: f64) -> Timestamp {
        Timestamp::from_secs_f64(s).expect("finite")
    }

    /// 20 s at 20 m/s along `path` (metres travelled → ENU), odometer 1 % low, VO in units
    /// of 0.5 m; a fix every 0.1 s of σ `sigma`, moved by `noise(k)`.
    fn drive(path: impl Fn(f64) -> Vector3<f64>, sigma: f64, noise: impl Fn(usize) -> Vector3<f64>) -> WheelScale {
        let mut w = WheelScale::default();
        for k in 0..400 {
            let t = k as f64 * 0.05;
            let truth = path(20.0 * t);
            w.push_frame(ts(t), &(truth / 0.5), 20.0 * t * 0.99, 5.0);
            if k % 2 == 0 {
                w.push_fix(ts(t), &(truth + noise(k)), sigma, 20.0 * t * 0.99, &(truth / 0.5));
            }
        }
        w
    }

    fn straight(s: f64) -> Vector3<f64> {
        Vector3::new(s, 0.0, 0.0)
    }

    #[test]
    fn calibrates_a_biased_odometer_and_scales_vo() {
        let w = drive(straight, 0.05, |_| Vector3::zeros());
        let measured = w.measured().expect("chords");
        assert!((measured - 1.0 / 0.99).abs() < 1e-9, "{measured}");
        // Centimetre fixes over 400 m outweigh the 3 % prior almost entirely.
        let (factor, rel_var) = w.calibration(1.0);
        assert!((factor - 1.0 / 0.99).abs() < 1e-5, "{factor}");
        assert!(rel_var < 1e-6, "{rel_var}");
        let scale = factor * w.uncalibrated_scale().expect("moving");
        assert!((scale - 0.5).abs() < 1e-5, "{scale}");
    }

    #[test]
    fn noisy_fixes_do_not_lengthen_the_chords() {
        // Fixes 5 m to either side in turn: one-second chords (20 m) would read 12 % long.
        let w = drive(straight, 5.0, |k| Vector3::new(0.0, if k % 4 == 0 { 5.0 } else { -5.0 }, 0.0));
        let measured = w.measured().expect("chords");
        assert!((measured * 0.99 - 1.0).abs() < 0.002, "{measured}");
    }

    #[test]
    fn a_bend_is_measured_along_its_arc() {
        // A circle of 100 m radius; chords of 80 m (σ 2 m) are 2.7 % shorter than the arc.
        let circle = |s: f64| Vector3::new(100.0 * (s / 100.0).sin(), 100.0 * (1.0 - (s / 100.0).cos()), 0.0);
        let w = drive(circle, 2.0, |_| Vector3::zeros());
        let measured = w.measured().expect("chords");
        assert!((measured * 0.99 - 1.0).abs() < 1e-3, "{measured}");
    }

    #[test]
    fn standing_still_teaches_nothing() {
        let mut w = WheelScale::default();
        for k in 0..100 {
            w.push_frame(ts(k as f64 * 0.05), &Vector3::zeros(), 0.0, 5.0);
            w.push_fix(ts(k as f64 * 0.05), &Vector3::new(0.3 * (k % 3) as f64, 0.0, 0.0), 1.0, 0.0, &Vector3::zeros());
        }
        assert_eq!(w.measured(), None);
        assert_eq!(w.calibration(1.0), (1.0, PRIOR_REL_SIGMA * PRIOR_REL_SIGMA));
        assert_eq!(w.uncalibrated_scale(), None);
    }
}
