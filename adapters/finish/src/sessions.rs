//! The VO sessions of a drive and their joins: each session solved on its own (a session
//! too short to fix its heading left unsolved), the finished poses of two sessions joined
//! where they meet, and a gap in the VO bridged by the wheels.

use dash2sim_core::nalgebra::Vector3;

use super::solve::{self, Anchor, AnchorAt, Fix, Inputs, Settings, Solution, VoSample};
use super::{median, tracks, walk, Drive};

/// A finished ego pose in the plane, with its height and smoothed velocity.
#[derive(Clone, Copy, Debug)]
pub(super) struct PlanarPose {
    pub(super) t: f64,
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) z: f64,
    pub(super) heading: f64,
    pub(super) vx: f64,
    pub(super) vy: f64,
    /// Horizontal 1-σ (DRMS), m.
    pub(super) sigma: f64,
}

/// Ego poses made for a gap in the VO.
pub(super) struct Bridge {
    pub(super) seconds: f64,
    pub(super) poses: Vec<PlanarPose>,
}

/// The speed error (m/s) a bridge's σ assumes: the ends' velocities are smoothed VO
/// velocities, good to a few per cent at town speeds.
pub(super) const BRIDGE_SPEED_SIGMA: f64 = 0.5;
/// Longest gap in the VO the finished ego is carried across, s.
pub(super) const MAX_BRIDGE_S: f64 = 5.0;
/// How far from a gap the two sessions' disagreement is spread, s.
pub(super) const JOIN_RAMP_S: f64 = 5.0;

/// Two sessions solved apart meet with the errors of their ends, independent of each other:
/// across the gap the car went on as the wheels say, so the second session's first pose
/// should be the first session's last one moved on by the wheels' distance over the gap
/// (the wheel factor of the two sessions applied; without speeds, the mean of their
/// velocities times the gap) along their mean direction. Each end is moved by half of the
/// disagreement (the mean of two independent estimates), the shift easing out to nothing
/// [`JOIN_RAMP_S`] into each session, where its own GNSS and anchors hold it: a smoothstep,
/// so that the shift adds no step in velocity, which the comfort metrics would read as a
/// jerk. `starts` are the indices where sessions begin, with their wheel factors.
pub(super) fn join_sessions(poses: &mut [PlanarPose], starts: &[(usize, f64)], speeds: &[(f64, f64)]) {
    let n = poses.len();
    for (k, &(b, factor)) in starts.iter().enumerate().filter(|(_, (b, _))| *b > 0 && *b < n) {
        let (end, start) = (poses[b - 1], poses[b]);
        let gap = start.t - end.t;
        if !(gap > 0.0 && gap <= MAX_BRIDGE_S) {
            continue;
        }
        let (mean_vx, mean_vy) = (0.5 * (end.vx + start.vx), 0.5 * (end.vy + start.vy));
        let factor = k.checked_sub(1).and_then(|j| starts.get(j)).map_or(factor, |&(_, f)| 0.5 * (f + factor));
        let travelled = solve::wheel_distance(speeds, end.t, start.t)
            .map(|d| d * factor)
            .filter(|d| d.is_finite())
            .unwrap_or_else(|| mean_vx.hypot(mean_vy) * gap);
        // Along the ends' mean direction; nowhere when the car stands.
        let speed = mean_vx.hypot(mean_vy);
        let (ux, uy) = if speed > 0.0 { (mean_vx / speed, mean_vy / speed) } else { (0.0, 0.0) };
        let predicted_x = end.x + travelled * ux;
        let predicted_y = end.y + travelled * uy;
        let (dx, dy) = (0.5 * (start.x - predicted_x), 0.5 * (start.y - predicted_y));
        if !(dx.is_finite() && dy.is_finite()) {
            continue;
        }
        let weight = |from_gap: f64| {
            let x = (from_gap / JOIN_RAMP_S).clamp(0.0, 1.0);
            1.0 - x * x * (3.0 - 2.0 * x)
        };
        for p in poses[..b].iter_mut().rev().take_while(|p| end.t - p.t < JOIN_RAMP_S) {
            let w = weight(end.t - p.t);
            (p.x, p.y) = (p.x + w * dx, p.y + w * dy);
            // The disagreement is an error of one session or the other: it counts in the σ.
            p.sigma = p.sigma.hypot(w * dx.hypot(dy));
        }
        for p in poses[b..].iter_mut().take_while(|p| p.t - start.t < JOIN_RAMP_S) {
            let w = weight(p.t - start.t);
            (p.x, p.y) = (p.x - w * dx, p.y - w * dy);
            p.sigma = p.sigma.hypot(w * dx.hypot(dy));
        }
    }
}

/// A session's velocity at its first pose, for the smoother to start from: the chord over
/// its first [`STARTING_CHORD_S`] (a smoother started at rest would pull the session's first
/// second towards a standstill the car never made).
pub(super) fn starting_velocity(planar: &[tracks::Sample]) -> (f64, f64) {
    let Some(first) = planar.first() else { return (0.0, 0.0) };
    match planar.iter().find(|s| s.t - first.t >= STARTING_CHORD_S) {
        Some(s) => ((s.x - first.x) / (s.t - first.t), (s.y - first.y) / (s.t - first.t)),
        None => (0.0, 0.0),
    }
}

/// The span whose chord gives a session's starting velocity, s.
pub(super) const STARTING_CHORD_S: f64 = 0.5;

/// The VO's frame interval: the median spacing of its poses, s.
pub(super) fn frame_interval(vo: &[VoSample]) -> f64 {
    let gaps: Vec<f64> = vo.windows(2).map(|w| w[1].t - w[0].t).filter(|d| *d > 0.0).collect();
    let m = median(gaps);
    if m.is_finite() {
        m
    } else {
        0.1
    }
}

/// Where the VO lost track (a re-initialisation, a stretch of dropped frames) the finished
/// ego has no pose, and a hole reads as a stop and a start to the metrics. Gaps up to
/// [`MAX_BRIDGE_S`] are filled at the frame rate along a cubic Hermite curve between the
/// smoothed poses at their two ends, leaving each along its heading. Where the wheels cover
/// the gap the curve is laid out by distance and each pose put where the odometer says the
/// car was (a car that braked in the gap brakes there too); without them, by time with the
/// ends' velocities. The heading and the height go linearly.
pub(super) fn bridge_gaps(poses: &[PlanarPose], interval: f64, speeds: &[(f64, f64)]) -> Vec<Bridge> {
    let mut out = Vec::new();
    for w in poses.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let gap = b.t - a.t;
        if !(gap > 1.5 * interval && gap <= MAX_BRIDGE_S) {
            continue;
        }
        let steps = (gap / interval).round().max(2.0) as usize;
        let turn = dash2sim_core::track3d::wrap_angle(b.heading - a.heading);
        // By distance: tangents along the ends' headings as long as the chord, and each
        // pose at the odometer's fraction of the gap's distance.
        let chord = (b.x - a.x).hypot(b.y - a.y);
        let (speed_a, speed_b) = (a.vx.hypot(a.vy), b.vx.hypot(b.vy));
        let by_distance = solve::wheel_distance(speeds, a.t, b.t)
            .filter(|&d| d > 0.5 && chord > 0.5 && speed_a > 0.0 && speed_b > 0.0)
            .map(|d| {
                let tangents =
                    (a.vx * chord / speed_a, a.vy * chord / speed_a, b.vx * chord / speed_b, b.vy * chord / speed_b);
                (d, tangents)
            });
        let poses = (1..steps)
            .map(|k| {
                let u = k as f64 / steps as f64;
                let t = a.t + u * gap;
                let (s, (ax, ay, bx, by)) = match by_distance {
                    Some((d, tangents)) => {
                        let s = solve::wheel_distance(speeds, a.t, t).map_or(u, |part| (part / d).clamp(0.0, 1.0));
                        (s, tangents)
                    }
                    None => (u, (gap * a.vx, gap * a.vy, gap * b.vx, gap * b.vy)),
                };
                let (h00, h10, h01, h11) = (
                    2.0 * s.powi(3) - 3.0 * s * s + 1.0,
                    s.powi(3) - 2.0 * s * s + s,
                    -2.0 * s.powi(3) + 3.0 * s * s,
                    s.powi(3) - s * s,
                );
                PlanarPose {
                    t,
                    x: h00 * a.x + h10 * ax + h01 * b.x + h11 * bx,
                    y: h00 * a.y + h10 * ay + h01 * b.y + h11 * by,
                    z: a.z + u * (b.z - a.z),
                    heading: dash2sim_core::track3d::wrap_angle(a.heading + u * turn),
                    vx: f64::NAN,
                    vy: f64::NAN,
                    // The ends' σ, and what a curve through a gap may miss: the speed's
                    // assumed error times the time to the nearer end.
                    sigma: a.sigma.max(b.sigma).hypot(BRIDGE_SPEED_SIGMA * gap * u.min(1.0 - u)),
                }
            })
            .collect();
        out.push(Bridge { seconds: gap, poses });
    }
    out
}

/// A VO session of a drive with several whose heading's 1-σ is above this is not anchored
/// on its own (rad): a session of a few frames, its fixes a few metres apart, points
/// anywhere within 10–20°, where one of seconds is known to a degree.
const MAX_SESSION_HEADING_SIGMA_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// Every VO session solved: the solutions, the sessions that could not be, and per anchor
/// why no session used it (`None`: used).
pub(super) struct Solved {
    pub(super) sessions: Vec<SessionSolution>,
    pub(super) unsolved: Vec<(u32, usize, String)>,
    pub(super) verdicts: Vec<Option<String>>,
}

pub(super) fn solve_sessions(drive: &Drive, anchors: &[Anchor], lever: Vector3<f64>, settings: Settings) -> Solved {
    let single_session = drive.vo.first().zip(drive.vo.last()).is_none_or(|(a, b)| a.session == b.session);
    let mut verdicts: Vec<Option<String>> = vec![Some("outside the VO poses' time span".to_owned()); anchors.len()];
    let (mut sessions, mut unsolved) = (Vec::new(), Vec::new());
    for range in session_ranges(&drive.vo) {
        let vo = &drive.vo[range.clone()];
        let session = vo[0].session;
        let inputs = Inputs { vo, fixes: &drive.fixes, speeds: &drive.speeds, anchors, lever };
        match solve_session(inputs, settings, &drive.fixes, single_session) {
            // A session too short to fix which way it points is not anchored on its own: its
            // heading would be a guess, and the bridge from it into the next session a turn the
            // car never made. Its poses stay without a finished pose (another session's
            // bridge may cover them).
            Ok((solution, session_verdicts, _))
                if !single_session && solution.heading_sigma_rad > MAX_SESSION_HEADING_SIGMA_RAD =>
            {
                let why = format!(
                    "its heading is not determined ({:.1}° 1-σ over {:.1} s of VO; at most {:.0}°)",
                    solution.heading_sigma_rad.to_degrees(),
                    vo[vo.len() - 1].t - vo[0].t,
                    MAX_SESSION_HEADING_SIGMA_RAD.to_degrees()
                );
                for (verdict, mine) in verdicts.iter_mut().zip(session_verdicts) {
                    if matches!(mine, AnchorVerdict::Used) && verdict.is_some() {
                        *verdict = Some(format!("in VO session {session}, not anchored: {why}"));
                    }
                }
                unsolved.push((session, vo.len(), why));
            }
            Ok((solution, session_verdicts, solved_with)) => {
                for (verdict, mine) in verdicts.iter_mut().zip(session_verdicts) {
                    match mine {
                        AnchorVerdict::Used => *verdict = None,
                        AnchorVerdict::Refused(why) if verdict.is_some() => *verdict = Some(why),
                        AnchorVerdict::Refused(_) | AnchorVerdict::Elsewhere => {}
                    }
                }
                sessions.push(SessionSolution { session, range, solution, solved_with });
            }
            Err(e) => unsolved.push((session, vo.len(), e.to_string())),
        }
    }
    Solved { sessions, unsolved, verdicts }
}

/// One VO session's re-anchoring: its poses (a range of the drive's) and its solution.
pub(super) struct SessionSolution {
    pub(super) session: u32,
    pub(super) range: std::ops::Range<usize>,
    pub(super) solution: Solution,
    pub(super) solved_with: SolvedWith,
}

/// What a session's solution was solved from: the settings (with the walks chosen) and which
/// anchors took part.
pub(super) type SolvedWith = (Settings, Vec<bool>);

/// The runs of consecutive poses of one VO session.
pub(super) fn session_ranges(vo: &[VoSample]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=vo.len() {
        if k == vo.len() || vo[k].session != vo[start].session {
            out.push(start..k);
            start = k;
        }
    }
    out
}

/// What one session made of an external anchor.
pub(super) enum AnchorVerdict {
    /// Used in the solution.
    Used,
    /// Refused, and why.
    Refused(String),
    /// Not this session's: outside its time span.
    Elsewhere,
}

/// Re-anchor one VO session. Anchors are first checked against the session anchored
/// without them: one far from it (a wrong place-recognition match) is refused before it can
/// pull. A VO-point anchor names a point of one VO frame, which a re-initialisation
/// replaces: it is used only in a log of one session.
pub(super) fn solve_session(
    inputs: Inputs<'_>,
    settings: Settings,
    fixes: &[Fix],
    vo_points_valid: bool,
) -> Result<(Solution, Vec<AnchorVerdict>, SolvedWith), solve::SolveError> {
    let anchors = inputs.anchors;
    let (first, last) = (inputs.vo[0].t, inputs.vo[inputs.vo.len() - 1].t);
    let mut verdicts: Vec<AnchorVerdict> = anchors
        .iter()
        .map(|a| match a.at {
            AnchorAt::Time(t) if (first..=last).contains(&t) => AnchorVerdict::Used,
            AnchorAt::VoPoint(_) if vo_points_valid => AnchorVerdict::Used,
            AnchorAt::VoPoint(_) => AnchorVerdict::Refused(
                "a VO point, but the VO re-initialised during the drive (give the anchor's time instead)".to_owned(),
            ),
            AnchorAt::Time(_) => AnchorVerdict::Elsewhere,
        })
        .collect();
    let candidate = |v: &AnchorVerdict| matches!(v, AnchorVerdict::Used);
    let mut latency_s = settings.latency_prior.0;
    if !fixes.is_empty() && verdicts.iter().any(candidate) {
        let without = solve::solve(inputs, settings, &vec![false; anchors.len()])?;
        latency_s = without.latency_s;
        let median_sigma = median(fixes.iter().map(|f| f.sigma_h).collect());
        let position_sigma = without.position_sigma_m.max(median_sigma);
        for (a, verdict) in anchors.iter().zip(verdicts.iter_mut()).filter(|(_, v)| candidate(v)) {
            let limit = settings.gate * (a.sigma * a.sigma + position_sigma * position_sigma).sqrt();
            match without.anchor_residual(&inputs, a) {
                Some(r) if r > limit => {
                    *verdict =
                        AnchorVerdict::Refused(format!("{r:.1} m from the drive anchored by GNSS (limit {limit:.1} m)"))
                }
                None => *verdict = AnchorVerdict::Elsewhere,
                Some(_) => {}
            }
        }
    }
    let enabled: Vec<bool> = verdicts.iter().map(candidate).collect();
    let settings = if enabled.iter().any(|&on| on) {
        let (scale_walk, rotation_walk) = walk::anchored_walk(inputs, settings, &enabled, latency_s)?;
        Settings { scale_walk, rotation_walk, ..settings }
    } else {
        settings
    };
    let solution = solve::solve(inputs, settings, &enabled)?;
    for ((verdict, &on), &used) in verdicts.iter_mut().zip(&enabled).zip(&solution.anchor_used) {
        if on && !used {
            *verdict = AnchorVerdict::Refused(format!("residual beyond {}σ in the solution", settings.gate));
        }
    }
    Ok((solution, verdicts, (settings, enabled)))
}
