//! Running `dash2sim can decode`'s library path over a capture, for the CAN tests.

use std::path::{Path, PathBuf};

use dash2sim_can::candump::CandumpReader;
use dash2sim_linux::can_decode::{decode_source, load_tables, CanDecoder, Summary};
use serde_json::Value;

/// Every message the CLI would print for `capture`, the problems (line, text) and the summary.
pub fn decode_capture(capture: &Path, dbcs: &[PathBuf]) -> (Vec<Value>, Vec<(u64, String)>, Summary) {
    let table = load_tables(dbcs).unwrap_or_else(|e| panic!("{e}"));
    let file = std::fs::File::open(capture).unwrap_or_else(|e| panic!("{}: {e}", capture.display()));
    let mut source = CandumpReader::new(std::io::BufReader::new(file));
    let mut decoder = CanDecoder::new(table);
    let mut messages = Vec::new();
    let mut problems = Vec::new();
    let summary = decode_source(
        &mut source,
        &mut decoder,
        |value| {
            messages.push(value);
            Ok(())
        },
        |line, text| problems.push((line, text.to_owned())),
    )
    .unwrap_or_else(|e| panic!("{}: {e}", capture.display()));
    (messages, problems, summary)
}

/// Rows of a CSV file with a header line, as numbers (empty cells are NaN).
pub fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default().split(',').map(str::to_owned).collect();
    let rows = lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split(',').map(|c| if c.is_empty() { f64::NAN } else { c.parse().unwrap_or(f64::NAN) }).collect())
        .collect();
    (header, rows)
}
