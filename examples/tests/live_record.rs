//! `dash2sim record` live, with real processes and real shared memory: `camera_sim`
//! publishes a generated drive at its frame rate while the logger (this process, through
//! the library) subscribes, reads the drive's NMEA from a pseudo-terminal (written by
//! the camera process at the receiver's rate), and replays the wheel-speed candump in real time.

use std::io::{Read, Write};
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use dash2sim_core::binlog::Record;
use dash2sim_linux::log;
use dash2sim_linux::record::live::{self, LiveReport, LiveRequest, LiveStatus};
use dash2sim_linux::record::{self, bridge, Setup, Sources};
use dash2sim_sim::scenario::judge::judge_log;
use dash2sim_sim::scenario::sensors::GnssModel;
use dash2sim_sim::scenario::write::write_scenario;
use dash2sim_sim::scenario::{generate, ScenarioConfig};

mod common;
use common::wait_for;

const SECONDS: f64 = 8.0;

/// The tests here run real processes against the clock: one at a time, so that they do
/// not slow each other down.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The logger's thread, recording until `stop` is set, returned once it has subscribed to
/// every camera service under the request's prefix (a frame published before that is not
/// kept for it).
fn logger(
    request: LiveRequest,
    setup: Setup,
    stop: &Arc<AtomicBool>,
) -> JoinHandle<dash2sim_linux::Result<LiveReport>> {
    let prefix = request.camera_prefix.clone().expect("a camera prefix");
    let stop = Arc::clone(stop);
    let logger = std::thread::spawn(move || live::run(&request, &setup, &live::Origin::Given, &stop));
    wait_for("the logger to subscribe", || {
        assert!(!logger.is_finished(), "the logger ended before it subscribed");
        bridge::listening(&prefix).expect("the camera services")
    });
    logger
}

/// CAN frames the logger has seen, as its last status said.
static CAN_FRAMES_SEEN: AtomicU64 = AtomicU64::new(0);

fn note_can_frames(status: &LiveStatus) {
    CAN_FRAMES_SEEN.store(status.stats.can_frames, Ordering::Relaxed);
}

/// A pseudo-terminal pair: the master to write to, the slave's path for the logger.
fn pty() -> (std::fs::File, String) {
    use rustix::pty::{grantpt, openpt, ptsname, unlockpt, OpenptFlags};
    let master = openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY).expect("openpt");
    grantpt(&master).expect("grantpt");
    unlockpt(&master).expect("unlockpt");
    let name = ptsname(&master, Vec::new()).expect("ptsname").into_string().expect("utf-8");
    (std::fs::File::from(master), name)
}

#[test]
fn a_live_recording_logs_every_published_frame_and_matches_the_file_recording() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = std::env::temp_dir().join(format!("dash2sim-live-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let drive = dir.join("drive");
    let scenario = generate(&ScenarioConfig {
        seed: 1,
        duration_s: SECONDS,
        gnss: GnssModel::good(),
        ..ScenarioConfig::default()
    });
    write_scenario(&scenario, &drive).expect("scenario");
    let [lat, lon, h] = scenario.config.origin;
    let origin = dash2sim_core::geo::Geodetic::new(lat, lon, h).expect("origin");
    let osm = dash2sim_linux::ingest::osm::read(&drive.join("road.osm")).expect("osm");
    let tile = dash2sim_linux::ingest::map_tile::encode(
        &dash2sim_linux::ingest::map_tile::from_osm(&osm, Some(origin), &mut Vec::new()),
        50.0,
    );
    let setup = Setup::work_zone(origin, Some(tile), *b"dash2sim-live\0\0\0");

    // The same drive recorded from its files, for comparison.
    let (stream, _) = record::read_sources(&Sources::scenario(&drive)).expect("sources");
    let from_files = record::run_stream(&stream, &setup).expect("file record");
    let from_files = judge_log(&scenario, &log::decode(&from_files.log, "files").expect("log"));

    // The receiver: the camera process writes the NMEA at its receive times, on the clock
    // its frames are paced by, into a FIFO; this test forwards it as it comes to a pty
    // (the serial port the logger reads). Pacing the NMEA here instead would start its
    // clock before the camera's: a slow start of the camera process (it generates the
    // drive first) would put every fix early against the frames.
    let (mut master, slave) = pty();
    let nmea = dir.join("gnss.fifo");
    rustix::fs::mkfifoat(rustix::fs::CWD, &nmea, rustix::fs::Mode::RUSR | rustix::fs::Mode::WUSR).expect("mkfifo");
    let prefix = format!("dash2sim-test/live/{}", std::process::id());
    let request = LiveRequest {
        dir: dir.join("log"),
        camera_prefix: Some(prefix.clone()),
        serial: Some(slave.into()),
        baud: 115_200,
        can_interface: None,
        can_replay: Some(drive.join("speed.can.log")),
        realtime: true,
        segment: Duration::from_secs(600),
        duration: None,
        status: Some(note_can_frames),
        storage: Default::default(),
        keep: None,
    };
    let stop = Arc::new(AtomicBool::new(false));
    let logger = logger(request, setup, &stop);
    let camera = Command::new(env!("CARGO_BIN_EXE_camera_sim"))
        .args(["--profile", "ideal", "--seconds", &SECONDS.to_string(), "--prefix", &prefix, "--nmea-out"])
        .arg(&nmea)
        .spawn()
        .expect("camera_sim");
    // Opening a FIFO's read end waits for its writer; its end of file is the writer's.
    let mut from_camera = std::fs::File::open(&nmea).expect("open the NMEA FIFO");
    let mut sentences = 0;
    let mut chunk = [0u8; 512];
    loop {
        let n = from_camera.read(&mut chunk).expect("read the NMEA FIFO");
        if n == 0 {
            break;
        }
        master.write_all(&chunk[..n]).expect("pty");
        sentences += chunk[..n].iter().filter(|&&b| b == b'\n').count();
    }
    let serial = std::fs::read_to_string(drive.join("gnss.serial.log")).expect("serial");
    assert_eq!(sentences, serial.lines().count(), "every sentence of the receiver went through");
    let camera = camera.wait_with_output().expect("camera_sim");
    assert!(camera.status.success());
    // Stopped once the camera process has published every frame and the logger has seen
    // every frame of the wheel-speed replay (it began with the logger, before the camera
    // process): however slowly it runs, the logger then has every input.
    let can_frames = std::fs::read_to_string(drive.join("speed.can.log")).expect("candump").lines().count() as u64;
    wait_for("the replay's CAN frames", || CAN_FRAMES_SEEN.load(Ordering::Relaxed) >= can_frames);
    stop.store(true, Ordering::Relaxed);
    let report = logger.join().expect("logger thread").expect("live record");
    let frames = (SECONDS * 10.0) as u64 + 1;
    println!("live: {report:?}");
    assert_eq!(report.frames, frames);
    assert_eq!(report.dropped, 0);

    let files: Vec<_> = std::fs::read_dir(dir.join("log"))
        .expect("log dir")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "d2slog"))
        .collect();
    assert_eq!(files.len(), 1);
    let log = log::read(&files[0]).expect("log");
    assert_eq!(log.stats.damaged, 0);
    let logged: Vec<i64> =
        log.records.iter().filter_map(|r| if let Record::FrameMeta(f) = r { Some(f.frame) } else { None }).collect();
    assert_eq!(logged, (1..=frames as i64).collect::<Vec<_>>(), "every published frame is in the log");
    let fixes = log.records.iter().filter(|r| matches!(r, Record::GnssFix(_))).count();
    let speeds = log.records.iter().filter(|r| matches!(r, Record::VehicleSpeed(_))).count();
    assert_eq!((fixes, speeds), (scenario.gnss.len(), scenario.speed.len()), "every fix and speed sample");

    let live = judge_log(&scenario, &log);
    println!(
        "live: {} anchored frames, ego RMSE {:.3} m, track IDF1 seen from the ego {:.3}; from files: {}, {:.3} m, {:.3}",
        live.ego_errors.len(),
        live.ego_rmse,
        live.tracks_relative.1,
        from_files.ego_errors.len(),
        from_files.ego_rmse,
        from_files.tracks_relative.1
    );
    // Real processes stamp with a real clock: the times jitter, and with them which fixes a
    // frame's anchor has seen. The anchoring must be no worse than from the files; the
    // tracks (36 anchored frames of 8 s: a small sample, seen IDF1 0.69–0.87 against 0.87
    // from the files) must be as many and of the same kind of quality. (Better is no defect
    // of the live path: on 8 s the first fixes a frame sees weigh on the whole RMSE, and a
    // CI run under load saw 1.40 m live against 2.20 m from the files, issue #57.)
    assert!(live.ego_errors.len().abs_diff(from_files.ego_errors.len()) <= 8);
    assert!(live.ego_rmse < 1.25 * from_files.ego_rmse + 0.1, "live RMSE {} m", live.ego_rmse);
    let states = |j: &dash2sim_sim::scenario::judge::LogJudgement| j.tracks_by_class.values().sum::<u64>() as f64;
    assert!((states(&live) - states(&from_files)).abs() <= 0.3 * states(&from_files));
    assert!(live.tracks_relative.1 > 0.5, "IDF1 seen from the ego {}", live.tracks_relative.1);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_camera_process_killed_and_restarted_is_a_gap_in_the_log_not_the_end_of_it() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = std::env::temp_dir().join(format!("dash2sim-live-restart-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let prefix = format!("dash2sim-test/restart/{}", std::process::id());
    let origin = dash2sim_core::geo::Geodetic::new(60.2711, 24.8572, 20.0).expect("origin");
    let setup = Setup::work_zone(origin, None, *b"dash2sim-live\0\0\0");
    let request = LiveRequest {
        dir: dir.clone(),
        camera_prefix: Some(prefix.clone()),
        serial: None,
        baud: 115_200,
        can_interface: None,
        can_replay: None,
        realtime: false,
        segment: Duration::from_secs(600),
        duration: None,
        status: None,
        storage: Default::default(),
        keep: None,
    };
    let stop = Arc::new(AtomicBool::new(false));
    let logger = logger(request, setup, &stop);
    // The test watches the frames too (its own subscriber, beside the logger's), to kill the
    // first process once it has published a second of them.
    let mut watch = common::FrameWatch::new(&prefix);
    let mut count_frames = || watch.frames();
    let camera = |seconds: &str| {
        Command::new(env!("CARGO_BIN_EXE_camera_sim"))
            .args(["--seconds", seconds, "--speedup", "2", "--prefix", &prefix])
            .stdout(std::process::Stdio::null())
            .spawn()
            .expect("camera_sim")
    };
    let mut first = camera("10");
    wait_for("the first camera process's frames", || count_frames() >= 12);
    first.kill().expect("SIGKILL");
    let _ = first.wait();
    let second = camera("3").wait().expect("second camera_sim");
    assert!(second.success());
    // Everything the second process published is in the logger's queues: stopped now, it
    // logs all of it.
    stop.store(true, Ordering::Relaxed);
    let report = logger.join().expect("logger thread").expect("the logger kept running");
    let files: Vec<_> = std::fs::read_dir(&dir)
        .expect("log dir")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "d2slog"))
        .collect();
    let log = log::read(&files[0]).expect("log");
    let frames = log::inspect::frames(&log);
    println!("{report:?}; {frames:?}");
    assert_eq!(frames.restarts, 1, "the restart is in the frame numbers");
    assert!(frames.logged > 31 + 10, "frames of both runs: {frames:?}");
    let restarted = dash2sim_core::pipeline::Issue::CameraRestarted.text().as_bytes();
    assert!(
        log.records.iter().any(|r| matches!(r, Record::Event(e) if e.text.starts_with(restarted))),
        "the restart is an event"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
