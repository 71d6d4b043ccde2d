//! The publishers' contract: the same folder of camera outputs published by the Rust
//! `camera_files` and by the C one (`examples/camera-c/camera_files.c`, compiled here with
//! `cc` against the C ABI's header and shared library) is logged byte for byte the same by
//! `dash2sim record --camera`, each a real process; a C camera process killed mid-run is a
//! restart in the log, as the Rust one is (`live_record.rs`). The Python publisher's side of
//! the contract is `adapters/python/tests/test_camera.py`.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

use dash2sim_core::binlog::Record;
use dash2sim_linux::log;
use dash2sim_linux::record::bridge;

mod common;
use common::wait_for;

/// The tests here run real processes against the clock: one at a time.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The build's output folder (`target/release`) and its `deps`, where this test runs from.
fn deps_dir() -> PathBuf {
    std::env::current_exe().expect("test binary").parent().expect("deps").to_path_buf()
}

/// The workspace's `dash2sim` binary, built beside this test by `cargo test --workspace`.
fn dash2sim() -> PathBuf {
    let path = deps_dir().parent().expect("target dir").join("dash2sim");
    assert!(path.is_file(), "{} is missing: build it (cargo build --release -p dash2sim)", path.display());
    path
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dash2sim-publishers-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// A generated drive's camera outputs: vo.csv, detections3d.csv, det2d.txt.
fn drive(dir: &Path, seconds: u32) -> PathBuf {
    let out = dir.join("drive");
    let status = Command::new(dash2sim())
        .args(["scenario", "generate", "--seed", "3", "--duration", &seconds.to_string(), "-o"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .expect("dash2sim scenario generate");
    assert!(status.success());
    out
}

/// The C camera process, compiled against the header and the shared library (or, with
/// `statically`, the static one and the system libraries Rust's standard library needs).
fn c_publisher_linked(dir: &Path, statically: bool) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace");
    let exe = dir.join(if statically { "camera_files_c_static" } else { "camera_files_c" });
    let mut cc = Command::new("cc");
    cc.args(["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-ffp-contract=off", "-I"])
        .arg(root.join("adapters/camera-c/include"))
        .arg(root.join("examples/camera-c/camera_files.c"));
    if statically {
        cc.arg(deps_dir().join("libdash2sim_camera.a")).args([
            "-lgcc_s",
            "-lutil",
            "-lrt",
            "-lpthread",
            "-lm",
            "-ldl",
            "-lc",
            "-Wl,--gc-sections",
        ]);
    } else {
        cc.arg("-L")
            .arg(deps_dir())
            .arg(format!("-Wl,-rpath,{}", deps_dir().display()))
            .args(["-ldash2sim_camera", "-lm"]);
    }
    let output = cc.arg("-o").arg(&exe).output().expect("cc");
    assert!(output.status.success(), "cc: {}", String::from_utf8_lossy(&output.stderr));
    exe
}

fn c_publisher(dir: &Path) -> PathBuf {
    c_publisher_linked(dir, false)
}

/// `dash2sim record --camera PREFIX` into `out`, returned once it is subscribed to every
/// camera service (samples published before a subscriber exists are not kept for it), with
/// no time limit: [`stopped`] ends it. Nothing here depends on how fast the logger runs.
fn logger(prefix: &str, out: &Path) -> Child {
    let mut child = common::recorder(&dash2sim())
        // --json: a failure shows what the logger received per service.
        .args(["record", "--json", "--camera", prefix, "--origin", "60.2711,24.8572,20"])
        .arg("-o")
        .arg(out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("dash2sim record");
    wait_for("the logger to subscribe", || {
        if let Ok(Some(status)) = child.try_wait() {
            panic!("the logger ended before it subscribed: {status}");
        }
        bridge::listening(prefix).expect("the camera services")
    });
    child
}

/// The logger stopped as a user stops it (SIGINT: it receives what is waiting, then closes
/// the log), and its output once it has ended well.
fn stopped(child: Child, what: &str) -> Output {
    let pid = rustix::process::Pid::from_child(&child);
    rustix::process::kill_process(pid, rustix::process::Signal::INT).expect("SIGINT");
    finished(child, what)
}

fn finished(child: Child, what: &str) -> Output {
    let output = child.wait_with_output().expect(what);
    assert!(output.status.success(), "{what}: {}", String::from_utf8_lossy(&output.stderr));
    output
}

/// The one log file `record` wrote into `dir`.
fn log_file(dir: &Path) -> PathBuf {
    let files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("log dir")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "d2slog"))
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    files[0].clone()
}

/// Publish `drive` with `publisher` while `record` logs it; the log's bytes.
fn logged_by(publisher: &Path, drive: &Path, dir: &Path, name: &str) -> Vec<u8> {
    let prefix = format!("dash2sim-test/publishers/{name}/{}", std::process::id());
    let out = dir.join(name);
    let record = logger(&prefix, &out);
    let published = Command::new(publisher)
        .arg(drive)
        .args(["--prefix", &prefix, "--speedup", "4", "--file-times"])
        .output()
        .expect("publisher");
    assert!(published.status.success(), "{name}: {}", String::from_utf8_lossy(&published.stderr));
    assert_eq!(String::from_utf8_lossy(&published.stdout).trim(), "31 frames published", "{name}");
    // Everything published is in the logger's queues (it outlives the publisher): stopped
    // now, however far behind it is, it logs all of it.
    stopped(record, "record");
    std::fs::read(log_file(&out)).expect("log")
}

#[test]
fn the_rust_and_the_c_publisher_shared_or_static_are_logged_byte_identically() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = scratch("identical");
    let drive = drive(&dir, 3);
    let from_rust = logged_by(Path::new(env!("CARGO_BIN_EXE_camera_files")), &drive, &dir, "rust");
    let from_c = logged_by(&c_publisher(&dir), &drive, &dir, "c");
    let from_static = logged_by(&c_publisher_linked(&dir, true), &drive, &dir, "static");

    // The log holds what was published: every frame, VO pose and 3D detection of the files,
    // and the 2D tracks made of the 2D detections.
    let log = log::decode(&from_rust, "rust").expect("log");
    let count = |f: fn(&Record) -> bool| log.records.iter().filter(|r| f(r)).count();
    let lines = |name: &str| std::fs::read_to_string(drive.join(name)).expect(name).lines().count() - 1;
    assert_eq!(count(|r| matches!(r, Record::FrameMeta(_))), 31);
    assert_eq!(count(|r| matches!(r, Record::VoPose(_))), lines("vo.csv"));
    assert_eq!(count(|r| matches!(r, Record::Detection3d(_))), lines("detections3d.csv"));
    assert!(count(|r| matches!(r, Record::Track2d(_))) > 0, "2D tracks from the 2D detections");
    // The IMU samples up to the last frame, preintegrated (every 0.1 s: the last interval's
    // few are still in the preintegrator when the recording stops).
    let last_frame: f64 = std::fs::read_to_string(drive.join("vo.csv"))
        .expect("vo.csv")
        .lines()
        .last()
        .and_then(|l| l.split(',').nth(1)?.parse().ok())
        .expect("last frame time");
    let sent = dash2sim_linux::record::sources::read_imu_csv(&drive.join("imu.csv"))
        .expect("imu.csv")
        .iter()
        .filter(|(t, _)| *t <= last_frame)
        .count() as i64;
    let integrated: i64 = log.records.iter().map(|r| if let Record::ImuDelta(d) = r { d.samples } else { 0 }).sum();
    assert!((sent - 11..=sent).contains(&integrated), "{integrated} of {sent} IMU samples preintegrated");
    assert!(
        from_rust == from_c,
        "the C publisher's log differs from the Rust one's ({} vs {} bytes)",
        from_c.len(),
        from_rust.len()
    );
    assert!(from_static == from_c, "the statically linked C publisher's log differs from the shared one's");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The C camera process publishing `drive`, SIGKILLed once three of its frames are out, and a
/// second one started in its place, returned once three of its frames are out with the number
/// of frames seen by then. The test watches the frames itself (its own subscriber, beside the
/// logger's).
fn killed_and_restarted(c: &Path, drive: &Path, prefix: &str) -> (Child, u64) {
    let mut watch = common::FrameWatch::new(prefix);
    let publish = || Command::new(c).arg(drive).args(["--prefix", prefix]).stdout(Stdio::null()).spawn().expect("C");
    let mut first = publish();
    wait_for("the first camera process's frames", || watch.frames() >= 3);
    first.kill().expect("SIGKILL");
    let _ = first.wait();
    let before = watch.frames();
    let second = publish();
    wait_for("the second camera process's frames", || watch.frames() >= before + 3);
    (second, watch.frames())
}

/// What a camera process published before it died waits for a logger that has not drained
/// it yet (issue #57): the camera process started after it leaves its predecessor's
/// publishers alone, where iceoryx2's default had it remove them — and with them what a
/// logger starved of CPU had not yet connected to. Here the late logger is the test's own,
/// drained only once the second process has published: deterministic, no starving needed.
#[test]
fn what_a_killed_camera_process_published_waits_for_a_late_logger() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = scratch("late");
    let drive = drive(&dir, 10);
    let c = c_publisher(&dir);
    let prefix = format!("dash2sim-test/publishers/late/{}", std::process::id());
    // Subscribed before either camera process starts, so each publishes to it too.
    let late = bridge::CameraSubscriber::new(&prefix).expect("the late logger");
    let (mut second, _) = killed_and_restarted(&c, &drive, &prefix);
    let mut poses = Vec::new();
    late.receive(|input| {
        if let bridge::CameraInput::Vo(_, frame, ..) = input {
            poses.push(frame);
        }
    })
    .expect("receive");
    let _ = second.kill();
    let _ = second.wait();
    // Both processes number their frames from the drive's first, and each published the
    // poses of its first two frames at least (a frame's pose follows its metadata, and the
    // watch saw three frames of each): they are there twice when the first process's reached
    // the late logger.
    let first_frame = poses.iter().copied().min().unwrap_or_default();
    let twice = (first_frame..first_frame + 2).filter(|f| poses.iter().filter(|p| *p == f).count() == 2).count();
    assert_eq!(twice, 2, "the first process's VO poses and the second's reached the late logger: {poses:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_c_camera_process_killed_mid_run_is_a_restart_in_the_log() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = scratch("killed");
    let drive = drive(&dir, 10);
    let c = c_publisher(&dir);
    let prefix = format!("dash2sim-test/publishers/killed/{}", std::process::id());
    let out = dir.join("log");
    let record = logger(&prefix, &out);
    let (mut second, seen) = killed_and_restarted(&c, &drive, &prefix);
    let output = stopped(record, "the logger kept running");
    let _ = second.kill();
    let _ = second.wait();

    let log = log::read(&log_file(&out)).expect("log");
    let frames = log::inspect::frames(&log);
    assert_eq!(
        frames.restarts,
        1,
        "the restart is in the frame numbers: {frames:?}; the test saw {seen} frames; the logger said: {}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    let restarted = dash2sim_core::pipeline::Issue::CameraRestarted.text().as_bytes();
    assert!(
        log.records.iter().any(|r| matches!(r, Record::Event(e) if e.text.starts_with(restarted))),
        "the restart is an event"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
