//! Where the solve starts: the keyframes, the wheels' odometer at them, and the drive's
//! first alignment and keyframe positions from the VO and the fixes.

use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::sim3::{AlignMode, Moments, Sim3};

use super::geometry::vo_at;
use super::{AnchorAt, Inputs, SolveError, VoSample, LOCAL_STEP_S, LOCAL_WINDOW_S};

/// Keyframes: the first VO sample, then each at least `spacing` after the previous, and
/// the last.
pub(super) fn keyframes(vo: &[VoSample], spacing: f64) -> Vec<usize> {
    let mut out = vec![0];
    for (j, s) in vo.iter().enumerate().skip(1) {
        if s.t - vo[out[out.len() - 1]].t >= spacing {
            out.push(j);
        }
    }
    if out.last() != Some(&(vo.len() - 1)) {
        if vo.len() >= 2 && out.len() >= 2 && vo[vo.len() - 1].t - vo[out[out.len() - 1]].t < 0.5 * spacing {
            out.pop();
        }
        out.push(vo.len() - 1);
    }
    out
}

/// Distance the wheels covered from `t0` to `t1`, odometer units (the wheel factor not
/// applied); `None` where the speeds leave it unknown.
pub(crate) fn wheel_distance(speeds: &[(f64, f64)], t0: f64, t1: f64) -> Option<f64> {
    odometer(speeds, &[t0, t1]).first().copied().filter(|d| d.is_finite())
}

/// Distance the wheels covered between keyframes (trapezoids; NaN where a gap of more
/// than 1 s leaves it unknown).
pub(super) fn odometer(speeds: &[(f64, f64)], keyframe_t: &[f64]) -> Vec<f64> {
    let mut out = vec![f64::NAN; keyframe_t.len()];
    for (k, w) in keyframe_t.windows(2).enumerate() {
        let (t0, t1) = (w[0], w[1]);
        let start = speeds.partition_point(|s| s.0 < t0).saturating_sub(1);
        let mut distance = 0.0;
        let mut covered = 0.0;
        for pair in speeds[start..].windows(2) {
            let ((ta, va), (tb, vb)) = (pair[0], pair[1]);
            if ta >= t1 {
                break;
            }
            let (a, b) = (ta.max(t0), tb.min(t1));
            if b <= a || tb - ta > 1.0 {
                continue;
            }
            let speed = |t: f64| va + (vb - va) * (t - ta) / (tb - ta);
            distance += 0.5 * (speed(a) + speed(b)) * (b - a);
            covered += b - a;
        }
        if covered >= 0.9 * (t1 - t0) {
            out[k] = distance * (t1 - t0) / covered;
        }
    }
    out
}

/// A first alignment of the whole VO path: Umeyama on the fixes (or, without fixes, the
/// anchors) paired with the VO positions at their times.
pub(super) fn initial_alignment(inputs: &Inputs<'_>, gravity: bool) -> Result<Sim3, SolveError> {
    let mut moments = Moments::default();
    for fix in inputs.fixes {
        if let Some((x, _, _)) = vo_at(inputs.vo, fix.t) {
            let _ = moments.push(&x, &fix.enu, 1.0 / (fix.sigma_h * fix.sigma_h));
        }
    }
    if moments.count() < 3 {
        for anchor in inputs.anchors {
            let x = match anchor.at {
                AnchorAt::Time(t) => vo_at(inputs.vo, t).map(|(x, _, _)| x),
                AnchorAt::VoPoint(x) => Some(x),
            };
            if let Some(x) = x {
                let _ = moments.push(&x, &anchor.enu, 1.0 / (anchor.sigma * anchor.sigma));
            }
        }
    }
    if moments.count() == 0 {
        return Err(SolveError::NothingToAnchorTo);
    }
    let mode = if gravity { AlignMode::YawScale } else { AlignMode::Sim3 };
    moments.align(mode).map_err(|e| SolveError::Degenerate(format!("{e:?} ({} positions)", moments.count())))
}

/// First positions of the keyframes: each from an alignment of the fixes within
/// ±[`LOCAL_WINDOW_S`] of it (recomputed every [`LOCAL_STEP_S`]), so that on a long drive
/// the VO's drift does not put the start hundreds of metres off; the whole-drive alignment
/// where a window has too few fixes or does not determine one.
pub(super) fn initial_positions(
    inputs: &Inputs<'_>,
    keyframe_vo: &[usize],
    global: &Sim3,
    gravity: bool,
) -> Vec<Vector3<f64>> {
    let pairs: Vec<(f64, Vector3<f64>, Vector3<f64>, f64)> = inputs
        .fixes
        .iter()
        .filter_map(|f| vo_at(inputs.vo, f.t).map(|(x, _, _)| (f.t, x, f.enu, 1.0 / (f.sigma_h * f.sigma_h))))
        .collect();
    let mode = if gravity { AlignMode::YawScale } else { AlignMode::Sim3 };
    let mut local: Option<(f64, Sim3)> = None;
    keyframe_vo
        .iter()
        .map(|&j| {
            let sample = &inputs.vo[j];
            if local.is_none_or(|(t, _)| (sample.t - t).abs() >= LOCAL_STEP_S) {
                let from = pairs.partition_point(|p| p.0 < sample.t - LOCAL_WINDOW_S);
                let to = pairs.partition_point(|p| p.0 <= sample.t + LOCAL_WINDOW_S);
                let mut moments = Moments::default();
                for (_, x, y, w) in &pairs[from..to] {
                    let _ = moments.push(x, y, *w);
                }
                let fit = if to - from >= 10 { moments.align(mode).ok() } else { None };
                local = Some((sample.t, fit.filter(Sim3::is_valid).unwrap_or(*global)));
            }
            local.map_or(*global, |(_, a)| a).transform_point(&sample.position)
        })
        .collect()
}
