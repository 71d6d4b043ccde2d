//! The 3D detections the device could not place, tracked offline.
//!
//! Until its anchor is observable — the first seconds of a drive, and again after the VO
//! re-initialises — the device has no world pose to place a detection through, so it
//! logs the detection raw, in the camera frame ([`Detection3d`] records), rather than lose
//! it. Finishing has a world pose for those frames: each raw detection goes through the
//! calibrated mount and the finished ego pose of its frame, into a tracker with the
//! device's own settings (the work-zone profile), and the tracks join the device's.

use std::collections::BTreeMap;

use dash2sim_core::binlog::{quantise, Detection3d as DetectionRecord, EgoPose, Track3d, Tracks3d, MAX_TRACKS};
use dash2sim_core::box3d::Box3d;
use dash2sim_core::obb::Pose2;
use dash2sim_core::pipeline::mount::to_world;
use dash2sim_core::pipeline::profile::{work_zone_tracker, WORK_ZONE, WORK_ZONE_CLASSES};
use dash2sim_core::pipeline::CameraMount;
use dash2sim_core::track3d::{Detection3d, Tracker3d};

/// Tracks of the offline tracker get ids from here on, apart from the device's.
pub const FIRST_ID: i64 = 1 << 31;
/// A detection is placed with the finished ego pose this close to it in time, µs.
const MAX_POSE_GAP_US: i64 = 50_000;
/// Tracks (and detections per frame) the offline tracker holds, as the device's.
const CAPACITY: usize = 64;

/// What became of the raw detections.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RawStats {
    /// Raw detections in the log.
    pub detections: usize,
    /// Placed through a finished ego pose and given to the tracker.
    pub placed: usize,
    /// Track states that came of them.
    pub track_states: usize,
}

/// Track the raw detections through the finished `ego` poses (by time, µs) and `mount`.
pub fn track_raw(
    detections: &[DetectionRecord],
    ego: &BTreeMap<i64, EgoPose>,
    mount: &CameraMount,
) -> (Vec<Tracks3d>, RawStats) {
    let mut stats = RawStats { detections: detections.len(), ..RawStats::default() };
    let mut by_frame: BTreeMap<i64, Vec<&DetectionRecord>> = BTreeMap::new();
    for d in detections {
        by_frame.entry(d.frame).or_default().push(d);
    }
    let mut tracker: Box<Tracker3d<'static, CAPACITY>> =
        Box::new(Tracker3d::new(work_zone_tracker(&WORK_ZONE_CLASSES)));
    let mut out = Vec::new();
    // Seconds per frame number, from the frames themselves (tracker velocities are per frame).
    let mut frame_interval = 0.1;
    let mut previous: Option<(i64, i64)> = None;
    for (frame, records) in by_frame {
        let Some(t_us) = records.first().map(|d| d.t_us) else { continue };
        if let Some((f0, t0)) = previous.replace((frame, t_us)) {
            let per_frame = (t_us - t0) as f64 * 1e-6 / (frame - f0) as f64;
            if per_frame.is_finite() && per_frame > 0.0 {
                frame_interval = per_frame;
            }
        }
        let Some(pose) = nearest(ego, t_us) else { continue };
        let placed: Vec<Detection3d> = records
            .iter()
            .filter_map(|r| camera_detection(r))
            .map(|d| {
                to_world(
                    &Pose2::new(pose.x_mm as f64 * 1e-3, pose.y_mm as f64 * 1e-3, pose.yaw_e4 as f64 * 1e-4),
                    &mount.to_body(&d),
                )
            })
            .take(CAPACITY)
            .collect();
        stats.placed += placed.len();
        let mut states: Vec<Track3d> = Vec::new();
        let Ok(frame) = u64::try_from(frame) else { continue };
        let z0 = pose.z_mm as f64 * 1e-3;
        // Frames come in increasing order, so the tracker refuses none.
        let _ = tracker.update(frame, &placed, |o| {
            let b = &o.bbox;
            states.push(Track3d {
                id: FIRST_ID + i64::from(o.id),
                class: WORK_ZONE.get(usize::from(o.class)).map_or(255, |c| c.code),
                x_mm: quantise(b.x, 1e-3),
                y_mm: quantise(b.y, 1e-3),
                z_mm: quantise(z0 + b.z, 1e-3),
                l_mm: quantise(b.l, 1e-3),
                w_mm: quantise(b.w, 1e-3),
                h_mm: quantise(b.h, 1e-3),
                yaw_e4: quantise(b.yaw, 1e-4),
                vx_mm_s: quantise(o.velocity[0] / frame_interval, 1e-3),
                vy_mm_s: quantise(o.velocity[1] / frame_interval, 1e-3),
                is_static: i64::from(o.is_static),
            });
        });
        stats.track_states += states.len();
        for chunk in states.chunks(MAX_TRACKS) {
            let mut batch = Tracks3d { t_us, ..Tracks3d::default() };
            for s in chunk {
                let _ = batch.tracks.push(*s);
            }
            out.push(batch);
        }
    }
    (out, stats)
}

/// The finished ego pose nearest to `t_us`, if one is close enough.
fn nearest(ego: &BTreeMap<i64, EgoPose>, t_us: i64) -> Option<&EgoPose> {
    let before = ego.range(..=t_us).next_back();
    let after = ego.range(t_us..).next();
    [before, after]
        .into_iter()
        .flatten()
        .filter(|(t, _)| (**t - t_us).abs() <= MAX_POSE_GAP_US)
        .min_by_key(|(t, _)| (**t - t_us).abs())
        .map(|(_, p)| p)
}

/// A raw record as the tracker's detection (camera frame); `None` for a class the profile
/// does not have.
fn camera_detection(r: &DetectionRecord) -> Option<Detection3d> {
    let class = u16::try_from(WORK_ZONE.iter().position(|c| c.code == r.class)?).ok()?;
    let m = |v: i64| v as f64 * 1e-3;
    let bbox = Box3d {
        x: m(r.x_mm),
        y: m(r.y_mm),
        z: m(r.z_mm),
        yaw: r.yaw_e4 as f64 * 1e-4,
        l: m(r.l_mm),
        w: m(r.w_mm),
        h: m(r.h_mm),
    };
    let covariance = [r.cov_xx_mm2, r.cov_xy_mm2, r.cov_yy_mm2].map(|v| v as f64 * 1e-6);
    Some(Detection3d {
        position_covariance: (covariance != [0.0; 3]).then_some(covariance),
        ..Detection3d::new(class, bbox, r.score_e3 as f64 * 1e-3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drum 20 m ahead and 3 m to the right of a car driving north at 10 m/s from (100, 50),
    /// seen by a camera pitched down 2° (1.8 m ahead, 1.3 m up), as raw records of frames 1–20.
    fn drive() -> (Vec<DetectionRecord>, BTreeMap<i64, EgoPose>, CameraMount) {
        let mount = CameraMount { roll_pitch_yaw: [0.0, 2.0_f64.to_radians(), 0.0], ..CameraMount::default() };
        let (mut detections, mut ego) = (Vec::new(), BTreeMap::new());
        for frame in 1..=20i64 {
            let t_us = 1_000_000 + frame * 100_000;
            let north = 50.0 + frame as f64;
            ego.insert(
                t_us,
                EgoPose { t_us, x_mm: 100_000, y_mm: quantise(north, 1e-3), z_mm: 0, yaw_e4: 15_708, sigma_mm: 0 },
            );
            // The drum at (103, 80): 80 − north ahead, 3 m right, 0.5 m up in the body frame.
            let body = dash2sim_core::nalgebra::Vector3::new(80.0 - north, -3.0, 0.5)
                - dash2sim_core::nalgebra::Vector3::from(mount.position);
            let camera = mount.rotation().transpose() * body;
            detections.push(DetectionRecord {
                t_us,
                frame,
                class: 7,
                score_e3: 900,
                x_mm: quantise(camera.x, 1e-3),
                y_mm: quantise(camera.y, 1e-3),
                z_mm: quantise(camera.z, 1e-3),
                l_mm: 580,
                w_mm: 580,
                h_mm: 1000,
                ..DetectionRecord::default()
            });
        }
        (detections, ego, mount)
    }

    #[test]
    fn raw_detections_are_tracked_where_the_finished_ego_and_the_mount_put_them() {
        let (detections, ego, mount) = drive();
        let (batches, stats) = track_raw(&detections, &ego, &mount);
        assert_eq!((stats.detections, stats.placed), (20, 20));
        let states: Vec<&Track3d> = batches.iter().flat_map(|b| b.tracks.iter()).collect();
        assert_eq!(states.len(), stats.track_states);
        assert!(states.len() >= 17, "{stats:?}");
        for s in &states {
            assert_eq!((s.class, s.id), (7, FIRST_ID + 1));
            assert!(
                (s.x_mm - 103_000).abs() < 20 && (s.y_mm - 80_000).abs() < 20 && (s.z_mm - 500).abs() < 20,
                "{s:?}"
            );
        }
        // Through the nominal (level) mount the drum would be metres off the ground and refused.
        let (level, level_stats) = track_raw(&detections, &ego, &CameraMount::default());
        assert!(level.is_empty() && level_stats.track_states == 0, "{level_stats:?}");
    }

    #[test]
    fn frames_without_a_finished_pose_are_not_placed() {
        let (detections, mut ego, mount) = drive();
        ego.retain(|t, _| *t > 1_000_000 + 10 * 100_000);
        let (_, stats) = track_raw(&detections, &ego, &mount);
        assert_eq!(stats.placed, 10);
    }
}
