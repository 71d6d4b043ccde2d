//! How fast the VO's scale and rotation wander, learnt per session from the anchors.
//!
//! The batch solve lets the VO-to-world similarity drift between keyframes by random walks
//! ([`Settings::scale_walk`], [`Settings::rotation_walk`]). Too tight, and the finished path
//! cannot follow a VO whose heading and scale really wander (a consumer dashcam's do), so it
//! sits between the anchors off by more than its σ says; too loose, and it follows each
//! anchor's own noise. The right setting is the camera's and the drive's, not a constant:
//! each session with enough anchors tries a few walks and keeps the one that best predicts
//! the anchors it was not given (three folds, every third anchor held out in each). Nothing
//! here reads how the drive was made; only the anchors' residuals decide.

use super::solve::{self, Inputs, Settings, SolveError};

/// The walks tried, as multiples of [`Settings::anchored_walk`], tightest first.
const WALK_FACTORS: [f64; 3] = [1.0, 2.0, 4.0];
/// Folds of the cross-validation: the `p`-th anchor used is held out by fold `p % FOLDS`.
const FOLDS: usize = 3;
/// Held-out anchors a fold needs before its residuals say anything.
const MIN_HELD_OUT: usize = 4;
/// Iterations of each trial solve (it starts from the first alignment, as the real one).
const TRIAL_ITERATIONS: usize = 20;

/// The walks (scale, rotation per √s) that predict held-out anchors best, with the GNSS latency held at `latency_s`; the configured
/// anchored walk when there are too few anchors to tell or no trial solves.
pub fn anchored_walk(
    inputs: Inputs<'_>,
    settings: Settings,
    enabled: &[bool],
    latency_s: f64,
) -> Result<(f64, f64), SolveError> {
    let base = settings.anchored_walk;
    let used: Vec<usize> = (0..enabled.len()).filter(|&i| enabled[i]).collect();
    if used.len() < FOLDS * MIN_HELD_OUT {
        return Ok(base);
    }
    // Per walk tried: each held-out anchor's squared residual (in anchor order).
    let mut tried: Vec<((f64, f64), Vec<f64>)> = Vec::new();
    'walks: for factor in WALK_FACTORS {
        let walk = (base.0 * factor, base.1 * factor);
        let trial = Settings {
            scale_walk: walk.0,
            rotation_walk: walk.1,
            latency_prior: (latency_s, 1e-4),
            latency_search: (0.0, -1.0, 0.0),
            max_iterations: TRIAL_ITERATIONS,
            ..settings
        };
        let mut errors = vec![f64::NAN; inputs.anchors.len()];
        for fold in 0..FOLDS {
            let mut given = vec![false; enabled.len()];
            for (p, &i) in used.iter().enumerate() {
                given[i] = p % FOLDS != fold;
            }
            let solution = match solve::solve(inputs, trial, &given) {
                Ok(solution) => solution,
                // A walk whose trial cannot be solved is not chosen.
                Err(SolveError::Singular) => continue 'walks,
                Err(e) => return Err(e),
            };
            for &i in used.iter().filter(|&&i| !given[i]) {
                let anchor = &inputs.anchors[i];
                if let Some(r) = solution.anchor_residual(&inputs, anchor) {
                    // Clipped at the gate: a wrong match the check let through must not
                    // choose the walk.
                    errors[i] = r.min(settings.gate * anchor.sigma).powi(2);
                }
            }
        }
        tried.push((walk, errors));
    }
    Ok(best_predicting(&tried).unwrap_or(base))
}

/// The walk with the smallest summed squared error over the anchors every walk predicted
/// (the tighter one on a tie).
fn best_predicting(tried: &[((f64, f64), Vec<f64>)]) -> Option<(f64, f64)> {
    let anchors = tried.first()?.1.len();
    let common: Vec<usize> = (0..anchors).filter(|&i| tried.iter().all(|(_, e)| e[i].is_finite())).collect();
    let cost = |e: &[f64]| common.iter().map(|&i| e[i]).sum::<f64>();
    let mut best: Option<(f64, (f64, f64))> = None;
    for (walk, errors) in tried {
        let c = cost(errors);
        if best.is_none_or(|(b, _)| c < b) {
            best = Some((c, *walk));
        }
    }
    best.map(|(_, walk)| walk)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_walk_that_predicts_the_held_out_anchors_best_is_chosen() {
        let (tight, mid, loose) = ((1.0, 1.0), (2.0, 2.0), (4.0, 4.0));
        let tried = [
            (tight, vec![0.50, 0.60, 0.55, 0.70]),
            (mid, vec![0.10, 0.12, 0.09, 0.11]),
            (loose, vec![0.20, 0.11, 0.10, 0.12]),
        ];
        assert_eq!(best_predicting(&tried), Some(mid));
        // A tie goes to the tighter walk.
        let tie = [(tight, vec![0.1, 0.2]), (mid, vec![0.2, 0.1])];
        assert_eq!(best_predicting(&tie), Some(tight));
        // An anchor a walk could not predict (NaN) is left out of every comparison: else
        // the walk that predicted fewer would look better.
        let partial = [(tight, vec![f64::NAN, 0.9, 0.8, 0.9]), (mid, vec![5.0, 0.1, 0.1, 0.1])];
        assert_eq!(best_predicting(&partial), Some(mid));
        assert_eq!(best_predicting(&[]), None);
    }
}
