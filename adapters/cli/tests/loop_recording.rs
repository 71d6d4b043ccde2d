//! Loop recording: `dash2sim record --quota` on a drive larger than the quota, a real
//! process writing real files — the folder never exceeds the quota, the files marked to be
//! kept (a `KEEP` file, the camera process's mark over the bridge, SIGUSR1) survive, every
//! deletion is in the index and an event, and `inspect DIR` lists it all. The recording is
//! signed: `inspect DIR --verify-key` follows the chain across the files, past the deleted
//! ones, and finds two files swapped by hand. An emergency stop on the bus keeps its file.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use dash2sim_core::binlog::Record;
use dash2sim_linux::log;
use dash2sim_linux::record::bridge::{device_now, CameraPublisher};
use dash2sim_linux::record::storage::{read_index, INDEX_FILE, KEEP_FILE};

const QUOTA: u64 = 80 * 1024;

fn folder_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries.flatten().filter_map(|e| e.metadata().ok()).filter(|m| m.is_file()).map(|m| m.len()).sum()
        })
        .unwrap_or(0)
}

fn events(path: &Path) -> Vec<String> {
    let Ok(contents) = log::read(path) else { return Vec::new() };
    contents
        .records
        .iter()
        .filter_map(
            |r| if let Record::Event(e) = r { Some(String::from_utf8_lossy(&e.text).into_owned()) } else { None },
        )
        .collect()
}

#[test]
fn a_quota_smaller_than_the_drive_keeps_the_folder_within_it_and_the_marked_files() {
    let dir = std::env::temp_dir().join(format!("dash2sim-loop-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    // 12 s of wheel speed at 1 kHz in real time: about 6 KB of log a second, almost twice
    // the quota in all; a new file every 1.2 s. 80 km/h, and an emergency stop at 6 m/s²
    // from 11 s (to 26 km/h): the last file, which holds it, is kept.
    let capture: String = (0..12_000)
        .map(|i| {
            let t = i as f64 * 0.001;
            let kmh = (80.0 - 21.6 * (t - 11.0).max(0.0)).max(26.0);
            let raw = (kmh * 256.0).round() as u16;
            format!("({t:.6}) can0 18FEF100#FF{:02X}{:02X}FFFFFFFFFF\n", raw & 0xff, raw >> 8)
        })
        .collect();
    let bus = dir.join("bus.log");
    std::fs::write(&bus, capture).expect("capture");
    let logs = dir.join("logs");
    let prefix = format!("dash2sim-test/loop/{}", std::process::id());
    let key = dir.join("device");
    let keygen =
        Command::new(env!("CARGO_BIN_EXE_dash2sim")).arg("keygen").arg("-o").arg(&key).output().expect("keygen");
    assert!(keygen.status.success(), "{}", String::from_utf8_lossy(&keygen.stderr));
    let mut record = Command::new(env!("CARGO_BIN_EXE_dash2sim"))
        .args(["record", "--camera", &prefix, "--can-replay"])
        .arg(&bus)
        .args(["--realtime", "--seconds", "12", "--segment-minutes", "0.02", "--quota", "80k"])
        .args(["--origin", "60.2711,24.8572", "--json", "--key"])
        .arg(key.with_extension("key"))
        .arg("-o")
        .arg(&logs)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("dash2sim record");
    let start = Instant::now();
    let camera = CameraPublisher::new(&prefix, false).expect("camera publisher");
    let (mut largest, mut marked_by_file, mut marked_by_signal, mut marked_by_camera) = (0, false, false, false);
    while record.try_wait().expect("record").is_none() {
        largest = largest.max(folder_bytes(&logs));
        if !marked_by_file && start.elapsed() > Duration::from_millis(2500) {
            std::fs::write(logs.join(KEEP_FILE), b"").expect("KEEP");
            marked_by_file = true;
        }
        if !marked_by_camera && start.elapsed() > Duration::from_millis(4500) {
            camera.keep(device_now()).expect("keep");
            marked_by_camera = true;
        }
        if !marked_by_signal && start.elapsed() > Duration::from_millis(6500) {
            let sent = Command::new("kill").args(["-USR1", &record.id().to_string()]).status().expect("kill");
            assert!(sent.success());
            marked_by_signal = true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let output = record.wait_with_output().expect("record");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json");
    println!("{summary}; the folder at most {largest} bytes");
    assert!(largest <= QUOTA, "the folder reached {largest} bytes, over the {QUOTA}-byte quota");
    assert!(summary["deleted_files"].as_u64().is_some_and(|n| n >= 3), "{summary}");

    let index = read_index(&logs).expect("index");
    let on_disk = |name: &str| logs.join(name).exists();
    // The two marked files are kept and survive; the deleted ones are gone, unmarked, oldest
    // first.
    let kept: Vec<_> = index.segments.iter().filter(|e| e.protected.is_some()).collect();
    let reasons: Vec<_> = kept.iter().filter_map(|e| e.protected.as_deref()).collect();
    assert_eq!(
        reasons,
        [
            "marked by the user (KEEP file)",
            "marked by the camera process (bridge)",
            "marked by the user (SIGUSR1)",
            "harsh braking"
        ],
        "{index:?}"
    );
    assert_eq!(summary["harsh_brakings"], 1, "{summary}");
    assert!(kept.iter().all(|e| e.deleted.is_none() && on_disk(&e.file)), "marked files survive");
    let deleted: Vec<_> = index.segments.iter().filter(|e| e.deleted.is_some()).collect();
    assert_eq!(deleted.len() as u64, summary["deleted_files"].as_u64().expect("n"));
    assert!(deleted.iter().all(|e| !on_disk(&e.file) && e.protected.is_none()));
    let first_kept = index.segments.iter().position(|e| e.protected.is_some()).expect("kept");
    assert!(index.segments[..first_kept].iter().all(|e| e.deleted.is_some()), "the oldest unmarked go first");
    // Every file on disk is in the index, and nothing else of the recording's is there.
    let mut files: Vec<PathBuf> = std::fs::read_dir(&logs).expect("logs").flatten().map(|e| e.path()).collect();
    files.retain(|p| p.extension().is_some_and(|e| e == "d2slog"));
    let present: Vec<_> = index.segments.iter().filter(|e| e.deleted.is_none()).map(|e| logs.join(&e.file)).collect();
    files.sort();
    assert_eq!(files, present);
    // Deletions and marks are events in the files recorded when they happened: those that
    // survive name files the index calls deleted.
    let said: Vec<String> = files.iter().flat_map(|f| events(f)).collect();
    let deletions: Vec<&String> = said.iter().filter(|t| t.starts_with("storage: deleted ")).collect();
    assert!(!deletions.is_empty(), "{said:?}");
    for text in &deletions {
        let name = text.trim_start_matches("storage: deleted ").split(' ').next().expect("name");
        assert!(deleted.iter().any(|e| e.file == name), "{text}");
    }
    assert!(said.iter().any(|t| t == "this file is kept: marked by the user (SIGUSR1)"));

    // `inspect DIR` lists the folder from its index.
    let inspect = Command::new(env!("CARGO_BIN_EXE_dash2sim")).arg("inspect").arg(&logs).output().expect("inspect");
    let text = String::from_utf8_lossy(&inspect.stdout);
    assert!(inspect.status.success(), "{}", String::from_utf8_lossy(&inspect.stderr));
    assert!(
        text.contains(&format!("files named in {INDEX_FILE}")) && text.contains("kept: marked by the user (KEEP file)")
    );
    assert!(text.contains("deleted (over the quota)"), "{text}");
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).expect("dir");
    let refused = Command::new(env!("CARGO_BIN_EXE_dash2sim")).arg("inspect").arg(&empty).output().expect("inspect");
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("a folder, but not a live recording's"));

    // Signed: every present file verifies, the chain followed across the files and past
    // the deleted ones (a file after a deleted one continues a segment not given).
    let verify = |what: &Path| {
        let out = Command::new(env!("CARGO_BIN_EXE_dash2sim"))
            .arg("inspect")
            .arg(what)
            .arg("--verify-key")
            .arg(key.with_extension("pub"))
            .args(["--json"])
            .output()
            .expect("inspect --verify-key");
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        (out.status.success(), report)
    };
    let (ok, report) = verify(&logs);
    assert!(ok, "{report}");
    assert_eq!(report["files"].as_array().map(Vec::len), Some(files.len()));
    let verdicts: Vec<&str> = report["files"]
        .as_array()
        .expect("files")
        .iter()
        .flat_map(|f| f["segments"].as_array().expect("segments").iter().map(|s| s["verdict"].as_str().expect("v")))
        .collect();
    assert!(verdicts.contains(&"ok (continues a segment not given)"), "{verdicts:?}");
    // A file's first segment "ok": it follows the last segment of the file before it.
    assert!(verdicts.contains(&"ok"), "{verdicts:?}");
    // Two files in a row swapped by hand (their contents): the chain breaks at the second.
    // (A file removed from the middle shows the same way, `signed_logs.rs` and the core's
    // tests; here every file before a present one was deleted by the quota, which the chain
    // cannot tell from a removal — the index says which.)
    let pair = index.segments.windows(2).rev().find(|w| w.iter().all(|e| e.deleted.is_none()));
    let pair = pair.unwrap_or_else(|| panic!("two files in a row: {index:?}"));
    let (a, b) = (logs.join(&pair[0].file), logs.join(&pair[1].file));
    let (bytes_a, bytes_b) = (std::fs::read(&a).expect("a"), std::fs::read(&b).expect("b"));
    std::fs::write(&a, &bytes_b).expect("swap");
    std::fs::write(&b, &bytes_a).expect("swap");
    let (ok, report) = verify(&logs);
    assert!(!ok, "swapped files must not verify: {report}");
    let second = report["files"]
        .as_array()
        .expect("files")
        .iter()
        .find(|f| f["file"].as_str().is_some_and(|n| n.ends_with(&pair[1].file)));
    assert_eq!(second.expect("the second file")["segments"][0]["verdict"], "chain broken", "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}
