//! Helpers the command line's test files share: the binary, fixtures, scratch folders.
#![allow(dead_code)] // each test file uses some of them

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn dash2sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dash2sim")).args(args).output().expect("binary runs")
}

pub fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/drive").join(name).display().to_string()
}

/// A scratch folder unique to one test.
pub fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dash2sim-cli-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

pub fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p.display().to_string()
}

/// `scenario generate` of drive `seed` on the ideal profile (the tests that pin its
/// figures test the tools, not the sensors) into `dir`.
pub fn generate_ideal(dir: &Path, seed: &str, duration: &str) -> Output {
    let dir = dir.display().to_string();
    dash2sim(&["scenario", "generate", "--profile", "ideal", "-o", &dir, "--seed", seed, "--duration", duration])
}

/// `demo --offline --json` of seed 1 on the ideal profile into `dir`.
pub fn demo_ideal_offline(dir: &Path, duration: &str) -> Output {
    let dir = dir.display().to_string();
    dash2sim(&["demo", "--profile", "ideal", "-o", &dir, "--duration", duration, "--offline", "--json"])
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `$body*HH` with a correct checksum.
pub fn nmea(body: &str) -> String {
    format!("${body}*{:02X}", body.bytes().fold(0u8, |a, b| a ^ b))
}

pub fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = entry.path();
        if p.is_dir() {
            out.extend(walk(&p));
        }
        out.push(p);
    }
    out
}

/// The shared data folder (`$DASH2SIM_DATA`, else `../shared` beside the checkout), if
/// there; with `DASH2SIM_REQUIRE_DATA=1` it must be.
pub fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("DASH2SIM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    if dir.is_dir() {
        return Some(dir);
    }
    assert!(std::env::var("DASH2SIM_REQUIRE_DATA").as_deref() != Ok("1"), "{} does not exist", dir.display());
    eprintln!("SKIPPED: {} not found", dir.display());
    None
}

/// Rows of a Parquet file and its Arrow schema, read with the parquet crate's own reader.
pub fn parquet_table(path: &Path) -> (usize, Vec<arrow_array::RecordBatch>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let reader = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .expect("parquet")
        .build()
        .expect("reader");
    let batches: Vec<_> = reader.map(|b| b.expect("batch")).collect();
    (batches.iter().map(|b| b.num_rows()).sum(), batches)
}
