//! The demo's recording step with real processes, as on a dashcam: the camera process
//! (`dash2sim scenario publish`, a child process of the executable the caller names) publishes the drive's frames, VO poses
//! and detections over shared memory (iceoryx2) and writes the GNSS receiver's NMEA and the
//! wheel-speed CAN frames into two FIFOs at their rates; the logger (`record`'s live loop,
//! a thread of this process) subscribes, reads the FIFOs as its serial port and its bus,
//! feeds the on-device pipeline and writes the 4D log.

use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::Progress;
use crate::scenario::profile::{Profile, Receiver};
use crate::scenario::publish::PublishRequest;
use crate::scenario::Driver;
use crate::{Error, Result};
use dash2sim_linux::record::live::{self, FileSink, LiveReport, LiveRequest};
use dash2sim_linux::record::Setup;

/// What to publish: the generated drive's seed, length, driver and sensor profile.
#[derive(Clone, Copy, Debug)]
pub struct Drive {
    /// Seed.
    pub seed: u64,
    /// Length, s.
    pub seconds: f64,
    /// Driver.
    pub driver: Driver,
    /// Sensor profile.
    pub profile: Profile,
}

impl Drive {
    /// What the camera process publishes: this drive at the demo's rates (10 frames a
    /// second, the good receiver, in real time) under `prefix`, its NMEA and CAN frames into
    /// the FIFOs `gnss` and `can`.
    fn request(&self, prefix: &str, gnss: &Path, can: &Path) -> PublishRequest {
        PublishRequest {
            seed: self.seed,
            driver: self.driver,
            seconds: self.seconds,
            profile: self.profile,
            receiver: Receiver::Good,
            fps: 10,
            laps: 1,
            objects: 0,
            speedup: 1.0,
            prefix: prefix.to_owned(),
            images: false,
            nmea_out: Some(gnss.to_path_buf()),
            can_out: Some(can.to_path_buf()),
            bus_load: 0,
        }
    }
}

/// What the live recording did.
#[derive(Clone, Debug)]
pub struct LiveRecording {
    /// The logger's counters.
    pub report: LiveReport,
    /// Frames the camera process published.
    pub published: u64,
    /// Wall-clock time of the recording, s.
    pub seconds: f64,
}

/// A FIFO at `path` (an old file of that name is replaced).
fn fifo(path: &Path) -> Result<()> {
    let _ = std::fs::remove_file(path);
    rustix::fs::mkfifoat(rustix::fs::CWD, path, rustix::fs::Mode::RUSR | rustix::fs::Mode::WUSR)
        .map_err(|e| Error::refused(format!("mkfifo {}", path.display()), e))
}

/// How to start a camera process that publishes a request: a command the caller knows (the
/// command line: its own executable's `scenario publish`), to which the demo adds its
/// environment and pipes.
pub type CameraCommand = fn(&PublishRequest) -> std::io::Result<Command>;

/// Record `drive` live into `log_path`, the camera process started by `camera`; `progress`
/// is told the drive's seconds as they pass.
pub fn record(
    drive: Drive,
    camera: CameraCommand,
    dir: &Path,
    log_path: &Path,
    setup: &Setup,
    progress: &dyn Progress,
) -> Result<LiveRecording> {
    let (gnss, can) = (dir.join("gnss.fifo"), dir.join("can.fifo"));
    fifo(&gnss)?;
    fifo(&can)?;
    let prefix = format!("dash2sim-demo/{}", std::process::id());
    let request = LiveRequest {
        dir: dir.to_path_buf(),
        camera_prefix: Some(prefix.clone()),
        serial: Some(gnss.clone()),
        baud: 115_200,
        can_interface: None,
        can_replay: Some(can.clone()),
        // The camera process writes the bus at its own pace: read it as it comes.
        realtime: false,
        segment: Duration::from_secs(24 * 3600),
        // A bound in case the camera process hangs; it normally ends the run.
        duration: Some(Duration::from_secs_f64(drive.seconds + 60.0)),
        status: None,
        storage: Default::default(),
        keep: None,
    };
    let stop = AtomicBool::new(false);
    let started = Instant::now();
    let result = std::thread::scope(|scope| {
        let logger = scope.spawn(|| {
            live::run_into(&request, setup, &live::Origin::Given, &stop, None, |index| match index {
                0 => FileSink::create(log_path),
                _ => Err(Error::invalid("the demo's log does not rotate")),
            })
        });
        // The logger subscribes before the camera publishes its first frame.
        std::thread::sleep(Duration::from_millis(300));
        let camera = publish(camera, &drive.request(&prefix, &gnss, &can), progress, started, &|| logger.is_finished());
        if camera.is_err() {
            // A camera process that never opened the FIFOs leaves the logger waiting in
            // open(): open them here so that it can see their end.
            for path in [&gnss, &can] {
                let _ = std::fs::OpenOptions::new().write(true).open(path);
            }
        }
        // What the camera published last is still in the bridge's buffers: let it drain.
        std::thread::sleep(Duration::from_millis(500));
        stop.store(true, Ordering::Relaxed);
        let report = logger.join().map_err(|_| Error::invalid("the logger thread panicked")).and_then(|r| r);
        Ok::<_, Error>((camera, report))
    });
    for path in [&gnss, &can] {
        let _ = std::fs::remove_file(path);
    }
    // The logger's error first: a camera process stopped because the logger had failed
    // is the consequence, not the cause.
    let (camera, report) = result?;
    let report = report?;
    let published = camera?;
    Ok(LiveRecording { report, published, seconds: started.elapsed().as_secs_f64() })
}

/// Run the camera process publishing `request` until it ends, or until the logger has (a
/// logger that failed reads nothing, and the camera process would wait for a reader of its
/// FIFOs forever); the frames it published. `progress` is told the drive's seconds.
fn publish(
    camera: CameraCommand,
    request: &PublishRequest,
    progress: &dyn Progress,
    started: Instant,
    logger_ended: &dyn Fn() -> bool,
) -> Result<u64> {
    let mut child = camera(request)
        .and_then(|mut command| {
            command
                .env("IOX2_LOG_LEVEL", std::env::var("IOX2_LOG_LEVEL").unwrap_or_else(|_| "Error".to_owned()))
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
        })
        .map_err(|e| Error::refused("starting the camera process", e))?;
    loop {
        progress.at(started.elapsed().as_secs().min(request.seconds as u64));
        match child.try_wait() {
            Ok(Some(_)) => break,
            Ok(None) if logger_ended() => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(Error::invalid("the camera process was stopped: the logger had ended"));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(100)),
            Err(e) => return Err(Error::invalid(format!("the camera process: {e}"))),
        }
    }
    let output = child.wait_with_output().map_err(|e| Error::refused("the camera process", e))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        return Err(Error::invalid(format!(
            "the camera process failed ({}): {}",
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        )));
    }
    stdout.split_whitespace().next().and_then(|n| n.parse().ok()).ok_or_else(|| {
        Error::invalid(format!("the camera process said {:?}, not how many frames it published", stdout.trim()))
    })
}
