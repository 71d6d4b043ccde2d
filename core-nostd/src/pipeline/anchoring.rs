//! VO and anchoring: each VO pose into the mount calibration and the anchorer (one
//! similarity per VO session, the ego carried across a re-initialisation), the anchored and
//! eased ego written to the log and handed on to the windows.

use embedded_io::Write;

use super::anchor_record;
use super::calibration::{CalibrationConfig, MountCalibration, MountEstimate};
use super::issues::Issue;
use super::{
    carry, ease, euler, lag, mount, mount_record, quantise, PipelineConfig, PipelineError, RelativeMotion, State,
};
use crate::anchor::{Anchorer, Observability};
use crate::binlog::{EgoPose, FrameMeta, Record, VoPose, FRAME_DEAD_RECKONED};
use crate::decimal::Decimal;
use crate::geo::LocalFrame;
use crate::obb::Pose2;
use crate::sim3::Pose;
use crate::time::Timestamp;

/// What anchoring keeps between VO poses.
#[derive(Debug)]
pub(super) struct Anchoring {
    pub(super) local: LocalFrame,
    pub(super) anchorer: Anchorer,
    pub(super) observability: Observability,
    pub(super) last_anchor_record: Option<Timestamp>,
    pub(super) calibration: MountCalibration,
    /// The ego carried across a VO re-initialisation until the new session is anchored.
    pub(super) carry: Option<carry::Carry>,
    /// The camera's world pose, the ego heading and the position's σ (m) at the latest
    /// anchored frame.
    pub(super) last_camera: Option<(Timestamp, Pose, f64, f64)>,
    /// The gyro's heading at that frame (rad), when the dashcam has an IMU: the turn across
    /// a VO gap is measured from it.
    pub(super) last_camera_gyro: Option<f64>,
    /// The anchored ego's turn rate, carried with the attitude across a VO gap.
    pub(super) turn_rate: carry::TurnRate,
    /// The ego the windows score, with the corrections eased in, and the VO session and
    /// pose it was last given.
    pub(super) ease: ease::Ease,
    pub(super) eased_vo: Option<(u32, Pose)>,
    /// The eased ego, smoothed a second late for the windows.
    pub(super) lag: lag::FixedLag,
    /// The mount poses and detections are placed with (the calibration's estimate).
    pub(super) mount: MountEstimate,
    pub(super) last_mount_record: Option<Timestamp>,
    /// Internal frame number = the camera's + this (raised when the camera restarts).
    pub(super) frame_offset: u64,
    /// The latest VO pose, with its internal frame number.
    pub(super) vo: Option<LastVo>,
    pub(super) ego: Option<Ego>,
    /// Seconds per frame number (for track velocities in m/s).
    pub(super) frame_interval: f64,
    /// The VO session's vertical from gravity.
    pub(super) vertical: super::vertical::Vertical,
}

impl Anchoring {
    pub(super) fn new(config: &PipelineConfig<'_>) -> Self {
        Anchoring {
            local: LocalFrame::new(config.origin),
            anchorer: Anchorer::new(match config.relative_motion {
                RelativeMotion::Vo => config.anchor,
                RelativeMotion::ImuWheels => {
                    crate::anchor::AnchorConfig { mode: crate::anchor::AnchorMode::GravityAligned, ..config.anchor }
                }
            }),
            observability: Observability::TooFewAnchors,
            last_anchor_record: None,
            calibration: MountCalibration::new(
                config.mount,
                CalibrationConfig {
                    pitch_from_ground: config.relative_motion == RelativeMotion::ImuWheels,
                    ..config.calibration
                },
            ),
            carry: None,
            last_camera: None,
            last_camera_gyro: None,
            turn_rate: carry::TurnRate::default(),
            ease: ease::Ease::new(config.ease_s),
            eased_vo: None,
            lag: lag::FixedLag::new(),
            mount: MountCalibration::new(config.mount, config.calibration).estimate(),
            last_mount_record: None,
            frame_offset: 0,
            vo: None,
            ego: None,
            frame_interval: 0.1,
            vertical: super::vertical::Vertical::default(),
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub(super) struct LastVo {
    pub(super) t: Timestamp,
    pub(super) frame: u64,
    pub(super) session: u32,
}

#[derive(Clone, Copy, Debug)]
pub(super) struct Ego {
    pub(super) t: Timestamp,
    pub(super) frame: u64,
    /// The anchored pose (the log's).
    pub(super) pose: Pose2,
    /// The eased pose (the windows', and the detections' placement: [`ease`]).
    pub(super) eased: Pose2,
    /// Height of the rear axle's ground point (ENU up), m.
    pub(super) z: f64,
}

impl<W: Write, const T3: usize, const T2: usize, const BUF: usize> State<'_, W, T3, T2, BUF> {
    pub(super) fn on_vo(
        &mut self,
        t: Timestamp,
        frame: u64,
        session: u32,
        pose: &Pose,
    ) -> Result<(), PipelineError<W::Error>> {
        if !pose.is_finite() {
            return self.log.issue(t, Issue::VoNotFinite, 1);
        }
        if self.anchoring.vo.is_some_and(|v| t <= v.t) {
            return self.log.issue(t, Issue::VoOutOfOrder, 1);
        }
        let raw_frame = frame;
        let mut frame = raw_frame.saturating_add(self.anchoring.frame_offset);
        let restarted = self.anchoring.vo.is_some_and(|v| frame <= v.frame);
        if let Some(v) = self.anchoring.vo.filter(|v| v.session != session) {
            self.new_session(t, &v, session, pose)?;
        }
        let up_in_camera = self.inertial.up_in_camera(&self.config.mount.rotation());
        let motion = self.config.relative_motion;
        self.anchoring.level_session(&mut self.log, motion, up_in_camera, t, session, pose)?;
        if self.anchoring.anchorer.push_vo(t, pose.translation).is_err() {
            return self.log.issue(t, Issue::VoOutOfOrder, 1);
        }
        if let Some(v) = self.anchoring.vo {
            if restarted {
                // Frame numbers went back while time went on: the camera process restarted.
                // Internally frames go on counting, so that the trackers keep their tracks.
                self.anchoring.frame_offset = v.frame.saturating_add(1).saturating_sub(raw_frame);
                frame = raw_frame.saturating_add(self.anchoring.frame_offset);
                self.log.issue(t, Issue::CameraRestarted, 1)?;
            }
            // Saturating: frame numbers near u64::MAX (untrusted) leave `frame` no further on
            // than the last one.
            let skipped = frame.saturating_sub(v.frame).saturating_sub(1);
            if skipped > 0 {
                self.log.issue(t, Issue::FramesMissing, skipped)?;
            }
            let per_frame = (t - v.t).as_secs_f64() / frame.saturating_sub(v.frame) as f64;
            if per_frame.is_finite() && per_frame > 0.0 {
                self.anchoring.frame_interval = per_frame;
            }
        }
        self.anchoring.vo = Some(LastVo { t, frame, session });
        self.log.stats.vo_poses = self.log.stats.vo_poses.saturating_add(1);
        let t_us = self.log.time(t);
        // The log keeps the camera's own numbers (sequence gaps and restarts show there).
        let frame_i64 = i64::try_from(raw_frame).unwrap_or(i64::MAX);
        // Under gyro + wheels every pose is dead-reckoned (the camera's VO is not used).
        let flags = if self.config.relative_motion == RelativeMotion::ImuWheels { FRAME_DEAD_RECKONED } else { 0 };
        self.log.write(&Record::FrameMeta(FrameMeta { t_us, frame: frame_i64, flags }))?;
        let [yaw, pitch, roll] = euler(&pose.rotation);
        let p = &pose.translation;
        self.log.write(&Record::VoPose(VoPose {
            t_us,
            x: quantise(p.x, 1e-3),
            y: quantise(p.y, 1e-3),
            z: quantise(p.z, 1e-3),
            yaw_e4: quantise(yaw, 1e-4),
            pitch_e4: quantise(pitch, 1e-4),
            roll_e4: quantise(roll, 1e-4),
            session: i64::from(session),
        }))?;
        self.calibrate(t, session, pose)?;
        self.anchor_changes(t)?;
        let (anchor, carried) = match self.anchoring.anchorer.estimate().copied() {
            Some(anchor) => {
                if let Some(c) = self.anchoring.carry.take() {
                    let after = t.as_secs_f64() - c.since();
                    self.log.event(
                        t,
                        2,
                        format_args!(
                            "ego anchored again in VO session {session}, {} s after the last anchored pose",
                            Decimal::new(after, 1)
                        ),
                    )?;
                }
                (anchor, false)
            }
            None => {
                let speed = self.gnss.last_speed() * self.anchoring.anchorer.wheel_factor().unwrap_or(1.0);
                let turn = self.gap_turn(t).map_or(0.0, |turn| turn.angle);
                match self.anchoring.carry.as_mut().and_then(|c| c.push(t.as_secs_f64(), pose, speed, turn)) {
                    Some(anchor) => (anchor, true),
                    None => return Ok(()),
                }
            }
        };
        let camera = mount::camera_in_world(&anchor, pose);
        let body = self.anchoring.mount.mount.body_pose(&camera);
        let b = &body.translation;
        let anchored = Pose2::new(b.x, b.y, mount::heading(&body.rotation));
        if !(anchored.is_finite() && b.z.is_finite()) {
            return Ok(());
        }
        // The previous eased frame's VO pose through this frame's similarity and mount: the
        // VO's motion since, apart from the anchorer's correction.
        let moved_from = self.anchoring.eased_vo.filter(|(s, _)| *s == session).map(|(_, previous)| {
            let body = self.anchoring.mount.mount.body_pose(&mount::camera_in_world(&anchor, &previous));
            Pose2::new(body.translation.x, body.translation.y, mount::heading(&body.rotation))
        });
        let eased = self.anchoring.ease.push(t.as_secs_f64(), anchored, moved_from);
        self.anchoring.eased_vo = Some((session, *pose));
        // A carried pose is the last anchored one's σ plus what dead reckoning may add.
        let sigma = match self.anchoring.last_camera.filter(|_| carried) {
            Some((tc, _, _, sigma)) => sigma + carry::CARRY_SPEED_SIGMA * (t - tc).as_secs_f64(),
            None => self.anchoring.anchorer.quality().position_sigma_m,
        };
        let ego = Ego { t, frame, pose: anchored, eased, z: b.z };
        self.anchoring.ego = Some(ego);
        if carried {
            self.log.stats.carried_frames = self.log.stats.carried_frames.saturating_add(1);
        } else {
            self.anchoring.last_camera = Some((t, camera, anchored.heading, sigma));
            self.anchoring.last_camera_gyro = self.inertial.heading();
            self.anchoring.turn_rate.push(t.as_secs_f64(), anchored.heading);
            if self.log.stats.anchored_frames == 0 {
                self.windows.anchored_first_at(t.as_secs_f64());
            }
            self.log.stats.anchored_frames = self.log.stats.anchored_frames.saturating_add(1);
        }
        self.log.write(&Record::EgoPose(EgoPose {
            t_us,
            x_mm: quantise(b.x, 1e-3),
            y_mm: quantise(b.y, 1e-3),
            z_mm: quantise(b.z, 1e-3),
            yaw_e4: quantise(ego.pose.heading, 1e-4),
            sigma_mm: quantise(sigma.min(1e6), 1e-3),
        }))?;
        self.windows.ego_in_doubt(self.config.window_doubt_sigmas * sigma);
        for (at, smoothed) in self.anchoring.lag.push(t, eased) {
            self.windows.score(&self.config, &mut self.log, at, &smoothed)?;
        }
        Ok(())
    }

    /// The VO started again under a new session number, `first` its first pose: anchoring
    /// starts afresh (the old similarity's position and scale say nothing of the new VO
    /// frame), with the camera's attitude carried across the gap as the prior on the new
    /// rotation; until the new session is observable the ego is carried.
    pub(super) fn new_session(
        &mut self,
        t: Timestamp,
        last: &LastVo,
        session: u32,
        first: &Pose,
    ) -> Result<(), PipelineError<W::Error>> {
        if session < last.session {
            self.log.issue(t, Issue::VoSessionBackwards, 1)?;
        }
        let old_rotation_sigma = self.anchoring.anchorer.quality().rotation_sigma_rad;
        self.anchoring.anchorer.new_vo_session();
        if let Some((tc, camera, _, _)) = self.anchoring.last_camera {
            let gap = (t - tc).as_secs_f64();
            let turn = self.gap_turn(t).unwrap_or(carry::Turn::extrapolated(self.anchoring.turn_rate.rate(), gap));
            let (rotation, sigma) = carry::rotation_prior(&camera, turn, first, old_rotation_sigma);
            // Refused only when the old session's rotation σ is not finite: then no prior.
            let _ = self.anchoring.anchorer.set_rotation_prior(rotation, sigma);
        }
        self.anchoring.ego = None;
        self.anchoring.carry = self
            .anchoring
            .last_camera
            .map(|(tc, camera, heading, _)| carry::Carry::new(camera, tc.as_secs_f64(), heading));
        let gap = (t - last.t).as_secs_f64();
        let until = if self.anchoring.carry.is_some() {
            "; until it is observable (for at most 10 s) the ego is carried by the last anchored pose and wheel speed"
        } else {
            ""
        };
        self.log.event(
            t,
            3,
            format_args!(
                "VO session {session} began {} s after the last pose of session {}: anchoring starts again{until}",
                Decimal::new(gap, 1),
                last.session
            ),
        )
    }

    /// How far the car turned since the last anchored frame, by the gyro (none without an
    /// IMU, or before its attitude settled then).
    fn gap_turn(&self, t: Timestamp) -> Option<carry::Turn> {
        let (tc, ..) = self.anchoring.last_camera?;
        self.inertial.turn_since(self.anchoring.last_camera_gyro?, (t - tc).as_secs_f64())
    }

    /// The pose into the mount calibration; the estimate as a record when it is due, an
    /// event when it is first calibrated.
    pub(super) fn calibrate(&mut self, t: Timestamp, session: u32, pose: &Pose) -> Result<(), PipelineError<W::Error>> {
        if !self.anchoring.calibration.push(t.as_secs_f64(), session, pose) {
            return Ok(());
        }
        let was_calibrated = self.anchoring.mount.calibrated;
        self.anchoring.mount = self.anchoring.calibration.estimate();
        if self.anchoring.mount.calibrated && !was_calibrated {
            let [_, pitch, yaw] = self.anchoring.mount.mount.roll_pitch_yaw;
            let [sy, sp] = self.anchoring.mount.sigma;
            let samples = self.anchoring.mount.samples;
            self.log.event(
                t,
                2,
                format_args!(
                    "camera mount calibrated from {} straight-driving frames: yaw {}° ±{}°, pitch {}° ±{}°",
                    samples,
                    Decimal::signed(yaw.to_degrees(), 2),
                    Decimal::new(sy.to_degrees(), 2),
                    Decimal::signed(pitch.to_degrees(), 2),
                    Decimal::new(sp.to_degrees(), 2)
                ),
            )?;
        } else if self.anchoring.last_mount_record.is_some_and(|last| t - last < self.config.anchor_interval) {
            return Ok(());
        }
        self.anchoring.last_mount_record = Some(t);
        self.log.write(&Record::MountEstimate(mount_record(self.log.time(t), &self.anchoring.mount)))
    }

    /// At the end: the last estimate, and an event when the drive never calibrated it.
    pub(super) fn close_calibration(&mut self, t: Timestamp) -> Result<(), PipelineError<W::Error>> {
        let m = self.anchoring.mount;
        if m.samples > 0 {
            self.log.write(&Record::MountEstimate(mount_record(self.log.time(t), &m)))?;
        }
        if m.calibrated {
            return Ok(());
        }
        let kept = if m.samples == 0 { "the nominal mount was kept" } else { "the nominal mount still weighs in" };
        self.log.event(
            t,
            3,
            format_args!(
                "camera mount not calibrated: {} straight-driving frames (yaw ±{}°, pitch ±{}°); {kept}",
                m.samples,
                Decimal::new(m.sigma[0].to_degrees(), 2),
                Decimal::new(m.sigma[1].to_degrees(), 2)
            ),
        )
    }

    /// Observability changes as events, the estimate as a record when it is due.
    pub(super) fn anchor_changes(&mut self, t: Timestamp) -> Result<(), PipelineError<W::Error>> {
        let quality = *self.anchoring.anchorer.quality();
        let changed = quality.observability != self.anchoring.observability;
        if changed {
            self.anchoring.observability = quality.observability;
            let scale = self.anchoring.anchorer.estimate().map_or(f64::NAN, |e| e.scale);
            self.log.event(
                t,
                2,
                format_args!(
                    "anchor: {:?} after {} fixes (scale {} ±{} %, geometry σ {} m)",
                    quality.observability,
                    quality.anchors_used,
                    Decimal::new(scale, 4),
                    Decimal::new(100.0 * quality.scale_rel_sigma, 2),
                    Decimal::new(quality.geometry_sigma_m, 2)
                ),
            )?;
        }
        let Some(estimate) = self.anchoring.anchorer.estimate().copied() else { return Ok(()) };
        let due = self.anchoring.last_anchor_record.is_none_or(|last| t - last >= self.config.anchor_interval);
        if !(changed || due) {
            return Ok(());
        }
        self.anchoring.last_anchor_record = Some(t);
        self.log.write(&Record::AnchorEstimate(anchor_record(self.log.time(t), &estimate, &quality)))
    }

    /// The VO pose a detection of `frame` at `t` belongs with: the anchored ego, or none.
    pub(super) fn pose_for(&self, t: Timestamp, frame: u64) -> (bool, Option<Ego>) {
        let near = |ft: Timestamp, f: u64| {
            f == frame || (t - ft).micros().saturating_abs() <= self.config.max_pose_age.micros()
        };
        let has_vo = self.anchoring.vo.is_some_and(|v| near(v.t, v.frame));
        (has_vo, self.anchoring.ego.filter(|e| near(e.t, e.frame)))
    }
}
