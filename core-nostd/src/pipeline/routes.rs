//! The routes between the pipeline's stages: what one stage's output makes another do. Each
//! stage keeps its own state and is handed what it needs; only here does the output of
//! one (a fix, a speed, a dead-reckoned pose) go on to the others.

use embedded_io::Write;

use super::gnss::{self, Fix, Reading};
use super::issues::Issue;
use super::signals::GnssFrame;
use super::{inertial, PipelineError, State};
use crate::anchor::gnss_sigma;
use crate::nmea::StreamEvent;
use crate::time::Timestamp;

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
        if self.anchoring.anchorer.push_speed(t, mps).is_err() {
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
                if self.anchoring.anchorer.push_course(rx, track.to_radians(), sigma) {
                    self.log.event(rx, 2, format_args!("anchor: the VO session's yaw from the GNSS course"))?;
                }
            }
        }
        let g = &self.config.gnss;
        let sigma = gnss_sigma(fix.hdop, fix.gst, g.uere_m).unwrap_or(g.default_sigma_m);
        let enu = self.anchoring.local.geodetic_to_enu(&position);
        if self.anchoring.anchorer.push_gnss(rx, enu, sigma).is_err() {
            return self.log.issue(rx, Issue::GnssRefused, 1);
        }
        self.log.stats.fixes = self.log.stats.fixes.saturating_add(1);
        Ok(())
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
        let later = self.anchoring.vo.is_none_or(|v| t > v.t);
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
            self.anchoring.calibration.restart();
        }
        self.on_vo(t, frame, inertial::DEAD_RECKONING_SESSION, &pose)
    }
}
