//! What the benches share: where the recorded data lives (`$DASH2SIM_DATA`, default
//! `../shared/data` beside the workspace), and how a bench says it skipped a part.

use std::path::PathBuf;

/// `$DASH2SIM_DATA/<sub>` if it exists; otherwise `None` after saying it is skipped.
pub fn data(sub: &str) -> Option<PathBuf> {
    let base = std::env::var_os("DASH2SIM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let path = base.join(sub);
    if path.exists() {
        return Some(path);
    }
    eprintln!("SKIPPED: {} not found", path.display());
    None
}
