//! Power cuts in loop recording: `record --quota`, rotating files every 1.2 s (a buffer of 4 KiB goes out mid-file) and deleting
//! the oldest, killed with SIGKILL at instants spread over file starts, writes and
//! deletions, and started again in the same folder each time, as a dashcam is. After every
//! cut the index is whole (it is replaced atomically), and what a restart makes of it names
//! every file on disk and no file that is gone; every file reads back to its last complete
//! frame. (The core's tests cut a log at every byte; `live_faults.rs` kills a logger
//! mid-file.)

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use dash2sim_linux::log;
use dash2sim_linux::record::storage::{read_index, Storage, StoragePolicy};

fn logs_on_disk(dir: &Path) -> Vec<String> {
    let mut files: Vec<String> = std::fs::read_dir(dir)
        .expect("folder")
        .flatten()
        .filter_map(|e| e.file_name().into_string().ok())
        .filter(|n| n.ends_with(".d2slog"))
        .collect();
    files.sort();
    files
}

#[test]
fn a_logger_killed_at_any_moment_leaves_an_index_that_names_every_file() {
    let dir = std::env::temp_dir().join(format!("dash2sim-cuts-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let capture: String =
        (0..4_000).map(|i| format!("({:.6}) can0 18FEF100#FF0050FFFFFFFFFF\n", i as f64 * 0.001)).collect();
    let bus = dir.join("bus.log");
    std::fs::write(&bus, capture).expect("capture");
    let logs: PathBuf = dir.join("logs");
    let mut killed_with_files = 0;
    for (run, ms) in [150u64, 420, 700, 1030, 1370, 1810, 2250, 2700].into_iter().enumerate() {
        let mut record = Command::new(env!("CARGO_BIN_EXE_dash2sim"))
            .args(["record", "--can-replay"])
            .arg(&bus)
            .args(["--realtime", "--seconds", "30", "--segment-minutes", "0.02", "--quota", "40k"])
            .args(["--origin", "60.2711,24.8572", "-o"])
            .arg(&logs)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("dash2sim record");
        std::thread::sleep(Duration::from_millis(ms));
        record.kill().expect("SIGKILL");
        record.wait().expect("killed");
        if !logs.exists() {
            continue;
        }
        // The index as the cut left it: whole, never torn.
        let before = read_index(&logs).unwrap_or_else(|e| panic!("run {run}, cut at {ms} ms: {e}"));
        // What the next start makes of it.
        let storage = Storage::open(&logs, StoragePolicy::default()).expect("restart");
        let index = storage.index();
        let present: Vec<String> =
            index.segments.iter().filter(|e| e.deleted.is_none()).map(|e| e.file.clone()).collect();
        let mut named = present.clone();
        named.sort();
        assert_eq!(named, logs_on_disk(&logs), "run {run}, cut at {ms} ms: index {before:?}");
        assert!(index.segments.len() >= before.segments.len());
        for file in &present {
            let path = logs.join(file);
            let contents = log::read(&path).unwrap_or_else(|e| panic!("run {run}: {e}"));
            assert!(
                contents.damage.iter().all(|(offset, len)| offset + len == contents.bytes),
                "run {run}: {file} is damaged before its tail: {:?}",
                contents.damage
            );
        }
        killed_with_files += usize::from(!present.is_empty());
    }
    let index = read_index(&logs).expect("index");
    let mut reasons: std::collections::BTreeMap<String, usize> = Default::default();
    for e in &index.segments {
        *reasons.entry(e.deleted.clone().unwrap_or_else(|| "present".into())).or_default() += 1;
    }
    println!("{} files named over 8 cuts: {reasons:?}", index.segments.len());
    assert!(killed_with_files >= 6, "the cuts fell while files were being recorded");
    assert!(reasons.get("empty after a crash").copied().unwrap_or(0) < 8, "some cuts fell in a file's middle");
    assert!(index.segments.iter().any(|e| e.deleted.as_deref() == Some("over the quota")), "and deleted");
    let _ = std::fs::remove_dir_all(&dir);
}
