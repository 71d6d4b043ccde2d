//! The on-device pipeline: raw inputs in as they arrive, the compact 4D log out.
//!
//! One [`Pipeline`] joins the core's parts the way a dashcam runs them, with bounded memory
//! (every capacity is in its type) and bounded work per input:
//!
//! ```text
//! serial bytes ─ NMEA framer ─ epochs ─┐
//! CAN frames ── N2K / J1939 / OBD-II / ├─ GNSS fixes, speeds ─ clock (device → UTC)
//!               DBC signal ────────────┘                     └ anchorer (VO → ENU Sim(3))
//! VO pose of a frame ───────────────────── anchored ego (rear axle, heading from VO) ─ eased, lagged ─ score windows
//! 3D detections (camera frame) ─ mount ─ world (through the anchored ego) ─ 3D tracker
//! 2D detections ───────────────────────── 2D tracker
//!                                   └──────────── binlog Writer (embedded-io) ──────────┘
//! ```
//!
//! Every input carries the device's receive time ([`Timestamp`], the device clock). The
//! pipeline turns it into a monotonic time that survives a clock reset and keeps the
//! device → UTC offset GNSS reveals ([`clock`]); the log is written in UTC from the first
//! fix on (a [`ClockOffset`] record marks the moment; earlier records carry device time).
//!
//! What goes into the log: GNSS fixes, speeds, frame metadata and VO poses (what offline
//! finishing re-anchors from); the anchored ego pose of every frame; the anchor estimate
//! when it changes (at most once per [`PipelineConfig::anchor_interval`]); 3D tracks placed
//! through the anchored ego pose; raw 3D detections of frames that could not be placed yet
//! (before the anchor is observable), so that finishing loses nothing; 2D tracks; one
//! verification record per window of nuPlan scenario length when a map is given; events
//! for observability changes, clock offsets and steps, and every refused input (counted
//! per [`Issue`], at most one event per reason per second).
//!
//! Nothing here panics on bad input: a refused input is counted, written as an event and
//! leaves the state as it was. The only error a push returns is the log's own (`Io`).

mod anchoring;
pub mod braking;
pub mod calibration;
pub mod carry;
pub mod clock;
pub mod ease;
pub mod edge;
mod gnss;
pub mod ground;
pub mod inertial;
pub mod issues;
pub mod lag;
pub mod mount;
pub mod profile;
pub mod replay;
mod routes;
pub mod signals;
mod sink;
mod tracking;
mod vertical;
mod windows;

use embedded_can::Frame;
use embedded_io::Write;
use nalgebra::Vector3;

use crate::anchor::{AnchorConfig, Anchorer, Observability};
use crate::binlog::signature::Sealer;
use crate::binlog::{
    quantise, AnchorEstimate, ClockOffset, Header, MountEstimate as MountRecord, Record, Verification, WriteError,
    Writer, WriterConfig,
};
use crate::can::signal::Signal;
use crate::geo::Geodetic;
use crate::imu::so3::yaw_pitch_roll as euler;
use crate::map::MapView;
use crate::obb::{Footprint, PACIFICA};
use crate::score::{AgentKind, ScoreConfig, Scores};
use crate::sim3::{Pose, Sim3};
use crate::time::{Duration, Timestamp};
use crate::track2d::{Detection, Tracker2d, TrackerConfig};
use crate::track3d::{Config3d, Detection3d, Tracker3d};
pub use calibration::{CalibrationConfig, MountCalibration, MountEstimate};
pub use clock::{Clock, OffsetChange};
pub use inertial::ImuConfig;
pub use issues::{Issue, Issues};
pub use mount::CameraMount;
pub use signals::{FrameId, GnssFrame, GnssSignals};
pub use windows::SETTLE_AFTER_ANCHORED_S;

/// The default time constant of the ego's corrections, s ([`ease`]).
pub const EASE_S: f64 = 1.0;
/// The default doubt the windows grant the ego's position, in its stated σ
/// ([`PipelineConfig::window_doubt_sigmas`]).
pub const WINDOW_DOUBT_SIGMAS: f64 = 1.0;
/// nuPlan's scenario length, s: the verification window.
pub const SCENARIO_SECONDS: f64 = 15.0;

/// Where the vehicle speed comes from on the bus.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpeedSource {
    /// J1939 CCVS1 wheel-based speed (PGN 65265).
    Ccvs1,
    /// OBD-II mode 01 PID 0x0D responses (the caller sends the requests).
    Obd,
    /// A DBC-defined signal of the frame with this id.
    Signal {
        /// The frame.
        frame: FrameId,
        /// The signal.
        signal: Signal,
        /// Physical value × this = m/s (1/3.6 for km/h).
        to_mps: f64,
    },
}

impl SpeedSource {
    /// The `source` code of [`VehicleSpeed`](crate::binlog::VehicleSpeed) records.
    pub const fn code(&self) -> i64 {
        match self {
            SpeedSource::Ccvs1 => 1,
            SpeedSource::Obd => 2,
            SpeedSource::Signal { .. } => 3,
        }
    }
}

/// Where the relative motion the anchorer anchors comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum RelativeMotion {
    /// The camera's VO poses ([`Pipeline::push_vo`]).
    #[default]
    Vo,
    /// Gyro + wheels dead reckoning ([`Pipeline::push_imu`] and the vehicle speed): a
    /// dashcam without VO. Its frame is levelled by gravity, so the anchorer estimates yaw,
    /// scale and translation only ([`AnchorMode::GravityAligned`](crate::anchor::AnchorMode)),
    /// which a straight road observes; VO poses pushed are not used.
    ImuWheels,
}

/// How a fix's 1-σ horizontal error is found: the receiver's GST statistics when given,
/// else HDOP × UERE, else a default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssErrorModel {
    /// User equivalent range error, m.
    pub uere_m: f64,
    /// σ when the fix carries neither GST nor HDOP, m.
    pub default_sigma_m: f64,
}

impl Default for GnssErrorModel {
    fn default() -> Self {
        GnssErrorModel { uere_m: 2.5, default_sigma_m: 5.0 }
    }
}

/// Everything the pipeline is built from.
#[derive(Clone, Copy, Debug)]
pub struct PipelineConfig<'a> {
    /// Origin of the log's ENU frame (the map tile's, when verifying on the device).
    pub origin: Geodetic,
    /// Who writes the log (the header's device id).
    pub device_id: [u8; 16],
    /// The camera (and GNSS receiver) on the vehicle as installed: the prior of the
    /// online calibration ([`calibration`]).
    pub mount: CameraMount,
    /// How the camera's yaw and pitch are calibrated online.
    pub calibration: CalibrationConfig,
    /// Anchoring.
    pub anchor: AnchorConfig,
    /// GNSS σ model.
    pub gnss: GnssErrorModel,
    /// Per tracker class id: its code in the log and what kind of road user it is for
    /// the score (classes beyond the table: code 255, an object).
    pub classes: &'a [ClassMeta],
    /// Which CAN message is the vehicle speed (none: speed is not read from CAN).
    pub speed: Option<SpeedSource>,
    /// GNSS from DBC-defined CAN signals, besides NMEA 0183, NMEA 2000 and J1939 VP1.
    pub gnss_signals: Option<GnssSignals>,
    /// Segments and flushing of the log.
    pub writer: WriterConfig,
    /// The map tile to verify against; `None` verifies nothing.
    pub map: Option<MapView<'a>>,
    /// The ego's outline for verification.
    pub footprint: Footprint,
    /// The score's settings.
    pub score: ScoreConfig,
    /// Verification window, s.
    pub window_s: f64,
    /// Detections are placed with the VO pose of their frame, or one this close in time.
    pub max_pose_age: Duration,
    /// The anchor estimate is written at most this often (and on every observability change).
    pub anchor_interval: Duration,
    /// Time constant with which the anchorer's corrections are eased into the ego the
    /// verification windows score, s (0: none; [`ease`]); the log's ego stays the anchored
    /// one.
    pub ease_s: f64,
    /// The verification windows give the map's metrics the benefit of this many of the
    /// ego's stated σ (`EgoPose::sigma_mm`) of doubt about where the ego is
    /// ([`Scorer::step_in_doubt`](crate::score::Scorer::step_in_doubt)); 0: nuPlan's own
    /// judgement, as `verify` makes it.
    pub window_doubt_sigmas: f64,
    /// The IMU's axes on the camera and what is made of it.
    pub imu: ImuConfig,
    /// Where the relative motion comes from.
    pub relative_motion: RelativeMotion,
}

impl<'a> PipelineConfig<'a> {
    /// Defaults: the default mount, anchoring and σ model, nuPlan's Pacifica and score,
    /// 15 s windows, no CAN speed, no map; `classes` says what the trackers' classes are.
    pub fn new(origin: Geodetic, classes: &'a [ClassMeta]) -> Self {
        PipelineConfig {
            origin,
            device_id: *b"dash2sim\0\0\0\0\0\0\0\0",
            mount: CameraMount::default(),
            calibration: CalibrationConfig::default(),
            anchor: AnchorConfig::default(),
            gnss: GnssErrorModel::default(),
            classes,
            speed: None,
            gnss_signals: None,
            writer: WriterConfig::default(),
            map: None,
            footprint: PACIFICA,
            score: ScoreConfig::default(),
            window_s: SCENARIO_SECONDS,
            max_pose_age: Duration::from_millis(50),
            anchor_interval: Duration::from_millis(1000),
            ease_s: EASE_S,
            window_doubt_sigmas: WINDOW_DOUBT_SIGMAS,
            imu: ImuConfig::default(),
            relative_motion: RelativeMotion::Vo,
        }
    }
}

/// What a tracker class is outside the tracker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClassMeta {
    /// The class code of `Track3d` records (`docs/binlog.md`).
    pub code: i64,
    /// The kind of road user, for the score.
    pub kind: AgentKind,
}

/// The pipeline's two trackers, its largest parts (98 KB with 64 3D and 32 2D tracks),
/// kept where the caller puts them: in a `static` on a microcontroller (their constructor
/// is const, so they are never built on the stack and moved), in a `Box` on the host.
#[derive(Clone, Debug)]
pub struct Trackers<'a, const T3: usize, const T2: usize> {
    tracker3d: Tracker3d<'a, T3>,
    tracker2d: Tracker2d<T2>,
}

impl<'a, const T3: usize, const T2: usize> Trackers<'a, T3, T2> {
    /// Empty trackers with these settings.
    pub const fn new(tracker: Config3d<'a>, tracker2d: TrackerConfig) -> Self {
        Trackers { tracker3d: Tracker3d::new(tracker), tracker2d: Tracker2d::new(tracker2d) }
    }

    /// The 3D tracker's counters.
    pub fn stats3d(&self) -> &crate::track3d::Stats3d {
        self.tracker3d.stats()
    }
}

/// A 2D detection of a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageDetection {
    /// Class id.
    pub class: u16,
    /// Box and score.
    pub detection: Detection,
}

/// What the pipeline has done.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct PipelineStats {
    /// VO poses accepted.
    pub vo_poses: u64,
    /// Frames with an anchored ego pose.
    pub anchored_frames: u64,
    /// Frames whose ego pose was carried across a VO re-initialisation (not anchored).
    pub carried_frames: u64,
    /// GNSS fixes used (NMEA and CAN).
    pub fixes: u64,
    /// Speed samples used.
    pub speeds: u64,
    /// CAN frames seen.
    pub can_frames: u64,
    /// Serial bytes seen.
    pub serial_bytes: u64,
    /// 3D detections given to the tracker (placed in the world).
    pub detections_placed: u64,
    /// 3D detections logged raw (no anchored pose for their frame yet).
    pub detections_raw: u64,
    /// 3D track states written.
    pub track_states: u64,
    /// 2D track states written.
    pub track2d_states: u64,
    /// Verification windows written.
    pub windows: u64,
    /// Windows decided verified: verified with the ego's doubt held against it.
    pub windows_verified: u64,
    /// Windows undecided: verified with the ego's doubt given to it, not with it held
    /// against it.
    pub windows_undecided: u64,
    /// Windows with an at-fault collision (their `no_at_fault_collisions` below 1).
    pub collision_windows: u64,
    /// Harsh brakings ([`braking`]).
    pub harsh_brakings: u64,
    /// IMU samples used.
    pub imu_samples: u64,
    /// Impacts the G-sensor saw ([`crate::imu::impact`]).
    pub impacts: u64,
    /// Records written.
    pub records: u64,
}

impl core::fmt::Display for PipelineStats {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{} VO poses ({} anchored, {} carried), {} fixes, {} speeds, {} 3D track states, {} windows ({} verified, {} undecided), {} records",
            self.vo_poses,
            self.anchored_frames,
            self.carried_frames,
            self.fixes,
            self.speeds,
            self.track_states,
            self.windows,
            self.windows_verified,
            self.windows_undecided,
            self.records
        )
    }
}

/// Errors of the log sink; inputs themselves never fail (they are counted as issues).
pub type PipelineError<E> = WriteError<E>;

/// Everything but the two byte/frame decoders, so that their callbacks may borrow it: the
/// configuration and one part per stage. Each stage's inputs are `State` methods in the
/// stage's module (an input may reach several stages: a fix goes into the log and the
/// anchorer), each stage's own state is its part.
#[derive(Debug)]
struct State<'a, W: Write, const T3: usize, const T2: usize, const BUF: usize> {
    config: PipelineConfig<'a>,
    /// The log being written, the clock, the issues and the counts ([`sink`]).
    log: sink::LogSink<W, BUF>,
    /// GNSS and vehicle-speed ingest ([`gnss`]).
    gnss: gnss::GnssIngest,
    /// VO, anchoring, the mount and the ego ([`anchoring`]).
    anchoring: anchoring::Anchoring,
    /// 3D and 2D tracking ([`tracking`]).
    tracking: tracking::Tracking<'a, T3, T2>,
    /// The verification windows and the agents they score ([`windows`]).
    windows: windows::Windows<'a, T3>,
    /// The IMU ([`inertial`]).
    inertial: inertial::Inertial,
}

/// The pipeline: `T3` 3D tracks (and 3D detections per frame), `T2` 2D tracks (and 2D
/// detections per frame) in caller-kept [`Trackers`], a `BUF`-byte log buffer.
#[derive(Debug)]
pub struct Pipeline<'a, W: Write, const T3: usize = 64, const T2: usize = 32, const BUF: usize = 4096> {
    nmea: crate::nmea::Stream<128>,
    can: crate::can::Decoder<8>,
    state: State<'a, W, T3, T2, BUF>,
}

/// How long an unfinished NMEA 2000 fast packet may wait for its next frame.
const FAST_PACKET_TIMEOUT: Duration = Duration::from_millis(750);

impl<'a, W: Write, const T3: usize, const T2: usize, const BUF: usize> Pipeline<'a, W, T3, T2, BUF> {
    /// Start a log on `io`; its header goes out with the first flush (the first segment's
    /// close). Infallible, so that it is built where it is kept rather than moved out of a
    /// `Result`.
    pub fn new(io: W, config: PipelineConfig<'a>, trackers: &'a mut Trackers<'a, T3, T2>) -> Self {
        let o = config.origin;
        let header = Header {
            device_id: config.device_id,
            origin: [
                quantise(o.lat_deg, 1e-7).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
                quantise(o.lon_deg, 1e-7).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
                quantise(o.height_m, 1e-3).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
            ],
        };
        Pipeline {
            nmea: crate::nmea::Stream::new(),
            can: crate::can::Decoder::new(FAST_PACKET_TIMEOUT),
            state: State {
                config,
                log: sink::LogSink::new(io, header, config.writer),
                gnss: gnss::GnssIngest::default(),
                anchoring: anchoring::Anchoring::new(&config),
                tracking: tracking::Tracking::new(trackers),
                windows: windows::Windows::default(),
                inertial: inertial::Inertial::new(&config),
            },
        }
    }

    /// What the pipeline has done so far.
    pub fn stats(&self) -> &PipelineStats {
        &self.state.log.stats
    }

    /// Refused inputs so far, by reason.
    pub fn issues(&self) -> &Issues {
        &self.state.log.issues
    }

    /// The clocks.
    pub fn clock(&self) -> &Clock {
        &self.state.log.clock
    }

    /// The anchorer (its estimate and quality).
    pub fn anchorer(&self) -> &Anchorer {
        self.state.anchoring.anchorer()
    }

    /// Bytes from the GNSS receiver's serial port, received at device time `t`.
    /// Work is linear in `bytes`.
    pub fn push_serial(&mut self, t: Timestamp, bytes: &[u8]) -> Result<(), PipelineError<W::Error>> {
        let state = &mut self.state;
        let t = state.log.monotonic(t)?;
        state.log.stats.serial_bytes = state.log.stats.serial_bytes.saturating_add(bytes.len() as u64);
        let mut result = Ok(());
        self.nmea.feed(bytes, |event| {
            if result.is_ok() {
                result = state.on_nmea(t, &event);
            }
        });
        result
    }

    /// A CAN frame received at device time `t`.
    pub fn push_can<F: Frame>(&mut self, t: Timestamp, frame: &F) -> Result<(), PipelineError<W::Error>> {
        let state = &mut self.state;
        let t = state.log.monotonic(t)?;
        state.log.stats.can_frames = state.log.stats.can_frames.saturating_add(1);
        if let Some(SpeedSource::Signal { frame: id, signal, to_mps }) = state.config.speed {
            if id.matches(frame) {
                if let Some(v) = signal.value(frame.data()) {
                    state.speed(t, v * to_mps, 3)?;
                }
                return Ok(());
            }
        }
        if let Some(read) = state.config.gnss_signals.and_then(|g| g.read(frame)) {
            return state.on_gnss_signals(t, read);
        }
        let mut result = Ok(());
        self.can.decode(t, frame, |event| {
            if result.is_ok() {
                result = state.on_can(t, event);
            }
        });
        result
    }

    /// The VO pose of camera frame `frame` (camera → VO frame, unknown scale), captured
    /// at device time `t`, in VO session `session`: a VO that lost track and started again
    /// (new origin, orientation and scale) counts its sessions up, and each is anchored on
    /// its own.
    pub fn push_vo(
        &mut self,
        t: Timestamp,
        frame: u64,
        session: u32,
        pose: &Pose,
    ) -> Result<(), PipelineError<W::Error>> {
        let t = self.state.log.monotonic(t)?;
        if self.state.config.relative_motion == RelativeMotion::ImuWheels {
            return self.state.log.issue(t, Issue::VoNotUsed, 1);
        }
        self.state.on_vo(t, frame, session, pose)
    }

    /// A sample of the IMU, taken at device time `t` (the sensor's own time mapped to the
    /// device clock by the caller): checked, preintegrated into the log, and used for the
    /// attitude, the gyro's bias, the impact trigger and — with
    /// [`RelativeMotion::ImuWheels`] — the dead-reckoned relative motion.
    pub fn push_imu(&mut self, t: Timestamp, sample: &crate::imu::ImuSample) -> Result<(), PipelineError<W::Error>> {
        let t = self.state.log.monotonic(t)?;
        self.state.on_imu(t, sample)
    }

    /// The body's pitch and roll (rad) from the IMU's gravity, once it has a sample.
    pub fn imu_pitch_roll(&self) -> Option<[f64; 2]> {
        self.state.inertial.pitch_roll()
    }

    /// The gyro's bias as estimated so far (body axes, rad/s) and its σ about the vertical.
    pub fn gyro_bias(&self) -> (Vector3<f64>, f64) {
        let imu = &self.state.inertial;
        (imu.gyro_bias(), imu.gyro_bias_sigma())
    }

    /// The camera mount as calibrated so far.
    pub fn mount(&self) -> &MountEstimate {
        self.state.anchoring.mount()
    }

    /// The 3D detections of camera frame `frame` in the camera frame. At most `T3` are
    /// used; the rest are counted.
    pub fn push_detections(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[Detection3d],
    ) -> Result<(), PipelineError<W::Error>> {
        let t = self.state.log.monotonic(t)?;
        self.state.dead_reckoned_frame(t, frame)?;
        self.state.on_detections(t, frame, detections)
    }

    /// The 2D detections of camera frame `frame`. At most `T2` are used.
    pub fn push_detections2d(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[ImageDetection],
    ) -> Result<(), PipelineError<W::Error>> {
        let t = self.state.log.monotonic(t)?;
        self.state.dead_reckoned_frame(t, frame)?;
        self.state.on_detections2d(t, frame, detections)
    }

    /// End of input: the last GNSS epoch, the open verification window, the counts not yet
    /// written, then the log is closed and flushed. Returns the sink and the totals.
    pub fn finish(mut self) -> Result<(W, PipelineStats, Issues), PipelineError<W::Error>> {
        self.close()?;
        let sink::LogSink { writer, stats, issues, .. } = self.state.log;
        Ok((writer.finish()?, stats, issues))
    }

    /// Close the log on the current sink and go on on `io` (a new file every few minutes,
    /// so that a crash or a full disk costs at most the file being written): the new log
    /// starts with its own header, the clock offset in force and an event naming the
    /// rotation; anchoring, tracking and verification go on undisturbed. Returns the old
    /// sink, flushed.
    pub fn rotate(&mut self, io: W) -> Result<W, PipelineError<W::Error>> {
        self.state.log.writer.close()?;
        let old = self.switch_file(io).finish()?;
        let rotations = self.state.log.rotations;
        self.start_file(2, format_args!("log continued on a new file (rotation {rotations})"))?;
        Ok(old)
    }

    /// After the sink failed (a full disk, an I/O error): continue the log on `io`, a new
    /// file, as [`Pipeline::rotate`] does, but without writing to the failed sink again —
    /// what it still held is lost, and its file ends at the last complete frame it took
    /// (readers recover it as after a power cut). The new file starts with the clock offset
    /// and an error event saying why (`failure`). Returns the failed sink.
    pub fn resume_after_failure(
        &mut self,
        io: W,
        failure: core::fmt::Arguments<'_>,
    ) -> Result<W, PipelineError<W::Error>> {
        let failed = self.switch_file(io).abandon();
        let rotations = self.state.log.rotations;
        self.start_file(
            3,
            format_args!("log writes failed ({failure}); the log continues on a new file (rotation {rotations})"),
        )?;
        Ok(failed)
    }

    /// Sign every segment of the log with the device's key (format v1.5,
    /// [`crate::binlog::signature`]); the chain runs on across rotated files. Call it before
    /// the first input, so that the first segment is signed too.
    pub fn sign_with(&mut self, sealer: Sealer) {
        self.state.log.writer.seal_with(sealer);
    }

    /// A writer on `io` in place of the current one, which is returned; one rotation more.
    /// The signing key and its chain move to the new writer.
    fn switch_file(&mut self, io: W) -> Writer<W, BUF> {
        let log = &mut self.state.log;
        let mut next = Writer::buffered(io, &log.header, self.state.config.writer);
        if let Some(sealer) = log.writer.take_sealer() {
            next.seal_with(sealer);
        }
        log.rotations = log.rotations.saturating_add(1);
        core::mem::replace(&mut log.writer, next)
    }

    /// A new file's first records: the clock offset in force and an event saying why.
    fn start_file(&mut self, level: u8, why: core::fmt::Arguments<'_>) -> Result<(), PipelineError<W::Error>> {
        let log = &mut self.state.log;
        let now = log.now;
        if let Some(offset) = log.clock.offset() {
            let record = ClockOffset { t_us: log.time(now), offset_us: offset, reason: 1 };
            log.write(&Record::ClockOffset(record))?;
        }
        log.event(now, level, why)
    }

    /// An event from the host at the pipeline's current time: what the device's storage did
    /// (a file kept, files deleted for the quota). `level` as `foxglove.Log` (0 debug … 4
    /// fatal); a text longer than an event holds is cut.
    pub fn note(&mut self, level: u8, text: core::fmt::Arguments<'_>) -> Result<(), PipelineError<W::Error>> {
        let now = self.state.log.now;
        self.state.log.event(now, level, text)
    }

    /// `n` inputs were dropped before they reached the pipeline (the host's queue was
    /// full); counted and written as an event like every refused input, at the pipeline's
    /// time (its latest input's): a host behind its inputs notes the drop among them — at
    /// its own clock, seconds ahead, the inputs after it would read as the clock going back.
    pub fn note_dropped(&mut self, n: u64) -> Result<(), PipelineError<W::Error>> {
        let now = self.state.log.now;
        self.state.log.issue(now, Issue::InputsDropped, n)
    }

    /// [`Pipeline::finish`] in place: everything but giving the sink back. A pipeline is
    /// large (130 KB with 64 tracks); on a microcontroller it should not be moved.
    pub fn close(&mut self) -> Result<(), PipelineError<W::Error>> {
        let state = &mut self.state;
        if let Some(fix) = self.nmea.decoder.finish() {
            let rx = state.gnss.last_sentence().unwrap_or(state.log.now);
            state.on_fix(rx, &gnss::nmea_fix(&fix))?;
        }
        let now = state.log.now;
        state.windows.finish(&state.config, &mut state.log, now)?;
        state.anchoring.close_calibration(&mut state.log, now)?;
        let tail: heapless::Vec<(Issue, u64), { Issue::ALL.len() }> = state.log.issues.unreported().collect();
        for (issue, count) in tail {
            state.log.event(now, 3, format_args!("{} ({count} in all)", issue.text()))?;
        }
        let s = state.log.stats;
        let issues = state.log.issues.total();
        state.log.event(now, 2, format_args!("pipeline finished: {s}, {issues} issues"))?;
        state.log.writer.close()
    }
}

/// A window's scores as a record, not decided (the device's; `dash2sim finish` adds the
/// decision with the log's doubt).
pub fn verification_record(t_us: i64, s: &Scores) -> Verification {
    Verification {
        t_us,
        collisions_e4: quantise(s.no_at_fault_collisions, 1e-4),
        drivable_e4: quantise(s.drivable_area, 1e-4),
        direction_e4: quantise(s.driving_direction, 1e-4),
        making_progress_e4: quantise(s.making_progress, 1e-4),
        progress_e4: quantise(s.progress, 1e-4),
        ttc_e4: quantise(s.ttc, 1e-4),
        speed_limit_e4: quantise(s.speed_limit, 1e-4),
        comfort_e4: quantise(s.comfort, 1e-4),
        score_e2: quantise(s.score, 1e-2),
        worst_corner_mm: quantise(s.worst_corner.clamp(-1e6, 1e6), 1e-3),
        decision: 0,
        score_low_e2: 0,
        score_high_e2: 0,
    }
}

/// The calibrated mount as a record (the device's and `dash2sim finish`'s).
pub fn mount_record(t_us: i64, m: &MountEstimate) -> MountRecord {
    let [roll, pitch, yaw] = m.mount.roll_pitch_yaw;
    MountRecord {
        t_us,
        yaw_e6: quantise(yaw, 1e-6),
        pitch_e6: quantise(pitch, 1e-6),
        roll_e6: quantise(roll, 1e-6),
        sigma_yaw_e6: quantise(m.sigma[0], 1e-6),
        sigma_pitch_e6: quantise(m.sigma[1], 1e-6),
        samples: i64::from(m.samples),
        calibrated: i64::from(m.calibrated),
    }
}

/// The anchor estimate as a record.
fn anchor_record(t_us: i64, e: &Sim3, q: &crate::anchor::Quality) -> AnchorEstimate {
    let observability = match q.observability {
        Observability::Observable => 2,
        Observability::Collinear => 1,
        _ => 0,
    };
    similarity_record(t_us, e, observability, i64::from(q.anchors_used), q.rms_residual_m, q.latency_s.unwrap_or(0.0))
}

/// A VO → ENU similarity as an `AnchorEstimate` record (the device's and `dash2sim
/// finish`'s): observability 0 none, 1 collinear, 2 observable; anchors used; RMS residual, m;
/// the GNSS latency the solution used, s.
pub fn similarity_record(
    t_us: i64,
    e: &Sim3,
    observability: i64,
    anchors: i64,
    rms_m: f64,
    latency_s: f64,
) -> AnchorEstimate {
    let [yaw, pitch, roll] = euler(&e.rotation);
    let t: &Vector3<f64> = &e.translation;
    AnchorEstimate {
        t_us,
        scale_e6: quantise(e.scale, 1e-6),
        yaw_e6: quantise(yaw, 1e-6),
        pitch_e6: quantise(pitch, 1e-6),
        roll_e6: quantise(roll, 1e-6),
        tx_mm: quantise(t.x, 1e-3),
        ty_mm: quantise(t.y, 1e-3),
        tz_mm: quantise(t.z, 1e-3),
        observability,
        anchors,
        rms_mm: quantise(rms_m, 1e-3),
        latency_us: quantise(latency_s, 1e-6),
    }
}

#[cfg(test)]
mod tests;
