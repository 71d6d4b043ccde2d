//! Tracking: 3D detections placed in the world by the anchored ego and the mount, into the
//! EKF track manager; 2D detections into the IoU tracker; the tracks written to the log and
//! given out as the agents the windows score. The stage keeps its trackers and the latest
//! frame of each kind; the pipeline's route ([`super::routes`]) hands it the frame's ego
//! and mount from the anchoring and its agents on to the windows.

use embedded_io::Write;

use super::anchoring::Ego;
use super::issues::Issue;
use super::sink::LogSink;
use super::{ease, mount, quantise, CameraMount, ClassMeta, ImageDetection, PipelineError, Trackers};
use crate::binlog::{Detection3d as DetectionRecord, Record, Track2d, Track3d, Tracks3d, MAX_TRACKS};
use crate::box2d::Box2d;
use crate::frame_order::FrameOrder;
use crate::obb::{OrientedBox, Pose2};
use crate::score::{Agent, AgentKind, PlaceSigma};
use crate::time::Timestamp;
use crate::track2d::Detection;
use crate::track3d::Detection3d;

/// What tracking keeps between frames: the caller-kept trackers and the latest frame of
/// each kind.
#[derive(Debug)]
pub(super) struct Tracking<'a, const T3: usize, const T2: usize> {
    trackers: &'a mut Trackers<'a, T3, T2>,
    /// The latest frame of 3D detections (those without a pose too, written raw).
    frames3d: FrameOrder,
    /// The latest frame of 2D detections.
    frames2d: FrameOrder,
}

/// A reported 3D track, as the log and the score use it.
#[derive(Clone, Copy, Debug)]
pub(super) struct TrackState {
    pub(super) id: u32,
    pub(super) class: u16,
    pub(super) bbox: crate::box3d::Box3d,
    /// Velocity (x, y) per frame.
    pub(super) velocity: [f64; 2],
    pub(super) is_static: bool,
    /// The filter's σ of its place across the ego's path as the ego headed when it was
    /// updated (one byte: 64 of these are on a microcontroller's stack).
    pub(super) sigma_across: PlaceSigma,
}

impl<'a, const T3: usize, const T2: usize> Tracking<'a, T3, T2> {
    pub(super) fn new(trackers: &'a mut Trackers<'a, T3, T2>) -> Self {
        Tracking { trackers, frames3d: FrameOrder::new(), frames2d: FrameOrder::new() }
    }

    /// Whether 3D detections of `frame` (the pipeline's internal number) come in order;
    /// the latest frame moves on to it when they do.
    pub(super) fn frame3d_in_order(&mut self, frame: u64) -> bool {
        self.frames3d.advance(frame).is_ok()
    }

    /// The detections placed through `ego` and the mount into the tracker; the tracks it
    /// reports (`None`: the frame was out of order). Never inlined: the placed detections
    /// (6.7 KB at 64) live in its frame, popped before the tracks are written — on a
    /// microcontroller the two frames would otherwise sit on the stack together.
    #[inline(never)]
    pub(super) fn track<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
        frame: u64,
        ego: &Ego,
        camera_mount: &CameraMount,
        detections: &[Detection3d],
    ) -> Result<Option<heapless::Vec<TrackState, T3>>, PipelineError<W::Error>> {
        let mut placed: heapless::Vec<Detection3d, T3> = heapless::Vec::new();
        let mut excess = 0u64;
        for d in detections {
            let world = mount::to_world(&ego.eased, &camera_mount.to_body(d));
            if placed.push(world).is_err() {
                excess += 1;
            }
        }
        log.stats.detections_placed = log.stats.detections_placed.saturating_add(placed.len() as u64);
        let rejected_before = self.trackers.tracker3d.stats().rejected;
        // Only what the log needs of each track: the filter's posterior is 0.9 KB a track,
        // too much to keep 64 of on a microcontroller's stack.
        let mut outputs: heapless::Vec<TrackState, T3> = heapless::Vec::new();
        if self
            .trackers
            .tracker3d
            .update(frame, &placed, |o| {
                // At most T3 tracks exist.
                let _ = outputs.push(TrackState {
                    id: o.id,
                    class: o.class,
                    bbox: o.bbox,
                    velocity: [o.velocity[0], o.velocity[1]],
                    is_static: o.is_static,
                    sigma_across: PlaceSigma::from_m(sigma_across(&o.state.p, ego.eased.heading)),
                });
            })
            .is_err()
        {
            return Ok(None);
        }
        let refused = self.trackers.tracker3d.stats().rejected.saturating_sub(rejected_before).saturating_add(excess);
        if refused > 0 {
            log.issue(t, Issue::DetectionsRefused, refused)?;
        }
        Ok(Some(outputs))
    }

    /// Detections without an anchored ego, as the camera gave them.
    pub(super) fn write_raw<W: Write, const BUF: usize>(
        &self,
        log: &mut LogSink<W, BUF>,
        classes: &[ClassMeta],
        t: Timestamp,
        frame: u64,
        detections: &[Detection3d],
    ) -> Result<(), PipelineError<W::Error>> {
        let t_us = log.time(t);
        for d in detections.iter().take(T3) {
            let b = &d.bbox;
            let [xx, xy, yy] = d.position_covariance.unwrap_or([0.0; 3]);
            log.write(&Record::Detection3d(DetectionRecord {
                t_us,
                frame: i64::try_from(frame).unwrap_or(i64::MAX),
                class: classes.get(usize::from(d.class)).map_or(255, |m| m.code),
                score_e3: quantise(d.score, 1e-3),
                x_mm: quantise(b.x, 1e-3),
                y_mm: quantise(b.y, 1e-3),
                z_mm: quantise(b.z, 1e-3),
                yaw_e4: quantise(b.yaw, 1e-4),
                l_mm: quantise(b.l, 1e-3),
                w_mm: quantise(b.w, 1e-3),
                h_mm: quantise(b.h, 1e-3),
                cov_xx_mm2: quantise(xx, 1e-6),
                cov_xy_mm2: quantise(xy, 1e-6),
                cov_yy_mm2: quantise(yy, 1e-6),
            }))?;
            log.stats.detections_raw = log.stats.detections_raw.saturating_add(1);
        }
        Ok(())
    }

    /// Frame `frame`'s 2D detections (the pipeline's internal number) into the IoU tracker;
    /// its tracks to the log.
    pub(super) fn detections2d<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
        frame: u64,
        detections: &[ImageDetection],
    ) -> Result<(), PipelineError<W::Error>> {
        if self.frames2d.advance(frame).is_err() {
            return log.issue(t, Issue::DetectionsOutOfOrder, 1);
        }
        let mut boxes: heapless::Vec<Detection, T2> = heapless::Vec::new();
        let mut excess = 0;
        for d in detections {
            if boxes.push(d.detection).is_err() {
                excess += 1;
            }
        }
        if excess > 0 {
            log.issue(t, Issue::DetectionsRefused, excess)?;
        }
        let mut outputs: heapless::Vec<crate::track2d::TrackOutput, T2> = heapless::Vec::new();
        if self
            .trackers
            .tracker2d
            .update(frame, &boxes, |o| {
                let _ = outputs.push(o);
            })
            .is_err()
        {
            return log.issue(t, Issue::DetectionsOutOfOrder, 1);
        }
        let t_us = log.time(t);
        for o in &outputs {
            // The class of the detection that fits the track's box best.
            let class = detections
                .iter()
                .take(T2)
                .map(|d| (d.class, o.bbox.iou(&d.detection.bbox)))
                .fold((None, 0.0), |best, (c, iou)| if iou > best.1 { (Some(c), iou) } else { best })
                .0
                .map_or(-1, i64::from);
            let b: &Box2d = &o.bbox;
            log.write(&Record::Track2d(Track2d {
                t_us,
                id: i64::from(o.id),
                class,
                score_e3: quantise(o.score, 1e-3),
                x_e1: quantise(b.x, 0.1),
                y_e1: quantise(b.y, 0.1),
                w_e1: quantise(b.w, 0.1),
                h_e1: quantise(b.h, 0.1),
            }))?;
        }
        log.stats.track2d_states = log.stats.track2d_states.saturating_add(outputs.len() as u64);
        Ok(())
    }
}

/// The tracks reported, in the log's frame beside the anchored ego; `per_second`: frame
/// numbers per second (for their velocities in m/s).
pub(super) fn write_tracks<W: Write, const BUF: usize>(
    log: &mut LogSink<W, BUF>,
    classes: &[ClassMeta],
    t: Timestamp,
    ego: &Ego,
    per_second: f64,
    outputs: &[TrackState],
) -> Result<(), PipelineError<W::Error>> {
    let t_us = log.time(t);
    // The tracks live in the eased ego's frame; the log has them beside its anchored one.
    let to_log = ease::Reframe::new(ego.eased, ego.pose);
    for chunk in outputs.chunks(MAX_TRACKS) {
        let mut batch = Tracks3d { t_us, tracks: heapless::Vec::new() };
        for o in chunk {
            let b = &o.bbox;
            let (vx, vy) = (o.velocity[0] * per_second, o.velocity[1] * per_second);
            let meta = classes.get(usize::from(o.class)).copied();
            let (x, y) = to_log.point(b.x, b.y);
            let (log_vx, log_vy) = to_log.vector(vx, vy);
            // At most MAX_TRACKS per chunk.
            let _ = batch.tracks.push(Track3d {
                id: i64::from(o.id),
                class: meta.map_or(255, |m| m.code),
                x_mm: quantise(x, 1e-3),
                y_mm: quantise(y, 1e-3),
                z_mm: quantise(ego.z + b.z, 1e-3),
                l_mm: quantise(b.l, 1e-3),
                w_mm: quantise(b.w, 1e-3),
                h_mm: quantise(b.h, 1e-3),
                yaw_e4: quantise(to_log.heading(b.yaw), 1e-4),
                vx_mm_s: quantise(log_vx, 1e-3),
                vy_mm_s: quantise(log_vy, 1e-3),
                is_static: i64::from(o.is_static),
            });
        }
        log.write(&Record::Tracks3d(batch))?;
    }
    log.stats.track_states = log.stats.track_states.saturating_add(outputs.len() as u64);
    Ok(())
}

/// The tracks reported as the agents the windows score.
pub(super) fn agents<'o>(
    classes: &'o [ClassMeta],
    per_second: f64,
    outputs: &'o [TrackState],
) -> impl Iterator<Item = Agent> + 'o {
    outputs.iter().map(move |o| {
        let kind = classes.get(usize::from(o.class)).map_or(AgentKind::Object, |m| m.kind);
        // A track reported static is scored standing still: its filtered velocity is the
        // ego's anchoring corrections seen against the world, not motion.
        let velocity = if o.is_static { (0.0, 0.0) } else { (o.velocity[0] * per_second, o.velocity[1] * per_second) };
        let b = &o.bbox;
        Agent {
            id: o.id,
            kind,
            bbox: OrientedBox { centre: Pose2::new(b.x, b.y, b.yaw), length: b.l, width: b.w },
            velocity,
            sigma_across: o.sigma_across,
        }
    })
}

/// The σ (m) of a track's place across a path heading `heading` (rad): its position
/// covariance (the state's x and y, [`crate::track3d`]) seen along the path's normal.
fn sigma_across(p: &nalgebra::SMatrix<f64, 10, 10>, heading: f64) -> f64 {
    let (nx, ny) = (-libm::sin(heading), libm::cos(heading));
    libm::sqrt((p[(0, 0)] * nx * nx + 2.0 * p[(0, 1)] * nx * ny + p[(1, 1)] * ny * ny).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tracks_doubt_across_the_path_is_its_covariance_along_the_paths_normal() {
        // Known to 2 m east–west (a camera's range, looking east) and 0.5 m north–south.
        let mut p = nalgebra::SMatrix::<f64, 10, 10>::identity();
        p[(0, 0)] = 4.0;
        p[(1, 1)] = 0.25;
        assert!((sigma_across(&p, 0.0) - 0.5).abs() < 1e-12, "heading east: across is north");
        assert!((sigma_across(&p, core::f64::consts::FRAC_PI_2) - 2.0).abs() < 1e-12, "heading north");
        // Correlated: along the diagonal the variance is (4 + 0.25)/2 ± the covariance.
        p[(0, 1)] = 0.5;
        p[(1, 0)] = 0.5;
        let diagonal = sigma_across(&p, core::f64::consts::FRAC_PI_4);
        assert!((diagonal - (2.125f64 - 0.5).sqrt()).abs() < 1e-12, "{diagonal}");
    }
}
