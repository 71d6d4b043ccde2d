//! The routes between the pipeline's stages: what one stage's output makes another do. Each
//! stage keeps its own state and is handed what it needs; only here does the output of
//! one (a fix, a speed, a dead-reckoned pose) go on to the others.

use embedded_io::Write;

use super::gnss::{self, Fix, Reading};
use super::issues::Issue;
use super::signals::GnssFrame;
use super::{inertial, tracking, ImageDetection, PipelineError, State};
use crate::anchor::gnss_sigma;
use crate::decimal::Decimal;
use crate::nmea::StreamEvent;
use crate::sim3::Pose;
use crate::time::Timestamp;
use crate::track3d::Detection3d;

impl<W: Write, const T3: usize, const T2: usize, const BUF: usize> State<'_, W, T3, T2, BUF> {
    /// An NMEA stream's event; a finished epoch's fix goes on.
    pub(super) fn on_nmea(&mut self, t: Timestamp, event: &StreamEvent<'_>) -> Result<(), PipelineError<W::Error>> {
        match self.gnss.nmea(&mut self.log, t, event)? {
            Some((rx, fix)) => self.on_fix(rx, &fix),
            None => Ok(()),
        }
    }

    /// A decoded CAN frame; a speed or a fix it carries goes on.
    pub(super) fn on_can(&mut self, t: Timestamp, event: crate::can::Event) -> Result<(), PipelineError<W::Error>> {
        match self.gnss.can(&mut self.log, self.config.speed, t, event)? {
            Some(Reading::Speed { mps, source }) => self.speed(t, mps, source),
            Some(Reading::Fix(fix)) => self.on_fix(t, &fix),
            None => Ok(()),
        }
    }

    /// A frame of DBC-defined GNSS signals; a fix goes on.
    pub(super) fn on_gnss_signals(&mut self, t: Timestamp, read: GnssFrame) -> Result<(), PipelineError<W::Error>> {
        match self.gnss.signals(&mut self.log, t, read)? {
            Some(fix) => self.on_fix(t, &fix),
            None => Ok(()),
        }
    }

    /// A vehicle speed, m/s: to the anchorer (refused: an issue), the IMU, the log.
    pub(super) fn speed(&mut self, t: Timestamp, mps: f64, source: i64) -> Result<(), PipelineError<W::Error>> {
        if !self.anchoring.speed(t, mps) {
            return self.log.issue(t, Issue::SpeedRefused, 1);
        }
        self.inertial.on_speed(t, mps);
        self.gnss.speed(&mut self.log, t, mps, source)
    }

    /// A fix received at `rx`: into the log (and its clock); its course to the gyro's bias
    /// and, fast enough, to the anchorer as a not yet anchored session's yaw; its position
    /// to the anchorer with its σ.
    pub(super) fn on_fix(&mut self, rx: Timestamp, fix: &Fix) -> Result<(), PipelineError<W::Error>> {
        let Some(position) = gnss::GnssIngest::fix(&mut self.log, self.config.origin.height_m, rx, fix)? else {
            return Ok(());
        };
        if let (Some(speed), Some(track)) = (fix.speed, fix.track_deg) {
            self.inertial.course(rx.as_secs_f64(), track.to_radians(), speed);
            if let Some(sigma) = gnss::course_sigma(speed) {
                // A session not yet anchored takes its yaw from the course.
                if self.anchoring.course(rx, track.to_radians(), sigma) {
                    self.log.event(rx, 2, format_args!("anchor: the VO session's yaw from the GNSS course"))?;
                }
            }
        }
        let g = &self.config.gnss;
        let sigma = gnss_sigma(fix.hdop, fix.gst, g.uere_m).unwrap_or(g.default_sigma_m);
        if !self.anchoring.fix(rx, &position, sigma) {
            return self.log.issue(rx, Issue::GnssRefused, 1);
        }
        self.log.stats.fixes = self.log.stats.fixes.saturating_add(1);
        let Some(latency) = self.anchoring.receiver_latency() else { return Ok(()) };
        if !self.log.clock.receiver_latency(super::quantise(latency, 1e-6)) {
            return Ok(());
        }
        self.log.event(
            rx,
            2,
            format_args!(
                "GNSS receiver latency {} s, as anchoring finds it: the log's UTC slews by it",
                Decimal::new(latency, 3)
            ),
        )
    }

    /// An IMU sample; a dead-reckoned pose it makes due is anchored as a VO pose.
    pub(super) fn on_imu(
        &mut self,
        t: Timestamp,
        sample: &crate::imu::ImuSample,
    ) -> Result<(), PipelineError<W::Error>> {
        match self.inertial.push(&mut self.log, &self.config, t, sample)? {
            Some(frame) => self.dead_reckoned_vo(t, frame),
            None => Ok(()),
        }
    }

    /// Under gyro + wheels, camera frame `frame` (its detections arrive at `t`): its
    /// dead-reckoned pose, once per frame.
    pub(super) fn dead_reckoned_frame(&mut self, t: Timestamp, frame: u64) -> Result<(), PipelineError<W::Error>> {
        let later = self.anchoring.later_than_vo(t);
        if !self.inertial.frame_due(self.config.relative_motion, frame, later) {
            return Ok(());
        }
        self.dead_reckoned_vo(t, frame)
    }

    /// The dead reckoning's camera pose at `t`, anchored as frame `frame`'s VO pose; the
    /// mount calibration starts again when the car's forward axis has just become known.
    fn dead_reckoned_vo(&mut self, t: Timestamp, frame: u64) -> Result<(), PipelineError<W::Error>> {
        let (pose, forward_known) = self.inertial.camera_pose(&self.config.mount);
        if forward_known {
            self.anchoring.restart_calibration();
        }
        self.on_vo(t, frame, inertial::DEAD_RECKONING_SESSION, &pose)
    }

    /// A VO pose: anchored; the ego it makes to the windows.
    pub(super) fn on_vo(
        &mut self,
        t: Timestamp,
        frame: u64,
        session: u32,
        pose: &Pose,
    ) -> Result<(), PipelineError<W::Error>> {
        let speed = self.gnss.last_speed();
        let anchored =
            self.anchoring.vo(&mut self.log, &self.config, &self.inertial, speed, t, frame, session, pose)?;
        let Some(anchored) = anchored else { return Ok(()) };
        if anchored.first {
            self.windows.anchored_first_at(t.as_secs_f64());
        }
        self.windows.ego_in_doubt(self.config.window_doubt_sigmas * anchored.sigma);
        self.windows.ego(&self.config, &mut self.log, t, anchored.eased, anchored.motion)
    }

    /// A frame's 3D detections: placed through the anchoring's ego and mount into the
    /// tracker (written raw without an ego), their tracks to the windows as agents.
    pub(super) fn on_detections(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[Detection3d],
    ) -> Result<(), PipelineError<W::Error>> {
        let frame = self.anchoring.frame(frame);
        if !self.tracking.frame3d_in_order(frame) {
            return self.log.issue(t, Issue::DetectionsOutOfOrder, 1);
        }
        let (has_vo, ego) = self.anchoring.pose_for(self.config.max_pose_age, t, frame);
        let classes = self.config.classes;
        let Some(ego) = ego else {
            if !has_vo {
                self.log.issue(t, Issue::DetectionsWithoutPose, detections.len().max(1) as u64)?;
            }
            return self.tracking.write_raw(&mut self.log, classes, t, frame, detections);
        };
        self.anchoring.detections_seen(detections);
        let camera_mount = self.anchoring.mount().mount;
        let Some(outputs) = self.tracking.track(&mut self.log, t, frame, &ego, &camera_mount, detections)? else {
            return self.log.issue(t, Issue::DetectionsOutOfOrder, 1);
        };
        let per_second = self.anchoring.frames_per_second();
        tracking::write_tracks(&mut self.log, classes, t, &ego, per_second, &outputs)?;
        let reports = |id| outputs.iter().any(|o| o.id == id);
        self.windows.agents_reported(t.as_secs_f64(), reports, tracking::agents(classes, per_second, &outputs));
        Ok(())
    }

    /// A frame's 2D detections into the IoU tracker.
    pub(super) fn on_detections2d(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[ImageDetection],
    ) -> Result<(), PipelineError<W::Error>> {
        let frame = self.anchoring.frame(frame);
        self.tracking.detections2d(&mut self.log, t, frame, detections)
    }
}
