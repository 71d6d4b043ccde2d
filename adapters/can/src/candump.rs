//! can-utils `candump` text, in the three dialects found in real captures:
//!
//! | dialect | example |
//! |---|---|
//! | old (candump ≤ 2010), after an `interface = can0, …` header | `<0x18eeff01> [8] 05 a0 be 1c 00 a0 a0 c0` |
//! | default, optionally with `-t` timestamps | `  can0  09F8027F   [8]  00 FC FF FF 00 00 FF FF` |
//! | `-l` log | `(1502984866.421964) slcan0 09F112CC#FF725AFF7FFF7FFD` |
//!
//! Identifiers printed with more than 3 hex digits are extended (29-bit), as candump
//! prints them. Timestamps are parsed exactly (integer microseconds, no float rounding).
//! Remote frames (`#R`, `remote request`) are read; CAN FD (`##`) is reported as such.

use std::io::{BufRead, Write};

use dash2sim_core::can::frame::{id_from_raw, raw_id};
use dash2sim_core::can::CanFrame;
use dash2sim_core::time::Timestamp;
use embedded_can::{Frame, Id};

pub use crate::source::ParseError;
use crate::source::{FrameSource, InterfaceName, Record, SourceError, SourceErrorKind};

/// One parsed line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Line<'a> {
    /// Blank or `#` comment.
    Comment,
    /// Old-dialect header naming the interface of the lines that follow.
    Header {
        /// The interface.
        interface: &'a str,
    },
    /// A frame; the old dialect carries no interface.
    Frame {
        /// Timestamp, when printed.
        time: Option<Timestamp>,
        /// Interface, when printed.
        interface: Option<&'a str>,
        /// The frame.
        frame: CanFrame,
    },
}

/// Parse one line of any dialect (a trailing CR is ignored).
pub fn parse_line(line: &str) -> Result<Line<'_>, ParseError> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(Line::Comment);
    }
    if let Some(rest) = line.strip_prefix("interface").and_then(|r| r.trim_start().strip_prefix('=')) {
        let interface = rest.split(',').next().unwrap_or_default().trim();
        return if interface.is_empty() { Err(ParseError::BadInterface) } else { Ok(Line::Header { interface }) };
    }
    let mut tokens = line.split_ascii_whitespace();
    let mut token = tokens.next().ok_or(ParseError::Unrecognized)?;
    let mut time = None;
    if let Some(stamp) = token.strip_prefix('(') {
        time = Some(parse_timestamp(stamp.strip_suffix(')').ok_or(ParseError::BadTimestamp)?)?);
        token = tokens.next().ok_or(ParseError::Unrecognized)?;
    }
    if let Some(id) = token.strip_prefix("<0x").and_then(|t| t.strip_suffix('>')) {
        let frame = parse_spaced(id, tokens)?;
        return Ok(Line::Frame { time, interface: None, frame });
    }
    let interface = token;
    if interface.len() > 15 {
        return Err(ParseError::BadInterface);
    }
    let body = tokens.next().ok_or(ParseError::Unrecognized)?;
    let frame = match body.split_once('#') {
        Some((id, data)) => {
            if tokens.next().is_some() {
                return Err(ParseError::Unrecognized);
            }
            parse_compact(id, data)?
        }
        None => parse_spaced(body, tokens)?,
    };
    Ok(Line::Frame { time, interface: Some(interface), frame })
}

/// `seconds.fraction` to microseconds, exactly.
fn parse_timestamp(text: &str) -> Result<Timestamp, ParseError> {
    let (secs, frac) = text.split_once('.').unwrap_or((text, ""));
    let all_digits = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    if secs.is_empty() || !all_digits(secs) || !all_digits(frac) || frac.len() > 9 {
        return Err(ParseError::BadTimestamp);
    }
    let secs: i64 = secs.parse().map_err(|_| ParseError::BadTimestamp)?;
    let mut micros: i64 = 0;
    for i in 0..6 {
        micros = micros * 10 + frac.as_bytes().get(i).map_or(0, |b| i64::from(b - b'0'));
    }
    secs.checked_mul(1_000_000)
        .and_then(|s| s.checked_add(micros))
        .map(Timestamp::from_micros)
        .ok_or(ParseError::BadTimestamp)
}

fn parse_id(text: &str) -> Result<Id, ParseError> {
    if text.is_empty() || text.len() > 8 {
        return Err(ParseError::BadId);
    }
    let raw = u32::from_str_radix(text, 16).map_err(|_| ParseError::BadId)?;
    id_from_raw(raw, text.len() > 3).ok_or(ParseError::BadId)
}

fn hex_byte(text: &[u8]) -> Result<u8, ParseError> {
    let digit = |b: u8| (b as char).to_digit(16).ok_or(ParseError::BadData);
    match text {
        [hi, lo] => Ok((digit(*hi)? * 16 + digit(*lo)?) as u8),
        _ => Err(ParseError::BadData),
    }
}

/// `-l` body: `ID#DATA`, `ID#R`, `ID#R5`.
fn parse_compact(id: &str, data: &str) -> Result<CanFrame, ParseError> {
    let id = parse_id(id)?;
    if data.starts_with('#') {
        return Err(ParseError::CanFd);
    }
    if let Some(dlc) = data.strip_prefix('R') {
        let dlc = if dlc.is_empty() { 0 } else { dlc.parse().map_err(|_| ParseError::BadLength)? };
        return CanFrame::remote(id, dlc).ok_or(ParseError::BadLength);
    }
    // can-utils accepts '.' separators between bytes.
    let mut bytes = [0u8; 8];
    let mut len = 0;
    let digits = data.as_bytes();
    let mut i = 0;
    while i < digits.len() {
        if digits[i] == b'.' {
            i += 1;
            continue;
        }
        let byte = hex_byte(digits.get(i..i + 2).ok_or(ParseError::BadData)?)?;
        *bytes.get_mut(len).ok_or(ParseError::TooManyBytes)? = byte;
        len += 1;
        i += 2;
    }
    CanFrame::data_frame(id, &bytes[..len]).ok_or(ParseError::TooManyBytes)
}

/// Default and old bodies: `ID [n] b0 b1 …` or `ID [n] remote request`.
fn parse_spaced<'a>(id: &str, mut tokens: impl Iterator<Item = &'a str>) -> Result<CanFrame, ParseError> {
    let id = parse_id(id)?;
    let len = tokens.next().ok_or(ParseError::BadLength)?;
    let announced: usize = len
        .strip_prefix('[')
        .and_then(|l| l.strip_suffix(']'))
        .and_then(|l| l.parse().ok())
        .filter(|&n| n <= 8)
        .ok_or(ParseError::BadLength)?;
    let mut bytes = [0u8; 8];
    let mut found = 0;
    for token in tokens {
        if token == "remote" {
            return CanFrame::remote(id, announced).ok_or(ParseError::BadLength);
        }
        let byte = hex_byte(token.as_bytes())?;
        *bytes.get_mut(found).ok_or(ParseError::TooManyBytes)? = byte;
        found += 1;
    }
    if found != announced {
        return Err(ParseError::LengthMismatch { announced, found });
    }
    CanFrame::data_frame(id, &bytes[..found]).ok_or(ParseError::TooManyBytes)
}

/// Write `frame` as one `candump -l` line: `(seconds.micros) interface ID#DATA`.
pub fn write_log_line(out: &mut impl Write, time: Timestamp, interface: &str, frame: &CanFrame) -> std::io::Result<()> {
    let micros = time.micros();
    let (secs, frac) = (micros.div_euclid(1_000_000), micros.rem_euclid(1_000_000));
    write!(out, "({secs:010}.{frac:06}) {interface} ")?;
    if frame.is_extended() {
        write!(out, "{:08X}#", raw_id(frame.id()))?;
    } else {
        write!(out, "{:03X}#", raw_id(frame.id()))?;
    }
    if frame.is_remote_frame() {
        if frame.dlc() > 0 {
            write!(out, "R{}", frame.dlc())?;
        } else {
            write!(out, "R")?;
        }
    } else {
        for byte in frame.data() {
            write!(out, "{byte:02X}")?;
        }
    }
    writeln!(out)
}

/// Replays a candump file of any dialect, line by line.
#[derive(Debug)]
pub struct CandumpReader<R> {
    input: R,
    line: String,
    line_number: u64,
    /// Interface for old-dialect lines (from the last `interface = …` header).
    header_interface: InterfaceName,
}

impl<R: BufRead> CandumpReader<R> {
    /// Read from `input`. Old-dialect lines before any header are on `can0`.
    pub fn new(input: R) -> Self {
        CandumpReader {
            input,
            line: String::new(),
            line_number: 0,
            header_interface: InterfaceName::try_from("can0").unwrap_or_default(),
        }
    }

    /// The 1-based number of the line last read.
    pub fn line_number(&self) -> u64 {
        self.line_number
    }
}

impl<R: BufRead> FrameSource for CandumpReader<R> {
    fn next_frame(&mut self) -> Option<Result<Record, SourceError>> {
        loop {
            self.line.clear();
            self.line_number += 1;
            let error = |kind, line| Some(Err(SourceError { line: Some(line), kind }));
            match self.input.read_line(&mut self.line) {
                Ok(0) => return None,
                Ok(_) => {}
                Err(e) => return error(SourceErrorKind::Io(e), self.line_number),
            }
            match parse_line(&self.line) {
                Ok(Line::Comment) => {}
                Ok(Line::Header { interface }) => match InterfaceName::try_from(interface) {
                    Ok(name) => self.header_interface = name,
                    Err(_) => return error(SourceErrorKind::Parse(ParseError::BadInterface), self.line_number),
                },
                Ok(Line::Frame { time, interface, frame }) => {
                    let interface = match interface {
                        Some(name) => InterfaceName::try_from(name).unwrap_or_default(),
                        None => self.header_interface.clone(),
                    };
                    return Some(Ok(Record { time, interface, frame }));
                }
                Err(e) => return error(SourceErrorKind::Parse(e), self.line_number),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(line: &str) -> (Option<Timestamp>, Option<&str>, CanFrame) {
        match parse_line(line) {
            Ok(Line::Frame { time, interface, frame }) => (time, interface, frame),
            other => panic!("{line:?} → {other:?}"),
        }
    }

    fn ext(raw: u32) -> Id {
        id_from_raw(raw, true).expect("29-bit")
    }

    #[test]
    fn three_dialects() {
        let (t, i, f) = frame("<0x18eeff01> [8] 05 a0 be 1c 00 a0 a0 c0 ");
        assert_eq!((t, i), (None, None));
        assert_eq!(f, CanFrame::data_frame(ext(0x18EE_FF01), &[5, 0xA0, 0xBE, 0x1C, 0, 0xA0, 0xA0, 0xC0]).expect("8"));
        let (t, i, f) = frame("  can0  09F8027F   [8]  00 FC FF FF 00 00 FF FF");
        assert_eq!(
            (t, i, f.raw_id(), f.data()),
            (None, Some("can0"), 0x09F8_027F, &[0, 0xFC, 0xFF, 0xFF, 0, 0, 0xFF, 0xFF][..])
        );
        let (t, i, f) = frame("(1502984866.421964) slcan0 09F112CC#FF725AFF7FFF7FFD\r\n");
        assert_eq!(t, Some(Timestamp::from_micros(1_502_984_866_421_964)));
        assert_eq!((i, f.raw_id(), f.dlc(), f.is_extended()), (Some("slcan0"), 0x09F1_12CC, 8, true));
        let (_, _, f) = frame("(46408.584930) can0 260#08FFFB0000001884");
        assert!(f.is_standard());
        assert_eq!(f.raw_id(), 0x260);
        let (t, _, _) = frame("(0000000000.352000) vcan0 09F20101#601A00B706670D0B");
        assert_eq!(t, Some(Timestamp::from_micros(352_000)));
        let (t, _, _) = frame("(12.5) can0 123#");
        assert_eq!(t, Some(Timestamp::from_micros(12_500_000)));
    }

    #[test]
    fn headers_comments_and_remote_frames() {
        assert_eq!(
            parse_line("interface = can0, family = 29, type = 3, proto = 1"),
            Ok(Line::Header { interface: "can0" })
        );
        assert_eq!(parse_line("# Name: NMEA2000 Bus"), Ok(Line::Comment));
        assert_eq!(parse_line("  \r\n"), Ok(Line::Comment));
        let (_, _, f) = frame("(1.0) can0 7DF#R");
        assert!(f.is_remote_frame() && f.dlc() == 0);
        let (_, _, f) = frame("(1.0) can0 7DF#R8");
        assert!(f.is_remote_frame() && f.dlc() == 8);
        let (_, _, f) = frame("  can0  7DF   [8]  remote request");
        assert!(f.is_remote_frame() && f.dlc() == 8);
    }

    #[test]
    fn garbage_is_named_not_panicked_on() {
        let cases: &[(&str, ParseError)] = &[
            ("(1.x) can0 123#00", ParseError::BadTimestamp),
            ("(1.0 can0 123#00", ParseError::BadTimestamp),
            ("(99999999999999999.0) can0 123#00", ParseError::BadTimestamp),
            ("(1.0) can0 12G#00", ParseError::BadId),
            ("(1.0) can0 800#00", ParseError::BadId),
            ("(1.0) can0 123456789#00", ParseError::BadId),
            ("(1.0) can0 123#0", ParseError::BadData),
            ("(1.0) can0 123#000102030405060708", ParseError::TooManyBytes),
            ("(1.0) can0 123##1000102", ParseError::CanFd),
            ("(1.0) can0 123#R9", ParseError::BadLength),
            ("  can0  123   [9]  00", ParseError::BadLength),
            ("  can0  123   [3]  00 01", ParseError::LengthMismatch { announced: 3, found: 2 }),
            ("  can0  123   [1]  0x", ParseError::BadData),
            ("<0x123> 8 00", ParseError::BadLength),
            ("hello", ParseError::Unrecognized),
            ("(1.0) averyveryverylongname 123#00", ParseError::BadInterface),
            ("interface = ", ParseError::BadInterface),
            ("(1.0) can0 123#00 trailing", ParseError::Unrecognized),
            ("(1.0) can0 123#ü0", ParseError::BadData),
        ];
        for (line, expected) in cases {
            assert_eq!(parse_line(line), Err(*expected), "{line:?}");
        }
    }

    #[test]
    fn writer_round_trips_through_the_reader() {
        let frames = [
            (
                "can0",
                Timestamp::from_micros(1_627_275_000_169_400),
                CanFrame::data_frame(id_from_raw(0x7E8, false).expect("11-bit"), &[3, 0x41, 0x0D, 0x39]).expect("4"),
            ),
            ("can1", Timestamp::from_micros(5), CanFrame::data_frame(ext(0x09F8_0102), &[]).expect("0")),
            ("vcan0", Timestamp::from_micros(7), CanFrame::remote(ext(0x18EA_FF00), 3).expect("remote")),
        ];
        let mut text = Vec::new();
        for (interface, t, f) in &frames {
            write_log_line(&mut text, *t, interface, f).expect("vec");
        }
        let text = String::from_utf8(text).expect("ascii");
        assert!(
            text.starts_with("(1627275000.169400) can0 7E8#03410D39\n(0000000000.000005) can1 09F80102#\n"),
            "{text}"
        );
        let mut reader = CandumpReader::new(text.as_bytes());
        for (interface, t, f) in &frames {
            let record = reader.next_frame().expect("line").expect("valid");
            assert_eq!((record.interface.as_str(), record.time, record.frame), (*interface, Some(*t), *f));
        }
        assert!(reader.next_frame().is_none());
    }

    #[test]
    fn reader_reports_line_numbers_and_keeps_going() {
        let text = "interface = can7, family = 29\n<0x18eeff01> [1] 05\nbroken line\n<0x123> [1] 07\n";
        let mut reader = CandumpReader::new(text.as_bytes());
        let first = reader.next_frame().expect("line").expect("valid");
        assert_eq!(first.interface.as_str(), "can7");
        let error = reader.next_frame().expect("line").expect_err("broken");
        assert_eq!(error.to_string(), "line 3: malformed CAN id");
        assert_eq!(reader.next_frame().expect("line").expect("valid").frame.raw_id(), 0x123);
        assert!(reader.next_frame().is_none());
    }
}
