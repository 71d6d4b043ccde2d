//! Dead-reckoned poses redone with the gyro's final bias.
//!
//! Under gyro + wheels the device made each pose with the gyro bias it knew then. Until the
//! GNSS course has measured it, that bias is wrong — comma's EON's is −0.068 rad/s, 4° of
//! heading a second — and the heading turns with the error: the first seconds of the
//! trajectory bend. The log keeps the bias as it was found (`ImuEstimate`, about once a
//! second); the heading a pose was made with differs from the one the final bias gives by
//! δψ(t) = ∫ (b(t′) − b_final) dt′ about the vertical. Each step of the trajectory is turned
//! by its δψ and the positions re-accumulated, each camera turned with it; finishing then
//! anchors the trajectory the device would have made had it known the bias from the start.

use dash2sim_core::nalgebra::{Matrix3, Rotation3, Vector3};

use super::solve::VoSample;

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

fn yaw(angle: f64) -> Matrix3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), angle).into_inner()
}

/// Redo the dead-reckoned samples of `vo` (those whose `dead_reckoned` flag is set; the
/// others, a camera's VO, are left alone) with the last bias of `history`. Returns the
/// largest heading correction made, rad (0 with no history).
pub fn with_final_bias(vo: &mut [VoSample], dead_reckoned: &[bool], history: &BiasHistory) -> f64 {
    let Some(&(_, final_bias)) = history.last() else { return 0.0 };
    let mut largest = 0.0f64;
    let mut previous: Option<Redone> = None;
    for (sample, &reckoned) in vo.iter_mut().zip(dead_reckoned) {
        if !reckoned {
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
                let step = yaw(0.5 * (p.delta + delta)) * (logged - p.logged);
                (p.corrected + step, delta)
            }
        };
        sample.position = position;
        sample.rotation = yaw(delta) * sample.rotation;
        largest = largest.max(delta.abs());
        previous = Some(Redone { t: sample.t, session: sample.session, logged, corrected: position, delta });
    }
    largest
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
            vo.push(VoSample { t, session: 0, position, rotation: yaw(heading) });
        }
        let history: Vec<(f64, f64)> = (0..=20).map(|s| (s as f64, known(s as f64))).collect();
        let end_before = (vo.last().expect("poses").position - truth(20.0).0).norm();
        let flags = vec![true; vo.len()];
        let largest = with_final_bias(&mut vo, &flags, &history);
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
                rotation: yaw(0.0),
            })
            .collect();
        let before: Vec<Vector3<f64>> = vo.iter().map(|s| s.position).collect();
        assert_eq!(with_final_bias(&mut vo, &[true; 10], &[]), 0.0);
        assert_eq!(with_final_bias(&mut vo, &[false; 10], &[(0.0, 0.1), (9.0, 0.0)]), 0.0);
        assert!(vo.iter().zip(&before).all(|(s, p)| s.position == *p));
    }
}
