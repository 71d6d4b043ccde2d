//! VO and anchoring: each VO pose into the mount calibration and the anchorer (one
//! similarity per VO session, the ego carried across a re-initialisation), the anchored and
//! eased ego written to the log and handed on to the windows.

use embedded_io::Write;
use nalgebra::Vector3;

use super::anchor_record;
use super::calibration::{CalibrationConfig, MountCalibration, MountEstimate};
use super::inertial::Inertial;
use super::issues::Issue;
use super::sink::LogSink;
use super::{carry, ease, euler, mount, mount_record, quantise, PipelineConfig, PipelineError, RelativeMotion};
use crate::anchor::{AnchorMode, Anchorer, Observability};
use crate::binlog::{EgoPose, FrameMeta, Record, VoPose, FRAME_DEAD_RECKONED};
use crate::decimal::Decimal;
use crate::geo::{Geodetic, LocalFrame};
use crate::obb::Pose2;
use crate::sim3::Pose;
use crate::time::{Duration, Timestamp};
use crate::track3d::Detection3d;

/// What anchoring keeps between VO poses.
#[derive(Debug)]
pub(super) struct Anchoring {
    local: LocalFrame,
    anchorer: Anchorer,
    observability: Observability,
    last_anchor_record: Option<Timestamp>,
    calibration: MountCalibration,
    /// The ego carried across a VO re-initialisation until the new session is anchored.
    carry: Option<carry::Carry>,
    /// The camera's world pose, the ego heading and the position's σ (m) at the latest
    /// anchored frame.
    last_camera: Option<(Timestamp, Pose, f64, f64)>,
    /// The gyro's heading at that frame (rad), when the dashcam has an IMU: the turn across
    /// a VO gap is measured from it.
    last_camera_gyro: Option<f64>,
    /// The anchored ego's turn rate, carried with the attitude across a VO gap.
    turn_rate: carry::TurnRate,
    /// The ego the windows score, with the corrections eased in, and the VO session and
    /// pose it was last given.
    ease: ease::Ease,
    eased_vo: Option<(u32, Pose)>,
    /// The mount poses and detections are placed with (the calibration's estimate).
    mount: MountEstimate,
    last_mount_record: Option<Timestamp>,
    /// Internal frame number = the camera's + this (raised when the camera restarts).
    frame_offset: u64,
    /// The latest VO pose, with its internal frame number.
    vo: Option<LastVo>,
    ego: Option<Ego>,
    /// Seconds per frame number (for track velocities in m/s).
    frame_interval: f64,
    /// The VO session's vertical from gravity.
    vertical: super::vertical::Vertical,
}

impl Anchoring {
    pub(super) fn new(config: &PipelineConfig<'_>) -> Self {
        Anchoring {
            local: LocalFrame::new(config.origin),
            anchorer: Anchorer::new(match config.relative_motion {
                RelativeMotion::Vo => config.anchor,
                RelativeMotion::ImuWheels => {
                    crate::anchor::AnchorConfig { mode: AnchorMode::GravityAligned, ..config.anchor }
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

/// What a VO pose made of the ego, for the windows.
#[derive(Clone, Copy, Debug)]
pub(super) struct Anchored {
    /// The drive's first anchored pose.
    pub(super) first: bool,
    /// The position's σ (m), anchored or carried.
    pub(super) sigma: f64,
    /// The eased ego.
    pub(super) eased: Pose2,
    /// The eased ego less the corrections eased in: the relative motion's path alone.
    pub(super) motion: Pose2,
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

impl Anchoring {
    /// The anchorer (the pipeline's accessor).
    pub(super) fn anchorer(&self) -> &Anchorer {
        &self.anchorer
    }

    /// The mount poses and detections are placed with.
    pub(super) fn mount(&self) -> &MountEstimate {
        &self.mount
    }

    /// The pipeline's internal number of the camera's frame `frame` (raised past a restart).
    pub(super) fn frame(&self, frame: u64) -> u64 {
        frame.saturating_add(self.frame_offset)
    }

    /// Frame numbers per second (for track velocities in m/s).
    pub(super) fn frames_per_second(&self) -> f64 {
        1.0 / self.frame_interval
    }

    /// Whether `t` is later than the latest VO pose (or there is none).
    pub(super) fn later_than_vo(&self, t: Timestamp) -> bool {
        self.vo.is_none_or(|v| t > v.t)
    }

    /// The mount calibration starts again (the car's forward axis has just become known).
    pub(super) fn restart_calibration(&mut self) {
        self.calibration.restart();
    }

    /// 3D detections placed with the ego: to the mount calibration (its pitch from the
    /// ground, when configured).
    pub(super) fn detections_seen(&mut self, detections: &[Detection3d]) {
        for d in detections {
            self.calibration.push_detection(d);
        }
    }

    /// A vehicle speed, m/s, to the anchorer; `false`: refused.
    pub(super) fn speed(&mut self, t: Timestamp, mps: f64) -> bool {
        self.anchorer.push_speed(t, mps).is_ok()
    }

    /// A GNSS course, rad, with its σ: a session not yet anchored takes its yaw from it
    /// (`true` when it did).
    pub(super) fn course(&mut self, rx: Timestamp, track: f64, sigma: f64) -> bool {
        self.anchorer.push_course(rx, track, sigma)
    }

    /// The GNSS receiver's latency, s, as the anchorer estimates it once anchored, where
    /// the drive has shown it.
    pub(super) fn receiver_latency(&self) -> Option<f64> {
        let quality = self.anchorer.quality();
        quality.latency_s.filter(|_| quality.latency_shown && quality.observability == Observability::Observable)
    }

    /// A fix's position, with its σ (m), to the anchorer; `false`: refused.
    pub(super) fn fix(&mut self, rx: Timestamp, position: &Geodetic, sigma: f64) -> bool {
        let enu = self.local.geodetic_to_enu(position);
        self.anchorer.push_gnss(rx, enu, sigma).is_ok()
    }

    /// A VO pose of frame `frame` (the camera's number) in VO session `session`: into the
    /// mount calibration and the anchorer, the frame, the pose and the anchored (or
    /// carried) ego to the log. `imu` is the IMU stage, read for its vertical, heading and
    /// turn; `speed` the latest vehicle speed (m/s). Returns what the windows take of the
    /// ego, when there is one.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn vo<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        config: &PipelineConfig<'_>,
        imu: &Inertial,
        speed: f64,
        t: Timestamp,
        frame: u64,
        session: u32,
        pose: &Pose,
    ) -> Result<Option<Anchored>, PipelineError<W::Error>> {
        if !pose.is_finite() {
            return log.issue(t, Issue::VoNotFinite, 1).map(|()| None);
        }
        if self.vo.is_some_and(|v| t <= v.t) {
            return log.issue(t, Issue::VoOutOfOrder, 1).map(|()| None);
        }
        let raw_frame = frame;
        let mut frame = raw_frame.saturating_add(self.frame_offset);
        let restarted = self.vo.is_some_and(|v| frame <= v.frame);
        if let Some(v) = self.vo.filter(|v| v.session != session) {
            self.new_session(log, imu, t, &v, session, pose)?;
        }
        let up_in_camera = imu.up_in_camera(&config.mount.rotation());
        let motion = config.relative_motion;
        self.level_session(log, motion, up_in_camera, t, session, pose)?;
        if self.anchorer.push_vo(t, pose.translation).is_err() {
            return log.issue(t, Issue::VoOutOfOrder, 1).map(|()| None);
        }
        if let Some(v) = self.vo {
            if restarted {
                // Frame numbers went back while time went on: the camera process restarted.
                // Internally frames go on counting, so that the trackers keep their tracks.
                self.frame_offset = v.frame.saturating_add(1).saturating_sub(raw_frame);
                frame = raw_frame.saturating_add(self.frame_offset);
                log.issue(t, Issue::CameraRestarted, 1)?;
            }
            // Saturating: frame numbers near u64::MAX (untrusted) leave `frame` no further on
            // than the last one.
            let skipped = frame.saturating_sub(v.frame).saturating_sub(1);
            if skipped > 0 {
                log.issue(t, Issue::FramesMissing, skipped)?;
            }
            let per_frame = (t - v.t).as_secs_f64() / frame.saturating_sub(v.frame) as f64;
            if per_frame.is_finite() && per_frame > 0.0 {
                self.frame_interval = per_frame;
            }
        }
        self.vo = Some(LastVo { t, frame, session });
        log.stats.vo_poses = log.stats.vo_poses.saturating_add(1);
        let t_us = log.time(t);
        // The log keeps the camera's own numbers (sequence gaps and restarts show there).
        let frame_i64 = i64::try_from(raw_frame).unwrap_or(i64::MAX);
        // Under gyro + wheels every pose is dead-reckoned (the camera's VO is not used).
        let flags = if config.relative_motion == RelativeMotion::ImuWheels { FRAME_DEAD_RECKONED } else { 0 };
        log.write(&Record::FrameMeta(FrameMeta { t_us, frame: frame_i64, flags }))?;
        let [yaw, pitch, roll] = euler(&pose.rotation);
        let p = &pose.translation;
        log.write(&Record::VoPose(VoPose {
            t_us,
            x: quantise(p.x, 1e-3),
            y: quantise(p.y, 1e-3),
            z: quantise(p.z, 1e-3),
            yaw_e4: quantise(yaw, 1e-4),
            pitch_e4: quantise(pitch, 1e-4),
            roll_e4: quantise(roll, 1e-4),
            session: i64::from(session),
        }))?;
        self.calibrate(log, config, t, session, pose)?;
        self.anchor_changes(log, config, t)?;
        let (anchor, carried) = match self.anchorer.estimate().copied() {
            Some(anchor) => {
                if let Some(c) = self.carry.take() {
                    let after = t.as_secs_f64() - c.since();
                    log.event(
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
                let speed = speed * self.anchorer.wheel_factor().unwrap_or(1.0);
                let turn = self.gap_turn(imu, t).map_or(0.0, |turn| turn.angle);
                match self.carry.as_mut().and_then(|c| c.push(t.as_secs_f64(), pose, speed, turn)) {
                    Some(anchor) => (anchor, true),
                    None => return Ok(None),
                }
            }
        };
        let camera = mount::camera_in_world(&anchor, pose);
        let body = self.mount.mount.body_pose(&camera);
        let b = &body.translation;
        let anchored = Pose2::new(b.x, b.y, mount::heading(&body.rotation));
        if !(anchored.is_finite() && b.z.is_finite()) {
            return Ok(None);
        }
        // The previous eased frame's VO pose through this frame's similarity and mount: the
        // VO's motion since, apart from the anchorer's correction.
        let moved_from = self.eased_vo.filter(|(s, _)| *s == session).map(|(_, previous)| {
            let body = self.mount.mount.body_pose(&mount::camera_in_world(&anchor, &previous));
            Pose2::new(body.translation.x, body.translation.y, mount::heading(&body.rotation))
        });
        let eased = self.ease.push(t.as_secs_f64(), anchored, moved_from);
        self.eased_vo = Some((session, *pose));
        // A carried pose is the last anchored one's σ plus what dead reckoning may add.
        let sigma = match self.last_camera.filter(|_| carried) {
            Some((tc, _, _, sigma)) => sigma + carry::CARRY_SPEED_SIGMA * (t - tc).as_secs_f64(),
            None => self.anchorer.quality().position_sigma_m,
        };
        let ego = Ego { t, frame, pose: anchored, eased, z: b.z };
        self.ego = Some(ego);
        let mut first = false;
        if carried {
            log.stats.carried_frames = log.stats.carried_frames.saturating_add(1);
        } else {
            self.last_camera = Some((t, camera, anchored.heading, sigma));
            self.last_camera_gyro = imu.heading();
            self.turn_rate.push(t.as_secs_f64(), anchored.heading);
            first = log.stats.anchored_frames == 0;
            log.stats.anchored_frames = log.stats.anchored_frames.saturating_add(1);
        }
        log.write(&Record::EgoPose(EgoPose {
            t_us,
            x_mm: quantise(b.x, 1e-3),
            y_mm: quantise(b.y, 1e-3),
            z_mm: quantise(b.z, 1e-3),
            yaw_e4: quantise(ego.pose.heading, 1e-4),
            sigma_mm: quantise(sigma.min(1e6), 1e-3),
        }))?;
        let motion = self.ease.motion().unwrap_or(eased);
        Ok(Some(Anchored { first, sigma, eased, motion }))
    }

    /// A VO pose's vertical into the session's mean, and the mean to the anchorer when due:
    /// `up_in_camera` is the IMU's vertical in the camera's axes (none before its attitude
    /// has settled). Only for a camera's VO (`relative_motion`) whose frame is not declared
    /// gravity-aligned already.
    pub(super) fn level_session<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        relative_motion: RelativeMotion,
        up_in_camera: Option<Vector3<f64>>,
        t: Timestamp,
        session: u32,
        pose: &Pose,
    ) -> Result<(), PipelineError<W::Error>> {
        if relative_motion != RelativeMotion::Vo || self.anchorer.config().mode != AnchorMode::Full {
            return Ok(());
        }
        let Some(up_in_camera) = up_in_camera else { return Ok(()) };
        let Some(sum) = self.vertical.push(session, &(pose.rotation * up_in_camera)) else {
            return Ok(());
        };
        let first = self.anchorer.mode() == AnchorMode::Full;
        if self.anchorer.level(&sum).is_err() || !first {
            return Ok(());
        }
        let poses = self.vertical.poses();
        log.event(
            t,
            2,
            format_args!("VO session {session} levelled by the IMU's gravity over {poses} poses: anchored gravity-aligned from here"),
        )
    }

    /// The VO started again under a new session number, `first` its first pose: anchoring
    /// starts afresh (the old similarity's position and scale say nothing of the new VO
    /// frame), with the camera's attitude carried across the gap as the prior on the new
    /// rotation; until the new session is observable the ego is carried.
    fn new_session<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        imu: &Inertial,
        t: Timestamp,
        last: &LastVo,
        session: u32,
        first: &Pose,
    ) -> Result<(), PipelineError<W::Error>> {
        if session < last.session {
            log.issue(t, Issue::VoSessionBackwards, 1)?;
        }
        let old_rotation_sigma = self.anchorer.quality().rotation_sigma_rad;
        self.anchorer.new_vo_session();
        if let Some((tc, camera, _, _)) = self.last_camera {
            let gap = (t - tc).as_secs_f64();
            let turn = self.gap_turn(imu, t).unwrap_or(carry::Turn::extrapolated(self.turn_rate.rate(), gap));
            let (rotation, sigma) = carry::rotation_prior(&camera, turn, first, old_rotation_sigma);
            // Refused only when the old session's rotation σ is not finite: then no prior.
            let _ = self.anchorer.set_rotation_prior(rotation, sigma);
        }
        self.ego = None;
        self.carry =
            self.last_camera.map(|(tc, camera, heading, _)| carry::Carry::new(camera, tc.as_secs_f64(), heading));
        let gap = (t - last.t).as_secs_f64();
        let until = if self.carry.is_some() {
            "; until it is observable (for at most 10 s) the ego is carried by the last anchored pose and wheel speed"
        } else {
            ""
        };
        log.event(
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
    fn gap_turn(&self, imu: &Inertial, t: Timestamp) -> Option<carry::Turn> {
        let (tc, ..) = self.last_camera?;
        imu.turn_since(self.last_camera_gyro?, (t - tc).as_secs_f64())
    }

    /// The pose into the mount calibration; the estimate as a record when it is due, an
    /// event when it is first calibrated.
    fn calibrate<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        config: &PipelineConfig<'_>,
        t: Timestamp,
        session: u32,
        pose: &Pose,
    ) -> Result<(), PipelineError<W::Error>> {
        if !self.calibration.push(t.as_secs_f64(), session, pose) {
            return Ok(());
        }
        let was_calibrated = self.mount.calibrated;
        self.mount = self.calibration.estimate();
        if self.mount.calibrated && !was_calibrated {
            let [_, pitch, yaw] = self.mount.mount.roll_pitch_yaw;
            let [sy, sp] = self.mount.sigma;
            let samples = self.mount.samples;
            log.event(
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
        } else if self.last_mount_record.is_some_and(|last| t - last < config.anchor_interval) {
            return Ok(());
        }
        self.last_mount_record = Some(t);
        log.write(&Record::MountEstimate(mount_record(log.time(t), &self.mount)))
    }

    /// At the end: the last estimate, and an event when the drive never calibrated it.
    pub(super) fn close_calibration<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
    ) -> Result<(), PipelineError<W::Error>> {
        let m = self.mount;
        if m.samples > 0 {
            log.write(&Record::MountEstimate(mount_record(log.time(t), &m)))?;
        }
        if m.calibrated {
            return Ok(());
        }
        let kept = if m.samples == 0 { "the nominal mount was kept" } else { "the nominal mount still weighs in" };
        log.event(
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
    fn anchor_changes<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        config: &PipelineConfig<'_>,
        t: Timestamp,
    ) -> Result<(), PipelineError<W::Error>> {
        let quality = *self.anchorer.quality();
        let changed = quality.observability != self.observability;
        if changed {
            self.observability = quality.observability;
            let scale = self.anchorer.estimate().map_or(f64::NAN, |e| e.scale);
            log.event(
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
        let Some(estimate) = self.anchorer.estimate().copied() else { return Ok(()) };
        let due = self.last_anchor_record.is_none_or(|last| t - last >= config.anchor_interval);
        if !(changed || due) {
            return Ok(());
        }
        self.last_anchor_record = Some(t);
        log.write(&Record::AnchorEstimate(anchor_record(log.time(t), &estimate, &quality)))
    }

    /// The VO pose a detection of `frame` at `t` belongs with, one of the same frame or at
    /// most `max_age` apart: whether there is one, and the anchored ego, or none.
    pub(super) fn pose_for(&self, max_age: Duration, t: Timestamp, frame: u64) -> (bool, Option<Ego>) {
        let near = |ft: Timestamp, f: u64| f == frame || (t - ft).micros().saturating_abs() <= max_age.micros();
        let has_vo = self.vo.is_some_and(|v| near(v.t, v.frame));
        (has_vo, self.ego.filter(|e| near(e.t, e.frame)))
    }
}
