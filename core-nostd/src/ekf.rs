//! A fixed-size (extended) Kalman filter: state and covariance on the stack, Joseph-form
//! covariance update, covariance kept symmetric.
//!
//! The linear form (`predict`, `update`) is filterpy's `KalmanFilter` step for step; the
//! extended form takes the propagated state / innovation and the Jacobians from the
//! caller, so the motion and measurement models stay with the trackers that own them.
//!
//! Offline finishing uses [`rts_smooth`]: the Rauch–Tung–Striebel backward pass over the
//! filtered states of a whole track (filterpy's `rts_smoother`), in place, so a finished
//! log gets the estimate that uses every measurement, past and future.

use nalgebra::{SMatrix, SVector};

/// Why an update was refused (the filter is unchanged).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum KalmanError {
    /// The innovation covariance could not be inverted.
    Singular,
    /// The measurement or the result contains NaN or infinity.
    NotFinite,
}

impl core::fmt::Display for KalmanError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            KalmanError::Singular => write!(f, "innovation covariance is singular"),
            KalmanError::NotFinite => write!(f, "measurement or state is not finite"),
        }
    }
}

impl core::error::Error for KalmanError {}

/// State `x` (N) and covariance `p` (N × N).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kalman<const N: usize> {
    /// State estimate.
    pub x: SVector<f64, N>,
    /// Its covariance.
    pub p: SMatrix<f64, N, N>,
}

impl<const N: usize> Kalman<N> {
    /// A filter at `x` with covariance `p`.
    pub fn new(x: SVector<f64, N>, p: SMatrix<f64, N, N>) -> Self {
        Kalman { x, p }
    }

    /// Linear prediction: x ← F x, P ← F P Fᵀ + Q.
    pub fn predict(&mut self, f: &SMatrix<f64, N, N>, q: &SMatrix<f64, N, N>) {
        let x = f * self.x;
        self.predict_with(x, f, q);
    }

    /// Extended prediction: the caller propagated the state to `x` through its model,
    /// whose Jacobian is `f`.
    pub fn predict_with(&mut self, x: SVector<f64, N>, f: &SMatrix<f64, N, N>, q: &SMatrix<f64, N, N>) {
        self.x = x;
        self.p = f * self.p * f.transpose() + q;
        self.symmetrize();
    }

    /// Linear update with measurement `z = H x + v`, v ~ N(0, R).
    pub fn update<const M: usize>(
        &mut self,
        z: &SVector<f64, M>,
        h: &SMatrix<f64, M, N>,
        r: &SMatrix<f64, M, M>,
    ) -> Result<(), KalmanError> {
        let innovation = z - h * self.x;
        self.update_with(&innovation, h, r)
    }

    /// Extended update: `innovation` = z − h(x) computed by the caller (angles wrapped),
    /// `h` the measurement Jacobian. Joseph form: P ← (I − KH) P (I − KH)ᵀ + K R Kᵀ, which
    /// stays positive semi-definite under rounding where (I − KH) P does not.
    pub fn update_with<const M: usize>(
        &mut self,
        innovation: &SVector<f64, M>,
        h: &SMatrix<f64, M, N>,
        r: &SMatrix<f64, M, M>,
    ) -> Result<(), KalmanError> {
        if !innovation.iter().all(|v| v.is_finite()) {
            return Err(KalmanError::NotFinite);
        }
        let s = h * self.p * h.transpose() + r;
        let s_inv = s.try_inverse().ok_or(KalmanError::Singular)?;
        let k = self.p * h.transpose() * s_inv;
        let x = self.x + k * innovation;
        let i_kh = SMatrix::<f64, N, N>::identity() - k * h;
        let p = i_kh * self.p * i_kh.transpose() + k * r * k.transpose();
        if !x.iter().chain(p.iter()).all(|v| v.is_finite()) {
            return Err(KalmanError::NotFinite);
        }
        self.x = x;
        self.p = p;
        self.symmetrize();
        Ok(())
    }

    /// Mahalanobis distance² of a measurement (for gating).
    pub fn mahalanobis_sq<const M: usize>(
        &self,
        z: &SVector<f64, M>,
        h: &SMatrix<f64, M, N>,
        r: &SMatrix<f64, M, M>,
    ) -> Option<f64> {
        let y = z - h * self.x;
        let s = h * self.p * h.transpose() + r;
        s.try_inverse().map(|s_inv| (y.transpose() * s_inv * y)[(0, 0)])
    }

    fn symmetrize(&mut self) {
        self.p = (self.p + self.p.transpose()) * 0.5;
    }
}

/// One filtered step for [`rts_smooth`]: the posterior at this step and the model that
/// led here from the previous step (`f`, `q`; ignored for the first step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmoothStep<const N: usize> {
    /// Filtered state; smoothed in place.
    pub x: SVector<f64, N>,
    /// Filtered covariance; smoothed in place.
    pub p: SMatrix<f64, N, N>,
    /// Transition from the previous step to this one (F^k after k predictions without
    /// an update).
    pub f: SMatrix<f64, N, N>,
    /// Process noise accumulated over that transition.
    pub q: SMatrix<f64, N, N>,
}

impl<const N: usize> SmoothStep<N> {
    /// A step from a filter's posterior; `f` and `q` start as I and 0 for the caller (or
    /// the track smoother) to set.
    pub fn filtered(kf: &Kalman<N>) -> Self {
        SmoothStep { x: kf.x, p: kf.p, f: SMatrix::identity(), q: SMatrix::zeros() }
    }
}

/// Rauch–Tung–Striebel smoothing of filtered steps, in place (filterpy's
/// `KalmanFilter.rts_smoother`): for k from the second last down,
/// Pp = F P_k Fᵀ + Q, C = P_k Fᵀ Pp⁻¹, x_k += C (x_{k+1} − F x_k), P_k += C (P_{k+1} − Pp) Cᵀ
/// (F, Q of step k + 1). Returns how many steps were left as filtered because their
/// predicted covariance was singular or the result not finite. States with an angle must
/// be unwrapped (continuous) before smoothing.
pub fn rts_smooth<const N: usize>(steps: &mut [SmoothStep<N>]) -> usize {
    let mut refused = 0;
    for k in (0..steps.len().saturating_sub(1)).rev() {
        let (head, tail) = steps.split_at_mut(k + 1);
        let (Some(step), Some(next)) = (head.last_mut(), tail.first()) else { continue };
        let predicted_p = next.f * step.p * next.f.transpose() + next.q;
        let Some(predicted_p_inv) = predicted_p.try_inverse() else {
            refused += 1;
            continue;
        };
        let gain = step.p * next.f.transpose() * predicted_p_inv;
        let x = step.x + gain * (next.x - next.f * step.x);
        let p = step.p + gain * (next.p - predicted_p) * gain.transpose();
        if !x.iter().chain(p.iter()).all(|v| v.is_finite()) {
            refused += 1;
            continue;
        }
        step.x = x;
        step.p = (p + p.transpose()) * 0.5;
    }
    refused
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix1, Matrix1x2, Matrix2, Vector1, Vector2};

    #[test]
    fn constant_velocity_in_one_dimension_by_hand() {
        // x = [position, velocity], P = diag(1, 1); measure position with R = 1.
        let mut kf = Kalman::new(Vector2::new(0.0, 1.0), Matrix2::identity());
        let f = Matrix2::new(1.0, 1.0, 0.0, 1.0);
        kf.predict(&f, &Matrix2::zeros());
        assert_eq!(kf.x, Vector2::new(1.0, 1.0));
        assert_eq!(kf.p, Matrix2::new(2.0, 1.0, 1.0, 1.0));
        let h = Matrix1x2::new(1.0, 0.0);
        kf.update(&Vector1::new(2.0), &h, &Matrix1::new(1.0)).expect("update");
        // S = 3, K = [2/3, 1/3]: x = [1 + 2/3, 1 + 1/3].
        assert!((kf.x - Vector2::new(5.0 / 3.0, 4.0 / 3.0)).norm() < 1e-15);
        // P = [[2/3, 1/3], [1/3, 2/3]].
        assert!((kf.p - Matrix2::new(2.0, 1.0, 1.0, 2.0) / 3.0).norm() < 1e-15);
        assert_eq!(kf.p, kf.p.transpose());
    }

    #[test]
    fn refuses_bad_measurements_without_changing_state() {
        let mut kf = Kalman::new(Vector2::new(0.0, 0.0), Matrix2::zeros());
        let before = kf;
        let h = Matrix1x2::new(1.0, 0.0);
        assert_eq!(kf.update(&Vector1::new(1.0), &h, &Matrix1::new(0.0)), Err(KalmanError::Singular));
        assert_eq!(kf.update(&Vector1::new(f64::NAN), &h, &Matrix1::new(1.0)), Err(KalmanError::NotFinite));
        assert_eq!(kf, before);
    }

    #[test]
    fn smoothing_a_random_walk_by_hand() {
        // Scalar random walk, Q = 1, measured twice with R = 1 from P0 = 1:
        // filtered P = 1/2 then (3/2 · 1)/(5/2) = 3/5; x1 = 0 → smoothed x0 gains
        // C = (1/2)/(3/2) = 1/3 of the difference x1 − x0.
        let f = Matrix1::new(1.0);
        let q = Matrix1::new(1.0);
        let mut steps = [
            SmoothStep { x: Vector1::new(1.0), p: Matrix1::new(0.5), f, q },
            SmoothStep { x: Vector1::new(0.0), p: Matrix1::new(0.6), f, q },
        ];
        assert_eq!(rts_smooth(&mut steps), 0);
        assert!((steps[0].x[0] - 2.0 / 3.0).abs() < 1e-15);
        // P0 = 1/2 + (1/3)² (3/5 − 3/2) = 1/2 − 1/10.
        assert!((steps[0].p[(0, 0)] - 0.4).abs() < 1e-15);
        // The last step is its filtered self.
        assert_eq!(steps[1].x[0], 0.0);
    }

    #[test]
    fn smoothing_skips_singular_steps_and_handles_empty_input() {
        assert_eq!(rts_smooth::<1>(&mut []), 0);
        let zero = Matrix1::new(0.0);
        let mut steps = [
            SmoothStep { x: Vector1::new(1.0), p: zero, f: zero, q: zero },
            SmoothStep { x: Vector1::new(5.0), p: zero, f: zero, q: zero },
        ];
        assert_eq!(rts_smooth(&mut steps), 1);
        assert_eq!(steps[0].x[0], 1.0);
    }

    #[test]
    fn mahalanobis_gate() {
        let kf = Kalman::new(Vector2::new(0.0, 0.0), Matrix2::identity());
        let h = Matrix1x2::new(1.0, 0.0);
        // S = 2: d² = 4 / 2.
        assert_eq!(kf.mahalanobis_sq(&Vector1::new(2.0), &h, &Matrix1::new(1.0)), Some(2.0));
    }
}
