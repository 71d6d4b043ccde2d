//! Judging a 4D log recorded from a generated drive against the drive's truth: where the
//! anchored ego was, and how its 3D tracks score (motmetrics' metrics, 2 m gate). The demo
//! reports these figures; the tests assert them. Nothing here feeds back into the log.

use std::collections::{BTreeMap, HashMap};

use dash2sim_core::binlog::Record;
use dash2sim_core::box3d::Box3d;
use dash2sim_core::obb::Pose2;

use super::actors::Class;
use super::evaluate::score_tracks;
use super::write::START_UNIX_S;
use super::Scenario;
use dash2sim_linux::log::LogContents;

/// What the log's ego and tracks measure against the truth.
#[derive(Clone, Debug, Default)]
pub struct LogJudgement {
    /// Horizontal ego (rear axle) error per anchored frame index (from 0), m; in frame order,
    /// so that its RMS is summed in one order and the same drive gives the same figure.
    pub ego_errors: BTreeMap<usize, f64>,
    /// RMS of `ego_errors`, m.
    pub ego_rmse: f64,
    /// Largest of `ego_errors`, m.
    pub ego_max: f64,
    /// Seconds from the drive's first frame to the first anchored pose.
    pub first_anchored_s: Option<f64>,
    /// MOTA and IDF1 of the log's 3D tracks over every frame.
    pub tracks: (f64, f64),
    /// The same over the frames with an anchored pose.
    pub tracks_anchored: (f64, f64),
    /// The same with each frame's tracks moved from the anchored to the true ego pose: the
    /// tracker's own error, without the anchoring's.
    pub tracks_relative: (f64, f64),
    /// Track states per class name.
    pub tracks_by_class: BTreeMap<String, u64>,
    /// How well the poses' stated σ covers their error, over the poses that state one.
    pub sigma: SigmaCoverage,
    /// The log's UTC against the drive's: the log's time of each frame less the frame's
    /// true UTC, median, s; none for a log without UTC or frames.
    pub clock_error_s: Option<f64>,
    /// The ego's horizontal error RMS as a user measures it: each pose at its own UTC stamp
    /// against the truth at that instant (interpolated between frames), m; NaN without
    /// UTC or poses.
    pub ego_rmse_utc: f64,
}

/// The ego poses' stated horizontal σ (DRMS) against their error.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SigmaCoverage {
    /// Poses with a σ.
    pub poses: usize,
    /// Of them, those within 2σ of the truth.
    pub within_2sigma: usize,
    /// Σ of each pose's normalised error squared, |e|² / (σ²/2): its mean is 2 (the
    /// horizontal NEES, taking the two axes' σ equal) when the σ is right.
    pub nees_sum: f64,
}

impl SigmaCoverage {
    /// The fraction within 2σ (NaN with none).
    pub fn fraction(&self) -> f64 {
        self.within_2sigma as f64 / self.poses as f64
    }

    /// The mean NEES (NaN with none).
    pub fn nees(&self) -> f64 {
        self.nees_sum / self.poses as f64
    }
}

/// The truth ego pose of the frame at device time `t`.
pub fn truth_at(scenario: &Scenario, t: f64) -> Option<Pose2> {
    let k = (t * scenario.config.frame_rate_hz).round() as usize;
    scenario.frames.get(k).filter(|f| (f.ego.t - t).abs() < 1e-3).map(|f| Pose2::new(f.ego.x, f.ego.y, f.ego.heading))
}

fn figures(s: &dash2sim_verify::mot::Summary) -> (f64, f64) {
    (s.get("mota").unwrap_or(f64::NAN), s.get("idf1").unwrap_or(f64::NAN))
}

/// Judge a log recorded from `scenario`: records are matched to the drive's frames through
/// the frame numbers of the log's `FrameMeta` records (same time, same frame), so that a
/// live recording on any device clock is judged as one from files.
pub fn judge_log(scenario: &Scenario, log: &LogContents) -> LogJudgement {
    let frame_at: HashMap<i64, u32> = log
        .records
        .iter()
        .filter_map(|r| match r {
            Record::FrameMeta(f) => Some((f.t_us, u32::try_from(f.frame).ok()?)),
            _ => None,
        })
        .collect();
    let truth = |frame: u32| {
        let f = scenario.frames.get(usize::try_from(frame).ok()?.checked_sub(1)?)?;
        Some(Pose2::new(f.ego.x, f.ego.y, f.ego.heading))
    };
    let mut j = LogJudgement::default();
    let mut ego_poses = HashMap::new();
    let mut reported: HashMap<u32, Vec<(u32, u16, Box3d)>> = HashMap::new();
    let t0 = scenario.frames.first().map_or(0.0, |f| f.ego.t);
    for r in &log.records {
        let Some(&frame) = frame_at.get(&r.t_us()) else { continue };
        match r {
            Record::EgoPose(p) => {
                let Some(truth) = truth(frame) else { continue };
                let (x, y) = (p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3);
                let error = (x - truth.x).hypot(y - truth.y);
                j.ego_errors.insert(frame as usize - 1, error);
                if p.sigma_mm > 0 {
                    let sigma = p.sigma_mm as f64 * 1e-3;
                    j.sigma.poses += 1;
                    j.sigma.within_2sigma += usize::from(error <= 2.0 * sigma);
                    j.sigma.nees_sum += error * error / (0.5 * sigma * sigma);
                }
                j.first_anchored_s.get_or_insert(scenario.frames[frame as usize - 1].ego.t - t0);
                ego_poses.insert(frame, (Pose2::new(x, y, p.yaw_e4 as f64 * 1e-4), truth));
            }
            Record::Tracks3d(batch) => {
                for track in &batch.tracks {
                    let name = dash2sim_core::class::name_of(track.class);
                    *j.tracks_by_class.entry(name.to_owned()).or_default() += 1;
                    let class = Class::ALL.iter().find(|c| c.name() == name).map_or(u16::MAX, |c| *c as u16);
                    let bbox = Box3d {
                        x: track.x_mm as f64 * 1e-3,
                        y: track.y_mm as f64 * 1e-3,
                        z: track.z_mm as f64 * 1e-3,
                        yaw: track.yaw_e4 as f64 * 1e-4,
                        l: track.l_mm as f64 * 1e-3,
                        w: track.w_mm as f64 * 1e-3,
                        h: track.h_mm as f64 * 1e-3,
                    };
                    let id = u32::try_from(track.id).unwrap_or(u32::MAX);
                    reported.entry(frame).or_default().push((id, class, bbox));
                }
            }
            _ => {}
        }
    }
    let n = j.ego_errors.len().max(1) as f64;
    j.ego_rmse = (j.ego_errors.values().map(|e| e * e).sum::<f64>() / n).sqrt();
    j.ego_max = j.ego_errors.values().copied().fold(0.0, f64::max);
    j.tracks = figures(&score_tracks(scenario, &reported));
    let mut anchored_only = scenario.clone();
    anchored_only.frames.retain(|f| j.ego_errors.contains_key(&(f.index as usize - 1)));
    j.tracks_anchored = figures(&score_tracks(&anchored_only, &reported));
    let relative: HashMap<u32, Vec<(u32, u16, Box3d)>> = reported
        .iter()
        .filter_map(|(frame, tracks)| {
            let (anchored, truth) = ego_poses.get(frame)?;
            let (s, c) = (truth.heading - anchored.heading).sin_cos();
            let moved = tracks
                .iter()
                .map(|(id, class, b)| {
                    let (dx, dy) = (b.x - anchored.x, b.y - anchored.y);
                    (*id, *class, Box3d { x: truth.x + c * dx - s * dy, y: truth.y + s * dx + c * dy, ..*b })
                })
                .collect();
            Some((*frame, moved))
        })
        .collect();
    j.tracks_relative = figures(&score_tracks(&anchored_only, &relative));
    let in_utc = log.records.iter().any(|r| matches!(r, Record::ClockOffset(_)));
    if in_utc {
        let mut errors: Vec<f64> = frame_at
            .iter()
            .filter_map(|(t_us, frame)| {
                let f = scenario.frames.get(usize::try_from(*frame).ok()?.checked_sub(1)?)?;
                Some(*t_us as f64 * 1e-6 - (START_UNIX_S + f.ego.t))
            })
            .collect();
        errors.sort_by(f64::total_cmp);
        j.clock_error_s = errors.get(errors.len() / 2).copied();
        j.ego_rmse_utc = utc_ape(scenario, log);
    } else {
        j.ego_rmse_utc = f64::NAN;
    }
    j
}

/// The RMS horizontal error of the log's ego poses, each at its UTC stamp against the
/// truth then (linear between the two frames around it), m; NaN with none in the drive.
fn utc_ape(scenario: &Scenario, log: &LogContents) -> f64 {
    let frames = &scenario.frames;
    let (mut squares, mut n) = (0.0, 0usize);
    for r in &log.records {
        let Record::EgoPose(p) = r else { continue };
        let t = p.t_us as f64 * 1e-6 - START_UNIX_S;
        let k = frames.partition_point(|f| f.ego.t <= t);
        let (Some(a), Some(b)) = (k.checked_sub(1).and_then(|i| frames.get(i)), frames.get(k)) else { continue };
        let w = (t - a.ego.t) / (b.ego.t - a.ego.t);
        let (x, y) = (a.ego.x + w * (b.ego.x - a.ego.x), a.ego.y + w * (b.ego.y - a.ego.y));
        squares += (p.x_mm as f64 * 1e-3 - x).powi(2) + (p.y_mm as f64 * 1e-3 - y).powi(2);
        n += 1;
    }
    (squares / n as f64).sqrt()
}
