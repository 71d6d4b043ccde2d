//! The live logger under faults: killed (SIGKILL) and restarted while the camera goes on
//! publishing, a sink slower than its input, and a disk that fills up and frees again.

use std::process::{Child, Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use dash2sim_core::binlog::Record;
use dash2sim_linux::log;
use dash2sim_linux::record::bridge::{device_now, CameraPublisher};
use dash2sim_linux::record::live::{self, LiveRequest};
use dash2sim_linux::record::Setup;
use dash2sim_sim::scenario::{generate, ScenarioConfig};

/// Longest a killed logger can lose (`docs/cli.md`): the open log segment, 5 s.
const FLUSH_INTERVAL_S: f64 = 5.0;

fn frames_in(log: &log::LogContents) -> Vec<i64> {
    log.records.iter().filter_map(|r| if let Record::FrameMeta(f) = r { Some(f.frame) } else { None }).collect()
}

fn logger(dir: &std::path::Path, prefix: &str) -> Child {
    Command::new(env!("CARGO_BIN_EXE_dash2sim"))
        .args(["record", "-o", &dir.display().to_string(), "--camera", prefix, "--origin", "60.2711,24.8572"])
        .env("IOX2_LOG_LEVEL", "Error")
        .stdout(Stdio::null())
        .spawn()
        .expect("dash2sim record")
}

fn log_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .expect("log dir")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "d2slog"))
        .collect();
    files.sort();
    files
}

#[test]
fn a_logger_killed_and_restarted_leaves_its_flushed_log_and_the_camera_unaffected() {
    let dir = std::env::temp_dir().join(format!("dash2sim-logger-kill-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let prefix = format!("dash2sim-test/logger-kill/{}", std::process::id());
    let scenario = generate(&ScenarioConfig { seed: 2, duration_s: 13.0, ..ScenarioConfig::default() });

    let mut first = Some(logger(&dir, &prefix));
    std::thread::sleep(Duration::from_millis(500));
    let camera = CameraPublisher::new(&prefix, false).expect("publisher");
    let start = Instant::now();
    let (mut killed_at, mut second) = (None, None);
    for (frame, pose) in scenario.frames.iter().zip(&scenario.vo.poses.poses) {
        let due = start + Duration::from_secs_f64(frame.ego.t);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let (sequence, t) = (u64::from(frame.index), device_now());
        // The publisher is unaffected: every publish succeeds, with or without a logger.
        camera.frame(sequence, t, 8_000, None).expect("frame published");
        camera.vo(sequence, t, pose, 0).expect("pose published");
        camera.detections3d(sequence, t, &frame.detections_3d).expect("detections published");
        if let Some(mut running) = first.take_if(|_| frame.ego.t >= 8.0) {
            running.kill().expect("SIGKILL");
            let _ = running.wait();
            killed_at = Some(sequence);
        }
        if frame.ego.t >= 8.5 && second.is_none() {
            second = Some(logger(&dir, &prefix));
        }
    }
    let published = scenario.frames.last().map_or(0, |f| i64::from(f.index));
    let killed_at = killed_at.expect("killed") as i64;
    std::thread::sleep(Duration::from_millis(300));
    let mut second = second.expect("restarted");
    let term = Command::new("kill").args(["-TERM", &second.id().to_string()]).status().expect("kill");
    assert!(term.success());
    assert!(second.wait().expect("second logger").success());

    let files = log_files(&dir);
    assert_eq!(files.len(), 2, "one file per logger run: {files:?}");
    // The killed logger's file reads back to its last flush: no damage, frames in order from
    // the first, and nothing older than the flush interval before the kill is missing.
    let killed = log::read(&files[0]).expect("the killed logger's file reads back");
    assert_eq!(killed.stats.damaged, 0, "{:?}", killed.stats);
    let before = frames_in(&killed);
    let last = *before.last().expect("frames before the kill");
    assert_eq!(before, (1..=last).collect::<Vec<_>>());
    let must_have = killed_at - (FLUSH_INTERVAL_S * 10.0) as i64 - 1;
    assert!(last >= must_have, "frames up to {last} of {killed_at} (at least {must_have})");
    // The restarted logger picks the stream up and closes cleanly.
    let restarted = log::read(&files[1]).expect("the restarted logger's file");
    assert_eq!(restarted.stats.damaged, 0);
    let after = frames_in(&restarted);
    let first_after = *after.first().expect("frames after the restart");
    assert!(first_after > killed_at, "the restarted logger starts after the kill: {first_after}");
    assert_eq!(after, (first_after..=published).collect::<Vec<_>>(), "every frame after the restart");
    println!("killed at frame {killed_at}: its file has 1..={last}; the restarted logger {first_after}..={published}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A live recording of `frames` wheel-speed frames (CCVS1) `step_s` apart, written to a
/// candump capture in `dir` and replayed (`realtime`: at their pace) for `duration`.
fn wheel_speed_replay(
    dir: &std::path::Path,
    frames: usize,
    step_s: f64,
    realtime: bool,
    duration: Duration,
) -> LiveRequest {
    let capture: String =
        (0..frames).map(|i| format!("({:.6}) can0 18FEF100#FF0050FFFFFFFFFF\n", i as f64 * step_s)).collect();
    let path = dir.join("bus.log");
    std::fs::write(&path, capture).expect("capture");
    LiveRequest {
        dir: dir.join("log"),
        camera_prefix: None,
        serial: None,
        baud: 115_200,
        can_interface: None,
        can_replay: Some(path),
        realtime,
        segment: Duration::from_secs(600),
        duration: Some(duration),
        status: None,
        storage: Default::default(),
        keep: None,
    }
}

/// A log sink that takes `delay` per write: a disk far slower than the inputs.
struct SlowSink {
    bytes: std::sync::Arc<std::sync::Mutex<Vec<u8>>>,
    delay: Duration,
}

impl embedded_io::ErrorType for SlowSink {
    type Error = core::convert::Infallible;
}

impl embedded_io::Write for SlowSink {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        std::thread::sleep(self.delay);
        self.bytes.lock().expect("sink").extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

#[test]
fn a_sink_slower_than_the_input_drops_inputs_counts_them_and_logs_them() {
    let dir = std::env::temp_dir().join(format!("dash2sim-slow-sink-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    // 20 000 wheel-speed frames (CCVS1, 20 ms apart), replayed as fast as the reader goes.
    const FRAMES: usize = 20_000;
    let request = wheel_speed_replay(&dir, FRAMES, 0.02, false, Duration::from_secs(3));
    let origin = dash2sim_core::geo::Geodetic::new(60.2711, 24.8572, 20.0).expect("origin");
    let setup = Setup::work_zone(origin, None, *b"dash2sim-slow\0\0\0");
    let bytes = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let report = live::run_into(&request, &setup, &live::Origin::Given, &AtomicBool::new(false), None, |_| {
        Ok(SlowSink { bytes: bytes.clone(), delay: Duration::from_millis(20) })
    })
    .expect("live run");
    println!("{report:?}");
    // The queue is bounded: with the sink this slow, most of the burst cannot wait in it.
    assert!(report.dropped >= (FRAMES - 2 * live::QUEUE) as u64, "{report:?}");
    assert_eq!(report.stats.can_frames + report.dropped, FRAMES as u64, "every frame used or counted as dropped");
    let log = log::decode(&bytes.lock().expect("sink"), "slow sink").expect("the log");
    assert_eq!(log::inspect::dropped_inputs(&log), report.dropped, "the drops are in the log");
    let speeds = log.records.iter().filter(|r| matches!(r, Record::VehicleSpeed(_))).count() as u64;
    assert_eq!(speeds, report.stats.speeds);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A disk that takes `budget` bytes, then refuses every write with ENOSPC until
/// `frees_at`, then takes everything: one buffer per file.
struct Disk {
    files: Vec<Vec<u8>>,
    budget: usize,
    frees_at: Instant,
}

/// One file on the [`Disk`].
struct DiskFile {
    disk: std::sync::Arc<std::sync::Mutex<Disk>>,
    index: usize,
}

#[derive(Debug)]
struct DiskError(std::io::Error);

impl std::fmt::Display for DiskError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for DiskError {}

impl embedded_io::Error for DiskError {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::OutOfMemory
    }
}

impl embedded_io::ErrorType for DiskFile {
    type Error = DiskError;
}

impl embedded_io::Write for DiskFile {
    fn write(&mut self, buf: &[u8]) -> Result<usize, DiskError> {
        let mut disk = self.disk.lock().expect("disk");
        let room = if Instant::now() >= disk.frees_at { buf.len() } else { disk.budget.min(buf.len()) };
        if room == 0 && !buf.is_empty() {
            return Err(DiskError(std::io::Error::from_raw_os_error(28)));
        }
        disk.budget = disk.budget.saturating_sub(room);
        disk.files[self.index].extend_from_slice(&buf[..room]);
        Ok(room)
    }

    fn flush(&mut self) -> Result<(), DiskError> {
        Ok(())
    }
}

#[test]
fn a_full_disk_ends_the_file_at_its_last_complete_frame_and_recording_resumes_when_space_returns() {
    let dir = std::env::temp_dir().join(format!("dash2sim-full-disk-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    // 4 s of wheel speed at 1 kHz, replayed in real time: a flush of the 4 KiB log buffer
    // about every 0.7 s.
    let request = wheel_speed_replay(&dir, 4000, 0.001, true, Duration::from_secs_f64(4.5));
    let origin = dash2sim_core::geo::Geodetic::new(60.2711, 24.8572, 20.0).expect("origin");
    let setup = Setup::work_zone(origin, None, *b"dash2sim-full\0\0\0");
    // The disk takes 6 000 bytes (a flush and a half), then is full until 2 s in.
    let start = Instant::now();
    let disk = std::sync::Arc::new(std::sync::Mutex::new(Disk {
        files: Vec::new(),
        budget: 6_000,
        frees_at: start + Duration::from_secs(2),
    }));
    let report = live::run_into(&request, &setup, &live::Origin::Given, &AtomicBool::new(false), None, |index| {
        let mut d = disk.lock().expect("disk");
        d.files.push(Vec::new());
        assert_eq!(d.files.len(), index as usize + 1, "files are opened in order");
        Ok(DiskFile { disk: disk.clone(), index: index as usize })
    })
    .expect("the recording goes on through a full disk");
    println!("{report:?}");
    let disk = disk.lock().expect("disk");
    let sizes: Vec<usize> = disk.files.iter().map(Vec::len).collect();
    println!("file sizes {sizes:?}");
    assert!(report.write_failures >= 1, "{report:?}");
    let speeds = |l: &log::LogContents| {
        l.records
            .iter()
            .filter_map(|r| if let Record::VehicleSpeed(v) = r { Some(v.t_us) } else { None })
            .collect::<Vec<_>>()
    };

    // The first file: everything the disk took, read back to its last complete frame.
    assert_eq!(sizes[0], 6_000);
    let first = log::decode(&disk.files[0], "first").expect("the first file reads");
    assert!(first.stats.damaged <= 1, "only the torn tail is damaged: {:?}", first.stats);
    let before = speeds(&first);
    assert!(before.len() > 100, "{} speed samples before the disk filled", before.len());

    // Every file with bytes reads back; together they hold the drive in order, nothing
    // twice. A file opened while the disk was full holds what its writer got out once the
    // disk freed up (it keeps its buffer and tries again), or nothing.
    let mut all: Vec<i64> = Vec::new();
    for (k, bytes) in disk.files.iter().enumerate().filter(|(_, b)| !b.is_empty()) {
        let contents = log::decode(bytes, "file").unwrap_or_else(|e| panic!("file {k}: {e}"));
        all.extend(speeds(&contents));
    }
    // (Two frames read within one microsecond share a time.)
    assert!(all.windows(2).all(|w| w[0] <= w[1]), "in order");
    assert!(all.len() as u64 <= report.stats.speeds, "nothing twice");

    // The last file is whole, says what happened and holds the drive after the gap.
    let last = log::decode(disk.files.last().expect("files"), "last").expect("the last file reads");
    assert_eq!(last.stats.damaged, 0);
    let said = last.records.iter().find_map(|r| match r {
        Record::Event(e) => {
            std::str::from_utf8(&e.text).ok().filter(|t| t.starts_with("log writes failed")).map(str::to_owned)
        }
        _ => None,
    });
    let said = said.expect("the failure is an event in the new file");
    assert!(said.contains("No space left on device"), "{said}");
    let after = speeds(&last);
    assert!(!after.is_empty() && after[0] > *before.last().expect("before"), "the drive goes on after the gap");
    // 4 000 samples were taken; the ones lost are those of the full disk's 2 s at most.
    assert!(all.len() >= 4000 - 2100, "{} of 4000 samples logged", all.len());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A real full disk: `dash2sim record` writing into a 64 KiB tmpfs that a filler file has
/// all but filled; the filler is removed 2 s in. Needs the right to mount (root in a
/// container that allows it); says it skipped otherwise.
#[test]
fn record_on_a_real_full_file_system_resumes_when_space_returns() {
    let dir = std::env::temp_dir().join(format!("dash2sim-tmpfs-{}", std::process::id()));
    let mount = dir.join("card");
    std::fs::create_dir_all(&mount).expect("dir");
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
        .arg(&mount)
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        println!(
            "skipped: cannot mount a tmpfs here (not root, or no CAP_SYS_ADMIN); the injected-sink test covers ENOSPC"
        );
        let _ = std::fs::remove_dir_all(&dir);
        return;
    }
    let capture: String =
        (0..5000).map(|i| format!("({:.6}) can0 18FEF100#FF0050FFFFFFFFFF\n", i as f64 * 0.001)).collect();
    let bus = dir.join("bus.log");
    std::fs::write(&bus, capture).expect("capture");
    // Leave about 8 KiB of the card free.
    let filler = mount.join("filler");
    let free = rustix::fs::statvfs(&mount).map(|s| s.f_bavail * s.f_frsize).expect("statvfs");
    std::fs::write(&filler, vec![0u8; (free as usize).saturating_sub(8192)]).expect("filler");
    let logs = mount.join("logs");
    let record = Command::new(env!("CARGO_BIN_EXE_dash2sim"))
        .args(["record", "--can-replay"])
        .arg(&bus)
        .args(["--realtime", "--seconds", "5", "--origin", "60.2711,24.8572", "--json", "-o"])
        .arg(&logs)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("dash2sim record");
    std::thread::sleep(Duration::from_secs(2));
    std::fs::remove_file(&filler).expect("free the card");
    let output = record.wait_with_output().expect("record");
    let files: Vec<std::path::PathBuf> = {
        let mut f: Vec<_> = std::fs::read_dir(&logs)
            .expect("logs")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "d2slog"))
            .collect();
        f.sort();
        f
    };
    let contents: Vec<Vec<u8>> = files.iter().map(|f| std::fs::read(f).expect("log")).collect();
    let _ = Command::new("umount").arg(&mount).status();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json summary");
    println!("{summary}; files {:?}", contents.iter().map(Vec::len).collect::<Vec<_>>());
    assert!(summary["write_failures"].as_u64().is_some_and(|n| n >= 1), "{summary}");
    assert!(contents.iter().all(|c| !c.is_empty()), "a file that never took a byte is removed");
    let first = log::decode(&contents[0], "first").expect("the first file reads");
    assert!(first.stats.damaged <= 1);
    let last = log::decode(contents.last().expect("files"), "last").expect("the last file reads");
    assert!(
        last.records.iter().any(
            |r| matches!(r, Record::Event(e) if e.text.starts_with(b"log writes failed (No space left on device"))
        ),
        "the failure is an event in the file written after the card freed up"
    );
}

/// A serial port that is a FIFO nobody writes to yet (a GNSS process that has not started):
/// the logger records meanwhile and stops on SIGTERM as always. Opening a FIFO's read end
/// waits for a writer; the logger used to wait so, deaf to SIGTERM until killed.
#[test]
fn a_logger_waiting_for_its_fifos_writer_stops_on_sigterm() {
    let dir = std::env::temp_dir().join(format!("dash2sim-fifo-term-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let fifo = dir.join("gnss.fifo");
    rustix::fs::mkfifoat(rustix::fs::CWD, &fifo, rustix::fs::Mode::RUSR | rustix::fs::Mode::WUSR).expect("mkfifo");
    let prefix = format!("dash2sim-test/fifo-term/{}", std::process::id());
    let mut record = Command::new(env!("CARGO_BIN_EXE_dash2sim"))
        .args(["record", "--camera", &prefix, "--serial"])
        .arg(&fifo)
        .args(["--origin", "60.2711,24.8572", "-o"])
        .arg(dir.join("log"))
        .env("IOX2_LOG_LEVEL", "Error")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("dash2sim record");
    // Subscribed to the camera: its signal handlers are in place (installed before).
    let start = Instant::now();
    while !dash2sim_linux::record::bridge::listening(&prefix).expect("the camera services") {
        assert!(record.try_wait().expect("record").is_none(), "the logger ended before it subscribed");
        assert!(start.elapsed() < Duration::from_secs(300), "the logger never subscribed");
        std::thread::sleep(Duration::from_millis(20));
    }
    rustix::process::kill_process(rustix::process::Pid::from_child(&record), rustix::process::Signal::TERM)
        .expect("SIGTERM");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = record.try_wait().expect("record") {
            break status;
        }
        if start.elapsed() > Duration::from_secs(300) {
            let _ = record.kill();
            panic!("the logger did not stop on SIGTERM while its FIFO had no writer");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let output = record.wait_with_output().expect("record");
    assert!(status.success(), "{status}: {}", String::from_utf8_lossy(&output.stderr));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A live recording refuses what it would otherwise silently ignore: a file source beside
/// the live ones (the 2D detections and the IMU too), and `--save-inputs` (only a recording
/// from files saves its input stream). Each is an error before anything runs: the sources'
/// names the choices, `--save-inputs`' names its flag.
#[test]
fn a_live_recording_refuses_file_sources_and_saving_its_inputs() {
    let dir = std::env::temp_dir().join(format!("dash2sim-live-refuses-{}", std::process::id()));
    let refused = |extra: &[&str]| {
        let output = Command::new(env!("CARGO_BIN_EXE_dash2sim"))
            .args(["record", "--camera", "dash2sim-test/refused", "-o"])
            .arg(&dir)
            .args(extra)
            .output()
            .expect("dash2sim record");
        assert!(!output.status.success(), "{extra:?} was accepted");
        String::from_utf8_lossy(&output.stderr).into_owned()
    };
    for flag in ["--imu", "--detections2d", "--vo"] {
        let stderr = refused(&[flag, "inputs.csv"]);
        assert!(stderr.contains("file sources do not mix"), "{flag}: {stderr}");
    }
    let stderr = refused(&["--save-inputs", "inputs.d2sin"]);
    assert!(stderr.contains("--save-inputs") && stderr.contains("does not save its input stream"), "{stderr}");
    assert!(!dir.exists(), "nothing was recorded");
}
