//! Loop recording keeps what the device verified: a live recording of a generated drive —
//! the camera process (`scenario publish`) over shared memory, GNSS as NMEA and speed as CAN
//! on FIFOs, `record --quota` writing 6 s files — keeps exactly the files in which a
//! verification window was verified, and says so in the index. (Harsh braking keeps its
//! file in `loop_recording.rs`; collisions are counted as the windows' records say in
//! `tests/device_windows.rs`.)

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use dash2sim_core::binlog::Record;
use dash2sim_linux::log;
use dash2sim_linux::record::storage::read_index;

const ORIGIN: &str = "60.2711,24.8572,20";

fn dash2sim() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dash2sim"));
    c.env("IOX2_LOG_LEVEL", "Error");
    c
}

fn run(c: &mut Command) {
    let out = c.output().expect("dash2sim");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// Whether the file holds a verification window the device verified (its event says so).
fn holds_window_not_rejected(path: &Path) -> bool {
    let log = log::read(path).expect("log");
    log.records
        .iter()
        .any(|r| matches!(r, Record::Verification(v) if v.decision_name().is_some_and(|d| d != "rejected")))
}

#[test]
fn the_files_holding_a_window_verified_or_undecided_are_kept() {
    let dir = std::env::temp_dir().join(format!("dash2sim-kept-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let (seed, seconds) = ("5", "32");
    run(dash2sim().args(["scenario", "generate", "--seed", seed, "--duration", seconds, "-o"]).arg(dir.join("drive")));
    run(dash2sim()
        .args(["map", "build"])
        .arg(dir.join("drive/road.osm"))
        .args(["--origin", ORIGIN, "-o"])
        .arg(dir.join("road.map")));
    let (gnss, can) = (dir.join("gnss.fifo"), dir.join("can.fifo"));
    run(Command::new("mkfifo").arg(&gnss).arg(&can));
    let logs = dir.join("logs");
    let prefix = format!("dash2sim-test/kept/{}", std::process::id());
    let record = dash2sim()
        .args(["record", "--camera", &prefix, "--serial"])
        .arg(&gnss)
        .arg("--can-replay")
        .arg(&can)
        .arg("--map")
        .arg(dir.join("road.map"))
        .args(["--origin", ORIGIN, "--quota", "10M", "--segment-minutes", "0.1", "--seconds", "90", "--json", "-o"])
        .arg(&logs)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("record");
    // The logger subscribes before the camera publishes its first frame.
    std::thread::sleep(Duration::from_millis(500));
    run(dash2sim()
        .args(["scenario", "publish", "--seed", seed, "--seconds", seconds, "--prefix", &prefix, "--nmea-out"])
        .arg(&gnss)
        .arg("--can-out")
        .arg(&can));
    // What the camera published last drains from the bridge, then the logger stops.
    std::thread::sleep(Duration::from_millis(1000));
    run(Command::new("kill").args(["-INT", &record.id().to_string()]));
    let output = record.wait_with_output().expect("record");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json");
    println!("{summary}");
    let not_rejected =
        summary["windows_verified"].as_u64().unwrap_or(0) + summary["windows_undecided"].as_u64().unwrap_or(0);
    assert!(not_rejected >= 1, "{summary}");
    assert_eq!(summary["collision_windows"], 0, "a careful drive: {summary}");

    let index = read_index(&logs).expect("index");
    assert!(index.segments.len() >= 4, "{index:?}");
    let mut kept = 0;
    for e in &index.segments {
        let holds = holds_window_not_rejected(&logs.join(&e.file));
        assert_eq!(e.protected.as_deref() == Some("it holds a window verified or undecided"), holds, "{e:?}");
        kept += usize::from(holds);
    }
    assert!(kept >= 1);
    let _ = std::fs::remove_dir_all(&dir);
}
