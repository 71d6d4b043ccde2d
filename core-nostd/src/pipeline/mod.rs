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

pub mod calibration;
pub mod carry;
pub mod clock;
pub mod ease;
pub mod edge;
pub mod issues;
pub mod lag;
pub mod mount;
pub mod profile;
pub mod replay;
pub mod signals;

use core::fmt::Write as _;

use embedded_can::Frame;
use embedded_io::Write;
use nalgebra::Vector3;

use crate::anchor::{gnss_sigma, AnchorConfig, Anchorer, Observability};
use crate::binlog::{
    quantise, AnchorEstimate, ClockOffset, Detection3d as DetectionRecord, EgoPose, EventRecord, FrameMeta, GnssFix,
    Header, MountEstimate as MountRecord, Record, Track2d, Track3d, Tracks3d, VehicleSpeed, Verification, VoPose,
    WriteError, Writer, WriterConfig, MAX_TEXT, MAX_TRACKS,
};
use crate::box2d::Box2d;
use crate::can::signal::Signal;
use crate::can::{Decoded, Message};
use crate::decimal::Decimal;
use crate::drivable::{Channel, Checker};
use crate::geo::{Geodetic, LocalFrame};
use crate::map::MapView;
use crate::nmea::{Event as NmeaEvent, StreamEvent};
use crate::obb::{Footprint, OrientedBox, Pose2, PACIFICA};
use crate::score::{Agent, AgentKind, ScoreConfig, Scorer, Scores};
use crate::sim3::{Pose, Sim3};
use crate::time::{Duration, Timestamp};
use crate::track2d::{Detection, Tracker2d, TrackerConfig};
use crate::track3d::{Config3d, Detection3d, Tracker3d};
pub use calibration::{CalibrationConfig, MountCalibration, MountEstimate};
pub use clock::{Clock, OffsetChange};
pub use issues::{Issue, Issues};
pub use mount::CameraMount;
pub use signals::{FrameId, GnssFrame, GnssSignals};

/// Agents the tracker stopped reporting are scored for this long after (s): the smoothed
/// ego's lag ([`lag`]) and half a second.
const KEEP_LOST_S: f64 = 1.5;
/// At most this many of them.
const KEPT_AGENTS: usize = 16;
/// The default time constant of the ego's corrections, s ([`ease`]).
pub const EASE_S: f64 = 1.0;
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
    /// The `source` code of [`VehicleSpeed`] records.
    pub const fn code(&self) -> i64 {
        match self {
            SpeedSource::Ccvs1 => 1,
            SpeedSource::Obd => 2,
            SpeedSource::Signal { .. } => 3,
        }
    }
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
    /// Verified windows.
    pub windows_verified: u64,
    /// Records written.
    pub records: u64,
}

impl core::fmt::Display for PipelineStats {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{} VO poses ({} anchored, {} carried), {} fixes, {} speeds, {} 3D track states, {} windows ({} verified), {} records",
            self.vo_poses,
            self.anchored_frames,
            self.carried_frames,
            self.fixes,
            self.speeds,
            self.track_states,
            self.windows,
            self.windows_verified,
            self.records
        )
    }
}

/// Errors of the log sink; inputs themselves never fail (they are counted as issues).
pub type PipelineError<E> = WriteError<E>;

#[derive(Clone, Copy, Debug)]
struct LastVo {
    t: Timestamp,
    frame: u64,
    session: u32,
}

#[derive(Clone, Copy, Debug)]
struct Ego {
    t: Timestamp,
    frame: u64,
    /// The anchored pose (the log's).
    pose: Pose2,
    /// The eased pose (the windows', and the detections' placement: [`ease`]).
    eased: Pose2,
    /// Height of the rear axle's ground point (ENU up), m.
    z: f64,
}

/// One verification window.
#[derive(Clone, Debug)]
struct Window<'a> {
    start: f64,
    scorer: Scorer<'a, 'static, 1>,
    /// The multiplier of a collision in the last second of the window before ([`edge`]).
    inherited_collision: Option<f64>,
}

/// A reported 3D track, as the log and the score use it.
#[derive(Clone, Copy, Debug)]
struct TrackState {
    id: u32,
    class: u16,
    bbox: crate::box3d::Box3d,
    /// Velocity (x, y) per frame.
    velocity: [f64; 2],
    is_static: bool,
}

/// A GNSS fix from NMEA or NMEA 2000, in the form the pipeline uses.
#[derive(Clone, Copy, Debug, Default)]
struct Fix {
    utc: Option<Timestamp>,
    lat: Option<f64>,
    lon: Option<f64>,
    alt: Option<f64>,
    speed: Option<f64>,
    track_deg: Option<f64>,
    hdop: Option<f64>,
    gst: Option<(f64, f64)>,
    satellites: Option<u32>,
    mode: i64,
}

/// Everything but the two byte/frame decoders, so that their callbacks may borrow it.
#[derive(Debug)]
struct State<'a, W: Write, const T3: usize, const T2: usize, const BUF: usize> {
    config: PipelineConfig<'a>,
    header: Header,
    writer: Writer<W, BUF>,
    /// Logs started on new sinks ([`Pipeline::rotate`]).
    rotations: u32,
    local: LocalFrame,
    clock: Clock,
    anchorer: Anchorer,
    observability: Observability,
    last_anchor_record: Option<Timestamp>,
    calibration: MountCalibration,
    /// The ego carried across a VO re-initialisation until the new session is anchored.
    carry: Option<carry::Carry>,
    /// The camera's world pose, the ego heading and the position's σ (m) at the latest
    /// anchored frame.
    last_camera: Option<(Timestamp, Pose, f64, f64)>,
    /// The anchored ego's turn rate, carried with the attitude across a VO gap.
    turn_rate: carry::TurnRate,
    /// The ego the windows score, with the corrections eased in, and the VO session and
    /// pose it was last given.
    ease: ease::Ease,
    eased_vo: Option<(u32, Pose)>,
    /// The eased ego, smoothed a second late for the windows.
    lag: lag::FixedLag,
    /// The latest vehicle speed, m/s.
    last_speed: f64,
    /// The mount poses and detections are placed with (the calibration's estimate).
    mount: MountEstimate,
    last_mount_record: Option<Timestamp>,
    trackers: &'a mut Trackers<'a, T3, T2>,
    /// Internal frame number = the camera's + this (raised when the camera restarts).
    frame_offset: u64,
    /// The latest VO pose, with its internal frame number.
    vo: Option<LastVo>,
    ego: Option<Ego>,
    /// Seconds per frame number (for track velocities in m/s).
    frame_interval: f64,
    last_frame3d: Option<u64>,
    last_frame2d: Option<u64>,
    agents: heapless::Vec<Agent, T3>,
    /// Of `agents`, those the tracker no longer reports, and since when (s).
    lost: heapless::Vec<(u32, f64), KEPT_AGENTS>,
    agents_t: f64,
    window: Option<Window<'a>>,
    /// The windows' latest at-fault collision, carried across a window's end ([`edge`]).
    edge_collisions: edge::EdgeCollisions,
    /// The latest HDOP from a full fix, for position-only CAN fixes.
    hdop: Option<f64>,
    /// Receive time of the NMEA sentence before the current one (the epoch's last).
    last_sentence: Option<Timestamp>,
    /// A DBC-defined GNSS source's latest time frame: (receive time, UTC of the fix).
    signal_epoch: Option<(Timestamp, Timestamp)>,
    /// The latest monotonic time of any input.
    now: Timestamp,
    issues: Issues,
    stats: PipelineStats,
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
                header,
                writer: Writer::buffered(io, &header, config.writer),
                rotations: 0,
                local: LocalFrame::new(config.origin),
                clock: Clock::new(),
                anchorer: Anchorer::new(config.anchor),
                observability: Observability::TooFewAnchors,
                last_anchor_record: None,
                calibration: MountCalibration::new(config.mount, config.calibration),
                carry: None,
                last_camera: None,
                turn_rate: carry::TurnRate::default(),
                ease: ease::Ease::new(config.ease_s),
                eased_vo: None,
                lag: lag::FixedLag::new(),
                last_speed: 0.0,
                mount: MountCalibration::new(config.mount, config.calibration).estimate(),
                last_mount_record: None,
                trackers,
                frame_offset: 0,
                vo: None,
                ego: None,
                frame_interval: 0.1,
                last_frame3d: None,
                last_frame2d: None,
                agents: heapless::Vec::new(),
                lost: heapless::Vec::new(),
                agents_t: 0.0,
                window: None,
                edge_collisions: edge::EdgeCollisions::default(),
                hdop: None,
                last_sentence: None,
                signal_epoch: None,
                now: Timestamp::ZERO,
                issues: Issues::default(),
                stats: PipelineStats::default(),
            },
        }
    }

    /// What the pipeline has done so far.
    pub fn stats(&self) -> &PipelineStats {
        &self.state.stats
    }

    /// Refused inputs so far, by reason.
    pub fn issues(&self) -> &Issues {
        &self.state.issues
    }

    /// The clocks.
    pub fn clock(&self) -> &Clock {
        &self.state.clock
    }

    /// The anchorer (its estimate and quality).
    pub fn anchorer(&self) -> &Anchorer {
        &self.state.anchorer
    }

    /// Bytes from the GNSS receiver's serial port, received at device time `t`.
    /// Work is linear in `bytes`.
    pub fn push_serial(&mut self, t: Timestamp, bytes: &[u8]) -> Result<(), PipelineError<W::Error>> {
        let state = &mut self.state;
        let t = state.monotonic(t)?;
        state.stats.serial_bytes = state.stats.serial_bytes.saturating_add(bytes.len() as u64);
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
        let t = state.monotonic(t)?;
        state.stats.can_frames = state.stats.can_frames.saturating_add(1);
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
        let t = self.state.monotonic(t)?;
        self.state.on_vo(t, frame, session, pose)
    }

    /// The camera mount as calibrated so far.
    pub fn mount(&self) -> &MountEstimate {
        &self.state.mount
    }

    /// The 3D detections of camera frame `frame` in the camera frame. At most `T3` are
    /// used; the rest are counted.
    pub fn push_detections(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[Detection3d],
    ) -> Result<(), PipelineError<W::Error>> {
        let t = self.state.monotonic(t)?;
        self.state.on_detections(t, frame, detections)
    }

    /// The 2D detections of camera frame `frame`. At most `T2` are used.
    pub fn push_detections2d(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[ImageDetection],
    ) -> Result<(), PipelineError<W::Error>> {
        let t = self.state.monotonic(t)?;
        self.state.on_detections2d(t, frame, detections)
    }

    /// End of input: the last GNSS epoch, the open verification window, the counts not yet
    /// written, then the log is closed and flushed. Returns the sink and the totals.
    pub fn finish(mut self) -> Result<(W, PipelineStats, Issues), PipelineError<W::Error>> {
        self.close()?;
        let State { writer, stats, issues, .. } = self.state;
        Ok((writer.finish()?, stats, issues))
    }

    /// Close the log on the current sink and go on on `io` (a new file every few minutes,
    /// so that a crash or a full disk costs at most the file being written): the new log
    /// starts with its own header, the clock offset in force and an event naming the
    /// rotation; anchoring, tracking and verification go on undisturbed. Returns the old
    /// sink, flushed.
    pub fn rotate(&mut self, io: W) -> Result<W, PipelineError<W::Error>> {
        let state = &mut self.state;
        state.writer.close()?;
        let next = Writer::buffered(io, &state.header, state.config.writer);
        let old = core::mem::replace(&mut state.writer, next).finish()?;
        state.rotations = state.rotations.saturating_add(1);
        let now = state.now;
        if let Some(offset) = state.clock.offset() {
            let record = ClockOffset { t_us: state.log_time(now), offset_us: offset, reason: 1 };
            state.write(&Record::ClockOffset(record))?;
        }
        let rotations = state.rotations;
        state.event(now, 2, format_args!("log continued on a new file (rotation {rotations})"))?;
        Ok(old)
    }

    /// `n` inputs were dropped before they reached the pipeline (the host's queue was
    /// full); counted and written as an event like every refused input.
    pub fn note_dropped(&mut self, t: Timestamp, n: u64) -> Result<(), PipelineError<W::Error>> {
        let t = self.state.monotonic(t)?;
        self.state.issue(t, Issue::InputsDropped, n)
    }

    /// [`Pipeline::finish`] in place: everything but giving the sink back. A pipeline is
    /// large (130 KB with 64 tracks); on a microcontroller it should not be moved.
    pub fn close(&mut self) -> Result<(), PipelineError<W::Error>> {
        let state = &mut self.state;
        if let Some(fix) = self.nmea.decoder.finish() {
            let rx = state.last_sentence.unwrap_or(state.now);
            state.on_fix(rx, &nmea_fix(&fix))?;
        }
        let now = state.now;
        for (at, smoothed) in state.lag.flush() {
            state.score(at, &smoothed)?;
        }
        state.close_window(now)?;
        state.close_calibration(now)?;
        let tail: heapless::Vec<(Issue, u64), { Issue::ALL.len() }> = state.issues.unreported().collect();
        for (issue, count) in tail {
            state.event(now, 3, format_args!("{} ({count} in all)", issue.text()))?;
        }
        let s = state.stats;
        let issues = state.issues.total();
        state.event(now, 2, format_args!("pipeline finished: {s}, {issues} issues"))?;
        state.writer.close()
    }
}

/// A finished NMEA epoch in the pipeline's form.
fn nmea_fix(f: &crate::nmea::GnssFix) -> Fix {
    Fix {
        utc: f.time(),
        lat: f.lat,
        lon: f.lon,
        alt: f.alt_hae().or(f.alt_msl),
        speed: f.speed_mps,
        track_deg: f.track_deg,
        hdop: f.hdop,
        gst: f.sigma_lat_m.zip(f.sigma_lon_m),
        satellites: f.satellites_used,
        mode: if f.has_position() { i64::from(f.mode.gpsd()) } else { 0 },
    }
}

/// Yaw, pitch, roll (Z-Y-X) of a rotation, rad.
fn euler(r: &nalgebra::Matrix3<f64>) -> [f64; 3] {
    [libm::atan2(r[(1, 0)], r[(0, 0)]), libm::asin((-r[(2, 0)]).clamp(-1.0, 1.0)), libm::atan2(r[(2, 1)], r[(2, 2)])]
}

impl<'a, W: Write, const T3: usize, const T2: usize, const BUF: usize> State<'a, W, T3, T2, BUF> {
    fn write(&mut self, record: &Record) -> Result<(), PipelineError<W::Error>> {
        match self.writer.write(record) {
            Ok(()) => {
                self.stats.records = self.stats.records.saturating_add(1);
                Ok(())
            }
            Err(WriteError::RecordTooLarge) => {
                self.issues.count(Issue::RecordRefused, 1, self.now.micros());
                Ok(())
            }
            Err(e) => Err(e),
        }
    }

    fn log_time(&self, t: Timestamp) -> i64 {
        self.clock.log_time(t)
    }

    fn event(
        &mut self,
        t: Timestamp,
        level: u8,
        args: core::fmt::Arguments<'_>,
    ) -> Result<(), PipelineError<W::Error>> {
        let mut text: heapless::String<MAX_TEXT> = heapless::String::new();
        // A text longer than an event holds is cut where it no longer fits.
        let _ = text.write_fmt(args);
        let mut e = EventRecord { t_us: self.log_time(t), level, ..EventRecord::default() };
        let _ = e.text.extend_from_slice(text.as_bytes());
        self.write(&Record::Event(e))
    }

    /// Count an issue and write its event when due.
    fn issue(&mut self, t: Timestamp, issue: Issue, n: u64) -> Result<(), PipelineError<W::Error>> {
        match self.issues.count(issue, n, t.micros()) {
            Some(total) => self.event(t, 3, format_args!("{} ({total} so far)", issue.text())),
            None => Ok(()),
        }
    }

    fn monotonic(&mut self, device: Timestamp) -> Result<Timestamp, PipelineError<W::Error>> {
        let (t, reset) = self.clock.monotonic(device);
        if t > self.now {
            self.now = t;
        }
        if let Some(back) = reset {
            self.issues.count(Issue::ClockReset, 1, t.micros());
            self.event(
                t,
                3,
                format_args!(
                    "device clock reset: went back {} s; monotonic time goes on, UTC is taken again from the next fix",
                    Decimal::new(back as f64 * 1e-6, 3)
                ),
            )?;
        }
        Ok(t)
    }

    fn on_nmea(&mut self, t: Timestamp, event: &StreamEvent<'_>) -> Result<(), PipelineError<W::Error>> {
        match event {
            StreamEvent::Sentence(NmeaEvent::Message { fix, .. }) => {
                if let Some(fix) = fix {
                    let rx = self.last_sentence.unwrap_or(t);
                    self.on_fix(rx, &nmea_fix(fix))?;
                }
                self.last_sentence = Some(t);
                Ok(())
            }
            StreamEvent::Sentence(_) => self.issue(t, Issue::NmeaBadSentence, 1),
            StreamEvent::Dropped(_) => self.issue(t, Issue::NmeaDropped, 1),
        }
    }

    fn on_can(&mut self, t: Timestamp, event: crate::can::Event) -> Result<(), PipelineError<W::Error>> {
        let Decoded { message, .. } = match event {
            crate::can::Event::Decoded(d) => d,
            crate::can::Event::Error(_) | crate::can::Event::Dropped(_) => {
                return self.issue(t, Issue::CanBadFrame, 1);
            }
        };
        let source = self.config.speed;
        match message {
            Message::WheelSpeed(w) if source == Some(SpeedSource::Ccvs1) => match w.speed_kmh {
                Some(kmh) => self.speed(t, kmh / 3.6, 1),
                None => Ok(()),
            },
            Message::Obd(r) if source == Some(SpeedSource::Obd) => match r.vehicle_speed_kmh() {
                Some(kmh) => self.speed(t, f64::from(kmh) / 3.6, 2),
                None => Ok(()),
            },
            Message::GnssPosition(p) => {
                let utc = p
                    .date
                    .zip(p.time)
                    .map(|(d, s)| Timestamp::from_micros(i64::from(d) * 86_400_000_000 + i64::from(s) * 100));
                if p.hdop.is_some() {
                    self.hdop = p.hdop;
                }
                let fix = Fix {
                    utc,
                    lat: p.latitude,
                    lon: p.longitude,
                    alt: p.altitude,
                    hdop: p.hdop,
                    satellites: p.satellites.map(u32::from),
                    mode: if p.method == 0 {
                        0
                    } else if p.altitude.is_some() {
                        3
                    } else {
                        2
                    },
                    ..Fix::default()
                };
                self.on_fix(t, &fix)
            }
            Message::PositionRapid(p) => {
                let fix = Fix { lat: p.latitude, lon: p.longitude, hdop: self.hdop, mode: 2, ..Fix::default() };
                self.on_fix(t, &fix)
            }
            Message::VehiclePosition(p) => {
                let fix = Fix { lat: p.latitude, lon: p.longitude, hdop: self.hdop, mode: 2, ..Fix::default() };
                self.on_fix(t, &fix)
            }
            _ => Ok(()),
        }
    }

    fn on_gnss_signals(&mut self, t: Timestamp, read: GnssFrame) -> Result<(), PipelineError<W::Error>> {
        match read {
            GnssFrame::Time(utc) => {
                self.signal_epoch = Some((t, utc));
                Ok(())
            }
            GnssFrame::Position { lat, lon, valid, sigma_m } => {
                let utc = self.signal_epoch.take().and_then(|(rx, utc)| (t - rx <= signals::EPOCH_GAP).then_some(utc));
                let fix = Fix {
                    utc,
                    lat: Some(lat),
                    lon: Some(lon),
                    gst: sigma_m.map(|s| (s, s)),
                    mode: if valid { 2 } else { 0 },
                    ..Fix::default()
                };
                self.on_fix(t, &fix)
            }
            GnssFrame::Unreadable => self.issue(t, Issue::CanBadFrame, 1),
        }
    }

    fn speed(&mut self, t: Timestamp, mps: f64, source: i64) -> Result<(), PipelineError<W::Error>> {
        if self.anchorer.push_speed(t, mps).is_err() {
            return self.issue(t, Issue::SpeedRefused, 1);
        }
        self.stats.speeds = self.stats.speeds.saturating_add(1);
        self.last_speed = mps;
        let record = VehicleSpeed { t_us: self.log_time(t), speed_mm_s: quantise(mps, 1e-3), source };
        self.write(&Record::VehicleSpeed(record))
    }

    fn on_fix(&mut self, rx: Timestamp, fix: &Fix) -> Result<(), PipelineError<W::Error>> {
        let mut utc_trusted = false;
        if let Some(utc) = fix.utc {
            match self.clock.utc_sample(utc, rx) {
                OffsetChange::None => utc_trusted = true,
                OffsetChange::Ignored(by) => {
                    self.issue(rx, Issue::GnssTimeIgnored, 1)?;
                    self.event(
                        rx,
                        3,
                        format_args!(
                            "GNSS time {} s off the clock: not used as time",
                            Decimal::signed(by as f64 * 1e-6, 3)
                        ),
                    )?;
                }
                change => {
                    utc_trusted = true;
                    let (offset, reason, text) = match change {
                        OffsetChange::First(o) => (o, 0, "UTC known from the first fix: the log is in UTC from here"),
                        OffsetChange::Drift(o) => (o, 1, ""),
                        OffsetChange::Step { offset, .. } => (offset, 2, "GNSS time stepped; the clock offset follows"),
                        _ => (self.clock.offset().unwrap_or(0), 3, "UTC taken again after the device clock reset"),
                    };
                    let record = ClockOffset { t_us: self.log_time(rx), offset_us: offset, reason };
                    self.write(&Record::ClockOffset(record))?;
                    if !text.is_empty() {
                        self.event(rx, 2, format_args!("{text} (offset {} µs)", offset))?;
                    }
                }
            }
        }
        let position = match (fix.lat, fix.lon, fix.mode >= 2) {
            (Some(lat), Some(lon), true) => {
                Geodetic::new(lat, lon, fix.alt.unwrap_or(self.config.origin.height_m)).ok()
            }
            _ => None,
        };
        let Some(position) = position else {
            return self.issue(rx, Issue::GnssNoPosition, 1);
        };
        let t_us = match fix.utc {
            Some(utc) if utc_trusted => utc.micros(),
            _ => self.log_time(rx),
        };
        let record = GnssFix {
            t_us,
            lat_e7: quantise(position.lat_deg, 1e-7),
            lon_e7: quantise(position.lon_deg, 1e-7),
            alt_mm: quantise(position.height_m, 1e-3),
            speed_mm_s: fix.speed.map_or(-1, |v| quantise(v, 1e-3)),
            track_e4: fix.track_deg.map_or(-1, |d| quantise(d * (core::f64::consts::PI / 180.0), 1e-4)),
            hdop_e2: fix.hdop.map_or(-1, |h| quantise(h, 1e-2)),
            satellites: fix.satellites.map_or(-1, i64::from),
            mode: fix.mode,
        };
        self.write(&Record::GnssFix(record))?;
        let g = &self.config.gnss;
        let sigma = gnss_sigma(fix.hdop, fix.gst, g.uere_m).unwrap_or(g.default_sigma_m);
        let enu = self.local.geodetic_to_enu(&position);
        if self.anchorer.push_gnss(rx, enu, sigma).is_err() {
            return self.issue(rx, Issue::GnssRefused, 1);
        }
        self.stats.fixes = self.stats.fixes.saturating_add(1);
        Ok(())
    }

    fn on_vo(&mut self, t: Timestamp, frame: u64, session: u32, pose: &Pose) -> Result<(), PipelineError<W::Error>> {
        if !pose.is_finite() {
            return self.issue(t, Issue::VoNotFinite, 1);
        }
        if self.vo.is_some_and(|v| t <= v.t) {
            return self.issue(t, Issue::VoOutOfOrder, 1);
        }
        let raw_frame = frame;
        let mut frame = raw_frame.saturating_add(self.frame_offset);
        let restarted = self.vo.is_some_and(|v| frame <= v.frame);
        if let Some(v) = self.vo.filter(|v| v.session != session) {
            self.new_session(t, &v, session, pose)?;
        }
        if self.anchorer.push_vo(t, pose.translation).is_err() {
            return self.issue(t, Issue::VoOutOfOrder, 1);
        }
        if let Some(v) = self.vo {
            if restarted {
                // Frame numbers went back while time went on: the camera process restarted.
                // Internally frames go on counting, so that the trackers keep their tracks.
                self.frame_offset = v.frame.saturating_add(1).saturating_sub(raw_frame);
                frame = raw_frame.saturating_add(self.frame_offset);
                self.issue(t, Issue::CameraRestarted, 1)?;
            }
            let skipped = frame - v.frame - 1;
            if skipped > 0 {
                self.issue(t, Issue::FramesMissing, skipped)?;
            }
            let per_frame = (t - v.t).as_secs_f64() / (frame - v.frame) as f64;
            if per_frame.is_finite() && per_frame > 0.0 {
                self.frame_interval = per_frame;
            }
        }
        self.vo = Some(LastVo { t, frame, session });
        self.stats.vo_poses = self.stats.vo_poses.saturating_add(1);
        let t_us = self.log_time(t);
        // The log keeps the camera's own numbers (sequence gaps and restarts show there).
        let frame_i64 = i64::try_from(raw_frame).unwrap_or(i64::MAX);
        self.write(&Record::FrameMeta(FrameMeta { t_us, frame: frame_i64, flags: 0 }))?;
        let [yaw, pitch, roll] = euler(&pose.rotation);
        let p = &pose.translation;
        self.write(&Record::VoPose(VoPose {
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
        let (anchor, carried) = match self.anchorer.estimate().copied() {
            Some(anchor) => {
                if let Some(c) = self.carry.take() {
                    let after = t.as_secs_f64() - c.since();
                    self.event(
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
                let speed = self.last_speed * self.anchorer.wheel_factor().unwrap_or(1.0);
                match self.carry.as_mut().and_then(|c| c.push(t.as_secs_f64(), pose, speed)) {
                    Some(anchor) => (anchor, true),
                    None => return Ok(()),
                }
            }
        };
        let camera = mount::camera_in_world(&anchor, pose);
        let body = self.mount.mount.body_pose(&camera);
        let b = &body.translation;
        let anchored = Pose2::new(b.x, b.y, mount::heading(&body.rotation));
        if !(anchored.is_finite() && b.z.is_finite()) {
            return Ok(());
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
        if carried {
            self.stats.carried_frames = self.stats.carried_frames.saturating_add(1);
        } else {
            self.last_camera = Some((t, camera, anchored.heading, sigma));
            self.turn_rate.push(t.as_secs_f64(), anchored.heading);
            self.stats.anchored_frames = self.stats.anchored_frames.saturating_add(1);
        }
        self.write(&Record::EgoPose(EgoPose {
            t_us,
            x_mm: quantise(b.x, 1e-3),
            y_mm: quantise(b.y, 1e-3),
            z_mm: quantise(b.z, 1e-3),
            yaw_e4: quantise(ego.pose.heading, 1e-4),
            sigma_mm: quantise(sigma.min(1e6), 1e-3),
        }))?;
        for (at, smoothed) in self.lag.push(t, eased) {
            self.score(at, &smoothed)?;
        }
        Ok(())
    }

    /// The VO started again under a new session number, `first` its first pose: anchoring
    /// starts afresh (the old similarity's position and scale say nothing of the new VO
    /// frame), with the camera's attitude carried across the gap as the prior on the new
    /// rotation; until the new session is observable the ego is carried.
    fn new_session(
        &mut self,
        t: Timestamp,
        last: &LastVo,
        session: u32,
        first: &Pose,
    ) -> Result<(), PipelineError<W::Error>> {
        if session < last.session {
            self.issue(t, Issue::VoSessionBackwards, 1)?;
        }
        let old_rotation_sigma = self.anchorer.quality().rotation_sigma_rad;
        self.anchorer.new_vo_session();
        if let Some((tc, camera, _, _)) = self.last_camera {
            let gap = (t - tc).as_secs_f64();
            let (rotation, sigma) =
                carry::rotation_prior(&camera, gap, self.turn_rate.rate(), first, old_rotation_sigma);
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
        self.event(
            t,
            3,
            format_args!(
                "VO session {session} began {} s after the last pose of session {}: anchoring starts again{until}",
                Decimal::new(gap, 1),
                last.session
            ),
        )
    }

    /// The pose into the mount calibration; the estimate as a record when it is due, an
    /// event when it is first calibrated.
    fn calibrate(&mut self, t: Timestamp, session: u32, pose: &Pose) -> Result<(), PipelineError<W::Error>> {
        if !self.calibration.push(t.as_secs_f64(), session, pose) {
            return Ok(());
        }
        let was_calibrated = self.mount.calibrated;
        self.mount = self.calibration.estimate();
        if self.mount.calibrated && !was_calibrated {
            let [_, pitch, yaw] = self.mount.mount.roll_pitch_yaw;
            let [sy, sp] = self.mount.sigma;
            let samples = self.mount.samples;
            self.event(
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
        } else if self.last_mount_record.is_some_and(|last| t - last < self.config.anchor_interval) {
            return Ok(());
        }
        self.last_mount_record = Some(t);
        self.write(&Record::MountEstimate(mount_record(self.log_time(t), &self.mount)))
    }

    /// At the end: the last estimate, and an event when the drive never calibrated it.
    fn close_calibration(&mut self, t: Timestamp) -> Result<(), PipelineError<W::Error>> {
        let m = self.mount;
        if m.samples > 0 {
            self.write(&Record::MountEstimate(mount_record(self.log_time(t), &m)))?;
        }
        if m.calibrated {
            return Ok(());
        }
        let kept = if m.samples == 0 { "the nominal mount was kept" } else { "the nominal mount still weighs in" };
        self.event(
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
    fn anchor_changes(&mut self, t: Timestamp) -> Result<(), PipelineError<W::Error>> {
        let quality = *self.anchorer.quality();
        let changed = quality.observability != self.observability;
        if changed {
            self.observability = quality.observability;
            let scale = self.anchorer.estimate().map_or(f64::NAN, |e| e.scale);
            self.event(
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
        let due = self.last_anchor_record.is_none_or(|last| t - last >= self.config.anchor_interval);
        if !(changed || due) {
            return Ok(());
        }
        self.last_anchor_record = Some(t);
        self.write(&Record::AnchorEstimate(anchor_record(self.log_time(t), &estimate, &quality)))
    }

    /// The VO pose a detection of `frame` at `t` belongs with: the anchored ego, or none.
    fn pose_for(&self, t: Timestamp, frame: u64) -> (bool, Option<Ego>) {
        let near = |ft: Timestamp, f: u64| {
            f == frame || (t - ft).micros().saturating_abs() <= self.config.max_pose_age.micros()
        };
        let has_vo = self.vo.is_some_and(|v| near(v.t, v.frame));
        (has_vo, self.ego.filter(|e| near(e.t, e.frame)))
    }

    fn on_detections(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[Detection3d],
    ) -> Result<(), PipelineError<W::Error>> {
        let frame = frame.saturating_add(self.frame_offset);
        if self.last_frame3d.is_some_and(|f| frame <= f) {
            return self.issue(t, Issue::DetectionsOutOfOrder, 1);
        }
        self.last_frame3d = Some(frame);
        let (has_vo, ego) = self.pose_for(t, frame);
        let Some(ego) = ego else {
            if !has_vo {
                self.issue(t, Issue::DetectionsWithoutPose, detections.len().max(1) as u64)?;
            }
            return self.write_raw(t, frame, detections);
        };
        let mut placed: heapless::Vec<Detection3d, T3> = heapless::Vec::new();
        let mut excess = 0u64;
        for d in detections {
            let world = mount::to_world(&ego.eased, &self.mount.mount.to_body(d));
            if placed.push(world).is_err() {
                excess += 1;
            }
        }
        self.stats.detections_placed = self.stats.detections_placed.saturating_add(placed.len() as u64);
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
                });
            })
            .is_err()
        {
            return self.issue(t, Issue::DetectionsOutOfOrder, 1);
        }
        let refused = self.trackers.tracker3d.stats().rejected.saturating_sub(rejected_before).saturating_add(excess);
        if refused > 0 {
            self.issue(t, Issue::DetectionsRefused, refused)?;
        }
        self.write_tracks(t, &ego, &outputs)
    }

    fn write_raw(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[Detection3d],
    ) -> Result<(), PipelineError<W::Error>> {
        let t_us = self.log_time(t);
        for d in detections.iter().take(T3) {
            let b = &d.bbox;
            let [xx, xy, yy] = d.position_covariance.unwrap_or([0.0; 3]);
            self.write(&Record::Detection3d(DetectionRecord {
                t_us,
                frame: i64::try_from(frame).unwrap_or(i64::MAX),
                class: self.config.classes.get(usize::from(d.class)).map_or(255, |m| m.code),
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
            self.stats.detections_raw = self.stats.detections_raw.saturating_add(1);
        }
        Ok(())
    }

    fn write_tracks(&mut self, t: Timestamp, ego: &Ego, outputs: &[TrackState]) -> Result<(), PipelineError<W::Error>> {
        let t_us = self.log_time(t);
        let per_second = 1.0 / self.frame_interval;
        // Agents the tracker stopped reporting stay a while, moved on by their velocity: the
        // windows score the ego a second back, when the cone the car passed was still
        // beside it (most leave the camera's view, not the road).
        let now = t.as_secs_f64();
        let dt = now - self.agents_t;
        let mut kept: heapless::Vec<(Agent, f64), KEPT_AGENTS> = heapless::Vec::new();
        for a in &self.agents {
            if outputs.iter().any(|o| o.id == a.id) {
                continue;
            }
            let since = self.lost.iter().find(|(id, _)| *id == a.id).map_or(now, |l| l.1);
            if now - since <= KEEP_LOST_S {
                let mut a = *a;
                a.bbox.centre.x += a.velocity.0 * dt;
                a.bbox.centre.y += a.velocity.1 * dt;
                // At most KEPT_AGENTS kept; beyond, the rest are forgotten.
                let _ = kept.push((a, since));
            }
        }
        self.agents.clear();
        self.lost.clear();
        self.agents_t = now;
        // The tracks live in the eased ego's frame; the log has them beside its anchored one.
        let to_log = ease::Reframe::new(ego.eased, ego.pose);
        for chunk in outputs.chunks(MAX_TRACKS) {
            let mut batch = Tracks3d { t_us, tracks: heapless::Vec::new() };
            for o in chunk {
                let b = &o.bbox;
                let (vx, vy) = (o.velocity[0] * per_second, o.velocity[1] * per_second);
                let meta = self.config.classes.get(usize::from(o.class)).copied();
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
                let kind = meta.map_or(AgentKind::Object, |m| m.kind);
                let _ = self.agents.push(Agent {
                    id: o.id,
                    kind,
                    bbox: OrientedBox { centre: Pose2::new(b.x, b.y, b.yaw), length: b.l, width: b.w },
                    velocity: (vx, vy),
                });
            }
            self.write(&Record::Tracks3d(batch))?;
        }
        for (a, since) in kept {
            if self.agents.push(a).is_ok() {
                let _ = self.lost.push((a.id, since));
            }
        }
        self.stats.track_states = self.stats.track_states.saturating_add(outputs.len() as u64);
        Ok(())
    }

    fn on_detections2d(
        &mut self,
        t: Timestamp,
        frame: u64,
        detections: &[ImageDetection],
    ) -> Result<(), PipelineError<W::Error>> {
        let frame = frame.saturating_add(self.frame_offset);
        if self.last_frame2d.is_some_and(|f| frame <= f) {
            return self.issue(t, Issue::DetectionsOutOfOrder, 1);
        }
        self.last_frame2d = Some(frame);
        let mut boxes: heapless::Vec<Detection, T2> = heapless::Vec::new();
        let mut excess = 0;
        for d in detections {
            if boxes.push(d.detection).is_err() {
                excess += 1;
            }
        }
        if excess > 0 {
            self.issue(t, Issue::DetectionsRefused, excess)?;
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
            return self.issue(t, Issue::DetectionsOutOfOrder, 1);
        }
        let t_us = self.log_time(t);
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
            self.write(&Record::Track2d(Track2d {
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
        self.stats.track2d_states = self.stats.track2d_states.saturating_add(outputs.len() as u64);
        Ok(())
    }

    /// One smoothed ego pose (of `t`, a second back) into the open verification window: the
    /// agents moved to `t` by their velocity (back, from their latest update); a window
    /// that reached its length is closed at `t`.
    fn score(&mut self, t: Timestamp, ego: &Pose2) -> Result<(), PipelineError<W::Error>> {
        let Some(map) = self.config.map else { return Ok(()) };
        let ts = t.as_secs_f64();
        if self.window.is_none() {
            let checker = Checker::new(map, self.config.footprint);
            self.window = Some(Window {
                start: ts,
                scorer: Scorer::new(checker, Channel::Insensitive, self.config.score),
                inherited_collision: self.edge_collisions.carried_into(ts),
            });
        }
        // The latest tracks, moved by their velocity to this pose's time (in place: a copy
        // of 64 agents is 4.6 KB of a microcontroller's stack).
        let dt = ts - self.agents_t;
        for a in self.agents.iter_mut() {
            a.bbox.centre.x += a.velocity.0 * dt;
            a.bbox.centre.y += a.velocity.1 * dt;
        }
        self.agents_t = ts;
        let Some(window) = self.window.as_mut() else { return Ok(()) };
        // A refused pose (not finite, time not increasing) leaves the window as it was.
        if let Ok(report) = window.scorer.step(ts, ego, &self.agents) {
            if let Some(collision) = &report.collision {
                self.edge_collisions.push(ts, collision);
            }
        }
        if ts - window.start >= self.config.window_s {
            self.close_window(t)?;
        }
        Ok(())
    }

    fn close_window(&mut self, t: Timestamp) -> Result<(), PipelineError<W::Error>> {
        let Some(window) = self.window.take() else { return Ok(()) };
        let own: Scores = window.scorer.finish(None);
        let s = window.inherited_collision.map_or(own, |m| edge::inherit(&own, m));
        if s.poses == 0 {
            return Ok(());
        }
        self.stats.windows = self.stats.windows.saturating_add(1);
        if s.verified {
            self.stats.windows_verified = self.stats.windows_verified.saturating_add(1);
        }
        self.write(&Record::Verification(verification_record(self.log_time(t), &s)))?;
        let verdict = if s.verified { "verified" } else { "not verified" };
        self.event(
            t,
            2,
            format_args!(
                "verification window of {} s: score {}, {verdict}",
                Decimal::new(s.duration, 1),
                Decimal::new(s.score, 2)
            ),
        )
    }
}

/// A window's scores as a record (the device's and `dash2sim finish`'s).
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
