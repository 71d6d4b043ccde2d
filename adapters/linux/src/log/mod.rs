//! The 4D log on the desktop: reading a whole file through the core's push decoder,
//! `dash2sim import` (existing recordings → log), `inspect` and `export` (MCAP with
//! Foxglove schemas, TUM, GeoJSON). The format is the core's (`docs/binlog.md`).

pub mod export;
pub mod import;
pub mod inspect;
pub mod mcap_export;
#[cfg(feature = "parquet")]
pub mod parquet_export;
pub mod signing;

use std::path::Path;

use dash2sim_core::binlog::{Decoder, Event, Header, HeaderError, Record, Stats};
use dash2sim_core::geo::{Geodetic, LocalFrame};

/// Everything a log file held, as far as it could be read.
#[derive(Debug)]
pub struct LogContents {
    /// The header, if intact.
    pub header: Option<Header>,
    /// Intact records in file order.
    pub records: Vec<Record>,
    /// Damaged stretches: (offset, length).
    pub damage: Vec<(u64, u64)>,
    /// Decoder totals.
    pub stats: Stats,
    /// File length.
    pub bytes: u64,
    /// The segment starts and signature trailers in file order, for a
    /// [`SealCheck`](dash2sim_core::binlog::signature::SealCheck) ([`signing`]).
    pub signing: Vec<Event>,
}

/// Why a file could not be read as a log at all.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// It could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// It is not a dash2sim log (its name, and what its header says).
    #[error("{0}: {1}")]
    NotALog(String, #[source] HeaderError),
}

/// Decode `bytes` completely.
pub fn decode(bytes: &[u8], name: &str) -> Result<LogContents, LogError> {
    let mut decoder: Box<Decoder> = Box::default();
    let mut contents = LogContents {
        header: None,
        records: Vec::new(),
        damage: Vec::new(),
        stats: Stats::default(),
        bytes: bytes.len() as u64,
        signing: Vec::new(),
    };
    let mut fatal = None;
    let mut on = |event: Event| match event {
        Event::Header(h) => contents.header = Some(h),
        Event::NotALog(e) => fatal = Some(e),
        Event::Record(r) => contents.records.push(r),
        Event::Damaged { offset, len } => contents.damage.push((offset, len)),
        e @ (Event::Segment { .. } | Event::Signature { .. }) => contents.signing.push(e),
        Event::Index { .. } | Event::Unknown { .. } | Event::Lost(_) => {}
    };
    for chunk in bytes.chunks(64 * 1024) {
        decoder.push(chunk, &mut on);
    }
    decoder.finish(&mut on);
    if let Some(e) = fatal {
        return Err(LogError::NotALog(name.to_owned(), e));
    }
    contents.stats = *decoder.stats();
    retime_before_utc(&mut contents.records);
    if let Some((first, last)) = contents.stats.time_span.as_mut() {
        let times = contents.records.iter().map(Record::t_us);
        (*first, *last) = (times.clone().min().unwrap_or(*first), times.max().unwrap_or(*last));
    }
    Ok(contents)
}

/// A device writes records in its own clock until a GNSS fix tells it UTC; the first
/// [`ClockOffset`](dash2sim_core::binlog::ClockOffset) record says by how much they are
/// off. Move those early records onto UTC, so that the whole log has one time base.
fn retime_before_utc(records: &mut [Record]) {
    let Some(first) = records.iter().position(|r| matches!(r, Record::ClockOffset(_))) else { return };
    let Record::ClockOffset(c) = &records[first] else { return };
    let offset = c.offset_us;
    for r in &mut records[..first] {
        r.set_t_us(r.t_us().saturating_add(offset));
    }
}

/// Read and decode a log file.
pub fn read(path: &Path) -> Result<LogContents, LogError> {
    let bytes = std::fs::read(path).map_err(|source| LogError::Io { path: path.to_path_buf(), source })?;
    decode(&bytes, &path.display().to_string())
}

/// The header's ENU frame.
pub fn frame(header: &Header) -> Option<LocalFrame> {
    let [lat, lon, h] = header.origin;
    Geodetic::new(f64::from(lat) * 1e-7, f64::from(lon) * 1e-7, f64::from(h) * 1e-3).ok().map(LocalFrame::new)
}

/// An event record with `text` cut at a character boundary to the record's limit.
pub fn event(t_us: i64, level: u8, text: &str) -> Record {
    let mut e = dash2sim_core::binlog::EventRecord { t_us, level, ..Default::default() };
    let mut end = text.len().min(dash2sim_core::binlog::MAX_TEXT);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let _ = e.text.extend_from_slice(&text.as_bytes()[..end]);
    Record::Event(e)
}

/// Seconds from µs.
pub fn seconds(t_us: i64) -> f64 {
    t_us as f64 / 1e6
}

pub use dash2sim_core::binlog::quantise;
