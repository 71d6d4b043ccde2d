//! Trajectory error metrics — APE and RPE with evo's definitions and statistics.
//!
//! The functions take already-associated pose slices (reference and estimate of equal
//! length) and write one error per pair into a caller-provided buffer, so they run
//! without allocation; [`Statistics::from_errors`] then sorts that buffer in place for
//! the median. Conventions follow evo 1.38 (`evo/core/metrics.py`; docs/conformance.md):
//!
//! * APE: translation part `‖p_est − p_ref‖`; full transformation `‖E − I₄‖_F` and
//!   rotation angle of `E = P_est⁻¹·P_ref`.
//! * RPE: `E = (Q_i⁻¹Q_j)⁻¹ (P_i⁻¹P_j)` over index pairs chosen by frames or by
//!   travelled path length (tolerance 0.1·δ for all pairs), consecutive or all pairs,
//!   chosen on the estimate's path unless asked otherwise (evo's default).
//! * Rotation angles follow SciPy's `Rotation.from_matrix(..).as_rotvec()`: a matrix that
//!   is not orthonormal to 1e-12 is first replaced by its nearest rotation (polar factor).

use nalgebra::Matrix3;

use crate::sim3::Pose;

/// What part of the pose error a metric looks at (evo's `PoseRelation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PoseRelation {
    /// Euclidean norm of the translation error (m).
    TranslationPart,
    /// Frobenius norm of `E − I` (unit-less).
    FullTransformation,
    /// Rotation angle of the error in degrees.
    RotationAngleDeg,
    /// Rotation angle of the error in radians.
    RotationAngleRad,
}

/// How RPE chooses the pose pairs it compares.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Delta {
    /// Pairs `δ` frames apart.
    Frames(usize),
    /// Pairs `δ` metres of travelled path apart (measured on the reference).
    Metres(f64),
}

/// Which pose pairs RPE compares.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RpePairs {
    /// Pair spacing.
    pub delta: Delta,
    /// Every pair at that spacing (`(i, i+δ)` for all i) instead of consecutive ones.
    pub all_pairs: bool,
    /// Choose pairs on the reference's path instead of the estimate's (evo's default is
    /// the estimate; it only matters for [`Delta::Metres`]).
    pub from_reference: bool,
}

/// Why a metric could not be computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrajError {
    /// Reference and estimate have different lengths.
    LengthMismatch,
    /// The output buffer is shorter than the number of errors.
    BufferTooSmall,
    /// No pose pair, or the delta produced no pair.
    Empty,
    /// A pose or delta is NaN/infinite, or the delta is not positive.
    InvalidInput,
}

impl core::fmt::Display for TrajError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            TrajError::LengthMismatch => "trajectories must have the same number of poses",
            TrajError::BufferTooSmall => "error buffer too small",
            TrajError::Empty => "no pose pairs to compare (try a smaller delta)",
            TrajError::InvalidInput => "non-finite pose or non-positive delta",
        })
    }
}

impl core::error::Error for TrajError {}

/// evo's error statistics.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Statistics {
    /// Root of the mean squared error.
    pub rmse: f64,
    /// Mean.
    pub mean: f64,
    /// Median (mean of the two middle values for an even count, as NumPy).
    pub median: f64,
    /// Population standard deviation.
    pub std: f64,
    /// Smallest error.
    pub min: f64,
    /// Largest error.
    pub max: f64,
    /// Sum of squared errors.
    pub sse: f64,
}

impl Statistics {
    /// Statistics of `errors`; sorts the slice in place (for the median).
    pub fn from_errors(errors: &mut [f64]) -> Result<Statistics, TrajError> {
        if errors.is_empty() {
            return Err(TrajError::Empty);
        }
        if errors.iter().any(|e| !e.is_finite()) {
            return Err(TrajError::InvalidInput);
        }
        let n = errors.len() as f64;
        let sum: f64 = pairwise_sum(errors, |e| e);
        let sse: f64 = pairwise_sum(errors, |e| e * e);
        let mean = sum / n;
        let var = pairwise_sum(errors, |e| (e - mean) * (e - mean)) / n;
        errors.sort_unstable_by(f64::total_cmp);
        let mid = errors.len() / 2;
        let median = if errors.len() % 2 == 1 { errors[mid] } else { (errors[mid - 1] + errors[mid]) / 2.0 };
        Ok(Statistics {
            rmse: libm::sqrt(sse / n),
            mean,
            median,
            std: libm::sqrt(var),
            min: errors[0],
            max: errors[errors.len() - 1],
            sse,
        })
    }
}

/// Pairwise summation (as NumPy's `sum`): error grows with log n, not n.
fn pairwise_sum(values: &[f64], f: impl Fn(f64) -> f64 + Copy) -> f64 {
    if values.len() <= 128 {
        values.iter().map(|&v| f(v)).sum()
    } else {
        let (a, b) = values.split_at(values.len() / 2);
        pairwise_sum(a, f) + pairwise_sum(b, f)
    }
}

/// Rotation angle (radians, 0..=π) of a rotation matrix, SciPy-compatible.
pub fn rotation_angle(r: &Matrix3<f64>) -> f64 {
    let r = nearest_rotation_if_needed(r);
    let q = shepperd_quaternion(&r);
    let norm = libm::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    let (mut x, mut y, mut z, mut w) = (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm);
    if w < 0.0 {
        (x, y, z, w) = (-x, -y, -z, -w);
    }
    let axis_norm = libm::sqrt(x * x + y * y + z * z);
    let angle = 2.0 * libm::atan2(axis_norm, w);
    if angle <= 1e-3 {
        // SciPy's small-angle series for the rotation-vector scale.
        let a2 = angle * angle;
        (2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0) * axis_norm
    } else {
        angle / libm::sin(angle / 2.0) * axis_norm
    }
}

fn nearest_rotation_if_needed(r: &Matrix3<f64>) -> Matrix3<f64> {
    let gram = r * r.transpose();
    let orthogonal = (0..3).all(|i| {
        (0..3).all(|j| {
            let target = if i == j { 1.0 } else { 0.0 };
            libm::fabs(gram[(i, j)] - target) <= 1e-12 + 1e-5 * libm::fabs(target)
        })
    });
    if orthogonal {
        return *r;
    }
    let svd =
        nalgebra::SVD::try_new(*r, true, true, f64::EPSILON * 5.0, crate::sim3::umeyama::MAX_DECOMPOSITION_ITERATIONS);
    match svd {
        Some(nalgebra::SVD { u: Some(u), v_t: Some(v_t), .. }) => u * v_t,
        _ => *r,
    }
}

/// Shepperd's method, `[x, y, z, w]`, not normalised.
fn shepperd_quaternion(m: &Matrix3<f64>) -> [f64; 4] {
    let trace = m[(0, 0)] + m[(1, 1)] + m[(2, 2)];
    let decision = [m[(0, 0)], m[(1, 1)], m[(2, 2)], trace];
    let mut choice = 0;
    for (i, &d) in decision.iter().enumerate() {
        if d > decision[choice] {
            choice = i;
        }
    }
    match choice {
        0 => [1.0 - trace + 2.0 * m[(0, 0)], m[(1, 0)] + m[(0, 1)], m[(2, 0)] + m[(0, 2)], m[(2, 1)] - m[(1, 2)]],
        1 => [m[(1, 0)] + m[(0, 1)], 1.0 - trace + 2.0 * m[(1, 1)], m[(2, 1)] + m[(1, 2)], m[(0, 2)] - m[(2, 0)]],
        2 => [m[(2, 0)] + m[(0, 2)], m[(2, 1)] + m[(1, 2)], 1.0 - trace + 2.0 * m[(2, 2)], m[(1, 0)] - m[(0, 1)]],
        _ => [m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)], 1.0 + trace],
    }
}

/// The scalar error of an error pose `e` under `relation`. For the translation part the
/// caller passes the difference of positions as `e.translation`.
fn error_of(e: &Pose, relation: PoseRelation) -> f64 {
    match relation {
        PoseRelation::TranslationPart => e.translation.norm(),
        PoseRelation::FullTransformation => (e.to_matrix() - nalgebra::Matrix4::identity()).norm(),
        PoseRelation::RotationAngleRad => rotation_angle(&e.rotation),
        PoseRelation::RotationAngleDeg => rotation_angle(&e.rotation).to_degrees(),
    }
}

fn check_inputs(reference: &[Pose], estimate: &[Pose]) -> Result<(), TrajError> {
    if reference.len() != estimate.len() {
        return Err(TrajError::LengthMismatch);
    }
    if reference.is_empty() {
        return Err(TrajError::Empty);
    }
    if !reference.iter().chain(estimate).all(Pose::is_finite) {
        return Err(TrajError::InvalidInput);
    }
    Ok(())
}

/// Absolute pose errors, one per pose pair, written to `out`; returns the count.
pub fn ape(reference: &[Pose], estimate: &[Pose], relation: PoseRelation, out: &mut [f64]) -> Result<usize, TrajError> {
    check_inputs(reference, estimate)?;
    let out = out.get_mut(..reference.len()).ok_or(TrajError::BufferTooSmall)?;
    for ((slot, r), e) in out.iter_mut().zip(reference).zip(estimate) {
        *slot = match relation {
            PoseRelation::TranslationPart => (e.translation - r.translation).norm(),
            _ => error_of(&e.relative_to(r), relation),
        };
    }
    Ok(reference.len())
}

/// Relative pose errors over the pairs `pairs` selects, written to `out`; returns the
/// count. `scratch` must hold `reference.len()` values when `all_pairs` is used with
/// [`Delta::Metres`] (accumulated path lengths).
pub fn rpe(
    reference: &[Pose],
    estimate: &[Pose],
    pairs: RpePairs,
    relation: PoseRelation,
    scratch: &mut [f64],
    out: &mut [f64],
) -> Result<usize, TrajError> {
    check_inputs(reference, estimate)?;
    let chooser = if pairs.from_reference { reference } else { estimate };
    let mut n = 0;
    let mut emit = |i: usize, j: usize| -> Result<(), TrajError> {
        let q_rel = reference[i].relative_to(&reference[j]);
        let p_rel = estimate[i].relative_to(&estimate[j]);
        let slot = out.get_mut(n).ok_or(TrajError::BufferTooSmall)?;
        *slot = error_of(&q_rel.relative_to(&p_rel), relation);
        n += 1;
        Ok(())
    };
    for_each_pair(chooser, pairs.delta, pairs.all_pairs, scratch, &mut emit)?;
    if n == 0 {
        return Err(TrajError::Empty);
    }
    Ok(n)
}

/// Calls `f(i, j)` for every index pair evo's `id_pairs_from_delta` would produce.
pub fn for_each_pair<E>(
    poses: &[Pose],
    delta: Delta,
    all_pairs: bool,
    scratch: &mut [f64],
    f: &mut impl FnMut(usize, usize) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<TrajError>,
{
    let n = poses.len();
    match delta {
        Delta::Frames(0) => return Err(TrajError::InvalidInput.into()),
        Delta::Frames(d) if all_pairs => {
            for i in 0..n.saturating_sub(d) {
                f(i, i + d)?;
            }
        }
        Delta::Frames(d) => {
            let mut i = 0;
            while i + d < n {
                f(i, i + d)?;
                i += d;
            }
        }
        Delta::Metres(d) if !(d.is_finite() && d > 0.0) => return Err(TrajError::InvalidInput.into()),
        Delta::Metres(d) if all_pairs => {
            let dist = scratch.get_mut(..n).ok_or(TrajError::BufferTooSmall)?;
            let mut acc = 0.0;
            for (k, slot) in dist.iter_mut().enumerate() {
                if k > 0 {
                    acc += (poses[k].translation - poses[k - 1].translation).norm();
                }
                *slot = acc;
            }
            let tol = d * 0.1;
            for i in 0..n.saturating_sub(1) {
                if let Some(j) = closest_by_path(dist, i, d) {
                    if libm::fabs(dist[j] - dist[i] - d) <= tol {
                        f(i, j)?;
                    }
                }
            }
        }
        Delta::Metres(d) => {
            let mut start = 0;
            let mut path = 0.0;
            for i in 1..n {
                path += (poses[i].translation - poses[i - 1].translation).norm();
                if path >= d {
                    f(start, i)?;
                    start = i;
                    path = 0.0;
                }
            }
        }
    }
    Ok(())
}

/// The first index `j > i` minimising `|dist[j] − dist[i] − d|` over the non-decreasing
/// accumulated distances (NumPy `argmin` semantics: the first of equal minima).
fn closest_by_path(dist: &[f64], i: usize, d: f64) -> Option<usize> {
    let tail = dist.get(i + 1..)?;
    if tail.is_empty() {
        return None;
    }
    let target = dist[i] + d;
    // The value dist[j] − dist[i] is compared to d, as evo does (not dist[j] to target).
    let cost = |j: usize| libm::fabs(tail[j] - dist[i] - d);
    let upper = tail.partition_point(|&v| v < target);
    let mut best: Option<usize> = None;
    for candidate in [upper.checked_sub(1), Some(upper)].into_iter().flatten() {
        if candidate >= tail.len() {
            continue;
        }
        // First index holding the same value (a plateau of zero motion).
        let value = tail[candidate];
        let first = tail.partition_point(|&v| v < value);
        best = match best {
            Some(b) if cost(b) <= cost(first) => Some(b),
            _ => Some(first),
        };
    }
    best.map(|j| j + i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim3::rotation_z;
    use nalgebra::Vector3;

    fn line(n: usize, step: f64) -> [Pose; 16] {
        let mut poses = [Pose::identity(); 16];
        for (k, p) in poses.iter_mut().enumerate().take(n) {
            p.translation = Vector3::new(k as f64 * step, 0.0, 0.0);
            p.rotation = rotation_z(k as f64 * 0.01);
        }
        poses
    }

    #[test]
    fn statistics_match_numpy_conventions() {
        let mut e = [3.0, 1.0, 2.0, 4.0];
        let s = Statistics::from_errors(&mut e).expect("non-empty");
        assert_eq!(s.median, 2.5);
        assert_eq!(s.mean, 2.5);
        assert_eq!(s.sse, 30.0);
        assert!((s.rmse - 7.5f64.sqrt()).abs() < 1e-15);
        assert!((s.std - 1.25f64.sqrt()).abs() < 1e-15);
        assert_eq!((s.min, s.max), (1.0, 4.0));
        assert_eq!(Statistics::from_errors(&mut []), Err(TrajError::Empty));
        assert_eq!(Statistics::from_errors(&mut [1.0, f64::NAN]), Err(TrajError::InvalidInput));
    }

    #[test]
    fn rotation_angle_of_known_rotations() {
        for angle in [0.0, 1e-6, 1e-3, 0.5, 3.0] {
            let got = rotation_angle(&rotation_z(angle));
            assert!((got - angle).abs() < 1e-12, "{angle} -> {got}");
        }
        // Slightly non-orthonormal (as printed KITTI matrices): still close to the angle.
        let mut r = rotation_z(0.2);
        r[(0, 0)] += 1e-7;
        assert!((rotation_angle(&r) - 0.2).abs() < 1e-6);
    }

    #[test]
    fn ape_of_identical_trajectories_is_zero_and_shift_shows() {
        let a = line(16, 1.0);
        let mut b = a;
        for p in b.iter_mut() {
            p.translation.y += 0.5;
        }
        let mut out = [0.0; 16];
        ape(&a, &a, PoseRelation::FullTransformation, &mut out).expect("ok");
        assert!(out.iter().all(|&e| e < 1e-12));
        ape(&a, &b, PoseRelation::TranslationPart, &mut out).expect("ok");
        assert!(out.iter().all(|&e| (e - 0.5).abs() < 1e-12));
        assert_eq!(ape(&a, &b[..3], PoseRelation::TranslationPart, &mut out), Err(TrajError::LengthMismatch));
        assert_eq!(ape(&a, &b, PoseRelation::TranslationPart, &mut out[..3]), Err(TrajError::BufferTooSmall));
    }

    #[test]
    fn pair_selection_by_frames_and_metres() {
        let poses = line(16, 1.0);
        let mut pairs: [(usize, usize); 32] = [(0, 0); 32];
        let mut n = 0;
        let mut scratch = [0.0; 16];
        let mut collect = |i, j| -> Result<(), TrajError> {
            pairs[n] = (i, j);
            n += 1;
            Ok(())
        };
        for_each_pair(&poses, Delta::Frames(5), false, &mut scratch, &mut collect).expect("ok");
        assert_eq!(&pairs[..n], &[(0, 5), (5, 10), (10, 15)]);
        n = 0;
        let mut collect = |i, j| -> Result<(), TrajError> {
            pairs[n] = (i, j);
            n += 1;
            Ok(())
        };
        for_each_pair(&poses, Delta::Metres(4.0), true, &mut scratch, &mut collect).expect("ok");
        assert_eq!(n, 12);
        assert_eq!(pairs[0], (0, 4));
        assert_eq!(pairs[11], (11, 15));
    }

    #[test]
    fn rpe_is_zero_for_a_rigidly_moved_copy() {
        let a = line(16, 2.0);
        let moved =
            crate::sim3::Sim3 { rotation: rotation_z(1.0), translation: Vector3::new(5.0, 5.0, 0.0), scale: 1.0 };
        let b = a.map(|p| moved.transform_pose(&p));
        let mut out = [1.0; 16];
        let frames = RpePairs { delta: Delta::Frames(1), all_pairs: false, from_reference: false };
        let n = rpe(&a, &b, frames, PoseRelation::TranslationPart, &mut [], &mut out).expect("ok");
        assert_eq!(n, 15);
        assert!(out[..n].iter().all(|&e| e < 1e-12));
        assert_eq!(
            rpe(
                &a,
                &b,
                RpePairs { delta: Delta::Metres(100.0), ..frames },
                PoseRelation::TranslationPart,
                &mut [],
                &mut out
            ),
            Err(TrajError::Empty)
        );
    }
}
