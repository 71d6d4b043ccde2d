//! What every command's `--json` output shares: the library's typed reports as JSON.

use dash2sim_linux::{Error, Result};

/// A report as the JSON `--json` prints: keys sorted, whatever order the struct declares them
/// in (the output is the same byte for byte as when the reports were built as JSON).
pub fn json_of(report: &impl serde::Serialize) -> Result<serde_json::Value> {
    serde_json::to_value(report).map_err(Error::other)
}
