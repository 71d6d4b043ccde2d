//! Reading a log, push-based: feed bytes as they come (a file in chunks, a radio link,
//! a fuzzer) and receive events. No I/O, no allocation, never a panic.
//!
//! After damage — a frame whose CRC fails, a length that cannot be, a torn tail — the
//! decoder looks, byte by byte, for the next sync marker or the next frame whose CRC
//! holds, reports the skipped bytes, and goes on. Records whose prediction state the
//! damage may have changed are reported lost until the next segment starts afresh.

use super::codec::Streams;
use super::signature::{Digest, SegmentDigest, Trailer, SIGNATURE};
use super::varint::{get, unzigzag};
use super::{Header, HeaderError, Kind, Record, CRC32C, HEADER_LEN, INDEX, MAX_FRAME, MAX_PAYLOAD, SEGMENT, SYNC};

/// Default decoder buffer: room for the longest frame and then some.
pub const DECODER_BUFFER: usize = 4096;

/// What the decoder found.
// Records are carried by value: there is no allocator to box them into.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Event {
    /// The header (first).
    Header(Header),
    /// The bytes are not a log this reader can read; nothing more will come.
    NotALog(HeaderError),
    /// A segment starts.
    Segment {
        /// Sequence number.
        seq: u64,
        /// Start time, µs.
        t0_us: i64,
    },
    /// An intact record.
    Record(Record),
    /// A segment's index: its records and bytes as the writer counted them.
    Index {
        /// Sequence number.
        seq: u64,
        /// Records the writer put in the segment.
        records: u64,
        /// Bytes before the index.
        bytes: u64,
    },
    /// A segment's signature trailer (v1.5, [`super::signature`]), right after its index.
    Signature {
        /// The trailer.
        trailer: Trailer,
        /// SHA-512 of the segment's bytes as read (the file's header included for its
        /// first segment); `None` when the trailer did not directly follow an index.
        digest: Option<Digest>,
    },
    /// An intact frame of a kind this reader does not know (skipped).
    Unknown {
        /// Its kind code.
        code: u8,
    },
    /// An intact frame of a known kind that cannot be decoded because damage before it
    /// broke its prediction state.
    Lost(Kind),
    /// Damaged bytes were skipped.
    Damaged {
        /// File offset of the first damaged byte.
        offset: u64,
        /// How many bytes were skipped.
        len: u64,
    },
}

/// Running totals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Records decoded, by kind (in [`Kind::ALL`] order).
    pub records: [u64; Kind::ALL.len()],
    /// Frame bytes of the decoded records, by kind.
    pub bytes: [u64; Kind::ALL.len()],
    /// Segments started.
    pub segments: u64,
    /// Damaged stretches skipped.
    pub damaged: u64,
    /// Bytes in them.
    pub damaged_bytes: u64,
    /// Intact records lost to broken prediction state.
    pub lost: u64,
    /// Frames of unknown kinds.
    pub unknown: u64,
    /// Signature trailers.
    pub signatures: u64,
    /// Earliest and latest record time, µs.
    pub time_span: Option<(i64, i64)>,
}

impl Stats {
    /// All records decoded.
    pub fn total(&self) -> u64 {
        self.records.iter().sum()
    }
}

enum Frame {
    /// Need more bytes to decide.
    Incomplete,
    /// Not a frame here.
    Invalid,
    /// A frame: kind code, where its payload lies in the frame, total length.
    Valid(u8, core::ops::Range<usize>, usize),
}

fn frame_at(b: &[u8]) -> Frame {
    let mut at = 0;
    let Some(len) = get(b, &mut at) else {
        // Up to 2 length bytes are legal; a longer run of continuation bytes is garbage.
        return if b.len() < 2 { Frame::Incomplete } else { Frame::Invalid };
    };
    let Some(len) = usize::try_from(len).ok().filter(|l| *l <= MAX_PAYLOAD) else { return Frame::Invalid };
    let total = at + 1 + len + 4;
    let Some(frame) = b.get(..total) else { return Frame::Incomplete };
    let (body, crc) = frame.split_at(total - 4);
    if CRC32C.checksum(body) != u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]) {
        return Frame::Invalid;
    }
    Frame::Valid(body[at], at + 1..total - 4, total)
}

/// The push decoder with an `N`-byte buffer (at least two frames).
#[derive(Clone, Debug)]
pub struct Decoder<const N: usize = DECODER_BUFFER> {
    buffer: [u8; N],
    start: usize,
    end: usize,
    /// File offset of `buffer[start]`.
    offset: u64,
    header: bool,
    failed: bool,
    /// Offset where the current damaged stretch began.
    damage: Option<u64>,
    streams: Streams,
    stats: Stats,
    /// The digest of the segment being read, for its signature.
    digest: SegmentDigest,
}

impl<const N: usize> Default for Decoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Decoder<N> {
    /// Compile-time check that the buffer holds two frames.
    const BUFFER_HOLDS_TWO_FRAMES: () = assert!(N >= 2 * MAX_FRAME, "the decoder buffer must hold two frames");

    /// A decoder expecting a header.
    pub fn new() -> Self {
        let () = Self::BUFFER_HOLDS_TWO_FRAMES;
        Decoder {
            buffer: [0; N],
            start: 0,
            end: 0,
            offset: 0,
            header: false,
            failed: false,
            damage: None,
            streams: Streams::default(),
            stats: Stats::default(),
            digest: SegmentDigest::new(),
        }
    }

    /// Totals so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Feed bytes; events go to `on`.
    pub fn push(&mut self, mut input: &[u8], on: &mut impl FnMut(Event)) {
        while !input.is_empty() && !self.failed {
            if self.start > 0 {
                self.buffer.copy_within(self.start..self.end, 0);
                self.end -= self.start;
                self.start = 0;
            }
            let room = N - self.end;
            let (now, rest) = input.split_at(room.min(input.len()));
            self.buffer[self.end..self.end + now.len()].copy_from_slice(now);
            self.end += now.len();
            input = rest;
            self.parse(false, on);
        }
    }

    /// The input has ended: whatever is left is a torn tail.
    pub fn finish(&mut self, on: &mut impl FnMut(Event)) {
        if !self.failed {
            self.parse(true, on);
        }
        if !self.header && !self.failed {
            self.failed = true;
            on(Event::NotALog(HeaderError::TooShort));
        }
        let left = (self.end - self.start) as u64;
        if left > 0 && !self.failed {
            self.damage.get_or_insert(self.offset);
            self.skip(left as usize);
        }
        self.end_damage(on);
    }

    /// Consume `n` bytes (every byte of the input passes here once, in order).
    fn skip(&mut self, n: usize) {
        self.digest.absorb(&self.buffer[self.start..self.start + n]);
        self.start += n;
        self.offset += n as u64;
    }

    fn end_damage(&mut self, on: &mut impl FnMut(Event)) {
        if let Some(from) = self.damage.take() {
            let len = self.offset - from;
            self.stats.damaged += 1;
            self.stats.damaged_bytes += len;
            on(Event::Damaged { offset: from, len });
        }
    }

    fn parse(&mut self, eof: bool, on: &mut impl FnMut(Event)) {
        loop {
            let avail = &self.buffer[self.start..self.end];
            if avail.is_empty() {
                return;
            }
            if !self.header {
                match Header::decode(avail) {
                    Ok((h, len)) => {
                        if avail.len() < len {
                            if eof {
                                self.failed = true;
                                on(Event::NotALog(HeaderError::TooShort));
                            }
                            return;
                        }
                        self.header = true;
                        self.skip(len);
                        on(Event::Header(h));
                    }
                    Err(HeaderError::TooShort) if !eof => return,
                    Err(HeaderError::BadChecksum) => {
                        // The magic is right: a damaged header, records may follow.
                        self.header = true;
                        self.damage = Some(self.offset);
                        self.skip(HEADER_LEN);
                    }
                    Err(e) => {
                        self.failed = true;
                        on(Event::NotALog(e));
                        return;
                    }
                }
                continue;
            }
            if avail.starts_with(&SYNC) {
                self.end_damage(on);
                self.digest.segment_starts();
                self.skip(SYNC.len());
                continue;
            }
            if !eof && avail.len() < SYNC.len() && SYNC.starts_with(avail) {
                return;
            }
            match frame_at(avail) {
                Frame::Incomplete if !eof => return,
                Frame::Incomplete | Frame::Invalid => {
                    if self.damage.is_none() {
                        self.damage = Some(self.offset);
                        self.streams.break_streams();
                    }
                    self.digest.other_frame();
                    self.skip(1);
                }
                Frame::Valid(code, range, total) => {
                    self.end_damage(on);
                    let at = self.start;
                    // Consumed (and digested) first: an index completes its segment's digest.
                    self.skip(total);
                    let payload = &self.buffer[at + range.start..at + range.end];
                    handle(&mut self.streams, &mut self.stats, &mut self.digest, code, payload, total, on);
                }
            }
        }
    }
}

/// One intact frame: update the state and report it.
fn handle(
    streams: &mut Streams,
    stats: &mut Stats,
    digest: &mut SegmentDigest,
    code: u8,
    payload: &[u8],
    total: usize,
    on: &mut impl FnMut(Event),
) {
    let mut at = 0;
    match code {
        INDEX => digest.index_read(),
        SIGNATURE => {}
        _ => digest.other_frame(),
    }
    match code {
        SEGMENT => {
            let (Some(seq), Some(t0)) = (get(payload, &mut at), get(payload, &mut at)) else {
                streams.break_streams();
                return;
            };
            let t0_us = unzigzag(t0);
            streams.start_segment(t0_us);
            stats.segments += 1;
            on(Event::Segment { seq, t0_us });
        }
        SIGNATURE => match Trailer::decode(payload) {
            Some(trailer) => {
                stats.signatures += 1;
                on(Event::Signature { trailer, digest: digest.take() });
            }
            // A trailer format this reader does not know: the segment reads as unsigned.
            None => {
                stats.unknown += 1;
                on(Event::Unknown { code });
            }
        },
        INDEX => {
            let fields = (get(payload, &mut at), get(payload, &mut at), get(payload, &mut at), get(payload, &mut at));
            if let (Some(seq), Some(records), Some(_span), Some(bytes)) = fields {
                on(Event::Index { seq, records, bytes });
            }
        }
        _ => match Kind::from_code(code) {
            None => {
                stats.unknown += 1;
                on(Event::Unknown { code });
            }
            Some(kind) if !streams.intact() => {
                stats.lost += 1;
                on(Event::Lost(kind));
            }
            Some(Kind::Tracks3d) => {
                let i = Kind::ALL.iter().position(|k| *k == Kind::Tracks3d).unwrap_or(0);
                let mut first = true;
                let ok = streams.decode_tracks(payload, |record| {
                    stats.records[i] += 1;
                    // The frame's bytes count once, with its first record.
                    if core::mem::take(&mut first) {
                        stats.bytes[i] += total as u64;
                    }
                    let t = record.t_us();
                    stats.time_span = Some(stats.time_span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
                    on(Event::Record(record));
                });
                if !ok {
                    streams.break_streams();
                    stats.lost += 1;
                    on(Event::Lost(Kind::Tracks3d));
                }
            }
            Some(kind) => match streams.decode(kind, payload) {
                Some(record) => {
                    let i = Kind::ALL.iter().position(|k| *k == kind).unwrap_or(0);
                    stats.records[i] += 1;
                    stats.bytes[i] += total as u64;
                    let t = record.t_us();
                    stats.time_span = Some(match stats.time_span {
                        None => (t, t),
                        Some((a, b)) => (a.min(t), b.max(t)),
                    });
                    on(Event::Record(record));
                }
                None => {
                    // Intact CRC, undecodable payload: a writer bug or a foreign producer;
                    // the prediction state can no longer be trusted.
                    streams.break_streams();
                    stats.lost += 1;
                    on(Event::Lost(kind));
                }
            },
        },
    }
}
