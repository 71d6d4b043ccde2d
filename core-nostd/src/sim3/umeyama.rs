//! Umeyama alignment computed from accumulated moments.
//!
//! Umeyama's closed form (PAMI 1991, as implemented by evo's `umeyama_alignment`) needs
//! only the means, the spread of the source points and the cross-covariance — all sums.
//! [`Moments`] keeps them with a weighted Welford update, so points can be added one at a
//! time in O(1) time and memory, weighted (GNSS uncertainty, robust down-weighting) and
//! exponentially forgotten (sliding behaviour on long drives). With unit weights and no
//! forgetting the result equals evo's batch computation to rounding.
//!
//! Notation (docs/anchoring.md): x are source points (e.g. VO), y target points (e.g. ENU),
//! Σxy = (1/W)Σwᵢ(yᵢ−μy)(xᵢ−μx)ᵀ, σx² = (1/W)Σwᵢ‖xᵢ−μx‖², U D Vᵀ = svd(Σxy),
//! R = U S Vᵀ, c = tr(DS)/σx², t = μy − cRμx.

use nalgebra::{Matrix3, Vector3};

use super::{rotation_z, Sim3};

/// Which parameters an alignment estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AlignMode {
    /// Rotation and translation (scale fixed at 1).
    Se3,
    /// Rotation, translation and scale.
    Sim3,
    /// Only the scale: the returned transform has identity rotation and zero
    /// translation (evo's `--correct_scale` without `--align`).
    ScaleOnly,
    /// Gravity-aligned 4-DoF: rotation about the z axis only, translation and scale.
    /// For source frames whose vertical is already known; better conditioned when the
    /// points barely leave a plane (a flat road).
    YawScale,
}

/// Iteration bound of the 3×3 SVD and eigen-decompositions: they converge in a few
/// dozen sweeps; nalgebra's default (0) means no bound at all.
pub(crate) const MAX_DECOMPOSITION_ITERATIONS: usize = 500;

/// Why an alignment could not be computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AlignError {
    /// Fewer than the minimum number of points (2 for the 4-DoF mode, 3 otherwise).
    TooFewPoints,
    /// The cross-covariance has fewer than two singular values above machine epsilon
    /// (points coincide or are collinear): the rotation is not determined.
    Degenerate,
    /// A point or weight was NaN or infinite.
    NonFinite,
}

impl core::fmt::Display for AlignError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            AlignError::TooFewPoints => "too few point pairs for an alignment",
            AlignError::Degenerate => "degenerate covariance rank, Umeyama alignment is not possible",
            AlignError::NonFinite => "a point or weight is not finite",
        })
    }
}

impl core::error::Error for AlignError {}

/// Weighted first and second moments of point pairs (x → y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moments {
    count: u32,
    weight: f64,
    mean_x: Vector3<f64>,
    mean_y: Vector3<f64>,
    /// Σ w (x−μx)(x−μx)ᵀ
    sxx: Matrix3<f64>,
    /// Σ w (y−μy)(x−μx)ᵀ
    syx: Matrix3<f64>,
    /// Σ w ‖y−μy‖²
    syy: f64,
}

impl Default for Moments {
    fn default() -> Self {
        Moments::new()
    }
}

impl Moments {
    /// No points yet.
    pub const fn new() -> Self {
        Moments {
            count: 0,
            weight: 0.0,
            mean_x: Vector3::new(0.0, 0.0, 0.0),
            mean_y: Vector3::new(0.0, 0.0, 0.0),
            sxx: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            syx: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            syy: 0.0,
        }
    }

    /// Add the pair x → y with weight `w` (> 0). Non-finite input is rejected and leaves
    /// the moments unchanged.
    pub fn push(&mut self, x: &Vector3<f64>, y: &Vector3<f64>, w: f64) -> Result<(), AlignError> {
        if !(w.is_finite() && x.iter().chain(y.iter()).all(|v| v.is_finite())) || w < 0.0 {
            return Err(AlignError::NonFinite);
        }
        if w == 0.0 {
            return Ok(());
        }
        let total = self.weight + w;
        let dx = x - self.mean_x;
        let dy = y - self.mean_y;
        // West (1979): the co-moment grows by w·(1 − w/W')·d dᵀ with the old means.
        let k = w * (1.0 - w / total);
        let next = Moments {
            count: self.count.saturating_add(1),
            weight: total,
            mean_x: self.mean_x + dx * (w / total),
            mean_y: self.mean_y + dy * (w / total),
            sxx: self.sxx + dx * dx.transpose() * k,
            syx: self.syx + dy * dx.transpose() * k,
            syy: self.syy + dy.norm_squared() * k,
        };
        // Finite inputs can still overflow (coordinates near 1e154): refuse, keep state.
        if !next.is_finite() {
            return Err(AlignError::NonFinite);
        }
        *self = next;
        Ok(())
    }

    /// The source points in other coordinates, x → `r`·x (a rotation): the moments of the
    /// same pairs, exactly.
    pub fn turn_x(&mut self, r: &Matrix3<f64>) {
        self.mean_x = r * self.mean_x;
        self.sxx = r * self.sxx * r.transpose();
        self.syx *= r.transpose();
    }

    /// Multiply every past weight by `factor` in (0, 1]: exponential forgetting.
    /// Means are unchanged; the effective number of points shrinks.
    pub fn forget(&mut self, factor: f64) {
        if !(factor.is_finite() && factor > 0.0 && factor <= 1.0) {
            return;
        }
        self.weight *= factor;
        self.sxx *= factor;
        self.syx *= factor;
        self.syy *= factor;
    }

    fn is_finite(&self) -> bool {
        self.weight.is_finite()
            && self.syy.is_finite()
            && self.mean_x.iter().chain(self.mean_y.iter()).all(|v| v.is_finite())
            && self.sxx.iter().chain(self.syx.iter()).all(|v| v.is_finite())
    }

    /// Number of points pushed (not reduced by forgetting).
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Total (forgotten) weight W.
    pub fn weight(&self) -> f64 {
        self.weight
    }

    /// Weighted mean of the source points.
    pub fn mean_x(&self) -> Vector3<f64> {
        self.mean_x
    }

    /// Weighted mean of the target points.
    pub fn mean_y(&self) -> Vector3<f64> {
        self.mean_y
    }

    /// Weighted covariance of the source points, (1/W)Σw(x−μx)(x−μx)ᵀ.
    pub fn covariance_x(&self) -> Matrix3<f64> {
        if self.weight > 0.0 {
            self.sxx / self.weight
        } else {
            Matrix3::zeros()
        }
    }

    /// Weighted cross-covariance of the pairs, (1/W)Σw(y−μy)(x−μx)ᵀ.
    pub fn cross_covariance(&self) -> Matrix3<f64> {
        if self.weight > 0.0 {
            self.syx / self.weight
        } else {
            Matrix3::zeros()
        }
    }

    /// Weighted sum of squared residuals Σw‖y − T(x)‖² of a transform, from the
    /// moments alone.
    pub fn weighted_sse(&self, t: &Sim3) -> f64 {
        let r = &t.rotation;
        let c = t.scale;
        let offset = self.mean_y - t.transform_point(&self.mean_x);
        let cross = r.component_mul(&self.syx).sum();
        let sse = self.syy - 2.0 * c * cross + c * c * self.sxx.trace() + self.weight * offset.norm_squared();
        sse.max(0.0)
    }

    /// The least-squares transform x → y for `mode`.
    pub fn align(&self, mode: AlignMode) -> Result<Sim3, AlignError> {
        let min_points = if mode == AlignMode::YawScale { 2 } else { 3 };
        if self.count < min_points || self.weight <= 0.0 {
            return Err(AlignError::TooFewPoints);
        }
        let sigma_x2 = self.sxx.trace() / self.weight;
        let cov = self.syx / self.weight;
        let (rotation, trace_ds) = match mode {
            AlignMode::YawScale => yaw_rotation(&cov)?,
            _ => umeyama_rotation(&cov)?,
        };
        let scale = match mode {
            AlignMode::Se3 => 1.0,
            _ => trace_ds / sigma_x2,
        };
        if !(scale.is_finite() && scale > 0.0) {
            return Err(AlignError::Degenerate);
        }
        if mode == AlignMode::ScaleOnly {
            return Ok(Sim3 { rotation: Matrix3::identity(), translation: Vector3::zeros(), scale });
        }
        let translation = self.mean_y - rotation * self.mean_x * scale;
        Ok(Sim3 { rotation, translation, scale })
    }
}

/// R = U S Vᵀ and tr(DS) from the cross-covariance (Umeyama eq. 39–43).
pub(crate) fn umeyama_rotation(cov: &Matrix3<f64>) -> Result<(Matrix3<f64>, f64), AlignError> {
    if !cov.iter().all(|v| v.is_finite()) {
        return Err(AlignError::NonFinite);
    }
    let svd = nalgebra::SVD::try_new(*cov, true, true, f64::EPSILON * 5.0, MAX_DECOMPOSITION_ITERATIONS)
        .ok_or(AlignError::Degenerate)?;
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(AlignError::Degenerate);
    };
    let d = svd.singular_values;
    if d.iter().any(|v| !v.is_finite()) {
        return Err(AlignError::NonFinite);
    }
    if d.iter().filter(|&&v| v > f64::EPSILON).count() < 2 {
        return Err(AlignError::Degenerate);
    }
    // The reflection fix flips the axis of the smallest singular value.
    let smallest = d.imin();
    let mut s = Matrix3::identity();
    if u.determinant() * v_t.determinant() < 0.0 {
        s[(smallest, smallest)] = -1.0;
    }
    let trace_ds = (0..3).map(|i| d[i] * s[(i, i)]).sum();
    Ok((u * s * v_t, trace_ds))
}

/// The rotation about z maximising tr(Rᵀ Σyx) and that maximum.
pub(crate) fn yaw_rotation(cov: &Matrix3<f64>) -> Result<(Matrix3<f64>, f64), AlignError> {
    let a = cov[(0, 0)] + cov[(1, 1)];
    let b = cov[(1, 0)] - cov[(0, 1)];
    let planar = libm::hypot(a, b);
    if !planar.is_finite() {
        return Err(AlignError::NonFinite);
    }
    if planar <= f64::EPSILON {
        return Err(AlignError::Degenerate);
    }
    let yaw = libm::atan2(b, a);
    Ok((rotation_z(yaw), planar + cov[(2, 2)]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn rot(axis: Vector3<f64>, angle: f64) -> Matrix3<f64> {
        *nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle).matrix()
    }

    fn points() -> [Vector3<f64>; 6] {
        [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(10.0, 1.0, 0.5),
            Vector3::new(20.0, 5.0, -0.3),
            Vector3::new(25.0, 15.0, 1.0),
            Vector3::new(27.0, 30.0, 2.0),
            Vector3::new(26.0, 45.0, 1.5),
        ]
    }

    #[test]
    fn recovers_a_known_similarity_exactly() {
        let truth = Sim3 {
            rotation: rot(Vector3::new(0.3, -1.0, 0.5), 2.1),
            translation: Vector3::new(5.0, -7.0, 100.0),
            scale: 3.7,
        };
        let mut m = Moments::new();
        for p in points() {
            m.push(&p, &truth.transform_point(&p), 1.0).expect("finite");
        }
        let est = m.align(AlignMode::Sim3).expect("well posed");
        assert!((est.rotation - truth.rotation).norm() < 1e-10);
        assert!((est.translation - truth.translation).norm() < 1e-9);
        assert!((est.scale - truth.scale).abs() < 1e-12);
        assert!(m.weighted_sse(&est) < 1e-12);
    }

    #[test]
    fn yaw_mode_recovers_yaw_scale_translation() {
        let truth = Sim3 { rotation: rotation_z(-2.5), translation: Vector3::new(1.0, 2.0, 3.0), scale: 0.25 };
        let mut m = Moments::new();
        for p in points() {
            m.push(&p, &truth.transform_point(&p), 2.0).expect("finite");
        }
        let est = m.align(AlignMode::YawScale).expect("well posed");
        assert!((est.rotation - truth.rotation).norm() < 1e-12);
        assert!((est.scale - 0.25).abs() < 1e-12);
        assert!((est.translation - truth.translation).norm() < 1e-10);
    }

    #[test]
    fn collinear_and_too_few_points_are_errors_not_nan() {
        let mut m = Moments::new();
        assert_eq!(m.align(AlignMode::Sim3), Err(AlignError::TooFewPoints));
        for i in 0..10 {
            let p = Vector3::new(i as f64, 2.0 * i as f64, 0.0);
            m.push(&p, &(p * 2.0), 1.0).expect("finite");
        }
        assert_eq!(m.align(AlignMode::Sim3), Err(AlignError::Degenerate));
        assert_eq!(m.push(&Vector3::new(f64::NAN, 0.0, 0.0), &Vector3::zeros(), 1.0), Err(AlignError::NonFinite));
        // Finite but overflowing when squared: refused, state kept.
        let before = m;
        assert_eq!(m.push(&Vector3::new(1e200, 0.0, 0.0), &Vector3::zeros(), 1.0), Err(AlignError::NonFinite));
        assert_eq!(m, before);
        assert_eq!(m.count(), 10);
    }

    #[test]
    fn forgetting_keeps_the_means_and_shrinks_the_weight() {
        let mut m = Moments::new();
        for p in points() {
            m.push(&p, &(p + Vector3::new(1.0, 0.0, 0.0)), 1.0).expect("finite");
        }
        let before = m;
        m.forget(0.5);
        assert_eq!(m.mean_x(), before.mean_x());
        assert!((m.weight() - 3.0).abs() < 1e-12);
        // Same alignment: forgetting everything equally changes nothing.
        let a = before.align(AlignMode::Sim3).expect("ok");
        let b = m.align(AlignMode::Sim3).expect("ok");
        assert!((a.translation - b.translation).norm() < 1e-12);
    }

    proptest! {
        #[test]
        fn incremental_equals_two_pass(seed in proptest::collection::vec((-100.0f64..100.0, -100.0f64..100.0, -10.0f64..10.0, 0.1f64..5.0), 4..40)) {
            let mut m = Moments::new();
            let truth = Sim3 { rotation: rot(Vector3::new(1.0, 2.0, 3.0), 0.4), translation: Vector3::new(3.0, 2.0, 1.0), scale: 1.5 };
            let mut sw = 0.0;
            let mut mx = Vector3::zeros();
            for &(a, b, c, w) in &seed {
                let x = Vector3::new(a, b, c);
                m.push(&x, &(truth.transform_point(&x) + Vector3::new(c * 0.01, a * 0.001, 0.0)), w).expect("finite");
                sw += w;
                mx += x * w;
            }
            mx /= sw;
            prop_assert!((m.mean_x() - mx).norm() < 1e-9);
            let mut sxx = 0.0;
            for &(a, b, c, w) in &seed {
                sxx += w * (Vector3::new(a, b, c) - mx).norm_squared();
            }
            prop_assert!((m.covariance_x().trace() - sxx / sw).abs() < 1e-7 * (1.0 + sxx / sw));
        }
    }
}
