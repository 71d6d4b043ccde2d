//! Harsh braking from the vehicle speed: what a dashcam's G-sensor marks, so that the file
//! holding it is kept by loop recording (`record --quota`, issue #35).
//!
//! The deceleration is the speed's change between samples, low-passed with a 0.3 s time
//! constant (wheel-speed quantisation at 50 Hz alone moves it by ~0.1 m/s²). A braking is
//! harsh from [`HARSH_BRAKING_MPS2`] — 0.41 g, inside the 0.3–0.45 g band fleet telematics
//! flag — and over when the deceleration falls below half of it, so one stop is counted once.
//! A gap over a second, or time going back, starts afresh; a sample stamped at the same
//! instant as the one before (frames read in a burst, stamped on receipt) is passed over.
//! A few dozen bytes: no history.

use crate::time::Timestamp;

/// Deceleration from which a braking is harsh, m/s².
pub const HARSH_BRAKING_MPS2: f64 = 4.0;
/// Below this the braking is over, m/s².
const CALM_MPS2: f64 = HARSH_BRAKING_MPS2 / 2.0;
/// Time constant of the low-pass filter, s.
const TAU_S: f64 = 0.3;
/// Longest gap between samples the filter bridges, s.
const MAX_GAP_S: f64 = 1.0;

/// The detector's state.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Braking {
    last: Option<(Timestamp, f64)>,
    /// Low-passed deceleration, m/s² (positive when slowing).
    decel: f64,
    harsh: bool,
}

impl Braking {
    /// A speed sample (m/s); the speed at which a harsh braking begins, when one does.
    pub(super) fn push(&mut self, t: Timestamp, mps: f64) -> Option<f64> {
        if self.last.is_some_and(|(t0, _)| t0 == t) && mps.is_finite() {
            // No time between them to divide by: the earlier sample stays the reference.
            return None;
        }
        let previous = self.last.replace((t, mps));
        let (t0, v0) = previous?;
        let dt = (t - t0).as_secs_f64();
        if !(dt > 0.0 && dt <= MAX_GAP_S && mps.is_finite() && v0.is_finite()) {
            self.decel = 0.0;
            self.harsh = false;
            return None;
        }
        let gain = 1.0 - libm::exp(-dt / TAU_S);
        self.decel += ((v0 - mps) / dt - self.decel) * gain;
        if !self.harsh && self.decel >= HARSH_BRAKING_MPS2 {
            self.harsh = true;
            return Some(v0);
        }
        if self.harsh && self.decel < CALM_MPS2 {
            self.harsh = false;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Speeds at 50 Hz, 2 cm/s quantisation: `profile(t)` m/s for `seconds`; the speeds at
    /// which harsh brakings began.
    fn run(seconds: f64, profile: impl Fn(f64) -> f64) -> heapless::Vec<f64, 8> {
        let mut b = Braking::default();
        let mut out = heapless::Vec::new();
        for k in 0..(seconds * 50.0) as i64 {
            let t = k as f64 * 0.02;
            let v = libm::round(profile(t) / 0.02) * 0.02;
            if let Some(at) = b.push(Timestamp::from_micros(k * 20_000), v) {
                let _ = out.push(at);
            }
        }
        out
    }

    #[test]
    fn an_emergency_stop_read_in_bursts_is_still_seen() {
        // 1 kHz wheel speed read ten frames at a time, each burst stamped on receipt: the
        // same instant for ten samples (a busy logger). Such a burst had reset the filter.
        let mut b = Braking::default();
        let mut seen = 0;
        for k in 0..12_000i64 {
            let t = k as f64 * 0.001;
            let v = (22.0 - 6.0 * (t - 5.0).max(0.0)).max(7.0);
            if b.push(Timestamp::from_micros((k / 10) * 10_000), v).is_some() {
                seen += 1;
            }
        }
        assert_eq!(seen, 1);
    }

    #[test]
    fn an_emergency_stop_is_one_harsh_braking_and_a_gentle_stop_none() {
        // 20 m/s, then 6 m/s² for 3 s from t = 5 s, then standing.
        let hard = run(12.0, |t| (20.0 - 6.0 * (t - 5.0).max(0.0)).max(2.0));
        assert_eq!(hard.len(), 1, "{hard:?}");
        assert!((18.0..=20.0).contains(&hard[0]), "{hard:?}");
        // A traffic-light stop at 2.5 m/s²: not harsh.
        assert!(run(15.0, |t| (20.0 - 2.5 * (t - 2.0).max(0.0)).max(0.0)).is_empty());
        // Two emergency stops are two.
        let twice = run(30.0, |t| {
            if t < 15.0 {
                (20.0 - 6.0 * (t - 3.0).max(0.0)).max(5.0)
            } else {
                (20.0 - 6.0 * (t - 20.0).max(0.0)).max(5.0)
            }
        });
        assert_eq!(twice.len(), 2, "{twice:?}");
    }

    #[test]
    fn a_gap_or_time_going_back_is_not_a_braking() {
        let mut b = Braking::default();
        assert_eq!(b.push(Timestamp::from_micros(0), 20.0), None);
        // 20 → 0 m/s over a 5 s gap: no sample in between, nothing known.
        assert_eq!(b.push(Timestamp::from_micros(5_000_000), 0.0), None);
        assert_eq!(b.push(Timestamp::from_micros(4_000_000), 30.0), None);
        assert_eq!(b.push(Timestamp::from_micros(4_020_000), f64::NAN), None);
    }
}
