//! `dash2sim record`: the core [`Pipeline`] on the host, fed from recorded files merged by
//! receive time ([`sources`]), writing the 4D log. The files go through the same input
//! stream format a microcontroller replays (`--save-inputs` writes it), so the host and the
//! device run the very same code on the very same bytes.

#[cfg(feature = "bridge")]
pub mod bridge;
#[cfg(feature = "bridge")]
pub mod interleave;
#[cfg(feature = "bridge")]
pub mod live;
mod request;
pub mod sources;
pub mod storage;
pub mod track2d;

pub use request::*;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dash2sim_can::SignalTable;
use dash2sim_core::anchor::{AnchorConfig, AnchorMode};
use dash2sim_core::can::signal::Signal;
use dash2sim_core::geo::Geodetic;
use dash2sim_core::imu::ImuMount;
use dash2sim_core::map::MapView;
use dash2sim_core::pipeline::replay::{feed, Input, Reader};
use dash2sim_core::pipeline::{
    CameraMount, ClassMeta, FrameId, GnssErrorModel, GnssFrame, GnssSignals, ImuConfig, Issue, Issues, Pipeline,
    PipelineConfig, PipelineStats, RelativeMotion, SpeedSource, Trackers,
};

use crate::ingest::can::SignalName;
use crate::log::signing::SecretKey;
use crate::{Error, Field, Result};
use dash2sim_core::pipeline::profile::{self, work_zone_meta, work_zone_pipeline, work_zone_trackers};

/// The first fix of an input stream (NMEA, or CAN through `gnss`), for the origin when
/// none is given.
fn first_fix(stream: &[u8], gnss: Option<&GnssSignals>) -> Option<Geodetic> {
    let mut reader = Reader::new(stream).ok()?;
    let mut finder = FixFinder::new(gnss);
    while let Some(Ok((_, input))) = reader.next_input() {
        if let Some(origin) = finder.push(&input) {
            return Some(origin);
        }
    }
    None
}

/// The first GNSS fix of inputs as they come — NMEA on serial, or CAN through the
/// `--gnss-signals` — for the ENU origin of a recording given none (from files, or live).
struct FixFinder<'a> {
    nmea: dash2sim_core::nmea::Stream,
    gnss: Option<&'a GnssSignals>,
}

impl<'a> FixFinder<'a> {
    fn new(gnss: Option<&'a GnssSignals>) -> Self {
        Self { nmea: dash2sim_core::nmea::Stream::new(), gnss }
    }

    /// The fix `input` completes, if it is the first.
    fn push(&mut self, input: &Input<'_>) -> Option<Geodetic> {
        match input {
            // Line by line: a chunk of a serial port holds several epochs, and the first
            // position is the one wanted.
            Input::Serial(bytes) => bytes.split_inclusive(|&b| b == b'\n').find_map(|line| {
                self.nmea.feed(line, |_| {});
                let f = self.nmea.decoder.current();
                f.has_position()
                    .then(|| Geodetic::new(f.lat?, f.lon?, f.alt_hae().or(f.alt_msl).unwrap_or(0.0)).ok())?
            }),
            Input::Can(frame) => match self.gnss.and_then(|g| g.read(frame)) {
                Some(GnssFrame::Position { lat, lon, valid: true, .. }) => Geodetic::new(lat, lon, 0.0).ok(),
                _ => None,
            },
            _ => None,
        }
    }
}

/// The frames the GNSS signals are read from, named.
fn gnss_frames(g: &GnssSignals) -> Vec<(&'static str, FrameId)> {
    let mut frames = vec![("the GNSS signals' position (lat, lon)", g.position)];
    frames.extend(g.time.map(|(frame, _)| ("the GNSS signals' time", frame)));
    frames
}

/// For each wanted frame the stream's CAN never carries, what was there instead: a DBC
/// written for a module at another base id reads nothing, and says so here.
fn absent_frames(stream: &[u8], wanted: &[(&str, FrameId)]) -> Vec<String> {
    let Ok(mut reader) = Reader::new(stream) else { return Vec::new() };
    let mut seen = std::collections::BTreeSet::new();
    let mut frames = 0u64;
    while let Some(Ok((_, input))) = reader.next_input() {
        if let Input::Can(frame) = input {
            let id = embedded_can::Frame::id(&frame);
            seen.insert((matches!(id, embedded_can::Id::Extended(_)), dash2sim_core::can::frame::raw_id(id)));
            frames += 1;
        }
    }
    let (Some(first), Some(last)) = (seen.first(), seen.last()) else { return Vec::new() };
    let hex = |(extended, id): (bool, u32)| if extended { format!("0x{id:08X}") } else { format!("0x{id:03X}") };
    wanted
        .iter()
        .filter(|(_, f)| !seen.contains(&(f.extended, f.id)))
        .map(|(option, f)| {
            format!(
                "{option}: no frame with id {} in {frames} CAN frames; ids seen: {}–{} ({} ids). A module at \
                 another base id? A DBC file given as FILE@+OFFSET has its ids moved",
                hex((f.extended, f.id)),
                hex(*first),
                hex(*last),
                seen.len()
            )
        })
        .collect()
}

/// What a run of the pipeline over an input stream produced.
#[derive(Debug)]
pub struct Recording {
    /// The log.
    pub log: Vec<u8>,
    /// Totals.
    pub stats: PipelineStats,
    /// Refused inputs.
    pub issues: Issues,
    /// Inputs the stream held.
    pub inputs: u64,
}

/// Everything the pipeline is configured from, besides the stream.
#[derive(Clone, Debug)]
pub struct Setup {
    /// ENU origin.
    pub origin: Geodetic,
    /// The camera on the car.
    pub mount: CameraMount,
    /// Anchoring mode.
    pub mode: AnchorMode,
    /// GNSS σ.
    pub gnss: GnssErrorModel,
    /// Vehicle speed on the bus.
    pub speed: Option<SpeedSource>,
    /// GNSS from DBC signals on the bus.
    pub gnss_signals: Option<GnssSignals>,
    /// Map tile bytes.
    pub map: Option<Vec<u8>>,
    /// Device id of the header.
    pub device_id: [u8; 16],
    /// The device's signing key, if the log is signed.
    pub key: Option<SecretKey>,
    /// The IMU's axes on the camera.
    pub imu_mount: ImuMount,
    /// Where the relative motion comes from.
    pub relative_motion: RelativeMotion,
}

impl Setup {
    /// The pipeline's configuration: the work-zone profile with this setup's mount,
    /// anchoring mode, GNSS σ model, speed source, map and device id.
    pub fn config<'a>(&'a self, meta: &'a [ClassMeta]) -> Result<PipelineConfig<'a>> {
        let map = self.map.as_deref().map(MapView::parse).transpose().map_err(|e| Error::refused("map", e))?;
        let base = work_zone_pipeline(self.origin, meta);
        Ok(PipelineConfig {
            device_id: self.device_id,
            mount: self.mount,
            anchor: AnchorConfig { mode: self.mode, ..base.anchor },
            gnss: self.gnss,
            speed: self.speed,
            gnss_signals: self.gnss_signals,
            map,
            imu: ImuConfig { mount: self.imu_mount, ..base.imu },
            relative_motion: self.relative_motion,
            ..base
        })
    }

    /// The work-zone dashcam of `dash2sim scenario generate`: the default mount, a
    /// gravity-aligned VO frame, σ = HDOP × 2.5 m, wheel speed from CCVS1.
    pub fn work_zone(origin: Geodetic, map: Option<Vec<u8>>, device_id: [u8; 16]) -> Self {
        Setup {
            origin,
            mount: CameraMount::default(),
            mode: AnchorMode::GravityAligned,
            gnss: GnssErrorModel::default(),
            speed: Some(SpeedSource::Ccvs1),
            gnss_signals: None,
            map,
            device_id,
            key: None,
            imu_mount: ImuMount::default(),
            relative_motion: RelativeMotion::Vo,
        }
    }
}

/// Run the pipeline over an input stream (the core's replay format).
pub fn run_stream(stream: &[u8], setup: &Setup) -> Result<Recording> {
    let meta = work_zone_meta();
    let config = setup.config(&meta)?;
    let mut trackers: Box<Trackers<'_, 64, 32>> = Box::new(work_zone_trackers());
    let mut pipeline: Box<Pipeline<'_, Vec<u8>>> = Box::new(Pipeline::new(Vec::new(), config, &mut trackers));
    if let Some(key) = &setup.key {
        pipeline.sign_with(key.sealer());
    }
    let mut reader = Reader::new(stream).map_err(Error::other)?;
    let mut inputs = 0u64;
    while let Some(entry) = reader.next_input() {
        let (t, input) = entry.map_err(|e| Error::refused("input stream", e))?;
        feed(&mut pipeline, t, &input).map_err(|e| Error::refused("log", e))?;
        inputs += 1;
    }
    let (log, stats, issues) = pipeline.finish().map_err(|e| Error::refused("log", e))?;
    Ok(Recording { log, stats, issues, inputs })
}

/// The speed source the arguments name.
fn speed_source(args: &RecordRequest, table: &SignalTable) -> Result<Option<SpeedSource>> {
    let Some(name) = &args.speed_signal else {
        let bus = !args.sources.can.is_empty()
            || args.replay.is_some()
            || args.can_iface.is_some()
            || args.can_replay.is_some();
        return Ok(bus.then_some(match args.speed_source {
            SpeedMessage::Ccvs1 => SpeedSource::Ccvs1,
            SpeedMessage::Obd => SpeedSource::Obd,
        }));
    };
    let (frame, signal) = dbc_signal(table, name, Field::SpeedSignal)?;
    Ok(Some(SpeedSource::Signal { frame, signal, to_mps: args.speed_unit.to_mps() }))
}

/// The frame and signal `name` names in the DBC files; `field` says who asked.
fn dbc_signal(table: &SignalTable, name: &SignalName, field: Field) -> Result<(FrameId, Signal)> {
    let SignalName { message, signal } = name;
    if table.is_empty() {
        return Err(Error::request(Field::Dbc, format!("{field} name {name}, but no DBC files were given")));
    }
    let m = table
        .message_by_name(message)
        .ok_or_else(|| Error::request(field, format!("no message {message:?} in the DBC files")))?;
    let i = m
        .signal_index(signal)
        .ok_or_else(|| Error::request(field, format!("message {message} has no signal {signal:?}")))?;
    let frame = match m.id {
        embedded_can::Id::Standard(s) => FrameId { id: u32::from(s.as_raw()), extended: false },
        embedded_can::Id::Extended(e) => FrameId { id: e.as_raw(), extended: true },
    };
    Ok((frame, m.signals[i]))
}

/// The GNSS signals of a request, found in the DBC files.
pub fn gnss_signals(args: &RecordRequest, table: &SignalTable) -> Result<Option<GnssSignals>> {
    let Some(names) = &args.gnss_signals else { return Ok(None) };
    let find = |name: &SignalName| dbc_signal(table, name, Field::GnssSignals);
    let signal = |name: &Option<SignalName>| name.as_ref().map(|n| find(n).map(|(_, s)| s)).transpose();
    let (position, latitude) = find(&names.lat)?;
    Ok(Some(GnssSignals {
        position,
        latitude,
        longitude: find(&names.lon)?.1,
        valid: signal(&names.valid)?,
        accuracy: signal(&names.accuracy)?,
        time: names.time.as_ref().map(find).transpose()?,
    }))
}

/// Read the file sources into one input stream.
pub fn read_sources(args: &Sources) -> Result<(Vec<u8>, sources::SourceCounts)> {
    let mut inputs = sources::Inputs::default();
    if let Some(p) = &args.vo {
        inputs.vo(p)?;
    }
    if let Some(p) = &args.nmea {
        inputs.serial(p)?;
    }
    for p in &args.can {
        inputs.can(p)?;
    }
    if let Some(p) = &args.detections {
        inputs.detections(p, profile::class_id)?;
    }
    if let Some(p) = &args.detections2d {
        if args.vo.is_none() && args.detections.is_none() {
            return Err(Error::request(
                Field::Detections2d,
                "they need VO poses or 3D detections beside them: 2D detections are stamped with their frame's VO \
                 time (or, without VO, its 3D detections' time)",
            ));
        }
        inputs.detections2d(p)?;
    }
    if let Some(p) = &args.imu {
        inputs.imu(p)?;
    }
    if inputs.is_empty() {
        return Err(Error::request(
            Field::Sources,
            "nothing to record: give files (VO poses, NMEA, CAN, detections, IMU samples, or a saved input stream \
             to replay) or live sources (the camera process, a serial port, a CAN interface or capture), with \
             inputs in them",
        ));
    }
    Ok((inputs.stream()?, inputs.counts))
}

/// The live sources the request names, if any.
#[cfg(feature = "bridge")]
pub fn live_request(args: &RecordRequest) -> Result<Option<live::LiveRequest>> {
    let live = args.camera.is_some() || args.serial.is_some() || args.can_iface.is_some() || args.can_replay.is_some();
    if !live {
        return Ok(None);
    }
    let s = &args.sources;
    let files = [&s.vo, &s.nmea, &s.detections, &s.detections2d, &s.imu, &args.replay];
    if files.iter().any(|f| f.is_some()) || !s.can.is_empty() {
        return Err(Error::request(
            Field::Sources,
            "live sources (the camera process, a serial port, a CAN interface or capture) and file sources do not mix",
        ));
    }
    if args.save_inputs.is_some() {
        return Err(Error::request(
            Field::SaveInputs,
            "a live recording does not save its input stream (only a recording from files does)",
        ));
    }
    if !(args.segment_minutes.is_finite() && args.segment_minutes > 0.0) {
        return Err(Error::request(
            Field::SegmentMinutes,
            format!("{} minutes must be positive", args.segment_minutes),
        ));
    }
    let duration = match args.seconds {
        Some(s) if s.is_finite() && s > 0.0 => Some(std::time::Duration::from_secs_f64(s)),
        Some(s) => return Err(Error::request(Field::Seconds, format!("{s} s must be positive"))),
        None => None,
    };
    Ok(Some(live::LiveRequest {
        dir: args.output.clone(),
        camera_prefix: args.camera.clone(),
        serial: args.serial.clone(),
        baud: args.baud,
        can_interface: args.can_iface.clone(),
        can_replay: args.can_replay.clone(),
        realtime: args.realtime,
        segment: std::time::Duration::from_secs_f64(args.segment_minutes * 60.0),
        duration,
        status: args.status,
        storage: storage::StoragePolicy { quota: args.quota, min_free: args.min_free },
        keep: None,
    }))
}

/// `record` from files (or a saved input stream), without writing the log or reporting:
/// the recording and what the files held (with the problems of the captures and the DBC
/// files' warnings).
pub fn record_files(args: &RecordRequest) -> Result<(Recording, sources::SourceCounts)> {
    let (stream, mut counts) = match &args.replay {
        Some(path) => (std::fs::read(path).map_err(|e| Error::file(path, e))?, Default::default()),
        None => read_sources(&args.sources)?,
    };
    if let Some(path) = &args.save_inputs {
        std::fs::write(path, &stream).map_err(|e| Error::file(path, e))?;
    }
    let setup = setup_from_args(args, &mut counts.problems, |gnss| {
        first_fix(&stream, gnss).ok_or_else(|| {
            let hints = gnss.map(|g| absent_frames(&stream, &gnss_frames(g))).unwrap_or_default();
            Error::request(
                Field::Origin,
                format!(
                    "none given, and nothing to take it from: give one, a map, or GNSS with a fix (NMEA, or CAN with \
                     GNSS signals){}",
                    hints.iter().map(|h| format!("; {h}")).collect::<String>()
                ),
            )
        })
    })?;
    let mut wanted = setup.gnss_signals.as_ref().map(gnss_frames).unwrap_or_default();
    if let Some(SpeedSource::Signal { frame, .. }) = setup.speed {
        wanted.push(("the speed signal", frame));
    }
    counts.problems.extend(absent_frames(&stream, &wanted));
    Ok((run_stream(&stream, &setup)?, counts))
}

/// The recorder's setup from its arguments (both recorders): the origin is `--origin`, else
/// the map's, else what `fallback` finds. The DBC files' warnings go to `warnings`.
fn setup_from_args(
    args: &RecordRequest,
    warnings: &mut Vec<String>,
    fallback: impl FnOnce(Option<&GnssSignals>) -> Result<Geodetic>,
) -> Result<Setup> {
    // The DBC files, read once for both signal options.
    let (table, dbc_warnings) = crate::ingest::can::load_tables(&args.dbc)?;
    warnings.extend(dbc_warnings);
    let gnss_signals = gnss_signals(args, &table)?;
    let map = args.map.as_ref().map(|p| std::fs::read(p).map_err(|e| Error::file(p, e))).transpose()?;
    let origin = match (args.origin, &map) {
        (Some(origin), _) => origin,
        (None, Some(bytes)) => {
            let h =
                MapView::parse(bytes).map_err(|e| Error::refused(display(&args.map).to_string(), e))?.header().origin;
            Geodetic::new(h[0], h[1], h[2]).map_err(|e| Error::refused("map origin", e))?
        }
        (None, None) => fallback(gnss_signals.as_ref())?,
    };
    let device = args.device.check()?;
    Ok(Setup {
        origin,
        mount: device.mount,
        mode: device.mode.anchor_mode(),
        gnss: GnssErrorModel { uere_m: device.uere, ..GnssErrorModel::default() },
        speed: speed_source(args, &table)?,
        gnss_signals,
        map,
        device_id: args.device_id,
        key: args.key.as_deref().map(SecretKey::read).transpose()?,
        imu_mount: args.device.imu_mount,
        relative_motion: args.device.relative_motion,
    })
}

/// The live logger: records until the request's duration is over or `stop` is set (the
/// command line sets it on SIGINT / SIGTERM; the library installs no signal handler, and
/// the request's `keep` flag is the caller's too). `warn` hears the DBC files' warnings before the recording starts. Without `--origin` or
/// a `--map` the recording starts anyway and takes its ENU origin from the first GNSS fix,
/// as a recording from files does (the inputs before it are kept and logged once it is
/// known).
#[cfg(feature = "bridge")]
pub fn record_live(
    args: &RecordRequest,
    request: &live::LiveRequest,
    stop: &std::sync::atomic::AtomicBool,
    warn: &mut dyn FnMut(&str),
) -> Result<live::LiveReport> {
    let mut warnings = Vec::new();
    let mut origin = live::Origin::Given;
    let setup = setup_from_args(args, &mut warnings, |gnss| {
        if request.serial.is_none() && gnss.is_none() {
            return Err(Error::request(
                Field::Origin,
                "a live recording needs one: give it, a map, or a GNSS source to take it from the first fix (a \
                 serial port with NMEA, or a CAN interface or capture with GNSS signals)",
            ));
        }
        origin = live::Origin::FirstFix;
        // Replaced by the first fix before the pipeline is built (`live::run`).
        Geodetic::new(0.0, 0.0, 0.0).map_err(|e| Error::refused("origin", e))
    });
    warnings.iter().for_each(|w| warn(w));
    let setup = setup?;
    live::run(request, &setup, &origin, stop)
}

fn display(p: &Option<PathBuf>) -> String {
    p.as_deref().map_or_else(String::new, |p: &Path| p.display().to_string())
}

/// The summary of a recording: the pipeline's totals, the inputs, the log's size and the
/// refused inputs by reason.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Summary {
    /// What the pipeline did.
    #[serde(flatten)]
    pub stats: PipelineStats,
    /// Inputs the stream held.
    pub inputs: u64,
    /// The log's size.
    pub log_bytes: usize,
    /// Refused inputs by reason (only reasons that occurred).
    pub issues: BTreeMap<String, u64>,
    /// What the files held, for a recording from files.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sources: Option<sources::SourceCounts>,
}

/// The summary of a recording.
pub fn summary(recording: &Recording) -> Summary {
    let issues = by_reason(&recording.issues);
    Summary { stats: recording.stats, inputs: recording.inputs, log_bytes: recording.log.len(), issues, sources: None }
}

/// The pipeline's refused inputs by reason, the reasons that occurred only (named as
/// `--json` names them).
pub fn by_reason(issues: &Issues) -> BTreeMap<String, u64> {
    Issue::ALL.iter().filter(|i| issues.get(**i) > 0).map(|i| (format!("{i:?}"), issues.get(*i))).collect()
}

/// The summary of a recording from files, with what the files held.
pub fn file_summary(recording: &Recording, counts: &sources::SourceCounts) -> Summary {
    Summary { sources: Some(counts.clone()), ..summary(recording) }
}
