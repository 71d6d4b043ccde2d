//! Shared helpers of the conformance tests: where the real data lives, and how a test
//! says it was skipped.
//!
//! The recordings in `../shared/data` are not part of the repository (their licenses
//! forbid it). Tests find them through `DASH2SIM_DATA`, defaulting to `../shared/data`
//! beside the workspace. When the folder is absent a test prints that it was skipped and
//! why — unless `DASH2SIM_REQUIRE_DATA=1` (CI), where a missing folder fails the test.
#![forbid(unsafe_code)]

use std::path::{Path, PathBuf};

pub mod can;
pub mod drive;
pub mod recorded;
pub mod road;

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

/// `$DASH2SIM_DATA/<sub>` if it exists; otherwise `None` after printing why the calling
/// test is skipped. Panics instead when `DASH2SIM_REQUIRE_DATA=1`.
pub fn data_dir(sub: &str) -> Option<PathBuf> {
    let base =
        std::env::var_os("DASH2SIM_DATA").map(PathBuf::from).unwrap_or_else(|| workspace_root().join("../shared/data"));
    let dir = base.join(sub);
    if dir.is_dir() {
        return Some(dir);
    }
    let required = std::env::var("DASH2SIM_REQUIRE_DATA").is_ok_and(|v| v == "1");
    assert!(!required, "DASH2SIM_REQUIRE_DATA=1 but {} does not exist", dir.display());
    eprintln!("SKIPPED: {} not found (set DASH2SIM_DATA to the shared data folder)", dir.display());
    None
}

/// Read a JSON file.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Relative difference |a − b| / max(|b|, tiny).
pub fn rel_diff(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}
