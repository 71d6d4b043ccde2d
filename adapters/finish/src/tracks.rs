//! 3D tracks under the finished anchoring: each state re-expressed through the finished
//! ego pose of its frame, each moving track smoothed (RTS, constant velocity), each static
//! object merged to one pose.
//!
//! The device placed a detection through its online ego pose; what it saw relative to the
//! car is right, where the car was is what finishing corrects. So a state is taken back
//! into the ego's frame with the online pose and out again with the finished one (planar:
//! x, y, heading; the height above the ego's ground is kept).
//!
//! Each kept track states how far its place is in doubt (`TrackCovariance`): how far the
//! states it was made of spread around the places it kept. They were each placed through the ego
//! of their own frame, so the spread is that of the object's place relative to the ego —
//! what a verdict holds against a clearance ([`dash2sim_verify::replay_in_doubt`]).

use std::collections::BTreeMap;

use dash2sim_core::binlog::{quantise, Track3d, TrackCovariance, Tracks3d, MAX_TRACKS};
use dash2sim_core::ekf::{rts_smooth, Kalman, SmoothStep};
use dash2sim_core::nalgebra::{Matrix1, Matrix1x2, Matrix1x4, Matrix2, Matrix2x4, Matrix4, Vector1, Vector2, Vector4};
use dash2sim_core::track3d::wrap_angle;
use std::f64::consts::{FRAC_PI_2, PI};

/// A planar ego pose with its height: x, y, z (m), heading (rad).
pub type EgoAt = [f64; 4];

/// Position noise of a re-expressed state for the smoother, m.
const MEASUREMENT_SIGMA_M: f64 = 0.3;
/// Acceleration noise of the constant-velocity model, m/s².
const ACCELERATION_SIGMA: f64 = 2.0;

/// What happened to the tracks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TrackStats {
    /// Track states in.
    pub states: usize,
    /// States whose frame had no online or no finished ego pose (dropped).
    pub unplaced: usize,
    /// Moving tracks smoothed.
    pub smoothed: usize,
    /// Static objects merged to one pose.
    pub merged_static: usize,
    /// Tracks dropped as ghosts: fewer than [`MIN_SUPPORT`] states.
    pub ghosts: usize,
}

/// A track with fewer states than this is not kept: the tracker confirms a track after
/// three hits (`min_hits`), but reports every new one in the first frames it sees, so a single
/// false detection at the start of a drive (or of a re-initialised VO session) becomes a
/// one-state track — and a drum in the lane for the score.
pub const MIN_SUPPORT: usize = 3;

/// The tracks `finish` keeps.
#[derive(Clone, Debug, Default)]
pub struct FinishedTracks {
    /// Their states, by time.
    pub batches: Vec<Tracks3d>,
    /// The covariance of each one's place (how far its states spread around it).
    pub covariances: Vec<TrackCovariance>,
    /// What happened to them.
    pub stats: TrackStats,
}

/// Re-express, smooth and merge. `online` and `finished` give the ego at a time (µs).
pub fn finish_tracks(
    batches: &[Tracks3d],
    online: &impl Fn(i64) -> Option<EgoAt>,
    finished: &impl Fn(i64) -> Option<EgoAt>,
) -> FinishedTracks {
    let mut stats = TrackStats::default();
    let mut by_id: BTreeMap<i64, Vec<(i64, Track3d)>> = BTreeMap::new();
    for batch in batches {
        for track in &batch.tracks {
            stats.states += 1;
            match (online(batch.t_us), finished(batch.t_us)) {
                (Some(a), Some(b)) => by_id.entry(track.id).or_default().push((batch.t_us, reexpress(track, &a, &b))),
                _ => stats.unplaced += 1,
            }
        }
    }
    let mut by_time: BTreeMap<i64, Vec<Track3d>> = BTreeMap::new();
    by_id.retain(|_, states| {
        let kept = states.len() >= MIN_SUPPORT;
        stats.ghosts += usize::from(!kept);
        kept
    });
    let mut covariances = Vec::with_capacity(by_id.len());
    for (id, states) in by_id.iter_mut() {
        states.sort_by_key(|s| s.0);
        let placed: Vec<(i64, i64)> = states.iter().map(|(_, s)| (s.x_mm, s.y_mm)).collect();
        let statics = states.iter().filter(|(_, s)| s.is_static == 1).count();
        if 2 * statics > states.len() {
            merge_static(states);
            stats.merged_static += 1;
        } else if states.len() >= 2 {
            smooth(states);
            stats.smoothed += 1;
        }
        let t_us = states.first().map_or(0, |s| s.0);
        let [xx, xy, yy] = spread_around(&placed, states);
        covariances.push(TrackCovariance {
            t_us,
            id: *id,
            cov_xx_mm2: quantise(xx, 1e-6),
            cov_xy_mm2: quantise(xy, 1e-6),
            cov_yy_mm2: quantise(yy, 1e-6),
        });
        for (t, s) in states.iter() {
            by_time.entry(*t).or_default().push(*s);
        }
    }
    let mut out = Vec::new();
    for (t_us, tracks) in by_time {
        for chunk in tracks.chunks(MAX_TRACKS) {
            let mut batch = Tracks3d { t_us, ..Tracks3d::default() };
            for t in chunk {
                let _ = batch.tracks.push(*t);
            }
            out.push(batch);
        }
    }
    FinishedTracks { batches: out, covariances, stats }
}

/// How far a track's states (`placed`, mm, as they came) spread around the places it kept
/// (`kept`, in the same order): the second moments of their differences east and north
/// (m²: xx, xy, yy), leaving out the few beyond three times their median distance — a state
/// the tracker placed wildly would otherwise make the whole track uncertain.
///
/// The states are the device tracker's filtered ones, so they are not independent: the
/// spread is not divided by their number — it is the doubt of one state, which the place
/// kept shares (their errors are alike from one frame to the next).
fn spread_around(placed: &[(i64, i64)], kept: &[(i64, Track3d)]) -> [f64; 3] {
    let d: Vec<(f64, f64)> = placed
        .iter()
        .zip(kept)
        .map(|(p, (_, k))| ((p.0 - k.x_mm) as f64 * 1e-3, (p.1 - k.y_mm) as f64 * 1e-3))
        .collect();
    let within = 3e-3 * median(d.iter().map(|(x, y)| (x.hypot(*y) * 1e3).round() as i64).collect()) as f64;
    let kept: Vec<&(f64, f64)> = d.iter().filter(|(x, y)| x.hypot(*y) <= within).collect();
    let n = kept.len().max(1) as f64;
    let moment = |f: fn(&(f64, f64)) -> f64| kept.iter().map(|d| f(d)).sum::<f64>() / n;
    [moment(|d| d.0 * d.0), moment(|d| d.0 * d.1), moment(|d| d.1 * d.1)]
}

/// The ego pose that, with a mount turned by `delta` more about the vertical (rad; about
/// the camera at `camera`, forward and left in the body frame, m), places every state where
/// `ego` with the old mount placed it.
///
/// The device placed each detection through the mount it had then (`MountEstimate`); the
/// finished ego goes with the mount `finish` calibrated over the whole drive. Taken back
/// through this pose instead of the device's, a state comes out through the finished ego
/// as the finished mount would have placed it — a body-frame point p goes to
/// c + R(δ)(p − c), which is the ego turned by −δ and moved by −R(h)(R(−δ)c − c).
pub fn as_if_mounted(ego: &EgoAt, camera: [f64; 2], delta: f64) -> EgoAt {
    let (sd, cd) = (-delta).sin_cos();
    let shift = [cd * camera[0] - sd * camera[1] - camera[0], sd * camera[0] + cd * camera[1] - camera[1]];
    let (sh, ch) = ego[3].sin_cos();
    [ego[0] - (ch * shift[0] - sh * shift[1]), ego[1] - (sh * shift[0] + ch * shift[1]), ego[2], ego[3] - delta]
}

/// Static tracks needed before their stillness speaks for the camera's yaw.
pub const MIN_STATIC_TRACKS: usize = 3;
/// The states each of them needs (seen from ranges far enough apart that a turn moves
/// them).
pub const MIN_STATIC_STATES: usize = 5;
/// The turns tried, rad: ±3° (a dead-reckoned camera's yaw on the car is known to a
/// degree or two) in steps of 0.02°.
const STATIC_YAW_RANGE_RAD: f64 = 3.0 * PI / 180.0;
const STATIC_YAW_STEP_RAD: f64 = 0.02 * PI / 180.0;

/// How much further the camera looks to the left (rad) than the mount that placed the
/// states says, from the objects that stand still: a camera turned by δ off the mount puts
/// an object at range r by r·δ aside, and as the car closes in the object slides — a cone
/// seen from 40 m and from 5 m moves 0.6 m per degree. The turn that holds the static
/// tracks' states closest together (the sum of their distances from each track's median)
/// is the camera's. `online(t, δ)` is the device's ego at `t` as if its mount had been
/// turned by δ ([`as_if_mounted`]); `None` when fewer than [`MIN_STATIC_TRACKS`] static
/// tracks were seen [`MIN_STATIC_STATES`] times.
pub fn static_yaw(
    batches: &[Tracks3d],
    online: &impl Fn(i64, f64) -> Option<EgoAt>,
    finished: &impl Fn(i64) -> Option<EgoAt>,
) -> Option<f64> {
    let mut by_id: BTreeMap<i64, Vec<(i64, Track3d, EgoAt)>> = BTreeMap::new();
    for batch in batches {
        let Some(b) = finished(batch.t_us) else { continue };
        for track in &batch.tracks {
            by_id.entry(track.id).or_default().push((batch.t_us, *track, b));
        }
    }
    let statics: Vec<Vec<(i64, Track3d, EgoAt)>> = by_id
        .into_values()
        .filter(|states| {
            let still = states.iter().filter(|(_, s, _)| s.is_static == 1).count();
            states.len() >= MIN_STATIC_STATES && 2 * still > states.len()
        })
        .collect();
    if statics.len() < MIN_STATIC_TRACKS {
        return None;
    }
    let spread = |delta: f64| -> f64 {
        let mut total = 0.0;
        for states in &statics {
            let placed: Vec<(f64, f64)> = states
                .iter()
                .filter_map(|(t, s, b)| online(*t, delta).map(|a| reexpress(s, &a, b)))
                .map(|s| (s.x_mm as f64 * 1e-3, s.y_mm as f64 * 1e-3))
                .collect();
            if placed.is_empty() {
                continue;
            }
            let (mx, my) = (
                super::median(placed.iter().map(|p| p.0).collect()),
                super::median(placed.iter().map(|p| p.1).collect()),
            );
            total += placed.iter().map(|(x, y)| (x - mx).hypot(y - my)).sum::<f64>();
        }
        total
    };
    let steps = (STATIC_YAW_RANGE_RAD / STATIC_YAW_STEP_RAD).round() as i64;
    (-steps..=steps)
        .map(|k| k as f64 * STATIC_YAW_STEP_RAD)
        .map(|delta| (spread(delta), delta))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, delta)| delta)
}

/// A state placed through the online ego `a`, placed again through the finished ego `b`.
fn reexpress(t: &Track3d, a: &EgoAt, b: &EgoAt) -> Track3d {
    let (x, y) = (t.x_mm as f64 * 1e-3, t.y_mm as f64 * 1e-3);
    let (sa, ca) = a[3].sin_cos();
    let (dx, dy) = (x - a[0], y - a[1]);
    let (fx, fy) = (ca * dx + sa * dy, -sa * dx + ca * dy);
    let turn = b[3] - a[3];
    let (sb, cb) = b[3].sin_cos();
    let (st, ct) = turn.sin_cos();
    let (vx, vy) = (t.vx_mm_s as f64 * 1e-3, t.vy_mm_s as f64 * 1e-3);
    Track3d {
        x_mm: quantise(b[0] + cb * fx - sb * fy, 1e-3),
        y_mm: quantise(b[1] + sb * fx + cb * fy, 1e-3),
        z_mm: quantise(t.z_mm as f64 * 1e-3 - a[2] + b[2], 1e-3),
        yaw_e4: quantise(wrap_angle(t.yaw_e4 as f64 * 1e-4 + turn), 1e-4),
        vx_mm_s: quantise(ct * vx - st * vy, 1e-3),
        vy_mm_s: quantise(st * vx + ct * vy, 1e-3),
        ..*t
    }
}

fn median(mut v: Vec<i64>) -> i64 {
    v.sort_unstable();
    v.get(v.len() / 2).copied().unwrap_or(0)
}

/// One pose for the whole track: the median position and size, the circular mean heading.
fn merge_static(states: &mut [(i64, Track3d)]) {
    let pick = |f: fn(&Track3d) -> i64| median(states.iter().map(|(_, s)| f(s)).collect());
    let (sin, cos) = states.iter().fold((0.0, 0.0), |(s, c), (_, t)| {
        let (a, b) = (t.yaw_e4 as f64 * 1e-4).sin_cos();
        (s + a, c + b)
    });
    let merged = Track3d {
        x_mm: pick(|s| s.x_mm),
        y_mm: pick(|s| s.y_mm),
        z_mm: pick(|s| s.z_mm),
        l_mm: pick(|s| s.l_mm),
        w_mm: pick(|s| s.w_mm),
        h_mm: pick(|s| s.h_mm),
        yaw_e4: quantise(f64::atan2(sin, cos), 1e-4),
        vx_mm_s: 0,
        vy_mm_s: 0,
        is_static: 1,
        ..states[0].1
    };
    for (_, s) in states.iter_mut() {
        *s = Track3d { class: s.class, ..merged };
    }
}

/// Constant-velocity smoothing of a track's positions and velocities, and the heading of a
/// moving one (see [`heading_of_motion`]).
fn smooth(states: &mut [(i64, Track3d)]) {
    let first = &states[0].1;
    let velocity = (first.vx_mm_s as f64 * 1e-3, first.vy_mm_s as f64 * 1e-3);
    let mut samples: Vec<Sample> = states
        .iter()
        .map(|(t, s)| Sample {
            t: *t as f64 * 1e-6,
            x: s.x_mm as f64 * 1e-3,
            y: s.y_mm as f64 * 1e-3,
            ..Sample::default()
        })
        .collect();
    smooth_planar(&mut samples, velocity, MEASUREMENT_SIGMA_M, ACCELERATION_SIGMA);
    let headings = heading_of_motion(states, &samples);
    for (((_, s), p), heading) in states.iter_mut().zip(&samples).zip(headings) {
        s.x_mm = quantise(p.x, 1e-3);
        s.y_mm = quantise(p.y, 1e-3);
        s.vx_mm_s = quantise(p.vx, 1e-3);
        s.vy_mm_s = quantise(p.vy, 1e-3);
        if let Some(yaw) = heading {
            s.yaw_e4 = quantise(yaw, 1e-4);
        }
    }
}

/// The heading each state of a moving track reports (`None`: keep the box's), from its box's
/// yaw and the direction of its smoothed motion.
///
/// A box's front is ambiguous to the detector (it flips some), a moving one's is where it
/// goes; and nuPlan, like `verify`, projects an agent along its box heading, so a flipped car
/// would be projected into oncoming traffic — the yaw is first turned by π where it points
/// against the motion. A detector's yaw also jitters by a few degrees from frame to frame,
/// enough to project an oncoming car across the centre line within the time-to-collision
/// horizon; so the yaws are smoothed (RTS, constant yaw rate) and then fused with the
/// smoothed velocity's direction by their variances — a car moves along its axis, so the
/// direction of its motion (known to σ_across / speed) measures the same angle. The box
/// yaw's variance is not assumed: it is the track's own mean squared difference between the
/// two (which also takes in the slip of a turning car's centre).
fn heading_of_motion(states: &[(i64, Track3d)], samples: &[Sample]) -> Vec<Option<f64>> {
    let mut previous: Option<f64> = None;
    let along: Vec<Option<(f64, f64)>> = states
        .iter()
        .zip(samples)
        .map(|((_, s), p)| {
            if p.vx.hypot(p.vy) <= FRONT_FROM_MOTION_MPS {
                return None;
            }
            let motion = p.vy.atan2(p.vx);
            let yaw = s.yaw_e4 as f64 * 1e-4;
            let yaw = if wrap_angle(yaw - motion).abs() > FRAC_PI_2 { wrap_angle(yaw + PI) } else { yaw };
            // Unwrapped along the track, for the smoother.
            let yaw = previous.map_or(yaw, |last| last + wrap_angle(yaw - last));
            previous = Some(yaw);
            Some((yaw, motion))
        })
        .collect();
    let residuals: Vec<f64> = along.iter().flatten().map(|(yaw, motion)| wrap_angle(yaw - motion).powi(2)).collect();
    if residuals.len() < MIN_HEADING_PAIRS {
        return along.iter().map(|pair| pair.map(|(yaw, _)| wrap_angle(yaw))).collect();
    }
    // Floored at the log's quantisation of a yaw (1e-4 rad, uniform): a detector that
    // agrees with the motion to the last digit still leaves the filter something to weigh.
    let yaw_var = (residuals.iter().sum::<f64>() / residuals.len() as f64).max(1e-8 / 12.0);
    let moving: Vec<(f64, f64)> =
        along.iter().zip(samples).filter_map(|(pair, p)| pair.map(|(yaw, _)| (p.t, yaw))).collect();
    let mut smoothed = smooth_yaw(&moving, yaw_var).into_iter();
    along
        .iter()
        .zip(samples)
        .map(|(pair, p)| {
            let (_, motion) = (*pair)?;
            let (yaw, var) = smoothed.next()?;
            let weight = var / (var + p.heading_var);
            Some(wrap_angle(if weight.is_finite() { yaw + weight * wrap_angle(motion - yaw) } else { yaw }))
        })
        .collect()
}

/// Yaw acceleration noise of the constant-yaw-rate model a track's yaw is smoothed with,
/// rad/s² per √s: a car's yaw rate changes by a few tenths of a rad/s within a second.
const YAW_ACCELERATION_SIGMA: f64 = 1.0;

/// `(t, unwrapped yaw)` measured with variance `yaw_var`, smoothed (constant yaw rate, RTS):
/// each yaw with its smoothed variance.
fn smooth_yaw(samples: &[(f64, f64)], yaw_var: f64) -> Vec<(f64, f64)> {
    let Some(&(t0, yaw0)) = samples.first() else { return Vec::new() };
    let h = Matrix1x2::new(1.0, 0.0);
    let r = Matrix1::new(yaw_var);
    let mut kf = Kalman::new(Vector2::new(yaw0, 0.0), Matrix2::new(yaw_var, 0.0, 0.0, 1.0));
    let q2 = YAW_ACCELERATION_SIGMA * YAW_ACCELERATION_SIGMA;
    let mut previous = t0;
    let mut steps = Vec::with_capacity(samples.len());
    for (k, &(t, yaw)) in samples.iter().enumerate() {
        let dt = t - previous;
        previous = t;
        let f = Matrix2::new(1.0, dt, 0.0, 1.0);
        let q = Matrix2::new(dt.powi(3) / 3.0, dt * dt / 2.0, dt * dt / 2.0, dt) * q2;
        if k > 0 {
            kf.predict(&f, &q);
        }
        // A refused update (not finite) leaves the prediction: the smoother bridges it.
        let _ = kf.update(&Vector1::new(yaw), &h, &r);
        steps.push(SmoothStep { f, q, ..SmoothStep::filtered(&kf) });
    }
    rts_smooth(&mut steps);
    steps.iter().map(|s| (s.x[0], s.p[(0, 0)])).collect()
}

/// Moving states a track needs before its box yaw's variance is estimated and the heading
/// fused; fewer, and the (flip-corrected) box yaw is kept.
const MIN_HEADING_PAIRS: usize = 5;

/// Above this speed a smoothed track's heading is turned to face its motion, m/s.
const FRONT_FROM_MOTION_MPS: f64 = 2.0;

/// A planar position at a time, and the velocity the smoother gives it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// East, m.
    pub x: f64,
    /// North, m.
    pub y: f64,
    /// Velocity east, m/s (output).
    pub vx: f64,
    /// Velocity north, m/s (output).
    pub vy: f64,
    /// Variance of the velocity's direction, rad² (output): the smoothed velocity's variance
    /// across the motion over the speed squared (infinite when standing).
    pub heading_var: f64,
    /// A speed measured at `t` and its σ, m/s (input; the ego's wheels), if any.
    pub speed: Option<(f64, f64)>,
}

/// Below this speed (m/s) a measured speed is not used: the direction it would act along is
/// the smoother's velocity, which is not known when standing.
const SPEED_UPDATE_MIN_MPS: f64 = 1.0;

/// Constant-velocity Kalman filter over planar positions measured with `sigma_m`, white
/// acceleration of `acceleration_sigma` (m/s² per √s), then Rauch–Tung–Striebel; in place,
/// starting from `velocity`. A sample's measured speed, where it has one, updates the speed
/// along the current velocity (an extended update). Used for the tracks and for the
/// finished ego (whose positions carry the VO's frame-to-frame noise; its wheels' speeds
/// are far finer than speeds differenced from them).
pub fn smooth_planar(samples: &mut [Sample], velocity: (f64, f64), sigma_m: f64, acceleration_sigma: f64) {
    let Some(first) = samples.first() else { return };
    let h = Matrix2x4::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
    let r = Matrix2::identity() * sigma_m * sigma_m;
    let x0 = Vector4::new(first.x, first.y, velocity.0, velocity.1);
    let mut kf = Kalman::new(x0, Matrix4::from_diagonal(&Vector4::new(sigma_m * sigma_m, sigma_m * sigma_m, 4.0, 4.0)));
    let mut steps = Vec::with_capacity(samples.len());
    let mut previous = first.t;
    let q2 = acceleration_sigma * acceleration_sigma;
    for (k, s) in samples.iter().enumerate() {
        let dt = s.t - previous;
        previous = s.t;
        let mut f = Matrix4::identity();
        f[(0, 2)] = dt;
        f[(1, 3)] = dt;
        let (a, b, c) = (dt.powi(3) / 3.0 * q2, dt * dt / 2.0 * q2, dt * q2);
        let q = Matrix4::new(a, 0.0, b, 0.0, 0.0, a, 0.0, b, b, 0.0, c, 0.0, 0.0, b, 0.0, c);
        if k > 0 {
            kf.predict(&f, &q);
        }
        // A refused update (not finite) leaves the prediction: the smoother bridges it.
        let _ = kf.update(&Vector2::new(s.x, s.y), &h, &r);
        if let Some((speed, sigma)) = s.speed {
            let (vx, vy) = (kf.x[2], kf.x[3]);
            let predicted = vx.hypot(vy);
            if predicted > SPEED_UPDATE_MIN_MPS {
                let along = Matrix1x4::new(0.0, 0.0, vx / predicted, vy / predicted);
                let _ = kf.update_with(&Vector1::new(speed - predicted), &along, &Matrix1::new(sigma * sigma));
            }
        }
        steps.push(SmoothStep { f, q, ..SmoothStep::filtered(&kf) });
    }
    rts_smooth(&mut steps);
    for (s, step) in samples.iter_mut().zip(&steps) {
        (s.x, s.y, s.vx, s.vy) = (step.x[0], step.x[1], step.x[2], step.x[3]);
        let speed2 = s.vx * s.vx + s.vy * s.vy;
        let across = Vector2::new(-s.vy, s.vx);
        let p = step.p.fixed_view::<2, 2>(2, 2);
        s.heading_var =
            if speed2 > 0.0 { (across.transpose() * p * across)[0] / (speed2 * speed2) } else { f64::INFINITY };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(id: i64, x: f64, y: f64, is_static: i64) -> Track3d {
        Track3d {
            id,
            class: 3,
            x_mm: quantise(x, 1e-3),
            y_mm: quantise(y, 1e-3),
            l_mm: 500,
            w_mm: 500,
            h_mm: 700,
            is_static,
            ..Track3d::default()
        }
    }

    /// Drums 3–4 m either side of a road the car drives east along at 10 m/s, placed by a
    /// device whose camera looked 1.5° further left than its mount said, each seen from 50 m
    /// down to 5 m.
    fn drums_seen_turned(drums: &[(f64, f64)], turned: f64) -> Vec<Tracks3d> {
        let camera = [1.8, 0.0];
        let (s, c) = (-turned).sin_cos();
        (0..150)
            .map(|k| {
                let t_us = 100_000 * k;
                let ego_x = k as f64;
                let mut batch = Tracks3d { t_us, ..Tracks3d::default() };
                for (id, (x, y)) in drums.iter().enumerate() {
                    let (px, py) = (x - ego_x - camera[0], *y);
                    if (5.0..=50.0).contains(&px) {
                        // Where the device's mount put it: turned by −δ about the camera.
                        let placed = (ego_x + camera[0] + c * px - s * py, s * px + c * py);
                        let _ = batch.tracks.push(track(id as i64, placed.0, placed.1, 1));
                    }
                }
                batch
            })
            .collect()
    }

    #[test]
    fn the_camera_s_turn_is_the_one_that_holds_the_static_objects_still() {
        let camera = [1.8, 0.0];
        let ego = |t: i64| Some([t as f64 * 1e-5, 0.0, 0.0, 0.0]);
        let online = |t: i64, delta: f64| ego(t).map(|e| as_if_mounted(&e, camera, delta));
        let drums = [(60.0, 3.0), (80.0, -3.5), (100.0, 4.0), (120.0, -4.0)];
        let turned = 1.5f64.to_radians();
        let found = static_yaw(&drums_seen_turned(&drums, turned), &online, &ego).expect("four drums");
        assert!((found - turned).abs() < 0.05f64.to_radians(), "found {}°", found.to_degrees());
        // Placed through the found turn the drums stand where they are.
        let finished = finish_tracks(&drums_seen_turned(&drums, turned), &|t| online(t, found), &ego).batches;
        for state in finished.iter().flat_map(|b| &b.tracks) {
            let (x, y) = drums[state.id as usize];
            let off = (state.x_mm as f64 * 1e-3 - x).hypot(state.y_mm as f64 * 1e-3 - y);
            assert!(off < 0.05, "drum {} {off:.3} m off", state.id);
        }
        // Two drums say nothing: too few to tell a turn from where they stand.
        assert_eq!(static_yaw(&drums_seen_turned(&drums[..2], turned), &online, &ego), None);
    }

    #[test]
    fn measured_speeds_hold_a_noisy_track_s_speed_to_the_wheels_to_its_ends() {
        // 10 m/s east; positions 5 cm off, alternately ahead and behind.
        let noisy = |with_speed: bool| -> Vec<Sample> {
            let mut samples: Vec<Sample> = (0..100)
                .map(|k| Sample {
                    t: 0.1 * k as f64,
                    x: k as f64 + if k % 2 == 0 { 0.05 } else { -0.05 },
                    speed: with_speed.then_some((10.0, 0.1)),
                    ..Sample::default()
                })
                .collect();
            smooth_planar(&mut samples, (10.0, 0.0), 0.05, 0.5);
            samples
        };
        let worst = |samples: &[Sample]| samples.iter().map(|s| (s.vx.hypot(s.vy) - 10.0).abs()).fold(0.0, f64::max);
        let (aided, alone) = (worst(&noisy(true)), worst(&noisy(false)));
        assert!(aided < 0.05, "with the wheels the speed is off by {aided:.3} m/s at worst");
        assert!(alone > 2.0 * aided, "the positions alone: {alone:.3} m/s, with the wheels {aided:.3}");
    }

    #[test]
    fn a_state_follows_the_ego_from_the_online_to_the_finished_pose() {
        // Online ego at the origin heading east sees a cone 10 m ahead; the finished ego is
        // at (5, 5) heading north: the cone is 10 m north of it.
        let t = track(1, 10.0, 0.0, 1);
        let moved = reexpress(&t, &[0.0, 0.0, 0.0, 0.0], &[5.0, 5.0, 1.0, FRAC_PI_2]);
        assert_eq!((moved.x_mm, moved.y_mm, moved.z_mm), (5000, 15000, 1000));
        assert_eq!(moved.yaw_e4, quantise(FRAC_PI_2, 1e-4));
    }

    #[test]
    fn a_state_the_device_placed_with_its_mount_moves_with_the_finished_one() {
        // The camera 1.8 m ahead of the rear axle saw a cone 10 m ahead of it; the device's
        // mount had the camera straight, the finished one has it turned 2° to the left: the
        // cone is 10 m along that direction from the camera, the ego unmoved.
        let delta = 2f64.to_radians();
        let ego = [3.0, -4.0, 0.5, 0.7];
        let t = track(1, 3.0 + 11.8 * 0.7f64.cos(), -4.0 + 11.8 * 0.7f64.sin(), 1);
        let moved = reexpress(&t, &as_if_mounted(&ego, [1.8, 0.0], delta), &ego);
        let (h, c) = (0.7 + delta, [3.0 + 1.8 * 0.7f64.cos(), -4.0 + 1.8 * 0.7f64.sin()]);
        assert!((moved.x_mm as f64 * 1e-3 - (c[0] + 10.0 * h.cos())).abs() < 2e-3, "{moved:?}");
        assert!((moved.y_mm as f64 * 1e-3 - (c[1] + 10.0 * h.sin())).abs() < 2e-3, "{moved:?}");
        assert_eq!(moved.yaw_e4, quantise(delta, 1e-4));
        assert_eq!(as_if_mounted(&ego, [1.8, 0.0], 0.0), ego);
    }

    #[test]
    fn a_static_object_becomes_one_pose_and_a_moving_one_is_smoothed() {
        let mut batches = Vec::new();
        for k in 0..50 {
            let jitter = if k % 2 == 0 { 0.2 } else { -0.2 };
            let mut b = Tracks3d { t_us: k * 100_000, ..Tracks3d::default() };
            // Static: 19.8, 20.0 or 20.2 m, and once a 5 m outlier.
            let cone_x = if k == 10 { 25.0 } else { 20.0 + 0.2 * ((k % 3) as f64 - 1.0) };
            let _ = b.tracks.push(track(1, cone_x, 3.0, 1));
            let _ = b.tracks.push(track(2, k as f64 + jitter, 0.0, 0));
            // A ghost: a drum in the lane for two frames.
            if k < 2 {
                let _ = b.tracks.push(track(3, 8.0, 0.0, 1));
            }
            batches.push(b);
        }
        let same = |_t: i64| Some([0.0; 4]);
        let none_late = |t: i64| if t < 4_900_000 { Some([0.0; 4]) } else { None };
        let FinishedTracks { batches: out, covariances, stats } = finish_tracks(&batches, &same, &none_late);
        assert_eq!(stats, TrackStats { states: 102, unplaced: 2, smoothed: 1, merged_static: 1, ghosts: 1 });
        assert!(out.iter().all(|b| b.tracks.iter().all(|t| t.id != 3)), "the ghost is gone");
        let cones: Vec<&Track3d> = out.iter().flat_map(|b| b.tracks.iter()).filter(|t| t.id == 1).collect();
        assert_eq!(cones.len(), 49);
        assert!(cones.iter().all(|c| c == &cones[0]), "one pose");
        assert_eq!(cones[0].x_mm, 20_000, "the median, not moved by the outlier");
        // 33 of its 48 placed states (the outlier, 5 m off, left out) 0.2 m east or west of
        // it: east 0.04 m² × 33/48, nothing north.
        let covariance =
            |id: i64| covariances.iter().find(|c| c.id == id).map(|c| [c.cov_xx_mm2, c.cov_xy_mm2, c.cov_yy_mm2]);
        assert_eq!(covariance(1), Some([27_500, 0, 0]), "{covariances:?}");
        assert_eq!(covariance(3), None, "a ghost states nothing");
        // The moving track's states ±0.2 m east about its smoothed path: about 0.04 m².
        let moving = covariance(2).unwrap_or_default();
        assert!((30_000..=50_000).contains(&moving[0]) && moving[2] == 0, "{covariances:?}");
        assert_eq!(covariances.iter().find(|c| c.id == 2).map(|c| c.t_us), Some(0), "at its first state");
        let moving: Vec<f64> =
            out.iter().flat_map(|b| b.tracks.iter()).filter(|t| t.id == 2).map(|t| t.x_mm as f64 * 1e-3).collect();
        let error = |xs: &[f64]| {
            (xs.iter().enumerate().map(|(k, x)| (x - k as f64).powi(2)).sum::<f64>() / xs.len() as f64).sqrt()
        };
        let raw: Vec<f64> = (0..49).map(|k| k as f64 + if k % 2 == 0 { 0.2 } else { -0.2 }).collect();
        assert!(error(&moving) < 0.5 * error(&raw), "smoothed {} raw {}", error(&moving), error(&raw));
    }

    #[test]
    fn a_moving_box_faces_where_it_goes_and_a_slow_one_keeps_its_heading() {
        // A car at 10 m/s east whose box the detector reports facing west (π), and a
        // pedestrian-slow one (0.5 m/s) with the same flipped box.
        let mut batches = Vec::new();
        for k in 0..30 {
            let mut b = Tracks3d { t_us: k * 100_000, ..Tracks3d::default() };
            let flipped = quantise(PI, 1e-4);
            let _ = b.tracks.push(Track3d { yaw_e4: flipped, ..track(1, k as f64, 0.0, 0) });
            let _ = b.tracks.push(Track3d { yaw_e4: flipped, ..track(2, 0.05 * k as f64, 5.0, 0) });
            batches.push(b);
        }
        let same = |_t: i64| Some([0.0; 4]);
        let out = finish_tracks(&batches, &same, &same).batches;
        let yaw = |id: i64| -> Vec<f64> {
            out.iter().flat_map(|b| b.tracks.iter()).filter(|t| t.id == id).map(|t| t.yaw_e4 as f64 * 1e-4).collect()
        };
        assert!(yaw(1).iter().all(|y| y.abs() < 1e-3), "turned to face east: {:?}", yaw(1));
        assert!(yaw(2).iter().all(|y| (y.abs() - PI).abs() < 1e-3), "{:?}", yaw(2));
    }

    #[test]
    fn a_fast_cars_jittering_box_reports_the_heading_it_drives_along() {
        // A car at 15 m/s east whose box yaw the detector reports 0.04 rad off, alternately
        // to either side, and once 0.06 rad off: projected 1 s ahead, 0.06 rad puts it
        // almost a metre across.
        let raw = |k: i64| {
            if k == 15 {
                0.06
            } else if k % 2 == 0 {
                0.04
            } else {
                -0.04
            }
        };
        let batches: Vec<Tracks3d> = (0..30)
            .map(|k| {
                let mut b = Tracks3d { t_us: k * 100_000, ..Tracks3d::default() };
                let _ = b.tracks.push(Track3d { yaw_e4: quantise(raw(k), 1e-4), ..track(1, 1.5 * k as f64, 0.0, 0) });
                b
            })
            .collect();
        let same = |_t: i64| Some([0.0; 4]);
        let out = finish_tracks(&batches, &same, &same).batches;
        let yaws: Vec<f64> = out.iter().flat_map(|b| b.tracks.iter()).map(|t| t.yaw_e4 as f64 * 1e-4).collect();
        assert_eq!(yaws.len(), 30);
        // The raw boxes: 0.041 rad RMS, 0.06 at worst.
        let rms = (yaws.iter().map(|y| y * y).sum::<f64>() / 30.0).sqrt();
        assert!(rms < 0.01 && yaws.iter().all(|y| y.abs() < 0.025), "RMS {rms}: {yaws:?}");
    }
}
