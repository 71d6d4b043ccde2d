//! The 4D log on the desktop: reading a whole file through the core's push decoder,
//! `dash2sim import` (existing recordings → log), `inspect`, and the views of a log its
//! readers share (`views`). The format is the core's (`docs/binlog.md`); the writers of other
//! formats are the `dash2sim-export` crate.

pub mod import;
pub mod inspect;
pub mod signing;
pub mod store;
pub mod views;

use std::path::Path;

use dash2sim_core::binlog::{Decoder, Event, Header, HeaderError, Record, Stats};
use dash2sim_core::geo::{Geodetic, LocalFrame};

pub use store::RecordStore;

/// Everything a log file held, as far as it could be read.
#[derive(Debug)]
pub struct LogContents<R = Vec<Record>> {
    /// The header, if intact.
    pub header: Option<Header>,
    /// Intact records in file order (those before the first clock offset moved onto UTC).
    pub records: R,
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

impl LogContents {
    /// The same contents with the records held compactly ([`RecordStore`]).
    pub fn compact(&self) -> LogContents<RecordStore> {
        LogContents {
            header: self.header,
            records: self.records.iter().collect(),
            damage: self.damage.clone(),
            stats: self.stats,
            bytes: self.bytes,
            signing: self.signing.clone(),
        }
    }
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
    decode_into(bytes, name)
}

/// Decode `bytes` completely into a compact [`RecordStore`] (a long drive; see [`store`]).
pub fn decode_compact(bytes: &[u8], name: &str) -> Result<LogContents<RecordStore>, LogError> {
    decode_into(bytes, name)
}

/// Decode `bytes` into any collection of records. A device writes records in its own clock
/// until a GNSS fix tells it UTC; the first
/// [`ClockOffset`](dash2sim_core::binlog::ClockOffset) record says by how much they are
/// off: the records before it are held (compactly) and moved onto UTC, so that the whole
/// log has one time base.
fn decode_into<R: Default + Extend<Record>>(bytes: &[u8], name: &str) -> Result<LogContents<R>, LogError> {
    let mut decoder: Box<Decoder> = Box::default();
    let mut contents = LogContents {
        header: None,
        records: R::default(),
        damage: Vec::new(),
        stats: Stats::default(),
        bytes: bytes.len() as u64,
        signing: Vec::new(),
    };
    let mut before_utc = Some(RecordStore::default());
    let mut span: Option<(i64, i64)> = None;
    let mut fatal = None;
    let mut on = |event: Event| match event {
        Event::Header(h) => contents.header = Some(h),
        Event::NotALog(e) => fatal = Some(e),
        Event::Record(r) => {
            let held = match (&r, before_utc.as_mut()) {
                (Record::ClockOffset(c), Some(held)) => {
                    let offset = c.offset_us;
                    for mut early in held.iter() {
                        early.set_t_us(early.t_us().saturating_add(offset));
                        keep(&mut contents.records, &mut span, early);
                    }
                    before_utc = None;
                    None
                }
                (_, held) => held,
            };
            match held {
                Some(held) => held.push(&r),
                None => keep(&mut contents.records, &mut span, r),
            }
        }
        Event::Damaged { offset, len } => contents.damage.push((offset, len)),
        e @ (Event::Segment { .. } | Event::Signature { .. }) => contents.signing.push(e),
        Event::Index { .. } | Event::Unknown { .. } | Event::Lost(_) => {}
    };
    for chunk in bytes.chunks(64 * 1024) {
        decoder.push(chunk, &mut on);
    }
    decoder.finish(&mut on);
    if let Some(held) = before_utc {
        for r in held.iter() {
            keep(&mut contents.records, &mut span, r);
        }
    }
    if let Some(e) = fatal {
        return Err(LogError::NotALog(name.to_owned(), e));
    }
    contents.stats = *decoder.stats();
    if let Some((first, last)) = contents.stats.time_span.as_mut() {
        (*first, *last) = span.unwrap_or((*first, *last));
    }
    Ok(contents)
}

/// Add `record` to `records` and its time to `span` (first, last).
fn keep<R: Extend<Record>>(records: &mut R, span: &mut Option<(i64, i64)>, record: Record) {
    let t = record.t_us();
    *span = Some(span.map_or((t, t), |(first, last)| (first.min(t), last.max(t))));
    records.extend([record]);
}

/// Read and decode a log file.
pub fn read(path: &Path) -> Result<LogContents, LogError> {
    let bytes = std::fs::read(path).map_err(|source| LogError::Io { path: path.to_path_buf(), source })?;
    decode(&bytes, &path.display().to_string())
}

/// Read and decode a log file into a compact [`RecordStore`] (a long drive; see [`store`]).
pub fn read_compact(path: &Path) -> Result<LogContents<RecordStore>, LogError> {
    let bytes = std::fs::read(path).map_err(|source| LogError::Io { path: path.to_path_buf(), source })?;
    decode_compact(&bytes, &path.display().to_string())
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
