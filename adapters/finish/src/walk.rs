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

/// The walks (scale, rotation per √s) that predict held-out anchors best, with the GNSS
/// latency held at `latency_s`; the configured anchored walk when there are too few anchors
/// to tell or no trial solves.
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
        let trial =
            Settings { scale_walk: walk.0, rotation_walk: walk.1, max_iterations: TRIAL_ITERATIONS, ..settings }
                .with_latency_held(latency_s);
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
    use super::super::solve::{Anchor, AnchorAt, Fix, VoSample};
    use super::*;
    use dash2sim_core::nalgebra::{Matrix3, Rotation3, Vector3};

    /// Deterministic noise in [−1, 1] (no generator to share).
    fn noise(state: &mut u64) -> f64 {
        *state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// The walk chosen for an 80 s drive whose VO heading wanders by `wander` rad (a slow
    /// sinusoid) on top of a fixed similarity; fixes of σ 1.5 m, anchors every 5 s of σ 0.3 m.
    fn chosen_walk(wander: f64) -> (f64, f64) {
        let mut state = 7;
        let truth = |t: f64| Vector3::new(10.0 * t, 20.0 * (t / 10.0).sin(), 0.0);
        let (scale, turn) = (2.0, Rotation3::from_axis_angle(&Vector3::z_axis(), 0.7));
        let mut vo = Vec::new();
        let mut position = Vector3::zeros();
        for k in 0..=800 {
            let t = k as f64 * 0.1;
            if k > 0 {
                let heading = wander * (std::f64::consts::TAU * t / 25.0).sin();
                let step = truth(t) - truth(t - 0.1);
                position += turn.inverse() * Rotation3::from_axis_angle(&Vector3::z_axis(), heading) * step / scale;
            }
            vo.push(VoSample {
                t,
                session: 0,
                position,
                rotation: Matrix3::identity(),
                grade_sigma: 0.0,
                reckoned: false,
            });
        }
        let fixes: Vec<Fix> = (0..=800)
            .map(|k| {
                let t = k as f64 * 0.1;
                let error = Vector3::new(noise(&mut state), noise(&mut state), noise(&mut state)) * 1.5 * 3f64.sqrt();
                Fix { t, enu: truth(t) + error, sigma_h: 1.5, sigma_v: 2.25 }
            })
            .collect();
        let speeds: Vec<(f64, f64)> =
            (0..=800).map(|k| k as f64 * 0.1).map(|t| (t, (truth(t + 0.05) - truth(t - 0.05)).norm() / 0.1)).collect();
        let anchors: Vec<Anchor> = (1..16)
            .map(|k| {
                let t = k as f64 * 5.0;
                let error = Vector3::new(noise(&mut state), noise(&mut state), 0.0) * 0.3 * 3f64.sqrt();
                Anchor { at: AnchorAt::Time(t), enu: truth(t) + error, sigma: 0.3 }
            })
            .collect();
        let inputs = Inputs { vo: &vo, fixes: &fixes, speeds: &speeds, anchors: &anchors, lever: Vector3::zeros() };
        // The tight walk's trial of the first fold solves: the tight walk kept below is a
        // choice, not the fallback for trials that all failed.
        let first_fold: Vec<bool> = (0..anchors.len()).map(|p| p % FOLDS != 0).collect();
        let trial = Settings::default().with_latency_held(0.0);
        let trial = Settings { scale_walk: trial.anchored_walk.0, rotation_walk: trial.anchored_walk.1, ..trial };
        assert!(solve::solve(inputs, trial, &first_fold).is_ok(), "the tight walk's trial solves");
        anchored_walk(inputs, Settings::default(), &[true; 15], 0.0).expect("solvable")
    }

    #[test]
    fn a_wandering_vo_gets_looser_walks_and_a_steady_one_keeps_the_tight_ones() {
        let tight = Settings::default().anchored_walk;
        assert_eq!(chosen_walk(0.0), tight);
        let wandering = chosen_walk(0.02);
        assert!(wandering.0 > tight.0 && wandering.1 > tight.1, "{wandering:?}");
    }

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
