//! Golden outputs of the command line (issue #32): the `--help` of every command, and what
//! each command prints (human and `--json`) and writes on fixed inputs, byte for byte — the
//! files by size and FNV-1a hash. Written before the command line moves into a crate of its
//! own, so that the move changes nothing a user sees.
//!
//! A change meant to alter an output is blessed with `DASH2SIM_BLESS=1 cargo test --release
//! -p dash2sim --test golden`, and the diff of `tests/golden/` is its review.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(path)
}

/// A folder of its own for one test, empty.
fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dash2sim-golden-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// FNV-1a, 64 bits: enough to tell two files apart, and no dependency.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// Every file under `dir` (relative path → size and hash).
fn files(dir: &Path) -> BTreeMap<String, (usize, u64)> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).expect("read_dir").flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if let Ok(bytes) = std::fs::read(&path) {
                let name = path.strip_prefix(dir).expect("under dir").display().to_string();
                out.insert(name, (bytes.len(), fnv1a(&bytes)));
            }
        }
    }
    out
}

/// How a command's written files enter its golden output.
#[derive(Clone, Copy, PartialEq)]
enum Written {
    /// Size and hash: the bytes are the product's.
    Bytes,
    /// Names only: the bytes depend on the machine (fonts in a picture, SQLite's pages).
    Names,
}

/// Runs `dash2sim args` in `dir`: what it printed, its exit status and the files it wrote
/// or changed, with `dir` itself written as `.`.
fn run(dir: &Path, args: &[&str], written: Written) -> String {
    let before = files(dir);
    let out = Command::new(env!("CARGO_BIN_EXE_dash2sim"))
        .args(args)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .env("IOX2_LOG_LEVEL", "Error")
        .output()
        .expect("the binary runs");
    let here = dir.display().to_string();
    let text = |b: &[u8]| wall_time_free(&String::from_utf8_lossy(b).replace(&here, "."));
    let mut s = format!("$ dash2sim {}\n", args.join(" "));
    s += &text(&out.stdout);
    let stderr = text(&out.stderr);
    if !stderr.is_empty() {
        s += "--- stderr\n";
        s += &stderr;
    }
    let _ = writeln!(s, "--- exit {}", out.status.code().map_or("signal".to_owned(), |c| c.to_string()));
    for (name, (size, hash)) in files(dir) {
        if before.get(&name) == Some(&(size, hash)) {
            continue;
        }
        match written {
            Written::Bytes => {
                let _ = writeln!(s, "wrote {name}: {size} bytes, fnv1a {hash:016x}");
            }
            Written::Names => {
                let _ = writeln!(s, "wrote {name}");
            }
        }
    }
    s
}

/// The text with the one wall-clock time a command prints (nuPlan's export ends its line
/// with the seconds it took, `(0.20 s)`) written as `(… s)`.
fn wall_time_free(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.split_inclusive('\n') {
        let (body, end) = line.strip_suffix('\n').map_or((line, ""), |b| (b, "\n"));
        let timed = body.rfind(" (").filter(|&i| {
            let tail = &body[i + 2..];
            tail.strip_suffix(" s)").is_some_and(|n| !n.is_empty() && n.chars().all(|c| c.is_ascii_digit() || c == '.'))
        });
        match timed {
            Some(i) if body.contains("generic_drivable_areas") => out += &format!("{} (… s){end}", &body[..i]),
            _ => out += line,
        }
    }
    out
}

/// Compares `got` with the golden file `name`, or writes it when blessing; a mismatch is
/// returned as the first line that differs.
fn check(name: &str, got: &str) -> Option<String> {
    let path = golden_dir().join(format!("{name}.txt"));
    if std::env::var_os("DASH2SIM_BLESS").is_some() {
        std::fs::create_dir_all(golden_dir()).expect("golden dir");
        std::fs::write(&path, got).expect("write golden");
        return None;
    }
    let want = match std::fs::read_to_string(&path) {
        Ok(w) => w,
        Err(e) => return Some(format!("{}: {e} (bless with DASH2SIM_BLESS=1)", path.display())),
    };
    if want == got {
        return None;
    }
    let (mut w, mut g) = (want.lines(), got.lines());
    for line in 1.. {
        match (w.next(), g.next()) {
            (Some(a), Some(b)) if a == b => continue,
            (a, b) => {
                return Some(format!(
                    "{name}.txt line {line}:\n  golden: {}\n  now:    {}",
                    a.unwrap_or("(end)"),
                    b.unwrap_or("(end)")
                ))
            }
        }
    }
    None
}

fn assert_all(mismatches: Vec<String>) {
    assert!(mismatches.is_empty(), "{} golden output(s) differ:\n{}", mismatches.len(), mismatches.join("\n"));
}

/// The subcommands a `--help` lists under "Commands:" (not `help`).
fn subcommands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_owned)
        .collect()
}

#[test]
fn every_commands_help_is_unchanged() {
    let dir = scratch("help");
    let mut mismatches = Vec::new();
    let mut queue = vec![Vec::<String>::new()];
    let mut seen = 0;
    while let Some(path) = queue.pop() {
        let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
        args.push("--help");
        let got = run(&dir, &args, Written::Bytes);
        let name = if path.is_empty() { "help".to_owned() } else { format!("help-{}", path.join("-")) };
        mismatches.extend(check(&name, &got));
        for sub in subcommands(&got) {
            let mut next = path.clone();
            next.push(sub);
            queue.push(next);
        }
        seen += 1;
    }
    assert!(seen > 20, "only {seen} commands found: the help's layout changed");
    assert_all(mismatches);
}

#[test]
fn every_commands_output_on_fixed_inputs_is_unchanged() {
    let dir = scratch("outputs");
    for (from, to) in [
        ("tests/fixtures/drive/truth.tum", "truth.tum"),
        ("tests/fixtures/drive/gnss.tum", "gnss.tum"),
        ("tests/fixtures/drive/vo.tum", "vo.tum"),
        ("tests/fixtures/drive/speed.csv", "speed.csv"),
        ("examples/mcu/drive.d2sin", "mcu.d2sin"),
        ("examples/mcu/drive.d2smap", "mcu.d2smap"),
        ("examples/mcu/road.osm", "road.osm"),
    ] {
        std::fs::copy(repo(from), dir.join(to)).expect("copy a fixture");
    }
    use Written::{Bytes, Names};
    let cases: &[(&str, &[&str], Written)] = &[
        ("traj-ape", &["traj", "ape", "truth.tum", "gnss.tum", "--align", "sim3", "--max-diff", "0.026"], Bytes),
        (
            "traj-ape-json",
            &["traj", "ape", "truth.tum", "gnss.tum", "--align", "sim3", "--max-diff", "0.026", "--json"],
            Bytes,
        ),
        ("traj-rpe", &["traj", "rpe", "truth.tum", "vo.tum", "--delta", "0.5"], Bytes),
        (
            "anchor",
            &["anchor", "--vo", "vo.tum", "--gnss", "gnss.tum", "--speed", "speed.csv", "-o", "anchored.tum"],
            Bytes,
        ),
        ("anchor-json", &["anchor", "--vo", "vo.tum", "--gnss", "gnss.tum", "--json"], Bytes),
        ("map-build", &["map", "build", "road.osm", "-o", "mcu-road.map", "--origin", "60.2711,24.8572"], Bytes),
        (
            "scenario-generate",
            &[
                "scenario",
                "generate",
                "--profile",
                "typical",
                "--receiver",
                "good",
                "--seed",
                "3",
                "--duration",
                "20",
                "-o",
                "drive",
            ],
            Bytes,
        ),
        (
            "map-build-scenario",
            &["map", "build", "drive/road.osm", "-o", "road.map", "--origin", "60.2711,24.8572"],
            Bytes,
        ),
        ("nmea-decode", &["nmea", "decode", "drive/gnss.nmea"], Bytes),
        ("can-decode", &["can", "decode", "drive/speed.can.log"], Bytes),
        ("track2d", &["track2d", "drive/det2d.txt", "-o", "tracks2d.txt"], Bytes),
        ("mot-eval", &["mot", "eval", "drive/gt2d.txt", "tracks2d.txt"], Bytes),
        (
            "record-mcu",
            &[
                "record",
                "--replay",
                "mcu.d2sin",
                "--map",
                "mcu.d2smap",
                "--device-id",
                "dash2sim-mcu",
                "-o",
                "mcu.d2slog",
            ],
            Bytes,
        ),
        (
            "record-json",
            &[
                "record",
                "-o",
                "drive.d2slog",
                "--vo",
                "drive/vo.csv",
                "--nmea",
                "drive/gnss.serial.log",
                "--can",
                "drive/speed.can.log",
                "--detections",
                "drive/detections3d.csv",
                "--detections2d",
                "drive/det2d.txt",
                "--map",
                "road.map",
                "--json",
            ],
            Bytes,
        ),
        ("inspect", &["inspect", "mcu.d2slog"], Bytes),
        ("inspect-json", &["inspect", "mcu.d2slog", "--json"], Bytes),
        ("verify", &["verify", "mcu.d2slog", "--map", "mcu.d2smap"], Bytes),
        ("verify-json", &["verify", "mcu.d2slog", "--map", "mcu.d2smap", "--json"], Bytes),
        (
            "verify-truth",
            &["verify", "--map", "road.map", "--ego", "drive/ego.tum", "--objects", "drive/objects.csv"],
            Bytes,
        ),
        ("finish", &["finish", "drive.d2slog", "-o", "finished.d2slog"], Bytes),
        ("finish-json", &["finish", "drive.d2slog", "-o", "finished-again.d2slog", "--json"], Bytes),
        (
            "export",
            &[
                "export",
                "finished.d2slog",
                "--mcap",
                "finished.mcap",
                "--tum",
                "finished.tum",
                "--geojson",
                "finished.geojson",
            ],
            Bytes,
        ),
        ("export-parquet", &["export", "finished.d2slog", "--parquet", "finished.parquet"], Bytes),
        ("export-nuplan-too-short", &["export", "finished.d2slog", "--nuplan", "nuplan", "--map", "road.map"], Names),
        (
            "export-nuplan",
            &["export", "finished.d2slog", "--nuplan", "nuplan", "--map", "road.map", "--scenario-seconds", "2"],
            Names,
        ),
        (
            "plot",
            &["plot", "drive.d2slog", "--map", "road.map", "--finished", "finished.d2slog", "-o", "plot.png"],
            Names,
        ),
        (
            "import",
            &[
                "import",
                "-o",
                "imported.d2slog",
                "--nmea",
                "drive/gnss.nmea",
                "--nmea-offset",
                "-1780300800",
                "--traj",
                "drive/ego.tum",
                "--objects",
                "drive/objects.csv",
                "--origin",
                "60.2711,24.8572",
            ],
            Bytes,
        ),
        (
            "scenario-sweep",
            &["scenario", "sweep", "--seeds", "7001", "--driver", "careful", "-o", "sweep", "-q"],
            Names,
        ),
        ("error-inspect-not-a-log", &["inspect", "truth.tum"], Bytes),
        ("error-traj-missing-file", &["traj", "ape", "missing.tum", "gnss.tum"], Bytes),
        (
            "error-finish-bad-anchors",
            &["finish", "drive.d2slog", "-o", "never.d2slog", "--anchors", "bad-anchors.csv"],
            Bytes,
        ),
        ("error-no-command", &[], Bytes),
    ];
    std::fs::write(dir.join("bad-anchors.csv"), "t,lat,lon,alt,sigma_m\n12.5,60.27,north,0,0.3\n").expect("write");
    let mut mismatches = Vec::new();
    for (name, args, written) in cases {
        mismatches.extend(check(name, &run(&dir, args, *written)));
    }
    assert_all(mismatches);
}
