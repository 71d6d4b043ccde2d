//! `dash2sim nmea decode` and `dash2sim can decode`: a capture decoded, one line per fix or
//! message on stdout (JSON lines or a table), problems on stderr with their line numbers,
//! and the summary. A closed stdout (`| head`) ends the output quietly.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use dash2sim_can::candump::CandumpReader;
use dash2sim_core::nmea::GnssFix;
use dash2sim_linux::ingest::can::{self, CanDecoder};
use dash2sim_linux::ingest::nmea::{self, tpv_json};
use dash2sim_linux::utc::iso8601;
use dash2sim_linux::{Error, Result};
use serde_json::Value;

/// `dash2sim nmea decode FILE [--json]`.
pub fn nmea(path: &Path, as_json: bool) -> Result<()> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let name = path.display();
    let decoded = nmea::decode(
        &bytes,
        |fix| writeln!(out, "{}", if as_json { tpv_json(fix).to_string() } else { fix_row(fix) }),
        |line, problem| eprintln!("{name}:{line}: {problem}"),
    );
    let written = decoded.and_then(|summary| {
        if as_json {
            writeln!(out, "{summary}")?;
        } else {
            eprintln!("{summary}");
        }
        out.flush()
    });
    ended(written)
}

/// `dash2sim can decode FILE [--dbc F]... [--json]`.
pub fn can(path: &Path, dbcs: &[PathBuf], as_json: bool) -> Result<()> {
    let (table, warnings) = can::load_tables(dbcs)?;
    for warning in &warnings {
        eprintln!("{warning}");
    }
    let file = std::fs::File::open(path).map_err(|e| Error::file(path, e))?;
    let mut source = CandumpReader::new(std::io::BufReader::new(file));
    let mut decoder = CanDecoder::new(table);
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let name = path.display();
    let summary = match can::decode_source(
        &mut source,
        &mut decoder,
        |value| writeln!(out, "{}", if as_json { value.to_string() } else { message_row(&value) }),
        |line, problem| eprintln!("{name}:{line}: {problem}"),
    ) {
        Ok(summary) => can::summary_json(&summary, &decoder),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(()),
        Err(e) => return Err(Error::invalid(format!("{name}: {e}"))),
    };
    let written = if as_json {
        writeln!(out, "{summary}").and_then(|()| out.flush())
    } else {
        eprintln!("{summary}");
        out.flush()
    };
    ended(written)
}

/// A write's outcome: a closed pipe is the reader's choice, not an error.
fn ended(written: std::io::Result<()>) -> Result<()> {
    match written {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(Error::invalid(format!("writing output: {e}"))),
        _ => Ok(()),
    }
}

/// One fix as a table row.
fn fix_row(fix: &GnssFix) -> String {
    let t = fix.time().map_or_else(|| "-".to_owned(), |t| iso8601(t.micros()));
    let f = |v: Option<f64>, p: usize| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.p$}"));
    let position = |v: Option<f64>| f(v.filter(|_| fix.has_position()), 9);
    format!(
        "{t:24} mode {} lat {:>13} lon {:>14} alt {:>9} speed {:>7} track {:>8} hdop {:>5} sats {}",
        fix.mode.gpsd(),
        position(fix.lat),
        position(fix.lon),
        f(fix.alt_msl, 2),
        f(fix.speed_mps, 3),
        f(fix.track_deg, 2),
        f(fix.hdop, 2),
        fix.satellites_used.map_or_else(|| "-".to_owned(), |n| n.to_string())
    )
}

/// One CAN message as a human-readable line.
fn message_row(value: &Value) -> String {
    let t = value.get("t").and_then(Value::as_f64).map_or_else(|| "-".to_owned(), |t| format!("{t:.6}"));
    let what = value
        .get("pgn")
        .map(|p| format!("PGN {p}"))
        .or_else(|| value.get("pid").map(|p| format!("PID {p}")))
        .or_else(|| value.get("message").and_then(Value::as_str).map(str::to_owned))
        .unwrap_or_default();
    let fields = value
        .get("fields")
        .and_then(Value::as_object)
        .map_or_else(String::new, |f| f.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>().join(" "));
    let s = |k: &str| value.get(k).and_then(Value::as_str).unwrap_or_default().to_owned();
    format!("{t:>18} {:6} {:>10} {what:12} {fields}", s("bus"), s("id"))
}
