//! Payload coding: each field is a zigzag varint of its difference to a prediction from
//! the previous record of the same kind in the segment ([`Mode`]).
//!
//! Differences wrap (two's complement), so any i64 survives the round trip exactly, even
//! hostile ones; well-behaved values just take few bytes.

use super::varint::{get, put, unzigzag, zigzag};
use super::{Kind, Mode, Record, MAX_TEXT};

/// Most fields a record kind has.
pub const MAX_FIELDS: usize = 16;

/// What the previous record of one kind left behind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Stream {
    previous: [i64; MAX_FIELDS],
    change: [i64; MAX_FIELDS],
    /// Records seen in this segment, saturating at 2 (enough for every mode).
    seen: u8,
}

/// Predictor state of every kind, reset at each segment start. After damage a reader
/// cannot know what the lost records changed: it marks the streams broken until the next
/// segment, and records in between are reported lost.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Streams {
    streams: [Stream; Kind::ALL.len()],
    t0: i64,
    broken: bool,
}

impl Default for Streams {
    fn default() -> Self {
        Streams { streams: [Stream::default(); Kind::ALL.len()], t0: 0, broken: true }
    }
}

fn index(kind: Kind) -> usize {
    Kind::ALL.iter().position(|k| *k == kind).unwrap_or(0)
}

impl Streams {
    /// Forget everything: a new segment starting at `t0_us`.
    pub fn start_segment(&mut self, t0_us: i64) {
        *self = Streams { streams: [Stream::default(); Kind::ALL.len()], t0: t0_us, broken: false };
    }

    /// Mark the streams broken until the next segment (after damage).
    pub fn break_streams(&mut self) {
        self.broken = true;
    }

    /// Whether records can be decoded (a segment started and no damage since).
    pub fn intact(&self) -> bool {
        !self.broken
    }

    fn prediction(&self, kind: Kind, field: usize) -> i64 {
        let s = &self.streams[index(kind)];
        let mode = kind.modes().get(field).copied().unwrap_or(Mode::Absolute);
        match (mode, s.seen) {
            (Mode::Absolute, _) => 0,
            // The first record's time is predicted by the segment's start.
            (_, 0) if field == 0 => self.t0,
            (_, 0) => 0,
            (Mode::Delta, _) | (Mode::DeltaDelta, 1) => s.previous[field],
            (Mode::DeltaDelta, _) => s.previous[field].wrapping_add(s.change[field]),
        }
    }

    fn update(&mut self, kind: Kind, values: &[i64]) {
        let s = &mut self.streams[index(kind)];
        for (k, &v) in values.iter().enumerate().take(MAX_FIELDS) {
            s.change[k] = if s.seen > 0 { v.wrapping_sub(s.previous[k]) } else { 0 };
            s.previous[k] = v;
        }
        s.seen = s.seen.saturating_add(1).min(2);
    }

    /// Encode `record`'s payload into `out`; its length, or `None` if it does not fit.
    /// The state advances only on success.
    pub fn encode(&mut self, record: &Record, out: &mut [u8]) -> Option<usize> {
        let kind = record.kind();
        let mut values = [0i64; MAX_FIELDS];
        let n = record.fields(&mut values);
        let mut at = 0;
        for (k, &v) in values[..n].iter().enumerate() {
            if !put(out, &mut at, zigzag(v.wrapping_sub(self.prediction(kind, k)))) {
                return None;
            }
        }
        if let Record::Event(e) = record {
            if !put(out, &mut at, e.text.len() as u64) {
                return None;
            }
            out.get_mut(at..at + e.text.len())?.copy_from_slice(&e.text);
            at += e.text.len();
        }
        self.update(kind, &values[..n]);
        Some(at)
    }

    /// Decode a payload of `kind`. Bytes after the known fields are ignored (a later minor
    /// version may append fields). `None` if the payload is short or malformed; the state
    /// advances only on success.
    pub fn decode(&mut self, kind: Kind, payload: &[u8]) -> Option<Record> {
        let n = kind.modes().len();
        let mut values = [0i64; MAX_FIELDS];
        let mut at = 0;
        for (k, slot) in values[..n].iter_mut().enumerate() {
            *slot = unzigzag(get(payload, &mut at)?).wrapping_add(self.prediction(kind, k));
        }
        let text: &[u8] = if kind == Kind::Event {
            let len = usize::try_from(get(payload, &mut at)?).ok().filter(|l| *l <= MAX_TEXT)?;
            payload.get(at..at + len)?
        } else {
            &[]
        };
        let record = Record::from_fields(kind, &values[..n], text)?;
        self.update(kind, &values[..n]);
        Some(record)
    }
}
