//! The IMU stage: each sample checked, preintegrated into the log, and — once its gravity
//! says its units and axes are as configured — into the attitude, the gyro's bias, the
//! impact trigger and, where the relative motion is gyro + wheels
//! ([`RelativeMotion::ImuWheels`]), the dead reckoning whose poses are anchored in place of
//! a VO's ([`crate::imu`]).

use embedded_io::Write;
use nalgebra::{Matrix3, Vector3};

use super::carry::Turn;
use super::issues::Issue;
use super::mount::CameraMount;
use super::sink::LogSink;
use super::{quantise, PipelineConfig, PipelineError, RelativeMotion};
use crate::binlog::{ImuDelta, ImuEstimate, Record};
use crate::decimal::Decimal;
use crate::imu::attitude::{motion_acceleration, Attitude};
use crate::imu::bias::GyroBias;
use crate::imu::dead_reckoning::DeadReckoning;
use crate::imu::forward::ForwardAxis;
use crate::imu::impact::Impact;
use crate::imu::preintegrate::Preintegrator;
use crate::imu::{check, ImuSample, UnitCheck, UnitVerdict, GRAVITY};
use crate::sim3::Pose;
use crate::time::{Duration, Timestamp};

/// A gap between samples longer than this (s) is not integrated across.
const MAX_SAMPLE_GAP_S: f64 = 0.5;
/// A wheel speed older than this (s) is not used.
const MAX_SPEED_AGE_S: f64 = 0.5;
/// Time constant of the wheel speed's low-passed derivative, s.
const SPEED_DERIVATIVE_TAU_S: f64 = 0.2;
/// A gyro whose rate is this many times the course's is not in rad/s.
const MAX_GYRO_SCALE: f64 = 3.0;
/// How long dead reckoning waits for a camera frame before it makes poses on its own clock.
const CAMERA_FRAME_WAIT: Duration = Duration::from_millis(500);
/// How long the attitude follows gravity before its vertical levels a VO session, s: three
/// of its settling time constants.
const LEVEL_AFTER_S: f64 = 3.0 * crate::imu::attitude::SETTLING_TIME_CONSTANT_S;
/// Relative σ of a consumer gyro's scale (sensitivity tolerance, a percent).
const GYRO_SCALE_REL_SIGMA: f64 = 0.01;
/// The VO session number of dead-reckoned poses.
pub const DEAD_RECKONING_SESSION: u32 = 0;

/// The IMU's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuConfig {
    /// The sensor's axes on the camera.
    pub mount: crate::imu::ImuMount,
    /// Specific force past gravity and motion that is an impact, m/s².
    pub impact_threshold_mps2: f64,
    /// The log's preintegrated interval.
    pub delta_interval: Duration,
    /// How often the estimate (tilt, bias) is written.
    pub estimate_interval: Duration,
    /// How often a dead-reckoned pose is anchored (gyro + wheels as the relative motion).
    pub pose_interval: Duration,
}

impl Default for ImuConfig {
    fn default() -> Self {
        ImuConfig {
            mount: crate::imu::ImuMount::default(),
            impact_threshold_mps2: crate::imu::impact::DEFAULT_THRESHOLD_MPS2,
            delta_interval: Duration::from_millis(100),
            estimate_interval: Duration::from_millis(1000),
            pose_interval: Duration::from_millis(50),
        }
    }
}

/// What the IMU stage keeps between samples.
#[derive(Debug)]
pub(super) struct Inertial {
    /// Sensor → body rotation.
    sensor_to_body: Matrix3<f64>,
    last: Option<Timestamp>,
    units: UnitCheck,
    /// Why the stream is refused, once it is.
    refused: Option<Issue>,
    preintegrator: Preintegrator,
    attitude: Attitude,
    bias: GyroBias,
    impact: Impact,
    dead_reckoning: DeadReckoning,
    /// The car's forward axis in the body frame, from its accelerations.
    forward: ForwardAxis,
    /// It was known when the last dead-reckoned pose was made.
    forward_known: bool,
    /// The dead reckoning's own frame numbers (until the camera's come).
    frame: u64,
    /// Since when dead reckoning has run (the attitude settled, a wheel speed known).
    reckoning: Option<Timestamp>,
    /// The last camera frame a pose was made at.
    camera_frame: Option<u64>,
    last_pose: Option<Timestamp>,
    last_estimate: Option<Timestamp>,
    /// The latest wheel speed (time, m/s) and its low-passed derivative, m/s².
    speed: Option<(Timestamp, f64)>,
    acceleration: f64,
}

impl Inertial {
    pub(super) fn new(config: &PipelineConfig<'_>) -> Self {
        Inertial {
            sensor_to_body: config.mount.rotation() * config.imu.mount.rotation(),
            last: None,
            units: UnitCheck::default(),
            refused: None,
            preintegrator: Preintegrator::default(),
            attitude: Attitude::default(),
            bias: GyroBias::default(),
            impact: Impact::default(),
            dead_reckoning: DeadReckoning::default(),
            forward: ForwardAxis::default(),
            forward_known: false,
            frame: 0,
            reckoning: None,
            camera_frame: None,
            last_pose: None,
            last_estimate: None,
            speed: None,
            acceleration: 0.0,
        }
    }

    /// A wheel speed sample: kept, with its derivative, for the motion the IMU sees.
    pub(super) fn on_speed(&mut self, t: Timestamp, mps: f64) {
        if let Some((t0, v0)) = self.speed {
            let dt = (t - t0).as_secs_f64();
            if dt <= 0.0 {
                return;
            }
            if dt < MAX_SPEED_AGE_S {
                let gain = 1.0 - libm::exp(-dt / SPEED_DERIVATIVE_TAU_S);
                self.acceleration += ((mps - v0) / dt - self.acceleration) * gain;
            } else {
                self.acceleration = 0.0;
            }
        }
        self.speed = Some((t, mps));
    }

    fn speed_at(&self, t: Timestamp) -> Option<f64> {
        self.speed.filter(|(ts, _)| (t - *ts).as_secs_f64() < MAX_SPEED_AGE_S).map(|(_, v)| v)
    }

    /// The body's up in body axes (the attitude's, or the body's z before it has one).
    pub(super) fn up(&self) -> Vector3<f64> {
        self.attitude.rotation().transpose() * Vector3::z()
    }

    /// Up in the camera's axes (`mount`: camera → body, the one the samples were turned to
    /// the body with), once the attitude has followed gravity for [`LEVEL_AFTER_S`] and the
    /// stream is not refused.
    pub(super) fn up_in_camera(&self, mount: &Matrix3<f64>) -> Option<Vector3<f64>> {
        self.settled().then(|| mount.transpose() * self.up())
    }

    /// The attitude has followed gravity for [`LEVEL_AFTER_S`] and the stream is not refused.
    fn settled(&self) -> bool {
        self.attitude.is_initialised() && self.attitude.levelled_for_s() >= LEVEL_AFTER_S && self.refused.is_none()
    }

    /// The body's heading as the gyro has carried it (rad, left positive; its zero is
    /// wherever the attitude started), once settled.
    pub(super) fn heading(&self) -> Option<f64> {
        let r = self.attitude.rotation();
        self.settled().then(|| libm::atan2(r[(1, 0)], r[(0, 0)]))
    }

    /// How far the car turned since the gyro's heading was `from` (rad), and how sure that
    /// is: the bias's σ about the vertical over `gap_s` and 1 % of the turn for the gyro's
    /// scale.
    pub(super) fn turn_since(&self, from: f64, gap_s: f64) -> Option<Turn> {
        let angle = crate::track3d::wrap_angle(self.heading()? - from);
        let drift = self.bias.sigma() * gap_s.max(0.0);
        let scale = GYRO_SCALE_REL_SIGMA * angle;
        Some(Turn { angle, sigma: libm::sqrt(drift * drift + scale * scale) })
    }

    /// The gyro's bias, every axis: the course's (or a standstill's) and the tilt's.
    pub(super) fn gyro_bias(&self) -> Vector3<f64> {
        self.bias.bias() + self.attitude.tilt_bias()
    }

    /// The σ of the gyro's bias about the vertical, rad/s.
    pub(super) fn gyro_bias_sigma(&self) -> f64 {
        self.bias.sigma()
    }

    /// The body's pitch and roll from gravity, once levelled.
    pub fn pitch_roll(&self) -> Option<[f64; 2]> {
        self.attitude.is_initialised().then(|| self.attitude.pitch_roll())
    }
}

impl Inertial {
    /// One sample: checked, preintegrated into the log, and into the attitude, the gyro's
    /// bias, the impact trigger and the dead reckoning. Returns the frame number of a
    /// dead-reckoned pose that is due on the dead reckoning's own clock (gyro + wheels, no
    /// camera frames): the pipeline anchors it in place of a VO pose.
    pub(super) fn push<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        config: &PipelineConfig<'_>,
        t: Timestamp,
        sample: &ImuSample,
    ) -> Result<Option<u64>, PipelineError<W::Error>> {
        if check(sample).is_err() {
            return log.issue(t, Issue::ImuRefused, 1).map(|()| None);
        }
        if self.last.is_some_and(|last| t <= last) {
            return log.issue(t, Issue::ImuOutOfOrder, 1).map(|()| None);
        }
        let dt = self.last.map_or(0.0, |last| (t - last).as_secs_f64());
        let dt = if dt > MAX_SAMPLE_GAP_S { 0.0 } else { dt };
        self.last = Some(t);
        if let Some(issue) = self.refused {
            return log.issue(t, issue, 1).map(|()| None);
        }
        log.stats.imu_samples = log.stats.imu_samples.saturating_add(1);
        let (gyro, force) = (Vector3::from(sample.gyro), Vector3::from(sample.accel));
        self.preintegrator.push(dt, &gyro, &force);
        if self.preintegrator.elapsed() >= config.imu.delta_interval.as_secs_f64() {
            let d = self.preintegrator.take();
            log.write(&Record::ImuDelta(ImuDelta {
                t_us: log.time(t),
                dt_us: quantise(d.dt, 1e-6),
                dtheta_x_e6: quantise(d.dtheta.x, 1e-6),
                dtheta_y_e6: quantise(d.dtheta.y, 1e-6),
                dtheta_z_e6: quantise(d.dtheta.z, 1e-6),
                dv_x_mm_s: quantise(d.dv.x, 1e-3),
                dv_y_mm_s: quantise(d.dv.y, 1e-3),
                dv_z_mm_s: quantise(d.dv.z, 1e-3),
                samples: i64::from(d.samples),
            }))?;
        }
        let gyro = self.sensor_to_body * gyro;
        let force = self.sensor_to_body * force;
        match self.units.push(&gyro, &force) {
            UnitVerdict::Undecided => return Ok(None),
            UnitVerdict::Consistent => {}
            UnitVerdict::InG => {
                self.refused = Some(Issue::ImuUnits);
                return log
                    .event(
                        t,
                        4,
                        format_args!("IMU refused: its specific force at rest is about 1, not 9.8 m/s² (given in g?)"),
                    )
                    .map(|()| None);
            }
            UnitVerdict::AxesOff(tilt) => {
                self.refused = Some(Issue::ImuAxes);
                return log
                    .event(
                        t,
                        4,
                        format_args!(
                            "IMU refused: gravity is {}° off the body's up (its axes or its mount are not as configured)",
                            Decimal::new(tilt.to_degrees(), 1)
                        ),
                    )
                    .map(|()| None);
            }
        }
        let speed = self.speed_at(t);
        let up = self.up();
        if self.bias.push(dt, &gyro, &up, speed) {
            // The standstill's mean has the bias about every axis.
            self.attitude.reset_tilt_bias();
        }
        if let Some(scale) = self.bias.scale().filter(|s| !(1.0 / MAX_GYRO_SCALE..MAX_GYRO_SCALE).contains(s)) {
            self.refused = Some(Issue::ImuUnits);
            return log
                .event(
                    t,
                    4,
                    format_args!(
                        "IMU refused: the gyro turns {} times as fast as the GNSS course (rates in °/s, or the wrong axis?)",
                        Decimal::new(scale, 1)
                    ),
                )
                .map(|()| None);
        }
        let rate = gyro - self.bias.bias();
        if let Some(v) = speed {
            // The sensor rides in the camera's housing, as far ahead of the rear axle.
            self.forward.push(dt, &force, v, rate.z, config.mount.position[0]);
        }
        let motion = motion_acceleration(speed.unwrap_or(0.0), self.acceleration, &(rate - self.attitude.tilt_bias()));
        self.attitude.update(dt, &rate, &force, &motion);
        let unexplained = force - motion - self.up() * GRAVITY;
        if let Some(g) = self.impact.push(dt, &unexplained, config.imu.impact_threshold_mps2) {
            log.stats.impacts = log.stats.impacts.saturating_add(1);
            log.event(t, 3, format_args!("impact: {} g past gravity and motion", Decimal::new(g / GRAVITY, 2)))?;
        }
        self.estimate_due(log, config, t)?;
        if config.relative_motion != RelativeMotion::ImuWheels {
            return Ok(None);
        }
        Ok(self.dead_reckon(config, t, dt, speed))
    }

    /// The tilt and bias as a record, once per `estimate_interval`.
    fn estimate_due<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        config: &PipelineConfig<'_>,
        t: Timestamp,
    ) -> Result<(), PipelineError<W::Error>> {
        if self.last_estimate.is_some_and(|last| t - last < config.imu.estimate_interval) {
            return Ok(());
        }
        let Some([pitch, roll]) = self.pitch_roll() else { return Ok(()) };
        self.last_estimate = Some(t);
        let b = self.gyro_bias();
        let (standstills, courses) = self.bias.evidence();
        let record = ImuEstimate {
            t_us: log.time(t),
            pitch_e6: quantise(pitch, 1e-6),
            roll_e6: quantise(roll, 1e-6),
            bias_x_e7: quantise(b.x, 1e-7),
            bias_y_e7: quantise(b.y, 1e-7),
            bias_z_e7: quantise(b.z, 1e-7),
            bias_sigma_e7: quantise(self.bias.sigma(), 1e-7),
            standstills: i64::from(standstills),
            courses: i64::from(courses),
        };
        log.write(&Record::ImuEstimate(record))
    }

    /// Gyro + wheels: the body moved along its heading; the frame number of a camera pose
    /// due in place of a VO pose every `pose_interval` — until the camera's frames come
    /// (with their detections): from then on a pose is made at each of them instead
    /// ([`Inertial::frame_due`]).
    fn dead_reckon(&mut self, config: &PipelineConfig<'_>, t: Timestamp, dt: f64, speed: Option<f64>) -> Option<u64> {
        let speed = speed?;
        self.dead_reckoning.advance(dt, speed, &self.attitude);
        let since = *self.reckoning.get_or_insert(t);
        // Its own poses only where no camera frame comes: not while a camera's first frame
        // may still be on its way (a pose of each clock at the start is an uneven step, and
        // the comfort metrics read it as a jerk).
        let waiting = t - since < CAMERA_FRAME_WAIT;
        if waiting
            || self.camera_frame.is_some()
            || self.last_pose.is_some_and(|last| t - last < config.imu.pose_interval)
        {
            return None;
        }
        self.last_pose = Some(t);
        let frame = self.frame;
        self.frame = frame.saturating_add(1);
        Some(frame)
    }

    /// A GNSS course over ground (`track`, rad, at `speed`, m/s) at `t` s, for the gyro's
    /// bias.
    pub(super) fn course(&mut self, t: f64, track: f64, speed: f64) {
        let up = self.up();
        self.bias.push_course(t, track, speed, &up);
    }

    /// The camera's pose as dead reckoning has it now, and whether the car's forward axis
    /// has just become known (the mount calibration then starts again). The car moves along
    /// the body's x as the nominal mounts make it; once the car's own forward axis is known
    /// (the housing turned on the car by `δ`: [`ForwardAxis`]), the camera is turned by `−δ`
    /// about the vertical in the dead reckoning's frame — the same as moving along the car's
    /// axis in a frame turned by `δ`, without a kink in the trajectory — so that the mount
    /// calibration finds the camera's yaw on the car, with which the detections are placed.
    pub(super) fn camera_pose(&mut self, mount: &CameraMount) -> (Pose, bool) {
        let mut pose =
            self.dead_reckoning.camera_pose(&self.attitude, &mount.rotation(), &Vector3::from(mount.position));
        let mut newly_known = false;
        if let Some(yaw) = self.forward.yaw() {
            pose.rotation = crate::sim3::rotation_z(-yaw) * pose.rotation;
            newly_known = !self.forward_known;
            self.forward_known = true;
        }
        (pose, newly_known)
    }

    /// Under gyro + wheels (`relative_motion`), whether camera frame `frame` (its detections
    /// arrive at `t`, `later` than the last pose) is due a dead-reckoned pose: once per
    /// frame, so that the detections are placed with the pose of their own frame and the
    /// log's frames are the camera's (each flagged dead-reckoned), as a VO camera's are.
    pub(super) fn frame_due(&mut self, relative_motion: RelativeMotion, frame: u64, later: bool) -> bool {
        if relative_motion != RelativeMotion::ImuWheels
            || self.reckoning.is_none()
            || self.camera_frame == Some(frame)
            || !later
        {
            return false;
        }
        self.camera_frame = Some(frame);
        true
    }
}
