//! Batch re-anchoring: the VO-to-world similarity of a whole drive as one sparse
//! least-squares problem (`docs/finishing.md`).
//!
//! **Model.** Keyframes are VO samples about [`Settings::keyframe_s`] apart. Keyframe `k`
//! has the camera's world position `p_k`; the segment from `k` to `k + 1` has a similarity
//! `S_k = e^{ρ_k} R_k` (log-scale and rotation; the translation is implied by `p_k`). Inside
//! a segment the camera is where the VO path, mapped by `S_k`, puts it between the two
//! keyframes: `c(t) = (1−α)·p_k + α·p_{k+1} + S_k·w(t)` with `w` the VO path's deviation from
//! its chord — so positions are continuous and linear in `p`. The similarity varies slowly:
//! `ρ` and `R` of neighbouring segments differ by random walks (VO scale and yaw drift).
//!
//! **Residuals.** VO: `p_{k+1} − p_k = S_k·(x_{k+1} − x_k)`. GNSS: `c(t_fix − τ)` at the fix,
//! with one latency `τ` for the drive, σ inflated by the errors' correlation time (n fixes
//! within it carry about one fix's information), Cauchy-weighted and gated at 6σ. Wheel
//! speed: `ρ_k + ln|x_{k+1} − x_k| = ω + ln D_k`, the odometer distance `D_k` over the
//! segment times one wheel factor `e^ω` (a weak prior near 1). Anchors: the rear axle at a
//! time, or a VO point, at a geodetic position.
//!
//! **Solver.** Gauss–Newton with iteratively reweighted residuals; the normal equations are
//! block-tridiagonal (7×7 blocks) plus two dense columns (τ, ω), assembled blockwise and
//! factored by faer's sparse Cholesky — linear in the drive's length.

use dash2sim_core::imu::so3;
use dash2sim_core::nalgebra::{Matrix3, Rotation3, Vector3};
use dash2sim_core::sim3::Sim3;
use faer::Side;

mod doubt;
mod geometry;
mod graph;
mod normal;
mod problem;
mod start;
use doubt::doubt;
use geometry::{skew, Geometry, Measured};
pub use graph::{factor_graph, FactorGraph};
use normal::{solve_normal, Factoriser, Normal, Row};
pub use problem::{Anchor, AnchorAt, Fix, Inputs, Settings, Solution, SolveError, VoSample};
pub(crate) use start::wheel_distance;
use start::{initial_alignment, initial_positions, keyframes, odometer};

/// Unknowns per keyframe: position (3), log-scale (1), rotation increment (3).
const BLOCK: usize = 7;
/// Information added to every rotation increment of the first step (a step of 0.3 rad
/// costs one σ): rotation about the direction of travel is unobservable on a straight road,
/// and an undamped step along it leaves the region where the linearisation holds. Later
/// steps get it in proportion to Levenberg–Marquardt's λ ([`FIRST_LAMBDA`]): held fixed, it
/// shrank every step along a weakly observed rotation so much that a drive in `full` mode
/// used up its 50 iterations short of the optimum (GTSAM's cost 3e-4 lower on the
/// comma2k19 minute, positions 2.7 cm apart, issue #58). The solution's σ are taken with it
/// whole, as a weak prior: without it an unobservable rotation makes the matrix singular.
const ROTATION_STEP_INFORMATION: f64 = 10.0;
/// Levenberg–Marquardt's damping at the first step.
const FIRST_LAMBDA: f64 = 1e-4;
/// The global unknowns after the blocks: GNSS latency τ, log wheel factor ω, and the
/// heading's drift rate of a dead-reckoned path.
const GLOBALS: usize = 3;
const TAU: usize = 0;
const OMEGA: usize = 1;
const HEADING_DRIFT: usize = 2;

/// What one assembly gives: the normal equations and the residuals' sizes in σ (NaN where
/// a measurement falls outside the drive).
struct Assembled {
    normal: Normal,
    fix_u: Vec<f64>,
    anchor_u: Vec<f64>,
    wheel_u: Vec<f64>,
}

/// How the measurements that can be outliers are weighted: plainly (the first iteration,
/// far from the solution), Cauchy, and Cauchy with the gate.
#[derive(Clone, Copy)]
struct Kernel {
    robust: bool,
    gate: bool,
}

/// The problem's state during the iterations.
#[derive(Clone)]
struct State<'a> {
    inputs: Inputs<'a>,
    settings: Settings,
    keyframe_vo: Vec<usize>,
    keyframe_t: Vec<f64>,
    p: Vec<Vector3<f64>>,
    rho: Vec<f64>,
    rotation: Vec<Matrix3<f64>>,
    tau: f64,
    omega: f64,
    heading_drift: f64,
    fix_weight: Vec<f64>,
    anchor_weight: Vec<f64>,
    /// Which anchors take part.
    anchor_enabled: Vec<bool>,
    /// The kernel the weights are of.
    kernel: Kernel,
    wheel_weight: Vec<f64>,
    /// Segment and offset of each VO-point anchor.
    anchor_keyframe: Vec<usize>,
    /// Odometer distance over each segment, m (NaN: no speed there).
    odometer: Vec<f64>,
}

impl State<'_> {
    fn geometry(&self) -> Geometry<'_> {
        Geometry {
            vo: self.inputs.vo,
            keyframe_vo: &self.keyframe_vo,
            keyframe_t: &self.keyframe_t,
            p: &self.p,
            rho: &self.rho,
            rotation: &self.rotation,
        }
    }

    fn scale_rotation(&self, k: usize) -> Matrix3<f64> {
        self.geometry().scale_rotation(k)
    }

    /// The normal equations at this state with its current weights, and every weighted
    /// residual's size in σ.
    fn assemble(&self) -> Assembled {
        let mut normal = Normal::new(self.keyframe_t.len());
        let wheel_u = self.add_motion(&mut normal);
        self.add_global_priors(&mut normal);
        let geometry = self.geometry();
        let fix_u = self.add_fixes(&mut normal, &geometry);
        let anchor_u = self.add_anchors(&mut normal, &geometry);
        Assembled { normal, fix_u, anchor_u, wheel_u }
    }

    /// The motion priors between neighbouring segments (scale and rotation walks), the VO
    /// chords and the wheel-speed odometer; each segment's normalised wheel residual.
    fn add_motion(&self, normal: &mut Normal) -> Vec<f64> {
        let s = &self.settings;
        let blocks = self.keyframe_t.len();
        let global = blocks * BLOCK;
        let mut wheel_u = vec![f64::NAN; blocks];
        for (k, wheel) in wheel_u.iter_mut().enumerate().take(blocks - 1) {
            let dt = (self.keyframe_t[k + 1] - self.keyframe_t[k]).max(1e-3);
            let (b0, b1) = (k * BLOCK, (k + 1) * BLOCK);
            if k + 2 < blocks {
                let sigma = s.scale_walk * dt.sqrt();
                normal.plain(
                    &Row::new((self.rho[k + 1] - self.rho[k]) / sigma)
                        .with(b1 + 3, 1.0 / sigma)
                        .with(b0 + 3, -1.0 / sigma),
                );
            }
            let relative = so3::log(&(self.rotation[k + 1] * self.rotation[k].transpose()));
            let sigma = if k + 2 < blocks { s.rotation_walk * dt.sqrt() } else { 1e-3 };
            // A dead-reckoned segment turns by the drive's heading drift besides its walk.
            let drift = if self.inputs.vo[self.keyframe_vo[k + 1]].reckoned { dt } else { 0.0 };
            for axis in 0..3 {
                let (value, drift) = if axis == 2 {
                    (relative[axis] - drift * self.heading_drift, -drift / sigma)
                } else {
                    (relative[axis], 0.0)
                };
                normal.plain(
                    &Row::new(value / sigma)
                        .with(b1 + 4 + axis, 1.0 / sigma)
                        .with(b0 + 4 + axis, -1.0 / sigma)
                        .with(global + HEADING_DRIFT, drift),
                );
            }
            if k + 2 >= blocks {
                // The last keyframe's segment is unused: tie its scale to the one before.
                normal.plain(&Row::new((self.rho[k + 1] - self.rho[k]) / 1e-3).with(b1 + 3, 1e3).with(b0 + 3, -1e3));
            }
            let chord = self.inputs.vo[self.keyframe_vo[k + 1]].position - self.inputs.vo[self.keyframe_vo[k]].position;
            let sd = self.scale_rotation(k) * chord;
            let r = self.p[k + 1] - self.p[k] - sd;
            let mut sigma = Vector3::repeat(s.vo_sigma.0 + s.vo_sigma.1 * sd.norm());
            let grade_sigma = self.inputs.vo[self.keyframe_vo[k + 1]].grade_sigma;
            sigma.z = sigma.z.hypot(grade_sigma * sd.xy().norm());
            let plus_skew = skew(&sd);
            let identity = [Vector3::x(), Vector3::y(), Vector3::z()];
            let minus_identity = [-Vector3::x(), -Vector3::y(), -Vector3::z()];
            let rotation_columns: [Vector3<f64>; 3] =
                [plus_skew.column(0).into(), plus_skew.column(1).into(), plus_skew.column(2).into()];
            normal.plain3(
                &r,
                &sigma,
                &[(b1, &identity), (b0, &minus_identity), (b0 + 3, &[-sd]), (b0 + 4, &rotation_columns)],
            );
            // Wheel speed: the segment's metric length against the odometer.
            let d = self.odometer[k];
            if d.is_finite() && d >= 1.0 && chord.norm() > 0.0 {
                let sigma = s.wheel_sigma.0 + s.wheel_sigma.1 / d;
                let r = self.rho[k] + chord.norm().ln() - self.omega - d.ln();
                *wheel = (r / sigma).abs();
                normal.push(
                    &Row::new(r / sigma).with(b0 + 3, 1.0 / sigma).with(global + OMEGA, -1.0 / sigma),
                    self.wheel_weight[k],
                );
                normal.cost += self.measurement_cost(*wheel, 1.0);
            }
        }
        if s.gravity_aligned {
            // Only yaw varies: roll and pitch increments are held at zero (and zeroed when
            // applied).
            for b in 0..blocks {
                for axis in 0..2 {
                    normal.plain(&Row::new(0.0).with(b * BLOCK + 4 + axis, 1e4));
                }
            }
        }
        wheel_u
    }

    /// The priors on the global unknowns: latency, odometer scale, heading drift.
    fn add_global_priors(&self, normal: &mut Normal) {
        let s = &self.settings;
        let global = self.keyframe_t.len() * BLOCK;
        let (mean, sigma) = s.latency_prior;
        normal.plain(&Row::new((self.tau - mean) / sigma).with(global + TAU, 1.0 / sigma));
        normal.plain(&Row::new(self.omega / s.wheel_factor_sigma).with(global + OMEGA, 1.0 / s.wheel_factor_sigma));
        let sigma = s.heading_drift_sigma;
        normal.plain(&Row::new(self.heading_drift / sigma).with(global + HEADING_DRIFT, 1.0 / sigma));
    }

    /// The GNSS fixes (with the latency's column); each fix's normalised residual.
    fn add_fixes(&self, normal: &mut Normal, geometry: &Geometry<'_>) -> Vec<f64> {
        let s = &self.settings;
        let global = self.keyframe_t.len() * BLOCK;
        let inflation = fix_inflation(self.inputs.fixes, s.gnss_correlation_s);
        let mut fix_u = vec![f64::NAN; self.inputs.fixes.len()];
        for (i, fix) in self.inputs.fixes.iter().enumerate() {
            let Some(at) = geometry.place(fix.t - self.tau) else { continue };
            let r = geometry.camera(&at) - fix.enu;
            let raw = Vector3::new(fix.sigma_h, fix.sigma_h, fix.sigma_v);
            let u = r.component_div(&raw).norm() / 3f64.sqrt();
            fix_u[i] = u;
            // u² = |r ÷ σ|² / 3 and the whitened residual's e² = |r ÷ (σ·inflation)|².
            normal.cost += self.measurement_cost(u, 3.0 / (inflation * inflation));
            let w = self.fix_weight[i];
            let v = -geometry.velocity(&at);
            geometry.add_position_rows(
                normal,
                &at,
                Measured { residual: r, sigma: raw * inflation, weight: w },
                &[(global + TAU, &[v])],
                None,
            );
        }
        fix_u
    }

    /// The street-imagery anchors; each anchor's normalised residual.
    fn add_anchors(&self, normal: &mut Normal, geometry: &Geometry<'_>) -> Vec<f64> {
        let mut anchor_u = vec![f64::NAN; self.inputs.anchors.len()];
        for (i, anchor) in self.inputs.anchors.iter().enumerate() {
            let w = self.anchor_weight[i];
            let sigma = Vector3::repeat(anchor.sigma);
            let u = match anchor.at {
                AnchorAt::Time(t) => {
                    let Some(at) = geometry.place(t) else { continue };
                    let lever = geometry.lever(&at, &self.inputs.lever);
                    let r = geometry.camera(&at) - lever - anchor.enu;
                    let u = r.norm() / anchor.sigma / 3f64.sqrt();
                    geometry.add_position_rows(
                        normal,
                        &at,
                        Measured { residual: r, sigma, weight: w },
                        &[],
                        Some(lever),
                    );
                    u
                }
                AnchorAt::VoPoint(x) => {
                    let k = self.anchor_keyframe[i];
                    let offset = x - self.inputs.vo[self.keyframe_vo[k]].position;
                    let su = self.scale_rotation(k) * offset;
                    let r = self.p[k] + su - anchor.enu;
                    let u = r.norm() / anchor.sigma / 3f64.sqrt();
                    let m = -skew(&su);
                    let identity = [Vector3::x(), Vector3::y(), Vector3::z()];
                    let rotation_columns: [Vector3<f64>; 3] =
                        [m.column(0).into(), m.column(1).into(), m.column(2).into()];
                    let b = k * BLOCK;
                    normal.push3(&r, &sigma, &[(b, &identity), (b + 3, &[su]), (b + 4, &rotation_columns)], w);
                    u
                }
            };
            anchor_u[i] = u;
            if self.anchor_enabled[i] {
                normal.cost += self.measurement_cost(u, 3.0);
            }
        }
        anchor_u
    }

    /// Weights from the residuals of this state: Cauchy when `robust`, zero beyond the
    /// gate when `gate`; anchors not enabled stay at zero.
    fn reweight(&mut self, at: &Assembled, robust: bool, gate: bool) {
        self.kernel = Kernel { robust, gate };
        let s = self.settings;
        let weight = |u: f64| {
            if !u.is_finite() || (gate && u > s.gate) {
                0.0
            } else if robust {
                cauchy(u, s.robust)
            } else {
                1.0
            }
        };
        self.fix_weight = at.fix_u.iter().map(|&u| weight(u)).collect();
        self.wheel_weight = at.wheel_u.iter().map(|&u| weight(u)).collect();
        self.anchor_weight =
            at.anchor_u.iter().zip(&self.anchor_enabled).map(|(&u, &on)| if on { weight(u) } else { 0.0 }).collect();
    }

    /// What a measurement `u` σ off costs under the current kernel: ½e² without it, the
    /// Cauchy's ½k²·ln(1 + e²/k²) with it — the cost whose minimum the Cauchy weights lead
    /// to — and beyond the gate as much as at the gate (a rejected measurement neither pulls
    /// nor makes the cost jump). `whitened` is e²/u².
    fn measurement_cost(&self, u: f64, whitened: f64) -> f64 {
        let s = &self.settings;
        if !u.is_finite() {
            return 0.0;
        }
        let u = if self.kernel.gate { u.min(s.gate) } else { u };
        whitened * if self.kernel.robust { cauchy_cost(u, s.robust) } else { 0.5 * u * u }
    }

    fn apply(&mut self, delta: &[f64]) -> f64 {
        let mut largest: f64 = 0.0;
        for k in 0..self.p.len() {
            let b = k * BLOCK;
            let dp = Vector3::new(delta[b], delta[b + 1], delta[b + 2]);
            largest = largest.max(dp.norm());
            self.p[k] += dp;
            self.rho[k] += delta[b + 3];
            let mut dphi = Vector3::new(delta[b + 4], delta[b + 5], delta[b + 6]);
            if self.settings.gravity_aligned {
                // Only yaw varies: the rows above keep roll and pitch increments near zero,
                // and here they are exactly zero, so that no iteration's remainder creeps
                // into the solution (GTSAM found the optimum 26 % lower in cost without the
                // creep, issue #58).
                dphi.x = 0.0;
                dphi.y = 0.0;
            }
            largest = largest.max(dphi.norm() * 10.0);
            self.rotation[k] = Rotation3::new(dphi).into_inner() * self.rotation[k];
        }
        let global = self.p.len() * BLOCK;
        self.tau = (self.tau + delta[global + TAU]).clamp(-0.5, 1.0);
        self.omega += delta[global + OMEGA];
        self.heading_drift += delta[global + HEADING_DRIFT];
        largest
    }
}

fn cauchy(u: f64, c: f64) -> f64 {
    1.0 / (1.0 + (u / c) * (u / c))
}

/// The cost whose minimum the weights [`cauchy`] lead to: ½c²·ln(1 + (u/c)²) (its
/// derivative is u·cauchy(u, c)).
fn cauchy_cost(u: f64, c: f64) -> f64 {
    0.5 * c * c * (u / c).mul_add(u / c, 1.0).ln()
}

/// GNSS errors are correlated over `correlation_s`: fixes closer than that carry together
/// about the information of one, so each counts √(τc / interval) less.
fn fix_inflation(fixes: &[Fix], correlation_s: f64) -> f64 {
    let (Some(first), Some(last)) = (fixes.first(), fixes.last()) else { return 1.0 };
    if fixes.len() < 2 {
        return 1.0;
    }
    let interval = (last.t - first.t) / (fixes.len() - 1) as f64;
    (correlation_s / interval.max(1e-3)).max(1.0).sqrt()
}

/// Converged when an accepted step moves no position by more than 0.1 mm (and no rotation
/// by more than 10 µrad), or a refused one by less than ten times that.
const CONVERGED_STEP: f64 = 1e-4;

/// Half-width of the local alignments that start the solve, s.
const LOCAL_WINDOW_S: f64 = 30.0;
/// How often they are recomputed along the drive, s.
const LOCAL_STEP_S: f64 = 5.0;

/// Re-anchor the drive. `anchor_enabled` says which anchors take part (the caller gates
/// them against a solution without them).
pub fn solve(inputs: Inputs<'_>, settings: Settings, anchor_enabled: &[bool]) -> Result<Solution, SolveError> {
    let (first, last, step) = settings.latency_search;
    if inputs.fixes.is_empty() || !(step > 0.0 && last >= first) {
        return solve_from(inputs, settings, anchor_enabled, settings.latency_prior.0);
    }
    // The latency is found by a search before it is refined: how well the fixes fit as a
    // function of it has several minima on real GNSS (its errors wander), and a descent
    // from one guess ends in whichever is nearest. Each candidate is solved with the
    // latency held and coarser keyframes; the fit is Σ min(u², gate²) over the fixes.
    let coarse = Settings { keyframe_s: settings.keyframe_s.max(2.0), max_iterations: 12, ..settings };
    let mut best = (f64::INFINITY, settings.latency_prior.0);
    let mut tau = first;
    while tau <= last + 1e-9 {
        let held = coarse.with_latency_held(tau);
        // Only the fit: the σ of a candidate (a factorisation and 128 solves) are not needed.
        if let Ok((_, current, _)) = minimised(inputs, held, anchor_enabled, tau) {
            let fit = fit(&current, anchor_enabled, held.gate);
            if fit < best.0 {
                best = (fit, tau);
            }
        }
        tau += step;
    }
    solve_from(inputs, settings, anchor_enabled, best.1)
}

/// [`solve`] from the latency `tau0`.
fn solve_from(
    inputs: Inputs<'_>,
    settings: Settings,
    anchor_enabled: &[bool],
    tau0: f64,
) -> Result<Solution, SolveError> {
    let (state, current, iterations) = minimised(inputs, settings, anchor_enabled, tau0)?;
    solution(state, current, iterations, anchor_enabled, tau0)
}

/// The problem minimised from the latency `tau0`: the state, its last system and the
/// iterations taken.
fn minimised<'a>(
    inputs: Inputs<'a>,
    settings: Settings,
    anchor_enabled: &[bool],
    tau0: f64,
) -> Result<(State<'a>, Assembled, usize), SolveError> {
    if inputs.vo.len() < 2 {
        return Err(SolveError::NoVo);
    }
    something_to_anchor_to(&inputs, anchor_enabled)?;
    let mut state = initial_state(inputs, settings, anchor_enabled, tau0)?;
    let (current, iterations) = minimise(&mut state)?;
    Ok((state, current, iterations))
}

/// How well the fixes and the enabled anchors fit: Σ min(u², gate²).
fn fit(current: &Assembled, anchor_enabled: &[bool], gate: f64) -> f64 {
    current
        .fix_u
        .iter()
        .chain(current.anchor_u.iter().zip(anchor_enabled).filter(|(_, &on)| on).map(|(u, _)| u))
        .filter(|u| u.is_finite())
        .map(|u| (u * u).min(gate * gate))
        .sum()
}

/// An error unless a fix or an enabled anchor falls within the VO poses' time span.
fn something_to_anchor_to(inputs: &Inputs<'_>, anchor_enabled: &[bool]) -> Result<(), SolveError> {
    let (t_first, t_last) = (inputs.vo[0].t, inputs.vo[inputs.vo.len() - 1].t);
    let within = |t: f64| t >= t_first && t <= t_last;
    let has_fix = inputs.fixes.iter().any(|f| within(f.t));
    let has_anchor = inputs.anchors.iter().zip(anchor_enabled).any(|(a, &on)| {
        on && match a.at {
            AnchorAt::Time(t) => within(t),
            AnchorAt::VoPoint(_) => true,
        }
    });
    if !has_fix && !has_anchor {
        return Err(SolveError::NothingToAnchorTo);
    }
    Ok(())
}

/// The unknowns where the solve starts: the first alignment at every keyframe, the
/// latency `tau0`, every measurement weighted 1 (a disabled anchor 0).
fn initial_state<'a>(
    inputs: Inputs<'a>,
    settings: Settings,
    anchor_enabled: &[bool],
    tau0: f64,
) -> Result<State<'a>, SolveError> {
    let initial = initial_alignment(&inputs, settings.gravity_aligned)?;
    let keyframe_vo = keyframes(inputs.vo, settings.keyframe_s);
    let keyframe_t: Vec<f64> = keyframe_vo.iter().map(|&j| inputs.vo[j].t).collect();
    let anchor_keyframe = inputs
        .anchors
        .iter()
        .map(|a| match a.at {
            AnchorAt::VoPoint(x) => nearest_keyframe(inputs.vo, &keyframe_vo, &x),
            AnchorAt::Time(_) => 0,
        })
        .collect();
    let blocks = keyframe_vo.len();
    Ok(State {
        inputs,
        settings,
        p: initial_positions(&inputs, &keyframe_vo, &initial, settings.gravity_aligned),
        rho: vec![initial.scale.ln(); blocks],
        rotation: vec![initial.rotation; blocks],
        tau: tau0,
        omega: 0.0,
        heading_drift: 0.0,
        fix_weight: vec![1.0; inputs.fixes.len()],
        anchor_weight: anchor_enabled.iter().map(|&on| if on { 1.0 } else { 0.0 }).collect(),
        anchor_enabled: anchor_enabled.to_vec(),
        kernel: Kernel { robust: false, gate: false },
        wheel_weight: vec![1.0; blocks],
        anchor_keyframe,
        odometer: odometer(inputs.speeds, &keyframe_t),
        keyframe_vo,
        keyframe_t,
    })
}

/// Levenberg–Marquardt on the reweighted problem: Cauchy weights from the second
/// iteration on, the 6σ gate from the fourth (a first alignment still far from the
/// solution must not reject what is right). A state's cost is the robust cost the weights
/// are the fixed point of (Σ ½k²·ln(1 + e²/k²), [`State::measurement_cost`]) — bounded per
/// measurement beyond the gate, so a step that moves an outlier is not refused for it; a
/// step that does not lower it is retried with more damping. (Judged by Σ w·e² instead,
/// steps towards the robust optimum were refused and the solve stopped short of it: GTSAM
/// found costs 3e-6 lower, issue #58.) The last system assembled (with the weights of the state before) and the iterations taken.
fn minimise(state: &mut State<'_>) -> Result<(Assembled, usize), SolveError> {
    let mut iterations = 0;
    let mut lambda = FIRST_LAMBDA;
    let mut factoriser = Factoriser::default();
    let mut current = state.assemble();
    while iterations < state.settings.max_iterations {
        iterations += 1;
        if iterations >= 2 {
            state.reweight(&current, true, iterations >= 4);
            current = state.assemble();
        }
        let delta = solve_normal(&current.normal, lambda, &mut factoriser)?;
        let mut trial = state.clone();
        let step = trial.apply(&delta);
        // The cost does not depend on the weights: the trial's is judged as it is.
        let assembled = trial.assemble();
        let (before, after) = (current.normal.cost, assembled.normal.cost);
        if after <= before {
            *state = trial;
            current = assembled;
            lambda = (lambda * 0.1).max(1e-9);
            if iterations >= 5 && (step < CONVERGED_STEP || before - after <= 1e-9 * before) {
                break;
            }
        } else {
            // A refused step this small: the cost is as low as reweighting noise lets it be.
            lambda *= 10.0;
            if lambda > 1e8 || (iterations >= 5 && step < 10.0 * CONVERGED_STEP) {
                break;
            }
        }
    }
    Ok((current, iterations))
}

/// The solution at `state`, with what the measurements say of it: which fixes and anchors
/// it used, the a-posteriori variance factor, the σ of its scale, positions and heading (from
/// the inverse of `current`'s normal matrix), and the fit of the measurements it used.
fn solution(
    state: State<'_>,
    current: Assembled,
    iterations: usize,
    anchor_enabled: &[bool],
    start_latency_s: f64,
) -> Result<Solution, SolveError> {
    let blocks = state.keyframe_vo.len();
    let (mut state, mut current) = (state, current);
    if iterations >= 2 {
        // The system the solution's σ come from, with the solution's own weights.
        state.reweight(&current, true, iterations >= 4);
        current = state.assemble();
    }
    let Assembled { normal, fix_u, anchor_u, .. } = current;
    let (chi2, rows) = (normal.chi2, normal.rows);
    let llt =
        normal.matrix(0.0, ROTATION_STEP_INFORMATION)?.sp_cholesky(Side::Upper).map_err(|_| SolveError::Singular)?;
    let unknowns = blocks * BLOCK + GLOBALS;
    let sigma0_sq = chi2 / (rows.saturating_sub(unknowns).max(1)) as f64;
    let gate = state.settings.gate;
    let fix_used: Vec<bool> = fix_u.iter().map(|u| u.is_finite() && *u <= gate).collect();
    let anchor_used: Vec<bool> =
        anchor_u.iter().zip(anchor_enabled).map(|(u, &on)| on && u.is_finite() && *u <= gate).collect();
    let inflation_factor = sigma0_sq.max(1.0).sqrt();
    let doubt = doubt(&llt, &state.keyframe_t, blocks, inflation_factor);
    let mut sse = 0.0;
    let mut used = 0;
    for (fix, &ok) in state.inputs.fixes.iter().zip(&fix_used) {
        if let (true, Some(at)) = (ok, state.geometry().place(fix.t - state.tau)) {
            let r = state.geometry().camera(&at) - fix.enu;
            sse += r.x * r.x + r.y * r.y;
            used += 1;
        }
    }
    let last_rho = state.rho[blocks.saturating_sub(2)];
    if let Some(r) = state.rho.last_mut() {
        *r = last_rho;
    }
    let solution = Solution {
        positions: state.p,
        log_scale: state.rho,
        rotation: state.rotation,
        latency_s: state.tau,
        start_latency_s,
        wheel_factor: state.omega.exp(),
        heading_drift: state.heading_drift,
        fix_used,
        anchor_used,
        iterations,
        sigma0_sq,
        scale_sigma: doubt.scale,
        position_sigma_m: doubt.position,
        horizontal_sigma: doubt.horizontal,
        heading_sigma_rad: doubt.heading,
        gnss_rms_m: if used > 0 { (sse / used as f64).sqrt() } else { f64::NAN },
        keyframe_t: state.keyframe_t,
        keyframe_vo: state.keyframe_vo,
    };
    Ok(solution)
}

fn nearest_keyframe(vo: &[VoSample], keyframe_vo: &[usize], x: &Vector3<f64>) -> usize {
    keyframe_vo
        .iter()
        .enumerate()
        .take(keyframe_vo.len().saturating_sub(1).max(1))
        .min_by(|a, b| (vo[*a.1].position - x).norm_squared().total_cmp(&(vo[*b.1].position - x).norm_squared()))
        .map_or(0, |(k, _)| k)
}

impl Solution {
    /// The horizontal 1-σ (DRMS, m) of the camera position at `t`: linear between the
    /// sampled keyframes, the nearest one's beyond them (NaN with none).
    pub fn horizontal_sigma_at(&self, t: f64) -> f64 {
        let s = &self.horizontal_sigma;
        let k = s.partition_point(|(tk, _)| *tk <= t);
        match (k.checked_sub(1).and_then(|i| s.get(i)), s.get(k)) {
            (Some(&(t0, a)), Some(&(t1, b))) if t1 > t0 => a + (b - a) * (t - t0) / (t1 - t0),
            (Some(&(_, a)), _) | (None, Some(&(_, a))) => a,
            (None, None) => f64::NAN,
        }
    }

    /// The camera's world pose at `t` (None outside the VO's time span).
    pub fn camera_at(&self, vo: &[VoSample], t: f64) -> Option<(Vector3<f64>, Matrix3<f64>)> {
        let geometry = self.geometry(vo);
        let at = geometry.place(t)?;
        Some((geometry.camera(&at), self.rotation[at.k] * at.vo_rotation))
    }

    /// The VO → world similarity of segment `k` (translation from the keyframe's position).
    pub fn sim3(&self, vo: &[VoSample], k: usize) -> Sim3 {
        let scale = self.log_scale[k].exp();
        let x = vo[self.keyframe_vo[k]].position;
        Sim3 { rotation: self.rotation[k], scale, translation: self.positions[k] - self.rotation[k] * x * scale }
    }

    fn geometry<'a>(&'a self, vo: &'a [VoSample]) -> Geometry<'a> {
        Geometry {
            vo,
            keyframe_vo: &self.keyframe_vo,
            keyframe_t: &self.keyframe_t,
            p: &self.positions,
            rho: &self.log_scale,
            rotation: &self.rotation,
        }
    }

    /// Residual of an anchor under this solution, m (None when it falls outside the drive).
    pub fn anchor_residual(&self, inputs: &Inputs<'_>, anchor: &Anchor) -> Option<f64> {
        let geometry = self.geometry(inputs.vo);
        match anchor.at {
            AnchorAt::Time(t) => {
                let at = geometry.place(t)?;
                let lever = geometry.lever(&at, &inputs.lever);
                Some((geometry.camera(&at) - lever - anchor.enu).norm())
            }
            AnchorAt::VoPoint(x) => {
                let k = nearest_keyframe(inputs.vo, &self.keyframe_vo, &x);
                Some((self.sim3(inputs.vo, k).transform_point(&x) - anchor.enu).norm())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::sim3::rotation_z;
    use std::f64::consts::FRAC_PI_2;

    /// A minute north at 25 m/s, dead-reckoned with a gyro whose bias the device got wrong
    /// by 1.5 mrad/s (the path's heading turns 5° over the minute), anchored to fixes every
    /// 2 s off by up to 2 m: the drift rate is found and the path is straight again.
    fn drifting_minute(reckoned: bool) -> (Solution, f64) {
        let (speed, drift) = (25.0, 1.5e-3);
        let mut vo = Vec::new();
        let mut position = Vector3::zeros();
        for k in 0..=600 {
            let t = 0.1 * k as f64;
            let heading = drift * t;
            if k > 0 {
                position += Vector3::new(heading.cos(), heading.sin(), 0.0) * speed * 0.1;
            }
            let rotation = rotation_z(heading);
            vo.push(VoSample { t, session: 0, position, rotation, grade_sigma: 0.03, reckoned });
        }
        let fixes: Vec<Fix> = (0..=30)
            .map(|k| {
                let t = 2.0 * k as f64;
                let error = Vector3::new(1.5 * (k as f64 * 1.7).sin(), 1.5 * (k as f64 * 0.9).cos(), 0.0);
                Fix { t, enu: Vector3::new(0.0, speed * t, 0.0) + error, sigma_h: 4.0, sigma_v: 6.0 }
            })
            .collect();
        let speeds: Vec<(f64, f64)> = (0..=600).map(|k| (0.1 * k as f64, speed)).collect();
        let inputs = Inputs { vo: &vo, fixes: &fixes, speeds: &speeds, anchors: &[], lever: Vector3::zeros() };
        let settings = Settings { gravity_aligned: true, ..Settings::default() }.with_latency_held(0.0);
        let solution = solve(inputs, settings, &[]).expect("solved");
        let squares: f64 = solution
            .keyframe_t
            .iter()
            .zip(&solution.positions)
            .map(|(t, p)| (p.xy() - Vector3::new(0.0, speed * t, 0.0).xy()).norm_squared())
            .sum();
        let rms = (squares / solution.positions.len() as f64).sqrt();
        (solution, rms)
    }

    /// `seconds` of VO north at 20 m/s, anchored to 10 Hz fixes off by up to 1.5 m: the
    /// solution's heading σ.
    fn heading_sigma_of_a_session(seconds: f64) -> f64 {
        let n = (seconds * 10.0).round() as usize;
        let vo: Vec<VoSample> = (0..=n)
            .map(|k| {
                let t = 0.1 * k as f64;
                let position = Vector3::new(0.0, 20.0 * t, 0.0);
                VoSample {
                    t,
                    session: 0,
                    position,
                    rotation: rotation_z(FRAC_PI_2),
                    grade_sigma: 0.03,
                    reckoned: false,
                }
            })
            .collect();
        let fixes: Vec<Fix> = (0..=n)
            .map(|k| {
                let t = 0.1 * k as f64;
                let error = Vector3::new(1.5 * (k as f64 * 1.7).sin(), 1.5 * (k as f64 * 0.9).cos(), 0.0);
                Fix { t, enu: Vector3::new(0.0, 20.0 * t, 0.0) + error, sigma_h: 1.5, sigma_v: 3.0 }
            })
            .collect();
        let speeds: Vec<(f64, f64)> = (0..=n).map(|k| (0.1 * k as f64, 20.0)).collect();
        let inputs = Inputs { vo: &vo, fixes: &fixes, speeds: &speeds, anchors: &[], lever: Vector3::zeros() };
        let settings = Settings { gravity_aligned: true, ..Settings::default() }.with_latency_held(0.0);
        solve(inputs, settings, &[]).expect("solved").heading_sigma_rad
    }

    /// A VO session of three frames (6 m of travel, its fixes metres off) points anywhere
    /// within many degrees; one of twenty seconds is known to well under one.
    #[test]
    fn a_short_sessions_heading_is_stated_as_undetermined() {
        let (short, long) = (heading_sigma_of_a_session(0.3), heading_sigma_of_a_session(20.0));
        assert!(short.to_degrees() > 5.0, "0.3 s: {:.2}°", short.to_degrees());
        assert!(long.to_degrees() < 1.0, "20 s: {:.2}°", long.to_degrees());
    }

    #[test]
    fn a_dead_reckoned_path_s_heading_drift_is_found() {
        let (solution, rms) = drifting_minute(true);
        assert!((solution.heading_drift + 1.5e-3).abs() < 3e-4, "drift {}", solution.heading_drift);
        assert!(rms < 0.5, "{rms:.2} m off the road");
        // A camera's VO has no such rate: the same path as VO keeps a bow.
        let (vo, bowed) = drifting_minute(false);
        assert_eq!(vo.heading_drift, 0.0);
        assert!(bowed > 1.0 && bowed > 3.0 * rms, "as VO {bowed:.2} m, reckoned {rms:.2} m");
    }
}
