//! The live logger under faults: killed (SIGKILL) and restarted while the camera goes on
//! publishing, and a sink slower than its input.

use std::process::{Child, Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use dash2sim_core::binlog::Record;
use dash2sim_linux::log;
use dash2sim_linux::record::bridge::{device_now, CameraPublisher};
use dash2sim_linux::record::live::{self, LiveRequest};
use dash2sim_linux::record::Setup;
use dash2sim_linux::sim::scenario::{generate, ScenarioConfig};

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
    let mut files: Vec<_> = std::fs::read_dir(dir).expect("log dir").map(|e| e.expect("entry").path()).collect();
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
    let capture: String =
        (0..FRAMES).map(|i| format!("({:.6}) can0 18FEF100#FF0050FFFFFFFFFF\n", i as f64 * 0.02)).collect();
    let path = dir.join("bus.log");
    std::fs::write(&path, capture).expect("capture");
    let request = LiveRequest {
        dir: dir.join("log"),
        camera_prefix: None,
        serial: None,
        baud: 115_200,
        can_interface: None,
        can_replay: Some(path),
        realtime: false,
        segment: Duration::from_secs(600),
        duration: Some(Duration::from_secs(3)),
        status: None,
    };
    let origin = dash2sim_core::geo::Geodetic::new(60.2711, 24.8572, 20.0).expect("origin");
    let setup = Setup::work_zone(origin, None, *b"dash2sim-slow\0\0\0");
    let bytes = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let report = live::run_into(&request, &setup, &live::Origin::Given, &AtomicBool::new(false), |_| {
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
