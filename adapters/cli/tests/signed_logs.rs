//! Signed logs end to end: `keygen`, `record --key`, then a flipped byte, a swapped
//! segment, a removed middle segment and another key, each named as such by `inspect
//! --verify-key` and refused by `finish --require-signed` (the corpus job's refusal is
//! tested with the Python package).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use dash2sim_core::binlog::SYNC;

fn dash2sim(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dash2sim")).args(args).output().expect("dash2sim")
}

fn os<S: AsRef<std::ffi::OsStr> + ?Sized>(s: &S) -> &std::ffi::OsStr {
    s.as_ref()
}

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/mcu")
}

/// Where each segment starts (its sync marker), and the file's end.
fn segments(bytes: &[u8]) -> Vec<usize> {
    let mut at: Vec<usize> = bytes.windows(4).enumerate().filter(|(_, w)| *w == SYNC).map(|(k, _)| k).collect();
    at.push(bytes.len());
    at
}

/// `inspect --verify-key --json`: success, and each segment's verdict.
fn verdicts(log: &Path, public: &Path) -> (bool, Vec<String>) {
    let out = dash2sim(&[os("inspect"), log.as_os_str(), os("--verify-key"), public.as_os_str(), os("--json")]);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let segments = report["files"][0]["segments"].as_array().expect("segments");
    (out.status.success(), segments.iter().map(|s| s["verdict"].as_str().expect("verdict").to_owned()).collect())
}

/// `finish --require-signed`: refused, with this reason.
fn refused(log: &Path, public: &Path, reason: &str) {
    let out = log.with_extension("finished");
    let run = dash2sim(&[
        os("finish"),
        log.as_os_str(),
        os("-o"),
        out.as_os_str(),
        os("--require-signed"),
        public.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && stderr.contains(reason), "{}: {stderr}", log.display());
    assert!(!out.exists(), "nothing is finished from a refused log");
}

#[test]
fn tampered_logs_are_named_by_inspect_and_refused_by_finish() {
    let dir = std::env::temp_dir().join(format!("dash2sim-signed-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    for name in ["device", "other"] {
        let out = dash2sim(&[os("keygen"), os("-o"), dir.join(name).as_os_str()]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let again = dash2sim(&[os("keygen"), os("-o"), dir.join("device").as_os_str()]);
    assert!(String::from_utf8_lossy(&again.stderr).contains("a key is never overwritten"));
    let (public, other) = (dir.join("device.pub"), dir.join("other.pub"));
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let mode = std::fs::metadata(dir.join("device.key")).expect("key").permissions().mode();
        assert_eq!(mode & 0o077, 0, "the secret key is its owner's only");
    }
    let log = dir.join("drive.d2slog");
    let recorded = dash2sim(&[
        os("record"),
        os("--replay"),
        examples().join("drive.d2sin").as_os_str(),
        os("--map"),
        examples().join("drive.d2smap").as_os_str(),
        os("--key"),
        dir.join("device.key").as_os_str(),
        os("-o"),
        log.as_os_str(),
    ]);
    assert!(recorded.status.success(), "{}", String::from_utf8_lossy(&recorded.stderr));

    let (ok, got) = verdicts(&log, &public);
    assert!(ok, "{got:?}");
    assert_eq!(got[0], "ok (chain starts)");
    assert!(got.len() >= 4 && got[1..].iter().all(|v| v == "ok"), "{got:?}");
    let finished = dash2sim(&[
        os("finish"),
        log.as_os_str(),
        os("-o"),
        dir.join("finished.d2slog").as_os_str(),
        os("--require-signed"),
        public.as_os_str(),
    ]);
    assert!(finished.status.success(), "{}", String::from_utf8_lossy(&finished.stderr));

    let bytes = std::fs::read(&log).expect("log");
    let s = segments(&bytes);
    let write = |name: &str, b: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, b).expect("write");
        p
    };
    // A flipped byte in the third segment's records.
    let mut flipped = bytes.clone();
    flipped[(s[2] + s[3]) / 2] ^= 0x04;
    let flipped = write("flipped.d2slog", &flipped);
    let (ok, got) = verdicts(&flipped, &public);
    assert!(!ok);
    assert_eq!(got[2], "bad signature", "{got:?}");
    assert!(got.iter().filter(|v| v.starts_with("ok")).count() == got.len() - 1, "{got:?}");
    refused(&flipped, &public, "segment 2 of");

    // The second and third segments swapped.
    let swapped = [&bytes[..s[1]], &bytes[s[2]..s[3]], &bytes[s[1]..s[2]], &bytes[s[3]..]].concat();
    let swapped = write("swapped.d2slog", &swapped);
    let (ok, got) = verdicts(&swapped, &public);
    assert!(!ok);
    assert_eq!(got[..4], ["ok (chain starts)", "chain broken", "chain broken", "chain broken"], "{got:?}");
    refused(&swapped, &public, "chain broken");

    // The second segment removed.
    let removed = [&bytes[..s[1]], &bytes[s[2]..]].concat();
    let removed = write("removed.d2slog", &removed);
    let (ok, got) = verdicts(&removed, &public);
    assert!(!ok);
    assert_eq!(got[..3], ["ok (chain starts)", "chain broken", "ok"], "{got:?}");
    refused(&removed, &public, "segment 2 of");

    // Another device's key.
    let (ok, got) = verdicts(&log, &other);
    assert!(!ok);
    assert!(got.iter().all(|v| v == "signed by another key"), "{got:?}");
    refused(&log, &other, "signed by another key (key id ");

    // A log recorded without a key.
    let unsigned = dir.join("unsigned.d2slog");
    let recorded = dash2sim(&[
        os("record"),
        os("--replay"),
        examples().join("drive.d2sin").as_os_str(),
        os("-o"),
        unsigned.as_os_str(),
    ]);
    assert!(recorded.status.success());
    let (ok, got) = verdicts(&unsigned, &public);
    assert!(!ok && got.iter().all(|v| v == "unsigned"), "{got:?}");
    refused(&unsigned, &public, "segment 0 of");
    let _ = std::fs::remove_dir_all(&dir);
}
