//! Dead-reckoned poses redone with what the whole drive shows: the gyro's final bias and
//! the road's heights.
//!
//! Under gyro + wheels the device made each pose with the gyro bias it knew then. Until the
//! GNSS course has measured it, that bias is wrong — comma's EON's is −0.068 rad/s, 4° of
//! heading a second — and the heading turns with the error: the first seconds of the
//! trajectory bend. The log keeps the bias as it was found (`ImuEstimate`, about once a
//! second); the heading a pose was made with differs from the one the final bias gives by
//! δψ(t) = ∫ (b(t′) − b_final) dt′ about the vertical. Each step of the trajectory is turned
//! by its δψ and the positions re-accumulated, each camera turned with it; finishing then
//! anchors the trajectory the device would have made had it known the bias from the start.
//!
//! The device reckons on the level: its poses say nothing of height, and a drive's road
//! climbs and falls by metres (comma2k19's minute: ±8 m), which the solve, whose similarity
//! only turns about the vertical, cannot bend a flat track into. The poses keep the body's
//! attitude, whose pitch is the road's grade — plus a constant offset: the camera's tilt on
//! the car, the sensor's on the camera and the accelerometer's bias along the direction of
//! travel (comma's EON: 4.4°, 8 % of grade, 70 m of height over the minute's kilometre, of
//! which 3.8° is the camera looking below the road). Integrated
//! along the horizontal distance travelled the grade gives each pose's height; the offset
//! is the one slope per distance that brings those heights onto the fixes' heights, every
//! session with its own level ([`with_grade`]). The cameras keep the offset: they do look
//! that far off the road.
//!
//! The device finds the sensor's yaw on the car (the car's forward axis) only once the car
//! has braked and sped up, and turns its cameras by it from then on; the ones before are
//! turned by what it knew last ([`with_final_forward_axis`]), the tilt by the horizontal
//! bias it knew last ([`with_final_tilt_bias`]).

use dash2sim_core::nalgebra::{Matrix3, Rotation3, Vector3};

use dash2sim_core::imu::attitude::{
    SETTLING_S, SETTLING_TIME_CONSTANT_S, TILT_BIAS_TIME_CONSTANT_S, TILT_TIME_CONSTANT_S,
};
use dash2sim_core::sim3::rotation_z;
use dash2sim_core::track3d::wrap_angle;

use super::solve::{Fix, VoSample};

/// A camera this close to its track's direction at the end (rad) is taken as one whose
/// device never found the car's forward axis: the camera and the track are then the same
/// axis turned by the mount, to the poses' rounding (1e-4 rad).
const FORWARD_AXIS_UNKNOWN_RAD: f64 = 1e-3;
/// The road between two fixes over which their heights measure a grade, m: over less
/// the fixes' height error (a metre or two, correlated for tens of seconds) outweighs it.
pub const GRADE_BASELINE_M: f64 = 200.0;
/// Pairs of fixes that measure the pitch offset before it is taken out: fewer, and the
/// poses are left level.
pub const MIN_GRADE_PAIRS: usize = 10;
/// Fixes whose vertical σ is larger than this (m) say nothing of height (a 2D fix's height
/// is a guess).
const MAX_HEIGHT_SIGMA_M: f64 = 50.0;
/// How far a dead-reckoned path's rise may stray from its attitude's grade per metre
/// travelled (1-σ): the solve leaves the height to the fixes where they disagree by more.
/// Once the attitude has settled its pitch is off by the sensor's noise, tenths of a
/// degree; before, see [`SETTLING_GRADE_SIGMA`].
pub const RECKONED_GRADE_SIGMA: f64 = 0.03;
/// What the grade's σ adds when the attitude has just levelled, decaying with the time
/// constant in which the core finds the gyro's horizontal bias
/// ([`TILT_BIAS_TIME_CONSTANT_S`]): until then the tilt is off by that bias times the
/// tilt's time constant, up to 0.07 rad for a consumer MEMS gyro's ±2°/s turn-on bias.
/// Without it the first seconds' heights were lifted by the early grade against the fixes
/// (comma2k19's minute: 3.9 m at the start, 1.44 m RMS vertical over the minute, 1.31 m
/// with it).
pub const SETTLING_GRADE_SIGMA: f64 = 0.1;

/// The gyro's bias about the vertical as the device found it: (time s, rad/s), in time
/// order.
pub type BiasHistory = [(f64, f64)];

/// A dead-reckoned sample already redone: its time and session, its position as logged and
/// as corrected, and its heading correction δψ (rad).
#[derive(Clone, Copy)]
struct Redone {
    t: f64,
    session: u32,
    logged: Vector3<f64>,
    corrected: Vector3<f64>,
    delta: f64,
}

/// The bias at `t`: linear between the records, the nearest one's outside them.
fn bias_at(history: &BiasHistory, t: f64) -> Option<f64> {
    let k = history.partition_point(|(ts, _)| *ts <= t);
    match (k.checked_sub(1).and_then(|i| history.get(i)), history.get(k)) {
        (Some(&(t0, b0)), Some(&(t1, b1))) if t1 > t0 => Some(b0 + (b1 - b0) * (t - t0) / (t1 - t0)),
        (Some(&(_, b)), _) | (None, Some(&(_, b))) => Some(b),
        (None, None) => None,
    }
}

/// Redo the dead-reckoned samples of `vo` (those marked `reckoned`; the others, a
/// camera's VO, are left alone) with the last bias of `history`. Returns the
/// largest heading correction made, rad (0 with no history).
pub fn with_final_bias(vo: &mut [VoSample], history: &BiasHistory) -> f64 {
    let Some(&(_, final_bias)) = history.last() else { return 0.0 };
    let mut largest = 0.0f64;
    let mut previous: Option<Redone> = None;
    for sample in vo.iter_mut() {
        if !sample.reckoned {
            previous = None;
            continue;
        }
        let logged = sample.position;
        let (position, delta) = match previous.filter(|p| p.session == sample.session) {
            None => (logged, 0.0),
            Some(p) => {
                let (b0, b1) = (bias_at(history, p.t), bias_at(history, sample.t));
                let rate = |b: Option<f64>| b.map_or(0.0, |b| b - final_bias);
                let delta = p.delta + 0.5 * (rate(b0) + rate(b1)) * (sample.t - p.t);
                let step = rotation_z(0.5 * (p.delta + delta)) * (logged - p.logged);
                (p.corrected + step, delta)
            }
        };
        sample.position = position;
        sample.rotation = rotation_z(delta) * sample.rotation;
        largest = largest.max(delta.abs());
        previous = Some(Redone { t: sample.t, session: sample.session, logged, corrected: position, delta });
    }
    largest
}

/// The attitude's tilt error, rad about the body's forward and left axes, carried from
/// `from` to `to` (s) with the rate error `u(t)` = b_final − b(t): e′ = u − e/τ, τ the
/// device's while it settles ([`SETTLING_TIME_CONSTANT_S`] for [`SETTLING_S`] after
/// `levelled`) and [`TILT_TIME_CONSTANT_S`] after; steps of at most 0.05 s.
fn carry_tilt_error(
    mut error: Vector3<f64>,
    (from, to): (f64, f64),
    levelled: f64,
    u: impl Fn(f64) -> Vector3<f64>,
) -> Vector3<f64> {
    const STEP_S: f64 = 0.05;
    let steps = ((to - from) / STEP_S).ceil().clamp(0.0, 1e6) as usize;
    for k in 0..steps {
        let (t0, t1) =
            (from + (to - from) * k as f64 / steps as f64, from + (to - from) * (k + 1) as f64 / steps as f64);
        let tau = if t0 < levelled + SETTLING_S { SETTLING_TIME_CONSTANT_S } else { TILT_TIME_CONSTANT_S };
        let decay = (-(t1 - t0) / tau).exp();
        error = error * decay + u(0.5 * (t0 + t1)) * (tau * (1.0 - decay));
    }
    error
}

/// Turn the dead-reckoned samples of `vo` by the tilt their attitude had from the
/// horizontal gyro bias it did not yet know: `x` and `y` are the bias about the body's
/// forward and left axes as the device logged it (rad/s; its first record is where the
/// attitude was levelled). Returns the largest correction, rad.
///
/// The attitude follows gravity; a rate error u = b_final − b(t) tilts it at u while
/// gravity pulls it back with the attitude's time constant τ, so its error obeys
/// e′ = u − e/τ, from 0 where it was levelled (`carry_tilt_error`). On comma's EON, whose
/// bias about the left axis is 2°/s and took the device 18 s to find, this is the pitch
/// error of 4–5° eight seconds in.
pub fn with_final_tilt_bias(
    vo: &mut [VoSample],
    x: &BiasHistory,
    y: &BiasHistory,
    camera_to_body: &Matrix3<f64>,
) -> f64 {
    let (Some(&(levelled, _)), Some(&(_, final_x)), Some(&(_, final_y))) = (x.first(), x.last(), y.last()) else {
        return 0.0;
    };
    let u = |t: f64| {
        let rate = |history: &BiasHistory, last: f64| bias_at(history, t).map_or(0.0, |b| last - b);
        Vector3::new(rate(x, final_x), rate(y, final_y), 0.0)
    };
    let mut largest = 0.0f64;
    for run in runs(vo) {
        let mut error = carry_tilt_error(Vector3::zeros(), (levelled, vo[run.start].t), levelled, u);
        for i in run.clone() {
            if i > run.start {
                error = carry_tilt_error(error, (vo[i - 1].t, vo[i].t), levelled, u);
            }
            let turn = Rotation3::new(-error).into_inner();
            vo[i].rotation = vo[i].rotation * camera_to_body.transpose() * turn * camera_to_body;
            largest = largest.max(error.norm());
        }
    }
    largest
}

/// Sample `i`'s camera's yaw away from the direction its track moves in there, rad: 0
/// while the device did not know the car's forward axis (it reckons along the sensor's),
/// −δ once it did (the camera turned by the sensor's yaw δ on the car); `None` where the
/// track does not move. The direction is the chord between the samples either side of it
/// (one side at a run's ends): a tangent to second order on a bend, and made of positions
/// only, so a camera turned between two samples does not blur it.
fn yaw_off_track(run: &[VoSample], i: usize, camera_to_body: &Matrix3<f64>) -> Option<f64> {
    let (before, after) = (run.get(i.saturating_sub(1))?, run.get((i + 1).min(run.len() - 1))?);
    let step = (after.position - before.position).xy();
    let forward = (run.get(i)?.rotation * camera_to_body.transpose()).column(0).into_owned();
    (step.norm() > 0.1 && forward.xy().norm() > 0.5)
        .then(|| wrap_angle(forward.y.atan2(forward.x) - step.y.atan2(step.x)))
}

/// Turn every dead-reckoned camera of `vo` by the sensor's yaw on the car as the device
/// knew it last (the car's forward axis, `imu::forward`: found only once the car has braked
/// and sped up, 34 s into the sweep's drives). The device turned its cameras from then on;
/// the ones before point along the sensor's axis, and the detections they place, and the
/// mount the whole drive calibrates, are off by that yaw. Returns the yaw taken (−δ, rad),
/// `None` when the device never found it.
pub fn with_final_forward_axis(vo: &mut [VoSample], camera_to_body: &Matrix3<f64>) -> Option<f64> {
    let runs = runs(vo);
    let last = runs.iter().rev().find_map(|run| {
        let samples = &vo[run.clone()];
        (0..samples.len()).rev().find_map(|i| yaw_off_track(samples, i, camera_to_body))
    })?;
    if last.abs() < FORWARD_AXIS_UNKNOWN_RAD {
        return None;
    }
    for run in runs {
        let offs: Vec<Option<f64>> =
            (0..run.len()).map(|i| yaw_off_track(&vo[run.clone()], i, camera_to_body)).collect();
        let mut off = 0.0;
        for (sample, known) in vo[run].iter_mut().zip(offs) {
            off = known.unwrap_or(off);
            let turn = if off.abs() < FORWARD_AXIS_UNKNOWN_RAD { last } else { last - off };
            sample.rotation = rotation_z(turn) * sample.rotation;
        }
    }
    Some(last)
}

/// What [`with_grade`] found: the pitch offset it took out, and over how much road.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grade {
    /// The sensor's pitch above the road's grade, rad (nose up positive): its tilt on the
    /// camera and the accelerometer's forward bias together.
    pub pitch_offset: f64,
    /// The dead-reckoned distance with fixes beside it, m.
    pub baseline_m: f64,
}

/// A run of dead-reckoned samples of one session, as indices into the samples.
fn runs(vo: &[VoSample]) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    for (i, sample) in vo.iter().enumerate() {
        if !sample.reckoned {
            continue;
        }
        match runs.last_mut() {
            Some(run) if run.end == i && vo[run.start].session == sample.session => run.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    runs
}

/// The body's grade at a dead-reckoned sample: its forward axis's rise over its run.
fn grade_of(sample: &VoSample, camera_to_body: &Matrix3<f64>) -> f64 {
    let forward = (sample.rotation * camera_to_body.transpose()).column(0).into_owned();
    let run = forward.xy().norm();
    if run > 0.5 {
        forward.z / run
    } else {
        0.0
    }
}

/// A run's height from its grades (`height`) and its horizontal distance (`distance`), per
/// sample, from 0 at its first.
fn profile(run: &[VoSample], camera_to_body: &Matrix3<f64>) -> (Vec<f64>, Vec<f64>) {
    let (mut height, mut distance) = (vec![0.0; run.len()], vec![0.0; run.len()]);
    for i in 1..run.len() {
        let step = (run[i].position - run[i - 1].position).xy().norm();
        let grade = 0.5 * (grade_of(&run[i - 1], camera_to_body) + grade_of(&run[i], camera_to_body));
        height[i] = height[i - 1] + step * grade;
        distance[i] = distance[i - 1] + step;
    }
    (height, distance)
}

/// `values` (one per sample of `run`) at time `t`, linear between samples; `None` outside.
fn at_time(run: &[VoSample], values: &[f64], t: f64) -> Option<f64> {
    let k = run.partition_point(|s| s.t <= t);
    let (a, b) = (run.get(k.checked_sub(1)?)?, run.get(k)?);
    let (va, vb) = (values.get(k - 1)?, values.get(k)?);
    let alpha = if b.t > a.t { (t - a.t) / (b.t - a.t) } else { 0.0 };
    Some(va + (vb - va) * alpha)
}

/// Give the dead-reckoned samples of `vo` heights from their pitch, less the pitch offset
/// the fixes' heights show; mark each with [`RECKONED_GRADE_SIGMA`]. `camera_to_body` is
/// the mount the device reckoned with. The cameras keep their attitude: the offset is
/// mostly the camera's real tilt on the car, which the mount calibration then finds
/// between the camera and its track.
///
/// The offset is the median, over pairs of fixes [`GRADE_BASELINE_M`] of road apart, of
/// the reckoned rise less the fixes' rise per metre: the attitude's settling spoils the
/// first pairs, not the median. Fewer than [`MIN_GRADE_PAIRS`] pairs, and the heights are
/// left level (and to the fixes) and `None` returned.
pub fn with_grade(vo: &mut [VoSample], fixes: &[Fix], camera_to_body: &Matrix3<f64>) -> Option<Grade> {
    let runs = runs(vo);
    let mut profiles = Vec::with_capacity(runs.len());
    let (mut slopes, mut baseline) = (Vec::new(), 0.0);
    for run in &runs {
        let samples = &vo[run.clone()];
        let (height, distance) = profile(samples, camera_to_body);
        // (distance, reckoned height, fix height) at each fix beside the run.
        let beside: Vec<(f64, f64, f64)> = fixes
            .iter()
            .filter(|f| f.sigma_v <= MAX_HEIGHT_SIGMA_M)
            .filter_map(|f| Some((at_time(samples, &distance, f.t)?, at_time(samples, &height, f.t)?, f.enu.z)))
            .collect();
        let mut later = 0;
        for (i, a) in beside.iter().enumerate() {
            later = later.max(i + 1);
            while beside.get(later).is_some_and(|b| b.0 - a.0 < GRADE_BASELINE_M) {
                later += 1;
            }
            let Some(b) = beside.get(later) else { break };
            slopes.push(((b.1 - a.1) - (b.2 - a.2)) / (b.0 - a.0));
        }
        if let (Some(first), Some(last)) = (beside.first(), beside.last()) {
            baseline += last.0 - first.0;
        }
        profiles.push((height, distance, beside));
    }
    let offset = (slopes.len() >= MIN_GRADE_PAIRS).then(|| super::median(slopes));
    // The attitude levelled at the first dead-reckoned pose.
    let levelled = runs.first().map_or(0.0, |run| vo[run.start].t);
    let slope = offset.unwrap_or(0.0);
    for (run, (height, distance, beside)) in runs.iter().zip(profiles) {
        // Each run at the fixes' mean level; one without fixes where it started.
        let n = beside.len() as f64;
        let level = if beside.is_empty() {
            vo[run.start].position.z
        } else {
            beside.iter().map(|(d, h, z)| z - (h - slope * d)).sum::<f64>() / n
        };
        for ((sample, h), d) in vo[run.clone()].iter_mut().zip(height).zip(distance) {
            if offset.is_some() {
                sample.position.z = level + h - slope * d;
            }
            let settling = (-(sample.t - levelled) / TILT_BIAS_TIME_CONSTANT_S).exp();
            sample.grade_sigma = RECKONED_GRADE_SIGMA + SETTLING_GRADE_SIGMA * settling;
        }
    }
    offset.map(|pitch_offset| Grade { pitch_offset, baseline_m: baseline })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A car at 20 m/s turning at 0.05 rad/s, dead-reckoned with a bias estimate that is 0
    /// for the first 4 s and converges to the true 0.03 rad/s by 6 s (as the course
    /// measures it): the logged poses bend; redone, they are the true path.
    #[test]
    fn a_late_bias_is_taken_out_of_the_early_poses() {
        let (v, turn, bias) = (20.0, 0.05, 0.03);
        let truth = |t: f64| {
            let heading = turn * t;
            (Vector3::new(v * heading.sin() / turn, v * (1.0 - heading.cos()) / turn, 0.0), heading)
        };
        let known = |t: f64| bias * ((t - 4.0) / 2.0).clamp(0.0, 1.0);
        let dt = 0.05;
        let (mut heading, mut position) = (0.0, Vector3::zeros());
        let mut vo = Vec::new();
        for k in 0..=400 {
            let t = k as f64 * dt;
            if k > 0 {
                // The gyro reads turn + bias; the device removes what it knows.
                let rate = turn + bias - known(t - dt);
                let before = heading;
                heading += rate * dt;
                let mid = 0.5 * (before + heading);
                position += Vector3::new(mid.cos(), mid.sin(), 0.0) * v * dt;
            }
            vo.push(VoSample {
                t,
                session: 0,
                position,
                rotation: rotation_z(heading),
                grade_sigma: 0.0,
                reckoned: true,
            });
        }
        let history: Vec<(f64, f64)> = (0..=20).map(|s| (s as f64, known(s as f64))).collect();
        let end_before = (vo.last().expect("poses").position - truth(20.0).0).norm();
        let largest = with_final_bias(&mut vo, &history);
        // Four seconds of a 0.03 rad/s error and half of it for two: 0.15 rad.
        assert!((largest - 0.15).abs() < 0.005, "{largest}");
        let worst = vo.iter().map(|s| (s.position - truth(s.t).0).norm()).fold(0.0f64, f64::max);
        assert!(end_before > 30.0, "the logged poses bend: {end_before} m off at the end");
        // What is left is the two integrations' difference (the device's bias of a 50 ms
        // step is the one at its start; here it is the step's mean).
        assert!(worst < 0.5, "{worst} m");
        let last = vo.last().expect("poses");
        let heading_error = last.rotation[(1, 0)].atan2(last.rotation[(0, 0)]) - truth(20.0).1;
        assert!(heading_error.abs() < 0.02, "{heading_error}");
    }

    #[test]
    fn a_camera_vo_and_a_log_without_estimates_are_left_alone() {
        let mut vo: Vec<VoSample> = (0..10)
            .map(|k| VoSample {
                t: k as f64,
                session: 0,
                position: Vector3::new(k as f64, 0.0, 0.0),
                rotation: rotation_z(0.0),
                grade_sigma: 0.0,
                reckoned: false,
            })
            .collect();
        let before: Vec<Vector3<f64>> = vo.iter().map(|s| s.position).collect();
        assert_eq!(with_final_bias(&mut vo, &[(0.0, 0.1), (9.0, 0.0)]), 0.0);
        for sample in &mut vo {
            sample.reckoned = true;
        }
        assert_eq!(with_final_bias(&mut vo, &[]), 0.0);
        assert!(vo.iter().zip(&before).all(|(s, p)| s.position == *p));
    }

    /// The car on a level road; the device's attitude (the core's own filter) starts with
    /// no horizontal bias known and learns the true 0.035 rad/s about the left axis over
    /// ten seconds, as comma's EON's was learnt: the logged poses pitch by degrees, redone
    /// they are level.
    #[test]
    fn a_late_horizontal_bias_is_taken_out_of_the_tilt() {
        use dash2sim_core::imu::attitude::Attitude;
        use dash2sim_core::imu::GRAVITY;
        let (bias, dt) = (0.035, 0.01);
        let known = |t: f64| bias * ((t - 4.0) / 10.0).clamp(0.0, 1.0);
        let mut attitude = Attitude::default();
        let up = Vector3::new(0.0, 0.0, GRAVITY);
        attitude.update(dt, &Vector3::zeros(), &up, &Vector3::zeros());
        let (mut vo, mut history) = (Vec::new(), Vec::new());
        for k in 0..=3000 {
            let t = k as f64 * dt;
            // Past the attitude's settling; the device removes only the bias it knows.
            if k > 0 {
                attitude.update(dt, &Vector3::new(0.0, bias - known(t), 0.0), &up, &Vector3::zeros());
            }
            if k % 5 == 0 {
                vo.push(VoSample {
                    t,
                    session: 0,
                    position: Vector3::new(t * 20.0, 0.0, 0.0),
                    rotation: *attitude.rotation(),
                    grade_sigma: 0.0,
                    reckoned: true,
                });
            }
            if k % 100 == 0 {
                // What the device logs: what it was given and what its filter found.
                history.push((t, known(t) + attitude.tilt_bias().y));
            }
        }
        let pitch = |r: &Matrix3<f64>| (-r[(2, 0)]).asin();
        let worst = |vo: &[VoSample]| vo.iter().map(|s| pitch(&s.rotation).abs()).fold(0.0f64, f64::max);
        assert!(worst(&vo) > 0.03, "the logged poses pitch: {}", worst(&vo));
        let zero: Vec<(f64, f64)> = history.iter().map(|(t, _)| (*t, 0.0)).collect();
        let largest = with_final_tilt_bias(&mut vo, &zero, &history, &Matrix3::identity());
        assert!(largest > 0.03, "{largest}");
        // What is left is the settling's start and the bias the filter itself found.
        assert!(worst(&vo[vo.len() / 5..]) < 0.01, "{}", worst(&vo[vo.len() / 5..]));
    }

    /// A minute over a hill (±10 m) with the sensor pitched 0.07 nose up on the road: the
    /// flat reckoned track gets the hill's heights, the offset found from fixes with a
    /// metre of error; a run with too few fixes is left level.
    #[test]
    fn heights_come_from_the_grade_less_the_offset_the_fixes_show() {
        let (speed, offset) = (25.0, 0.07);
        let height = |d: f64| 10.0 * (d / 300.0).sin();
        let grade = |d: f64| 10.0 / 300.0 * (d / 300.0).cos();
        let sample = |t: f64| {
            let d = speed * t;
            let pitch_up = (grade(d) + offset).atan();
            VoSample {
                t,
                session: 0,
                position: Vector3::new(d, 0.0, 0.0),
                rotation: Rotation3::from_axis_angle(&Vector3::y_axis(), -pitch_up).into_inner(),
                grade_sigma: 0.0,
                reckoned: true,
            }
        };
        let mut vo: Vec<VoSample> = (0..=1200).map(|k| sample(k as f64 * 0.05)).collect();
        let fixes: Vec<Fix> = (0..=600)
            .map(|k| {
                let t = k as f64 * 0.1;
                let error = (k as f64 * 0.37).sin() + 0.5 * (k as f64 * 0.011).cos();
                Fix {
                    t,
                    enu: Vector3::new(speed * t, 0.0, height(speed * t) + 3.0 + error),
                    sigma_h: 2.0,
                    sigma_v: 3.0,
                }
            })
            .collect();
        let cameras: Vec<Matrix3<f64>> = vo.iter().map(|s| s.rotation).collect();
        let found = with_grade(&mut vo, &fixes, &Matrix3::identity()).expect("an offset");
        assert!((found.pitch_offset - offset).abs() < 0.005, "{found:?}");
        assert!(found.baseline_m > 1400.0, "{found:?}");
        let worst = vo.iter().map(|s| (s.position.z - 3.0 - height(s.position.x)).abs()).fold(0.0f64, f64::max);
        assert!(worst < 1.5, "heights {worst} m off");
        // The grade is trusted less while the attitude settles, then as much as ever.
        let sigma = |k: usize| vo[k].grade_sigma - RECKONED_GRADE_SIGMA;
        assert!((sigma(0) - SETTLING_GRADE_SIGMA).abs() < 1e-12, "{}", sigma(0));
        assert!(vo.windows(2).all(|w| w[1].grade_sigma <= w[0].grade_sigma));
        assert!(vo.last().is_some_and(|s| s.grade_sigma - RECKONED_GRADE_SIGMA < 1e-6));
        // The camera does look that far above the road: only the track drops the offset.
        assert!(vo.iter().zip(&cameras).all(|(s, c)| s.rotation == *c));

        let mut short: Vec<VoSample> = (0..=40).map(|k| sample(k as f64 * 0.05)).collect();
        assert_eq!(with_grade(&mut short, &fixes, &Matrix3::identity()), None);
        assert!(short.iter().all(|s| s.position.z == 0.0 && s.grade_sigma >= RECKONED_GRADE_SIGMA));
    }

    /// A track along a gentle bend; the device found the sensor's yaw on the car 10 s in
    /// (−0.03 rad) and refined it at 15 s (−0.035): every camera ends turned by the last,
    /// the ones before as well. A device that never found it is left alone.
    #[test]
    fn every_camera_takes_the_forward_axis_the_device_knew_last() {
        let known = |t: f64| {
            if t < 10.0 {
                0.0
            } else if t < 15.0 {
                -0.03
            } else {
                -0.035
            }
        };
        let heading = |t: f64| 0.01 * t;
        let track = |turned: &dyn Fn(f64) -> f64| -> Vec<VoSample> {
            let mut position = Vector3::zeros();
            (0..=400)
                .map(|k| {
                    let t = k as f64 * 0.05;
                    if k > 0 {
                        let mid = heading(t - 0.025);
                        position += Vector3::new(mid.cos(), mid.sin(), 0.0) * 20.0 * 0.05;
                    }
                    VoSample {
                        t,
                        session: 0,
                        position,
                        rotation: rotation_z(heading(t) + turned(t)),
                        grade_sigma: 0.0,
                        reckoned: true,
                    }
                })
                .collect()
        };
        let mut vo = track(&known);
        let last = with_final_forward_axis(&mut vo, &Matrix3::identity()).expect("a forward axis");
        assert!((last + 0.035).abs() < 1e-3, "{last}");
        for s in &vo {
            let off = s.rotation[(1, 0)].atan2(s.rotation[(0, 0)]) - heading(s.t);
            assert!((off + 0.035).abs() < 2e-3, "{} s: {off}", s.t);
        }

        let mut never = track(&|_| 0.0);
        let before: Vec<Matrix3<f64>> = never.iter().map(|s| s.rotation).collect();
        assert_eq!(with_final_forward_axis(&mut never, &Matrix3::identity()), None);
        assert!(never.iter().zip(&before).all(|(s, r)| s.rotation == *r));
    }
}
