//! `dash2sim record` live: the logger process of a dashcam. It subscribes to the camera
//! process over the shared-memory bridge, reads the GNSS receiver's serial port (raw mode)
//! and the vehicle bus (SocketCAN, or a candump replay), stamps everything with the shared
//! device clock, feeds the on-device pipeline and writes the 4D log as files that rotate
//! every few minutes, until told to stop (SIGINT / SIGTERM, or `--seconds`).
//!
//! Serial and CAN are read by one thread each into a bounded queue; when the logger falls
//! behind, the queue is full and inputs are dropped, counted and written to the log as
//! events (never unbounded memory). The camera's services keep their own bounded buffers
//! (iceoryx2's safe overflow): what they lose shows as skipped frame numbers.

use std::fs::File;
use std::io::{Read, Write as _};
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use dash2sim_can::source::FrameSource;
use dash2sim_core::binlog::WriteError;
use dash2sim_core::can::CanFrame;
use dash2sim_core::pipeline::profile::{work_zone_meta, work_zone_trackers};
use dash2sim_core::pipeline::replay::{feed, Input, Reader, Recorder};
use dash2sim_core::pipeline::{GnssSignals, Pipeline, PipelineStats, Trackers};
use dash2sim_core::time::Timestamp;
use rustix::fs::{Mode, OFlags};

use super::interleave::{Interleave, Next};
use super::storage::{self, Storage, StoragePolicy};
use super::{FixFinder, Setup};
use crate::record::bridge::sequence::ServiceCounts;
use crate::record::bridge::{device_now, CameraInput, CameraSubscriber};
use crate::{Error, Field, Result};

/// Inputs waiting between the reader threads and the pipeline.
pub const QUEUE: usize = 4096;

/// The log files' sink: a file written directly (no user-space buffer beyond the log
/// writer's own), so that what the writer flushed survives the process being killed. A file
/// that never took a byte (opened on a full disk) is removed when the sink is dropped.
#[derive(Debug)]
pub struct FileSink {
    file: File,
    path: PathBuf,
    written: u64,
}

impl FileSink {
    /// A new file at `path` (an existing one is not overwritten).
    pub fn create(path: &Path) -> Result<FileSink> {
        let file = File::options().write(true).create_new(true).open(path).map_err(|e| Error::file(path, e))?;
        Ok(FileSink { file, path: path.to_path_buf(), written: 0 })
    }
}

impl Drop for FileSink {
    fn drop(&mut self) {
        if self.written == 0 {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// A file write failed.
#[derive(Debug)]
pub struct FileError(std::io::Error);

impl std::fmt::Display for FileError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for FileError {}

impl embedded_io::Error for FileError {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::Other
    }
}

impl embedded_io::ErrorType for FileSink {
    type Error = FileError;
}

impl embedded_io::Write for FileSink {
    fn write(&mut self, buf: &[u8]) -> Result<usize, FileError> {
        let n = self.file.write(buf).map_err(FileError)?;
        self.written += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), FileError> {
        self.file.flush().map_err(FileError)
    }
}

/// What the live logger reads and where it writes.
#[derive(Clone, Debug)]
pub struct LiveRequest {
    /// Folder of the rotating log files.
    pub dir: PathBuf,
    /// The camera's services, when subscribing.
    pub camera_prefix: Option<String>,
    /// The GNSS receiver's serial device (or a file of raw NMEA bytes).
    pub serial: Option<PathBuf>,
    /// Its baud rate (set when the device is a terminal).
    pub baud: u32,
    /// A SocketCAN interface.
    pub can_interface: Option<String>,
    /// A candump capture to replay as the bus.
    pub can_replay: Option<PathBuf>,
    /// Replay the capture at its own pace (else as fast as the queue takes it).
    pub realtime: bool,
    /// Start a new file after this long.
    pub segment: Duration,
    /// Stop after this long (else only on a signal).
    pub duration: Option<Duration>,
    /// Told how the recording goes twice a second (a status line), if set.
    pub status: Option<fn(&LiveStatus)>,
    /// How much of the disk the folder may use (loop recording).
    pub storage: StoragePolicy,
    /// Set (the command line's SIGUSR1 handler sets it) to keep the file being recorded.
    pub keep: Option<Arc<AtomicBool>>,
}

/// How a live recording goes, for a status line.
#[derive(Clone, Copy, Debug)]
pub struct LiveStatus {
    /// Camera frames received.
    pub frames: u64,
    /// Inputs dropped for want of queue space.
    pub dropped: u64,
    /// What was lost before the pipeline, by kind and reason.
    pub lost: Lost,
    /// The camera's messages received per service.
    pub camera: ServiceCounts,
    /// Whether the pipeline has an anchored estimate.
    pub anchored: bool,
    /// The pipeline's totals.
    pub stats: PipelineStats,
}

/// Where a live recording's ENU origin comes from.
#[derive(Clone, Debug)]
pub enum Origin {
    /// The setup's (`--origin`, or the map's).
    Given,
    /// The first fix of the serial NMEA, or of the CAN through the setup's GNSS signals:
    /// until it arrives the inputs are kept in memory (bounded), then logged with it.
    FirstFix,
}

/// Inputs kept while waiting for the first fix, at most (beyond, they are dropped and
/// counted): about an hour of a dashcam's VO and detections.
pub const WAITING_BYTES: usize = 256 << 20;

enum BusInput {
    Serial(Vec<u8>),
    Can(CanFrame),
}

/// What a live recording lost before its inputs reached the pipeline, by kind and reason
/// (issue #57): with what reached it, what was sent. What the pipeline then refused is in
/// its issues; what the camera's publishers sent after the recording stopped, or the serial
/// port and the bus before the recording's last drain, is not in either.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Lost {
    /// Serial bytes dropped because the readers' queue was full (the logger fell behind).
    pub queue_full_serial_bytes: u64,
    /// CAN frames dropped because the readers' queue was full.
    pub queue_full_can_frames: u64,
    /// Inputs dropped while waiting for the first fix, because [`WAITING_BYTES`] were held.
    pub waiting_full: u64,
    /// The camera's messages skipped in their numbers: lost to the subscriber's overflow (the
    /// logger more than its buffers behind), or never published (a frame whose VO had lost
    /// track has no pose).
    pub camera_skipped: ServiceCounts,
}

/// The reader threads' and the waiting buffer's drops, counted as they happen.
#[derive(Debug, Default)]
struct Drops {
    /// Inputs (serial reads, CAN frames, waiting inputs): the pipeline's "inputs dropped".
    inputs: AtomicU64,
    serial_bytes: AtomicU64,
    can_frames: AtomicU64,
    waiting: AtomicU64,
}

impl Drops {
    fn lost(&self, camera_skipped: ServiceCounts) -> Lost {
        Lost {
            queue_full_serial_bytes: self.serial_bytes.load(Ordering::Relaxed),
            queue_full_can_frames: self.can_frames.load(Ordering::Relaxed),
            waiting_full: self.waiting.load(Ordering::Relaxed),
            camera_skipped,
        }
    }
}

/// Counters of a live run: the summary `record --live --json` prints.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct LiveReport {
    /// What the pipeline did.
    #[serde(flatten)]
    pub stats: PipelineStats,
    /// Camera frames received (frame metadata messages).
    pub frames: u64,
    /// Inputs dropped because the queue was full (serial reads and CAN frames) or the
    /// waiting buffer was ([`Lost`] has them by kind).
    pub dropped: u64,
    /// What was lost before the pipeline, by kind and reason.
    pub lost: Lost,
    /// The camera's messages received per service.
    pub camera: ServiceCounts,
    /// Log files written.
    pub files: u32,
    /// Refused inputs (all reasons).
    pub issues: u64,
    /// Refused inputs by reason (the reasons that occurred).
    pub refused: std::collections::BTreeMap<String, u64>,
    /// Files deleted to keep the folder within its policy.
    pub deleted_files: u32,
    /// Times the log's sink failed (a full disk, an I/O error): each ended its file at the
    /// last complete frame and, once a new file could be written, is an event there.
    pub write_failures: u32,
}

/// How often a failed sink's replacement is tried (a full disk is retried until space
/// returns; the pipeline runs on meanwhile and what it would have logged is lost).
pub const RETRY_FAILED_SINK: Duration = Duration::from_secs(1);

fn send(queue: &SyncSender<(Timestamp, BusInput)>, drops: &Drops, input: BusInput) -> bool {
    match queue.try_send((device_now(), input)) {
        Ok(()) => true,
        Err(TrySendError::Full((_, input))) => {
            drops.inputs.fetch_add(1, Ordering::Relaxed);
            match input {
                BusInput::Serial(bytes) => drops.serial_bytes.fetch_add(bytes.len() as u64, Ordering::Relaxed),
                BusInput::Can(_) => drops.can_frames.fetch_add(1, Ordering::Relaxed),
            };
            true
        }
        Err(TrySendError::Disconnected(_)) => false,
    }
}

/// Raw mode and the baud rate, when `file` is a terminal.
fn raw_mode(file: &File, baud: u32) -> Result<()> {
    if !rustix::termios::isatty(file) {
        return Ok(());
    }
    let mut termios = rustix::termios::tcgetattr(file).map_err(|e| Error::refused("tcgetattr", e))?;
    termios.make_raw();
    termios.set_speed(baud).map_err(|e| Error::refused(format!("baud {baud}"), e))?;
    rustix::termios::tcsetattr(file, rustix::termios::OptionalActions::Now, &termios)
        .map_err(|e| Error::refused("tcsetattr", e))
}

fn serial_reader(
    path: &Path,
    baud: u32,
    queue: SyncSender<(Timestamp, BusInput)>,
    drops: Arc<Drops>,
) -> Result<std::thread::JoinHandle<()>> {
    let fifo = std::fs::metadata(path).map_err(|e| Error::file(path, e))?.file_type().is_fifo();
    let opened = if fifo {
        // Opening a FIFO's read end waits for a writer, for ever if none comes: it is opened
        // in the reader's thread, so that the logger runs (and a signal stops it) meanwhile.
        // That it can be opened is checked here, without waiting.
        rustix::fs::open(path, OFlags::RDONLY | OFlags::NONBLOCK | OFlags::CLOEXEC, Mode::empty())
            .map_err(|e| Error::file(path, std::io::Error::from(e)))?;
        None
    } else {
        let file = File::open(path).map_err(|e| Error::file(path, e))?;
        raw_mode(&file, baud).map_err(|e| Error::file(path, e))?;
        Some(file)
    };
    let path = path.to_path_buf();
    Ok(std::thread::spawn(move || {
        let Some(mut file) = opened.or_else(|| File::open(&path).ok()) else { return };
        let mut buffer = [0u8; 1024];
        // A pty whose writer closed reads as an error (EIO), a file as its end: both end input.
        while let Ok(n) = file.read(&mut buffer) {
            if n == 0 || !send(&queue, &drops, BusInput::Serial(buffer[..n].to_vec())) {
                break;
            }
        }
    }))
}

fn can_reader(
    request: &LiveRequest,
    queue: SyncSender<(Timestamp, BusInput)>,
    drops: Arc<Drops>,
) -> Result<Option<std::thread::JoinHandle<()>>> {
    if let Some(interface) = &request.can_interface {
        let mut source = dash2sim_can::source::SocketCanSource::open(interface).map_err(|e| {
            Error::request(
                Field::CanInterface,
                format!(
                    "{interface}: {e} (no such interface, or a kernel without SocketCAN; a candump capture can be \
                     replayed instead)"
                ),
            )
        })?;
        return Ok(Some(std::thread::spawn(move || {
            while let Some(Ok(record)) = source.next_frame() {
                if !send(&queue, &drops, BusInput::Can(record.frame)) {
                    break;
                }
            }
        })));
    }
    let Some(path) = request.can_replay.clone() else { return Ok(None) };
    let file = File::open(&path).map_err(|e| Error::file(&path, e))?;
    let realtime = request.realtime;
    Ok(Some(std::thread::spawn(move || {
        let mut source = dash2sim_can::candump::CandumpReader::new(std::io::BufReader::new(file));
        let start = Instant::now();
        let mut first: Option<Timestamp> = None;
        while let Some(record) = source.next_frame() {
            let Ok(record) = record else { continue };
            if let (true, Some(t)) = (realtime, record.time) {
                let t0 = *first.get_or_insert(t);
                let due = start + Duration::from_micros(u64::try_from((t - t0).micros()).unwrap_or(0));
                if let Some(wait) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
            }
            if !send(&queue, &drops, BusInput::Can(record.frame)) {
                break;
            }
        }
    })))
}

/// Run until `stop` is set (a signal) or the duration is over; then close the log cleanly.
/// The log goes to rotating files in `request.dir`, kept within `request.storage` and named
/// in the folder's index ([`storage`]).
pub fn run(request: &LiveRequest, setup: &Setup, origin: &Origin, stop: &AtomicBool) -> Result<LiveReport> {
    let mut storage = Storage::open(&request.dir, request.storage)?;
    let started = storage::now_ms();
    let dir = request.dir.clone();
    let folder = Folder::new(&mut storage, started);
    run_into(request, setup, origin, stop, Some(folder), |index| {
        FileSink::create(&dir.join(storage::file_name(started, index)))
    })
}

/// The live loop's side of loop recording: the folder's index told of every file opened
/// and closed; twice a second the file being recorded protected when it has earned it and
/// the folder brought within its policy, each step an event in the log.
#[derive(Debug)]
pub struct Folder<'s> {
    storage: &'s mut Storage,
    started: u64,
    /// The pipeline's totals when the file being recorded was opened (its verified windows,
    /// collisions and harsh brakings are those after them).
    at_open: PipelineStats,
    tended: Option<Instant>,
    deleted: u32,
}

/// Extra bytes the folder keeps free under its quota: the file being recorded grows by a
/// writer's buffer at a time, and the folder is tended twice a second.
pub const QUOTA_HEADROOM: u64 = 4 * 4096;

impl<'s> Folder<'s> {
    /// The folder of a run whose files are named from `started` (Unix ms).
    pub fn new(storage: &'s mut Storage, started: u64) -> Self {
        Folder { storage, started, at_open: PipelineStats::default(), tended: None, deleted: 0 }
    }

    fn opened(&mut self, index: u32, stats: PipelineStats) -> Result<()> {
        self.at_open = stats;
        let path = self.storage.dir().join(storage::file_name(self.started, index));
        self.storage.started(&path)
    }

    fn closed(&mut self) -> Result<()> {
        self.storage.closed()
    }

    /// Why the file being recorded is worth keeping by what the pipeline saw since it was
    /// opened: a collision in a verification window, a harsh braking, an impact, a verified
    /// window.
    fn earned(&self, now: &PipelineStats) -> Option<&'static str> {
        let then = &self.at_open;
        if now.collision_windows > then.collision_windows {
            Some("a collision in a verification window")
        } else if now.harsh_brakings > then.harsh_brakings {
            Some("harsh braking")
        } else if now.impacts > then.impacts {
            Some("an impact (the G-sensor's trigger)")
        } else if now.windows_verified + now.windows_undecided > then.windows_verified + then.windows_undecided {
            // Undecided too: the evidence could not tell within the ego's doubt, and
            // finishing with anchors may verify it.
            Some("it holds a window verified or undecided")
        } else {
            None
        }
    }

    /// Protect the file being recorded if it earned it ([`Folder::earned`]) or the user
    /// marked it (`keep`: SIGUSR1; `camera_keep`: the camera process's mark over the bridge;
    /// a `KEEP` file in the folder), and delete what the policy says. Twice a second, or
    /// now when `closing` (the file is about to close: what it earned since the last look
    /// must keep it).
    fn tend<W: embedded_io::Write>(
        &mut self,
        pipeline: &mut Pipeline<'_, W>,
        keep: Option<&AtomicBool>,
        camera_keep: &AtomicBool,
        closing: bool,
    ) -> Result<std::result::Result<(), WriteError<W::Error>>> {
        if !closing && self.tended.is_some_and(|t| t.elapsed() < Duration::from_millis(500)) {
            return Ok(Ok(()));
        }
        self.tended = Some(Instant::now());
        let keep_file = self.storage.dir().join(storage::KEEP_FILE);
        // Every mark is taken now, so that none is left over for the next file.
        let by_signal = keep.is_some_and(|k| k.swap(false, Ordering::Relaxed));
        let by_camera = camera_keep.swap(false, Ordering::Relaxed);
        let by_file = std::fs::remove_file(&keep_file).is_ok();
        let reason = if let Some(earned) = self.earned(pipeline.stats()) {
            Some(earned)
        } else if by_signal {
            Some("marked by the user (SIGUSR1)")
        } else if by_camera {
            Some("marked by the camera process (bridge)")
        } else if by_file {
            Some("marked by the user (KEEP file)")
        } else {
            None
        };
        if let Some(reason) = reason {
            if self.storage.protect(reason)? {
                if let Err(e) = pipeline.note(2, format_args!("this file is kept: {reason}")) {
                    return Ok(Err(e));
                }
            }
        }
        for gone in self.storage.enforce(QUOTA_HEADROOM)? {
            self.deleted += 1;
            let written = match &gone.protected {
                None => pipeline
                    .note(2, format_args!("storage: deleted {} ({} bytes), the oldest file", gone.file, gone.bytes)),
                Some(why) => pipeline.note(
                    3,
                    format_args!(
                        "storage: only kept files were left to delete: deleted {} ({} bytes, kept because {why})",
                        gone.file, gone.bytes
                    ),
                ),
            };
            if let Err(e) = written {
                return Ok(Err(e));
            }
        }
        Ok(Ok(()))
    }
}

/// [`run`] into the sinks `open` gives: the first file is `open(0)`, each rotation opens
/// the next (tests give a slow sink here); `folder`, when given, is told of each file and
/// tended (files, not other sinks).
pub fn run_into<S: embedded_io::Write<Error: std::fmt::Display>>(
    request: &LiveRequest,
    setup: &Setup,
    origin: &Origin,
    stop: &AtomicBool,
    mut folder: Option<Folder<'_>>,
    mut open: impl FnMut(u32) -> Result<S>,
) -> Result<LiveReport> {
    let camera = request.camera_prefix.as_deref().map(CameraSubscriber::new).transpose().map_err(Error::other)?;
    let (queue, inputs): (SyncSender<_>, Receiver<_>) = sync_channel(QUEUE);
    let drops = Arc::new(Drops::default());
    let mut readers = Vec::new();
    if let Some(path) = &request.serial {
        readers.push(serial_reader(path, request.baud, queue.clone(), drops.clone())?);
    }
    readers.extend(can_reader(request, queue.clone(), drops.clone())?);
    drop(queue);

    let begun = Instant::now();
    let mut frames = 0u64;
    // The camera process's "keep" marks (the bridge's keep service) until the folder sees them.
    let camera_keep = AtomicBool::new(false);
    let (setup, waited) = match origin {
        Origin::Given => (setup.clone(), None),
        Origin::FirstFix => {
            let waiting = Waiting {
                request,
                camera: camera.as_ref(),
                inputs: &inputs,
                drops: &drops,
                stop,
                begun,
                camera_keep: &camera_keep,
            };
            let (fix, kept, seen) = waiting.for_fix(setup.gnss_signals.as_ref())?;
            frames = seen;
            (Setup { origin: fix, ..setup.clone() }, Some(kept))
        }
    };
    let meta = work_zone_meta();
    let config = setup.config(&meta)?;
    let mut trackers: Box<Trackers<'_, 64, 32>> = Box::new(work_zone_trackers());
    let mut index = 0;
    let mut pipeline: Box<Pipeline<'_, S>> = Box::new(Pipeline::new(open(index)?, config, &mut trackers));
    if let Some(key) = &setup.key {
        pipeline.sign_with(key.sealer());
    }
    // The folder's bookkeeping never stops the recording: what fails (an index that cannot
    // be written on a full disk) is an event.
    let mut storage_problem = None;
    if let Some(f) = folder.as_mut() {
        storage_problem = f.opened(index, PipelineStats::default()).err();
    }
    let (mut file_started, mut last_status) = (Instant::now(), Instant::now());
    let mut dropped_noted = 0u64;
    let (mut skips_noted, mut skips_looked) = (ServiceCounts::default(), Instant::now());
    let log_error = |e: WriteError<S::Error>| Error::other(format!("log: {e}"));
    // A sink that fails (a full disk, an I/O error) does not stop the recording: its file
    // ends at its last complete frame, the pipeline runs on, and a new file is tried until
    // one can be written (the failure is an event there).
    let (mut failure, mut retried, mut write_failures): (Option<String>, Option<Instant>, u32) = (None, None, 0);
    let failed = |result: std::result::Result<(), WriteError<S::Error>>, failure: &mut Option<String>| match result {
        Ok(()) => Ok(()),
        Err(WriteError::Io(e)) => {
            failure.get_or_insert_with(|| e.to_string());
            Ok(())
        }
        Err(e) => Err(log_error(e)),
    };
    // What came before the first fix, in its order, with its own times.
    if let Some(waited) = &waited {
        let mut reader =
            Reader::new(waited).map_err(|e| Error::other(format!("inputs kept for the first fix: {e:?}")))?;
        while let Some(Ok((t, input))) = reader.next_input() {
            feed(&mut pipeline, t, &input).map_err(log_error)?;
        }
    }
    // The camera's and the bus's inputs in the order of their stamps.
    let mut interleave = Interleave::new(camera.is_some());
    loop {
        let mut released = Vec::new();
        if let Some(camera) = &camera {
            camera.receive_in_order(|input| released.push(input)).map_err(Error::other)?;
        }
        let mut busy = !released.is_empty();
        // At most a queue's worth a turn: a bus faster than the logger does not starve the
        // camera's drain.
        for (t, input) in inputs.try_iter().take(QUEUE) {
            busy = true;
            interleave.push_bus(t, input);
        }
        let mut result = Ok(());
        interleave.release(released, CameraInput::t, device_now(), |next| {
            if result.is_ok() {
                result = feed_next(&mut pipeline, next, &mut frames, &camera_keep);
            }
        });
        failed(result, &mut failure)?;
        let lost = drops.inputs.load(Ordering::Relaxed);
        if lost > dropped_noted {
            failed(pipeline.note_dropped(lost - dropped_noted), &mut failure)?;
            dropped_noted = lost;
        }
        if let Some(camera) = camera.as_ref().filter(|_| skips_looked.elapsed() >= Duration::from_millis(500)) {
            skips_looked = Instant::now();
            failed(note_skipped(&mut pipeline, camera, &mut skips_noted), &mut failure)?;
        }
        let rotating = failure.is_none() && file_started.elapsed() >= request.segment;
        if let Some(f) = folder.as_mut() {
            match f.tend(&mut pipeline, request.keep.as_deref(), &camera_keep, rotating) {
                Ok(written) => failed(written, &mut failure)?,
                Err(e) => storage_problem = Some(e),
            }
        }
        if failure.is_some() && retried.is_none_or(|t| t.elapsed() >= RETRY_FAILED_SINK) {
            // A new file, at most once a second: on a full disk opening it may fail, or
            // only its writes (then the failure comes back through `failed`).
            retried = Some(Instant::now());
            if let Ok(sink) = open(index + 1) {
                let why = failure.take().unwrap_or_default();
                index += 1;
                write_failures += 1;
                failed(pipeline.resume_after_failure(sink, format_args!("{why}")).map(drop), &mut failure)?;
                file_started = Instant::now();
                if let Some(f) = folder.as_mut() {
                    storage_problem =
                        storage_problem.or(f.closed().and_then(|()| f.opened(index, *pipeline.stats())).err());
                }
            }
        } else if rotating {
            index += 1;
            failed(pipeline.rotate(open(index)?).map(drop), &mut failure)?;
            file_started = Instant::now();
            if let Some(f) = folder.as_mut() {
                storage_problem =
                    storage_problem.or(f.closed().and_then(|()| f.opened(index, *pipeline.stats())).err());
            }
        }
        if let Some(problem) = storage_problem.take() {
            failed(pipeline.note(3, format_args!("storage: {problem}")), &mut failure)?;
        }
        if let Some(status) = request.status.filter(|_| last_status.elapsed() >= Duration::from_millis(500)) {
            let (received, skipped) = camera.as_ref().map(CameraSubscriber::tally).unwrap_or_default();
            status(&LiveStatus {
                frames,
                dropped: lost,
                lost: drops.lost(skipped),
                camera: received,
                anchored: pipeline.anchorer().estimate().is_some(),
                stats: *pipeline.stats(),
            });
            last_status = Instant::now();
        }
        let over = request.duration.is_some_and(|d| begun.elapsed() >= d);
        if stop.load(Ordering::Relaxed) || over {
            break;
        }
        if !busy {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    // The recording ends: what the readers queued, what waits on the camera's services and
    // what the camera's inputs held back for their order (the last frame's pose and
    // detections) go in; what is still in the kernel's buffers does not.
    let mut released = Vec::new();
    if let Some(camera) = &camera {
        camera.flush(|input| released.push(input)).map_err(Error::other)?;
    }
    for (t, input) in inputs.try_iter() {
        interleave.push_bus(t, input);
    }
    let mut result = Ok(());
    interleave.flush(released, CameraInput::t, |next| {
        if result.is_ok() {
            result = feed_next(&mut pipeline, next, &mut frames, &camera_keep);
        }
    });
    failed(result, &mut failure)?;
    if let Some(camera) = &camera {
        failed(note_skipped(&mut pipeline, camera, &mut skips_noted), &mut failure)?;
    }
    let lost = drops.inputs.load(Ordering::Relaxed);
    if lost > dropped_noted {
        failed(pipeline.note_dropped(lost - dropped_noted), &mut failure)?;
    }
    // What the last file earned since the last look keeps it (the pipeline's closing, below,
    // may still close a window: that protection is in the index only, as the log is closed).
    if let Some(f) = folder.as_mut() {
        match f.tend(&mut pipeline, request.keep.as_deref(), &camera_keep, true) {
            Ok(written) => failed(written, &mut failure)?,
            Err(e) => failed(pipeline.note(3, format_args!("storage: {e}")), &mut failure)?,
        }
    }
    let issues = pipeline.issues().total();
    let refused = super::by_reason(pipeline.issues());
    let mut stats = *pipeline.stats();
    // Closing completes the last fix and writes the last segment: on a sink that fails,
    // that is lost like the rest.
    let lost_at_close = match pipeline.finish() {
        Ok((_, finished, _)) => {
            stats = finished;
            false
        }
        Err(WriteError::Io(_)) => true,
        Err(e) => return Err(log_error(e)),
    };
    if failure.is_some() || lost_at_close {
        write_failures += 1;
    }
    drop(inputs);
    let (camera_received, camera_skipped) = camera.as_ref().map(CameraSubscriber::tally).unwrap_or_default();
    let deleted_files = folder.as_ref().map_or(0, |f| f.deleted);
    if let Some(f) = folder.as_mut() {
        if let Some(reason) = f.earned(&stats) {
            f.storage.protect(reason)?;
        }
        f.closed()?;
    }
    Ok(LiveReport {
        stats,
        frames,
        dropped: drops.inputs.load(Ordering::Relaxed),
        lost: drops.lost(camera_skipped),
        camera: camera_received,
        files: index + 1,
        issues,
        refused,
        write_failures,
        deleted_files,
    })
}

/// One input of either source into the pipeline (`frames` counts the camera's frames; its
/// keep mark sets `camera_keep`).
fn feed_next<S: embedded_io::Write>(
    pipeline: &mut Pipeline<'_, S>,
    next: Next<CameraInput, BusInput>,
    frames: &mut u64,
    camera_keep: &AtomicBool,
) -> std::result::Result<(), WriteError<S::Error>> {
    match next {
        Next::Camera(input) => feed_camera(pipeline, input, frames, camera_keep),
        Next::Bus(t, BusInput::Serial(bytes)) => pipeline.push_serial(t, &bytes),
        Next::Bus(t, BusInput::Can(frame)) => pipeline.push_can(t, &frame),
    }
}

/// The camera's messages skipped in their numbers since the last note, as an event.
fn note_skipped<S: embedded_io::Write>(
    pipeline: &mut Pipeline<'_, S>,
    camera: &CameraSubscriber,
    noted: &mut ServiceCounts,
) -> std::result::Result<(), WriteError<S::Error>> {
    let (_, skipped) = camera.tally();
    if skipped.total() == noted.total() {
        return Ok(());
    }
    *noted = skipped;
    pipeline.note(
        3,
        format_args!(
            "camera: skipped in the messages' numbers so far: {skipped} (lost to the bridge's buffers with the \
             logger behind, or never published)"
        ),
    )
}

/// One camera input into the pipeline (`frames` counts the frames; a keep mark sets
/// `camera_keep`).
fn feed_camera<S: embedded_io::Write>(
    pipeline: &mut Pipeline<'_, S>,
    input: CameraInput,
    frames: &mut u64,
    camera_keep: &AtomicBool,
) -> std::result::Result<(), WriteError<S::Error>> {
    match input {
        CameraInput::Frame { .. } => {
            *frames += 1;
            Ok(())
        }
        CameraInput::Vo(t, frame, session, pose) => pipeline.push_vo(t, frame, session, &pose),
        CameraInput::Detections3d(t, frame, d) => pipeline.push_detections(t, frame, &d),
        CameraInput::Detections2d(t, frame, d) => pipeline.push_detections2d(t, frame, &d),
        CameraInput::Keep(_) => {
            camera_keep.store(true, Ordering::Relaxed);
            Ok(())
        }
        CameraInput::Imu(t, sample) => pipeline.push_imu(t, &sample),
    }
}

/// The inputs of a live recording while it waits for its first fix.
struct Waiting<'a> {
    request: &'a LiveRequest,
    camera: Option<&'a CameraSubscriber>,
    inputs: &'a Receiver<(Timestamp, BusInput)>,
    drops: &'a Drops,
    stop: &'a AtomicBool,
    begun: Instant,
    /// Set by the camera process's "keep" mark.
    camera_keep: &'a AtomicBool,
}

impl Waiting<'_> {
    /// Keep every input (as an input stream) until one completes a fix: the fix, the stream
    /// and the camera frames seen. An error when the recording is stopped first.
    fn for_fix(&self, gnss: Option<&GnssSignals>) -> Result<(dash2sim_core::geo::Geodetic, Vec<u8>, u64)> {
        let recorder = Recorder::new(Vec::new()).map_err(|e| match e {})?;
        let mut kept = Kept { recorder, drops: self.drops };
        let mut finder = FixFinder::new(gnss);
        let (mut frames, mut last_status) = (0u64, Instant::now());
        loop {
            let mut busy = false;
            if let Some(camera) = self.camera {
                camera
                    .receive_in_order(|input| {
                        busy = true;
                        match input {
                            CameraInput::Frame { .. } => frames += 1,
                            CameraInput::Vo(t, frame, session, pose) => kept.keep(|k| k.vo(t, frame, session, &pose)),
                            CameraInput::Detections3d(t, frame, d) => kept.keep(|k| k.detections3d(t, frame, &d)),
                            CameraInput::Detections2d(t, frame, d) => kept.keep(|k| k.detections2d(t, frame, &d)),
                            CameraInput::Keep(_) => self.camera_keep.store(true, Ordering::Relaxed),
                            CameraInput::Imu(t, sample) => kept.keep(|k| k.imu(t, &sample)),
                        }
                    })
                    .map_err(Error::other)?;
            }
            for (t, input) in self.inputs.try_iter().take(QUEUE) {
                busy = true;
                let fix = match &input {
                    BusInput::Serial(bytes) => {
                        kept.keep(|k| k.serial(t, bytes));
                        finder.push(&Input::Serial(bytes))
                    }
                    BusInput::Can(frame) => {
                        kept.keep(|k| k.can(t, frame));
                        finder.push(&Input::Can(*frame))
                    }
                };
                if let Some(fix) = fix {
                    let stream = kept.recorder.finish().map_err(|e| match e {})?;
                    return Ok((fix, stream, frames));
                }
            }
            if let Some(status) = self.request.status.filter(|_| last_status.elapsed() >= Duration::from_millis(500)) {
                let (received, skipped) = self.camera.map(CameraSubscriber::tally).unwrap_or_default();
                status(&LiveStatus {
                    frames,
                    dropped: self.drops.inputs.load(Ordering::Relaxed),
                    lost: self.drops.lost(skipped),
                    camera: received,
                    anchored: false,
                    stats: PipelineStats::default(),
                });
                last_status = Instant::now();
            }
            let over = self.request.duration.is_some_and(|d| self.begun.elapsed() >= d);
            if self.stop.load(Ordering::Relaxed) || over {
                return Err(Error::request(
                    Field::Origin,
                    format!(
                        "no GNSS fix arrived in {:.0} s, so the log has none and nothing was written; give one, or a \
                         map, to record without a fix",
                        self.begun.elapsed().as_secs_f64()
                    ),
                ));
            }
            if !busy {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
}

/// The inputs kept while waiting for the first fix, at most [`WAITING_BYTES`] of them.
struct Kept<'a> {
    recorder: Recorder<Vec<u8>>,
    drops: &'a Drops,
}

impl Kept<'_> {
    /// Keep an input, or count it as dropped when the buffer is full.
    fn keep(&mut self, write: impl FnOnce(&mut Recorder<Vec<u8>>) -> Result<(), core::convert::Infallible>) {
        if self.recorder.get_ref().len() < WAITING_BYTES {
            let Ok(()) = write(&mut self.recorder);
        } else {
            self.drops.inputs.fetch_add(1, Ordering::Relaxed);
            self.drops.waiting.fetch_add(1, Ordering::Relaxed);
        }
    }
}
