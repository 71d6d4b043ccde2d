//! How far a detector's stated covariances can be trusted, learnt from the innovations.
//!
//! A detector that reports each box's covariance may be too sure of itself or too
//! modest (a monocular network's depth σ is a guess; on the typical profile it is off by
//! up to 2× either way), and the tracks placed in the world inherit the ego's error on top.
//! For an update with prediction covariance P and stated covariance R, the innovation ν
//! has E\[νᵀν\] = tr P + α·tr R where α is the factor R should have been scaled by: each
//! update gives a sample (νᵀν − tr P) / tr R, their exponentially weighted mean is α, and
//! the tracker scales the stated covariances by it (clamped to [`MIN_SCALE`, `MAX_SCALE`])
//! once [`MIN_UPDATES`] samples are in. No parameter of any generator is read: only what
//! the filter sees.

/// Updates before the learnt factor is applied.
pub const MIN_UPDATES: u32 = 30;
/// The factor's bounds: a detector is trusted at most 2× more than it says, and distrusted
/// at most 10×.
pub const MIN_SCALE: f64 = 0.5;
/// See [`MIN_SCALE`].
pub const MAX_SCALE: f64 = 10.0;
/// Weight kept per update: a memory of about 200 updates (a few seconds of a work zone).
const KEEP: f64 = 1.0 - 1.0 / 200.0;
/// A single sample is clipped here, so one wrong association cannot swing the factor.
const MAX_SAMPLE: f64 = 25.0;

/// The learnt factor on stated detection covariances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CovarianceScale {
    mean: f64,
    weight: f64,
    updates: u32,
}

impl Default for CovarianceScale {
    fn default() -> Self {
        CovarianceScale::new()
    }
}

impl CovarianceScale {
    /// Nothing learnt: the stated covariances are taken as they are.
    pub const fn new() -> Self {
        CovarianceScale { mean: 1.0, weight: 0.0, updates: 0 }
    }

    /// One update's horizontal innovation `(νx, νy)`, the trace of the prediction's
    /// horizontal covariance and the trace of the stated one; non-finite or degenerate
    /// values are ignored.
    pub fn push(&mut self, innovation: [f64; 2], predicted_trace: f64, stated_trace: f64) {
        let [x, y] = innovation;
        let sample = (x * x + y * y - predicted_trace) / stated_trace;
        if !(sample.is_finite() && stated_trace > 0.0) {
            return;
        }
        let sample = sample.clamp(0.0, MAX_SAMPLE);
        self.weight = self.weight * KEEP + 1.0;
        self.mean += (sample - self.mean) / self.weight;
        self.updates = self.updates.saturating_add(1);
    }

    /// The factor to scale a stated covariance by: 1 until enough updates are in.
    pub fn factor(&self) -> f64 {
        if self.updates < MIN_UPDATES {
            1.0
        } else {
            self.mean.clamp(MIN_SCALE, MAX_SCALE)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Innovations of a stated covariance `stated` (per axis, m²) whose truth is `truth`,
    /// with a prediction of variance `predicted` per axis: deterministic ±σ samples.
    fn learn(stated: f64, truth: f64, predicted: f64) -> f64 {
        let mut scale = CovarianceScale::new();
        let s = libm::sqrt(truth + predicted);
        for k in 0..2000 {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            scale.push([s * sign, -s * sign], 2.0 * predicted, 2.0 * stated);
        }
        scale.factor()
    }

    #[test]
    fn learns_how_far_the_stated_covariance_is_off() {
        assert!((learn(1.0, 4.0, 0.5) - 4.0).abs() < 1e-6);
        assert!((learn(1.0, 1.0, 0.5) - 1.0).abs() < 1e-6);
        assert!((learn(1.0, 0.6, 0.5) - 0.6).abs() < 1e-6);
        // Bounded both ways.
        assert_eq!(learn(1.0, 0.1, 0.5), MIN_SCALE);
        assert_eq!(learn(1.0, 100.0, 0.5), MAX_SCALE);
    }

    #[test]
    fn waits_for_evidence_and_ignores_garbage() {
        let mut scale = CovarianceScale::new();
        for _ in 0..MIN_UPDATES - 1 {
            scale.push([3.0, 3.0], 0.0, 1.0);
        }
        assert_eq!(scale.factor(), 1.0);
        scale.push([f64::NAN, 0.0], 1.0, 1.0);
        scale.push([1.0, 0.0], 1.0, 0.0);
        scale.push([1.0, 0.0], f64::INFINITY, 1.0);
        assert_eq!(scale.factor(), 1.0, "non-finite and degenerate samples are not counted");
        scale.push([3.0, 3.0], 0.0, 1.0);
        assert_eq!(scale.factor(), MAX_SCALE.min(18.0));
    }
}
