//! What a solution says of its own precision: the σ of its scale, positions and heading
//! from the inverse of its normal matrix, a few columns at a time.

use faer::linalg::solvers::Solve;
use faer::Mat;

use super::{BLOCK, GLOBALS};

/// The solution's σ, inflated by the variance factor when the fit is worse than the
/// measurements' σ say.
pub(super) struct Doubt {
    /// Of the drive's mean log-scale.
    pub(super) scale: f64,
    /// Of a position, m (the mean over the sampled keyframes).
    pub(super) position: f64,
    /// Of the horizontal position at up to 32 keyframes along the drive: (time, σ m).
    pub(super) horizontal: Vec<(f64, f64)>,
    /// Of the heading where the session fixes it best, rad.
    pub(super) heading: f64,
}

/// The σ of the solution from the Cholesky factor `llt` of its normal matrix (`blocks`
/// keyframes at `keyframe_t`), each times `inflation_factor`.
pub(super) fn doubt(
    llt: &faer::sparse::linalg::solvers::Llt<usize, f64>,
    keyframe_t: &[f64],
    blocks: usize,
    inflation_factor: f64,
) -> Doubt {
    // The drive's mean log-scale (segments weighted by duration): aᵀ H⁻¹ a.
    let n = blocks * BLOCK + GLOBALS;
    let total: f64 = keyframe_t.windows(2).map(|w| w[1] - w[0]).sum();
    let mean_scale = Mat::from_fn(n, 1, |i, _| {
        let k = i / BLOCK;
        if i < blocks * BLOCK && i % BLOCK == 3 && k + 1 < blocks {
            (keyframe_t[k + 1] - keyframe_t[k]) / total
        } else {
            0.0
        }
    });
    let solved = llt.solve(&mean_scale);
    let scale_var: f64 = (0..n).map(|i| mean_scale[(i, 0)] * solved[(i, 0)]).sum();
    // Position σ at up to 32 keyframes along the drive.
    let count = blocks.min(32);
    let samples: Vec<usize> = (0..count).map(|i| if count > 1 { i * (blocks - 1) / (count - 1) } else { 0 }).collect();
    // Per sample the variances of the position's three unknowns and the heading's (the
    // rotation's increment about the vertical, the block's seventh): four columns of the
    // inverse, solved a sample at a time (all at once, an hour's were two dense 50 MB
    // matrices, issue #58).
    let variances: Vec<[f64; 4]> = samples
        .iter()
        .map(|&k| {
            let unknowns = [0, 1, 2, 6].map(|u| k * BLOCK + u);
            let rhs = Mat::from_fn(n, 4, |i, c| if i == unknowns[c] { 1.0 } else { 0.0 });
            let cov = llt.solve(&rhs);
            [0, 1, 2, 3].map(|c| cov[(unknowns[c], c)])
        })
        .collect();
    let trace: f64 = variances.iter().flat_map(|v| [v[0], v[1], v[2]]).sum();
    // The heading where the session fixes it best: the VO carries it along the rest (a
    // standstill's keyframes, the last one that only marks the session's end, are held by
    // little else).
    let heading = (0..samples.len())
        .filter(|&j| blocks == 1 || samples[j] + 1 < blocks)
        .map(|j| variances[j][3].max(0.0).sqrt() * inflation_factor)
        .fold(f64::INFINITY, f64::min);
    let position_var = trace / samples.len().max(1) as f64;
    let horizontal = samples
        .iter()
        .zip(&variances)
        .map(|(&k, v)| (keyframe_t[k], (v[0] + v[1]).max(0.0).sqrt() * inflation_factor))
        .collect();
    Doubt {
        scale: scale_var.max(0.0).sqrt() * inflation_factor,
        position: position_var.max(0.0).sqrt() * inflation_factor,
        horizontal,
        heading,
    }
}
