//! `dash2sim can decode FILE [--dbc F.dbc]...`: a candump capture → one JSON object per
//! decoded message, in the shape docs/cli.md gives:
//! `{"t": 1410714882.622188, "bus": "can0", "id": "0x09F80102", "src": 2, "pgn": 129025, "fields": {…}}`.
//!
//! NMEA 2000 messages carry canboat's field names and units (degrees, m/s, metres) and
//! its lookup names; J1939 the SPN names; OBD-II responses `"pid"` and the J1979 name;
//! DBC messages the DBC's message and signal names. A DBC that defines an id takes
//! precedence over the built-in decoders for that id. Every bad line, malformed frame
//! and abandoned fast-packet message is reported on stderr with its line number.

use std::io::BufRead;
use std::path::{Path, PathBuf};

use crate::{Error, Field, Result};
use dash2sim_can::candump::CandumpReader;
use dash2sim_can::source::SourceErrorKind;
use dash2sim_can::{FrameSource, Record, SignalTable};
use dash2sim_core::can::fast_packet::DropReason;
use dash2sim_core::can::n2k::{CogSogRapid, GnssPosition, PositionRapid};
use dash2sim_core::can::{Decoded, Decoder, Event, J1939Id, Message};
use embedded_can::Frame;
use serde_json::{json, Map, Value};

/// Fast-packet messages in flight; a busy NMEA 2000 bus has a handful of senders.
const FAST_PACKET_SLOTS: usize = 16;

/// What a decode saw, beyond the messages themselves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Summary {
    /// Frames read.
    pub frames: u64,
    /// Messages decoded by the built-in decoders.
    pub decoded: u64,
    /// Messages decoded with a DBC.
    pub dbc_decoded: u64,
    /// Lines that were not candump frames.
    pub bad_lines: u64,
    /// Frames of decoded PGNs that were malformed.
    pub bad_frames: u64,
    /// DBC signals the frame was too short to carry.
    pub missing_signals: u64,
    /// Fast-packet messages given up.
    pub dropped_messages: u64,
}

/// What one record produced.
#[derive(Debug, PartialEq)]
pub enum Output {
    /// A decoded message as JSON.
    Message(Value),
    /// A problem, for stderr.
    Problem(String),
}

/// Built-in decoders plus DBC signal tables, over any [`FrameSource`].
#[derive(Debug)]
pub struct CanDecoder {
    decoder: Decoder<FAST_PACKET_SLOTS>,
    table: SignalTable,
    summary: Summary,
}

impl CanDecoder {
    /// A decoder using `table` for DBC-defined ids (empty: built-in decoders only).
    pub fn new(table: SignalTable) -> Self {
        CanDecoder { decoder: Decoder::default(), table, summary: Summary::default() }
    }

    /// Counters so far.
    pub fn summary(&self) -> Summary {
        self.summary
    }

    /// Decode one record; `emit` sees its messages and problems.
    pub fn decode(&mut self, record: &Record, mut emit: impl FnMut(Output)) {
        self.summary.frames += 1;
        let frame = &record.frame;
        if let Some(message) = self.table.message(frame.id()).filter(|_| !frame.is_remote_frame()) {
            let mut fields = Map::new();
            let missing = message.decode(frame.data(), |name, value| {
                fields.insert(name.to_owned(), json!(value));
            });
            self.summary.dbc_decoded += 1;
            self.summary.missing_signals += missing as u64;
            if missing > 0 {
                emit(Output::Problem(format!(
                    "{}: {} of its signals are past the frame's {} bytes",
                    message.name,
                    missing,
                    frame.dlc()
                )));
            }
            let mut o = envelope(record);
            o.insert("message".into(), json!(message.name));
            o.insert("fields".into(), Value::Object(fields));
            emit(Output::Message(Value::Object(o)));
            return;
        }
        let summary = &mut self.summary;
        self.decoder.decode(record.time.unwrap_or_default(), frame, |event| match event {
            Event::Decoded(decoded) => {
                summary.decoded += 1;
                emit(Output::Message(message_json(record, &decoded)));
            }
            Event::Error(e) => {
                summary.bad_frames += 1;
                emit(Output::Problem(e.to_string()));
            }
            Event::Dropped(d) => {
                summary.dropped_messages += 1;
                let why = match d.reason {
                    DropReason::SequenceClash => "a frame index repeated (sequence clash)",
                    DropReason::TimedOut => "frames stopped (timeout)",
                    DropReason::Evicted => "all reassembly slots were busy",
                };
                emit(Output::Problem(format!(
                    "PGN {} from {}: fast-packet message dropped after {} frames: {why}",
                    d.pgn, d.source, d.frames_received
                )));
            }
        });
    }
}

/// Decode every record of `source`; `on_message` gets the JSON objects, `on_problem`
/// (line, text) everything wrong. Returns the summary.
pub fn decode_source<R: BufRead>(
    source: &mut CandumpReader<R>,
    decoder: &mut CanDecoder,
    mut on_message: impl FnMut(Value) -> std::io::Result<()>,
    mut on_problem: impl FnMut(u64, &str),
) -> std::io::Result<Summary> {
    while let Some(next) = source.next_frame() {
        let line = source.line_number();
        match next {
            Ok(record) => {
                let mut result = Ok(());
                decoder.decode(&record, |output| match output {
                    Output::Message(value) => {
                        if result.is_ok() {
                            result = on_message(value);
                        }
                    }
                    Output::Problem(text) => on_problem(line, &text),
                });
                result?;
            }
            Err(e) if matches!(e.kind, SourceErrorKind::Io(_)) => {
                return Err(std::io::Error::other(e.to_string()));
            }
            Err(e) => {
                decoder.summary.bad_lines += 1;
                on_problem(line, e.to_string().trim_start_matches(&format!("line {line}: ")));
            }
        }
    }
    Ok(decoder.summary())
}

/// The unit a DBC speed signal is in (km/h unless named).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpeedUnit {
    /// km/h (`km/h` or `kph`).
    #[default]
    KilometresPerHour,
    /// m/s.
    MetresPerSecond,
    /// Miles per hour.
    MilesPerHour,
}

impl SpeedUnit {
    /// Metres per second in one of this unit.
    pub fn to_mps(self) -> f64 {
        match self {
            SpeedUnit::KilometresPerHour => 1.0 / 3.6,
            SpeedUnit::MetresPerSecond => 1.0,
            SpeedUnit::MilesPerHour => 0.44704,
        }
    }
}

impl std::str::FromStr for SpeedUnit {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        match text {
            "km/h" | "kph" => Ok(SpeedUnit::KilometresPerHour),
            "m/s" => Ok(SpeedUnit::MetresPerSecond),
            "mph" => Ok(SpeedUnit::MilesPerHour),
            other => Err(Error::invalid(format!("{other:?} is not a speed unit: expected km/h, m/s or mph"))),
        }
    }
}

/// A DBC signal named `MESSAGE.SIGNAL`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SignalName {
    /// The message's name.
    pub message: String,
    /// The signal's name within it.
    pub signal: String,
}

impl std::str::FromStr for SignalName {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        match text.split_once('.') {
            Some((message, signal)) if !message.is_empty() && !signal.is_empty() => {
                Ok(SignalName { message: message.to_owned(), signal: signal.to_owned() })
            }
            _ => Err(Error::invalid(format!("{text:?}: expected MESSAGE.SIGNAL"))),
        }
    }
}

impl std::fmt::Display for SignalName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{}", self.message, self.signal)
    }
}

/// Load and merge DBC files (later files win on equal ids); the warnings, `FILE: what`,
/// of what was skipped in them. `FILE@+OFFSET` (or `@-OFFSET`, decimal or `0x` hex) moves
/// every id of the file by the offset: a module configured to another base id.
pub fn load_tables(paths: &[PathBuf]) -> Result<(SignalTable, Vec<String>)> {
    let mut table = SignalTable::default();
    let mut warnings = Vec::new();
    for given in paths {
        let (path, offset) = id_offset(given)?;
        let (one, found) = SignalTable::load(&path).map_err(|e| Error::file(&path, e))?;
        let one = if offset == 0 { one } else { one.shifted(offset).map_err(|e| Error::file(given, e))? };
        warnings.extend(found.iter().map(|w| format!("{}: {w}", path.display())));
        table.extend(one);
    }
    Ok((table, warnings))
}

/// A DBC file as given split into the file and its id offset (`FILE@+0x64`); a file whose
/// own name has such an ending is taken whole.
fn id_offset(given: &Path) -> Result<(PathBuf, i64)> {
    let text = given.to_string_lossy();
    let Some((file, suffix)) = text.rsplit_once('@') else { return Ok((given.to_path_buf(), 0)) };
    if given.exists() || !suffix.starts_with(['+', '-']) {
        return Ok((given.to_path_buf(), 0));
    }
    let (sign, digits) = suffix.split_at(1);
    let value = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        Some(hex) => i64::from_str_radix(hex, 16),
        None => digits.parse::<i64>(),
    }
    .map_err(|_| {
        Error::request(Field::Dbc, format!("{text}: the id offset {suffix:?} is not +N or -N (decimal or 0x hex)"))
    })?;
    Ok((PathBuf::from(file), if sign == "-" { -value } else { value }))
}

/// A decode's summary as `dash2sim can decode` prints it (`class` `SUMMARY`), with the
/// decoder's fast-packet and ignored-frame counts.
pub fn summary_json(summary: &Summary, decoder: &CanDecoder) -> Value {
    let fp = decoder.decoder.fast_packet_stats();
    json!({
        "class": "SUMMARY",
        "frames": summary.frames,
        "decoded": summary.decoded,
        "dbc_decoded": summary.dbc_decoded,
        "ignored": decoder.decoder.stats().ignored,
        "bad_lines": summary.bad_lines,
        "bad_frames": summary.bad_frames,
        "missing_signals": summary.missing_signals,
        "fast_packet": {
            "completed": fp.completed,
            "rejected_frames": fp.rejected_frames,
            "clashed": fp.clashed,
            "timed_out": fp.timed_out,
            "evicted": fp.evicted,
        },
    })
}

/// `t`, `bus` and `id` of every output object.
fn envelope(record: &Record) -> Map<String, Value> {
    let mut o = Map::new();
    if let Some(t) = record.time {
        // Via the decimal text, so the double printed is the one nearest the log's digits.
        let micros = t.micros();
        let text = format!("{}.{:06}", micros.div_euclid(1_000_000), micros.rem_euclid(1_000_000));
        o.insert("t".into(), json!(text.parse::<f64>().unwrap_or(t.as_secs_f64())));
    }
    o.insert("bus".into(), json!(record.interface.as_str()));
    let raw = record.frame.raw_id();
    o.insert(
        "id".into(),
        json!(if record.frame.is_extended() { format!("0x{raw:08X}") } else { format!("0x{raw:03X}") }),
    );
    o
}

/// A decoded message as its JSON object.
pub fn message_json(record: &Record, decoded: &Decoded) -> Value {
    let mut o = envelope(record);
    if let Some(J1939Id { priority, pgn, source, destination }) = decoded.header {
        o.insert("prio".into(), json!(priority));
        o.insert("src".into(), json!(source));
        o.insert("dst".into(), json!(destination));
        if !matches!(decoded.message, Message::Obd(_)) {
            o.insert("pgn".into(), json!(pgn));
        }
    }
    let mut fields = Map::new();
    let mut put = |k: &str, v: Value| {
        fields.insert(k.to_owned(), v);
    };
    let description = match &decoded.message {
        Message::PositionRapid(PositionRapid { latitude, longitude }) => {
            put_opt(&mut put, "Latitude", *latitude);
            put_opt(&mut put, "Longitude", *longitude);
            "Position, Rapid Update"
        }
        Message::CogSogRapid(m) => cog_sog_fields(m, &mut put),
        Message::GnssPosition(m) => gnss_position_fields(m, &mut put),
        Message::WheelSpeed(m) => {
            put_opt(&mut put, "Wheel-Based Vehicle Speed", m.speed_kmh.map(|v| v / 3.6));
            "Cruise Control/Vehicle Speed 1"
        }
        Message::VehiclePosition(m) => {
            put_opt(&mut put, "Latitude", m.latitude);
            put_opt(&mut put, "Longitude", m.longitude);
            "Vehicle Position 1"
        }
        Message::Obd(r) => {
            o.insert("service".into(), json!(1));
            o.insert("pid".into(), json!(r.pid));
            o.insert("ecu".into(), json!(r.ecu));
            match r.vehicle_speed_kmh() {
                Some(kmh) => put("Vehicle Speed", json!(kmh)),
                None => {
                    for (name, byte) in ["A", "B", "C", "D"].iter().zip(r.data()) {
                        put(name, json!(byte));
                    }
                }
            }
            if r.pid == dash2sim_core::can::obd::VEHICLE_SPEED {
                "Vehicle Speed"
            } else {
                "OBD-II Mode 01 Response"
            }
        }
    };
    o.insert("description".into(), json!(description));
    o.insert("fields".into(), Value::Object(fields));
    Value::Object(o)
}

fn put_opt<T: serde::Serialize>(put: &mut impl FnMut(&str, Value), key: &str, value: Option<T>) {
    if let Some(v) = value {
        put(key, json!(v));
    }
}

fn cog_sog_fields(m: &CogSogRapid, put: &mut impl FnMut(&str, Value)) -> &'static str {
    put_opt(put, "SID", m.sid);
    put("COG Reference", json!(m.cog_reference.name()));
    put_opt(put, "COG", m.cog);
    put_opt(put, "SOG", m.sog);
    "COG & SOG, Rapid Update"
}

fn gnss_position_fields(m: &GnssPosition, put: &mut impl FnMut(&str, Value)) -> &'static str {
    put_opt(put, "SID", m.sid);
    put_opt(put, "Date", m.date.map(canboat_date));
    put_opt(put, "Time", m.time.map(canboat_time));
    put_opt(put, "Latitude", m.latitude);
    put_opt(put, "Longitude", m.longitude);
    put_opt(put, "Altitude", m.altitude);
    put_opt(put, "GNSS type", m.gnss_type_name());
    put_opt(put, "Method", m.method_name());
    put_opt(put, "Integrity", m.integrity_name());
    put_opt(put, "Number of SVs", m.satellites);
    put_opt(put, "HDOP", m.hdop);
    put_opt(put, "PDOP", m.pdop);
    put_opt(put, "Geoidal Separation", m.geoidal_separation);
    put_opt(put, "Reference Stations", m.reference_stations);
    "GNSS Position Data"
}

/// Days since 1970 as canboat prints them: `2013.03.01`.
fn canboat_date(days: u16) -> String {
    let iso = crate::utc::iso8601(i64::from(days) * 86_400_000_000);
    iso.get(..10).unwrap_or_default().replace('-', ".")
}

/// 0.1 ms units since midnight as canboat prints them: `19:28:16.0000`.
fn canboat_time(units: u32) -> String {
    let secs = units / 10_000;
    format!("{:02}:{:02}:{:02}.{:04}", secs / 3600, secs / 60 % 60, secs % 60, units % 10_000)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canboat_date_and_time_format() {
        assert_eq!(canboat_date(15_765), "2013.03.01");
        assert_eq!(canboat_time(700_960_000), "19:28:16.0000");
        assert_eq!(canboat_time(177_700_005), "04:56:10.0005");
    }
}
