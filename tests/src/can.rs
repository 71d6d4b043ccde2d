//! Running `dash2sim can decode`'s library path over a capture, for the CAN tests.

use std::path::{Path, PathBuf};

use dash2sim_can::candump::CandumpReader;
use dash2sim_linux::ingest::can::{decode_source, load_tables, CanDecoder, Summary};
use serde_json::Value;

/// Every message the CLI would print for `capture`, the problems (line, text) and the summary.
pub fn decode_capture(capture: &Path, dbcs: &[PathBuf]) -> (Vec<Value>, Vec<(u64, String)>, Summary) {
    let (table, _) = load_tables(dbcs).unwrap_or_else(|e| panic!("{e}"));
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

/// A CSV file with a header line, its cells as text.
pub fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default().split(',').map(str::to_owned).collect();
    let rows = lines.filter(|l| !l.trim().is_empty()).map(|l| l.split(',').map(str::to_owned).collect()).collect();
    (header, rows)
}

/// Half a unit in the last digit of a printed number (`56.098655` → 5e-7,
/// `1.62727447e+09` → 5), plus a relative 1e-12 for the float arithmetic behind it.
pub fn printed_tolerance(cell: &str) -> f64 {
    let (mantissa, exponent) = match cell.split_once(['e', 'E']) {
        Some((m, e)) => (m, e.parse::<i32>().unwrap_or(0)),
        None => (cell, 0),
    };
    let decimals = mantissa.split_once('.').map_or(0, |(_, f)| f.len() as i32);
    let value: f64 = cell.parse().unwrap_or(0.0);
    0.5 * 10f64.powi(exponent - decimals) + value.abs() * 1e-12
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tolerance_follows_the_printed_digits() {
        assert!((printed_tolerance("56.098655") - 5e-7).abs() < 1e-10);
        assert!((printed_tolerance("1.62727447e+09") - 5.0).abs() < 1e-2);
        assert!((printed_tolerance("29") - 0.5).abs() < 1e-10);
    }
}
