//! Writing a log onto any [`embedded_io::Write`] (an SD card file, flash, a UART, a `Vec`).
//!
//! Records are framed into a bounded buffer of `N` bytes and handed to the writer as the
//! [`FlushPolicy`] says: what is flushed survives a power cut, what is still buffered
//! does not — the policy is the trade between write amplification and what a crash may
//! cost. Segments close after [`WriterConfig::segment_us`] or
//! [`WriterConfig::segment_records`], whichever comes first.

use embedded_io::Write;

use super::codec::{Streams, TracksFrame};
use super::signature::{Sealer, SIGNATURE, TRAILER_LEN};
use super::varint::{put, zigzag};
use super::{Header, Kind, Record, CRC32C, HEADER_LEN, INDEX, MAX_FRAME, MAX_PAYLOAD, MAX_TRACKS, SEGMENT, SYNC};

/// Longest index payload: seq, records, time span, bytes, then a (kind, count) pair per kind.
const MAX_INDEX: usize = 4 * 10 + 2 * 10 * Kind::ALL.len();
// A segment's index and trailer go into the room `make_room` leaves for one frame, so that
// no flush (which may fail) comes between them.
const _: () = assert!(MAX_INDEX + TRAILER_LEN + 2 * (2 + 1 + 4) <= MAX_FRAME);

/// When the buffer goes to the underlying writer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlushPolicy {
    /// After every record: nothing written is lost, many small writes.
    EveryRecord,
    /// When a segment closes (and when full): a crash loses at most the open segment.
    EverySegment,
    /// Only when the buffer is full: fewest writes, a crash loses up to a buffer.
    WhenFull,
}

/// Segment bounds and flushing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WriterConfig {
    /// A segment closes when a record is this much later than its start, µs.
    pub segment_us: i64,
    /// … or when it holds this many records.
    pub segment_records: u32,
    /// Flushing.
    pub flush: FlushPolicy,
}

impl Default for WriterConfig {
    fn default() -> Self {
        WriterConfig { segment_us: 5_000_000, segment_records: 4096, flush: FlushPolicy::EverySegment }
    }
}

/// Why a write failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WriteError<E> {
    /// The underlying writer failed; the buffer is kept for a retry with `flush`.
    Io(E),
    /// The record's payload exceeds [`MAX_PAYLOAD`] (only an event text can).
    RecordTooLarge,
    /// The buffer `N` is smaller than two frames.
    BufferTooSmall,
}

impl<E: core::fmt::Debug> core::fmt::Display for WriteError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            WriteError::Io(e) => write!(f, "write failed: {e:?}"),
            WriteError::RecordTooLarge => write!(f, "record larger than {MAX_PAYLOAD} bytes"),
            WriteError::BufferTooSmall => write!(f, "writer buffer smaller than {} bytes", 2 * MAX_FRAME),
        }
    }
}

impl<E: core::fmt::Debug> core::error::Error for WriteError<E> {}

#[derive(Clone, Copy, Debug)]
struct OpenSegment {
    seq: u32,
    t0: i64,
    t_last: i64,
    records: u32,
    bytes: u64,
    counts: [u32; Kind::ALL.len()],
}

/// A log writer with an `N`-byte buffer.
#[derive(Debug)]
pub struct Writer<W: Write, const N: usize> {
    io: W,
    buffer: [u8; N],
    len: usize,
    streams: Streams,
    config: WriterConfig,
    segment: Option<OpenSegment>,
    next_seq: u32,
    /// The `Tracks3d` frame being filled (all tracks of one time share a frame).
    tracks: Option<TracksFrame>,
    /// The file's header (the first segment's signature covers it).
    header: Header,
    /// Signs each segment when set.
    sealer: Option<Sealer>,
}

impl<W: Write, const N: usize> Writer<W, N> {
    /// Start a log: the header goes out at once.
    pub fn new(io: W, header: &Header, config: WriterConfig) -> Result<Self, WriteError<W::Error>> {
        if N < 2 * MAX_FRAME {
            return Err(WriteError::BufferTooSmall);
        }
        let mut w = Self::buffered(io, header, config);
        w.flush()?;
        Ok(w)
    }

    /// Start a log whose header waits in the buffer for the first flush. Infallible (a
    /// buffer smaller than two frames does not compile), so that a large writer can be built
    /// in place rather than moved out of a `Result`.
    #[inline(always)]
    pub fn buffered(io: W, header: &Header, config: WriterConfig) -> Self {
        const { assert!(N >= 2 * MAX_FRAME, "a Writer's buffer must hold two frames") };
        let mut w = Writer {
            io,
            buffer: [0; N],
            len: 0,
            streams: Streams::default(),
            config,
            segment: None,
            next_seq: 0,
            tracks: None,
            header: *header,
            sealer: None,
        };
        w.buffer[..HEADER_LEN].copy_from_slice(&header.encode());
        w.len = HEADER_LEN;
        w
    }

    /// Sign every segment from the next one on with `sealer`'s key (format v1.5,
    /// [`super::signature`]). Set it before the first record, so that the file's first
    /// segment, whose signature covers the header, is signed too.
    pub fn seal_with(&mut self, sealer: Sealer) {
        self.sealer = Some(sealer);
    }

    /// The sealer back (its chain goes on in the next file's writer).
    pub fn take_sealer(&mut self) -> Option<Sealer> {
        self.sealer.take()
    }

    /// Append one record (records should come in time order; small reorderings cost a
    /// few bytes, not correctness).
    pub fn write(&mut self, record: &Record) -> Result<(), WriteError<W::Error>> {
        let t = record.t_us();
        let roll = match &self.segment {
            None => true,
            Some(s) => t.wrapping_sub(s.t0) >= self.config.segment_us || s.records >= self.config.segment_records,
        };
        let same_frame = matches!((record, &self.tracks), (Record::Tracks3d(b), Some(f)) if f.t_us == b.t_us);
        if !same_frame {
            self.end_tracks_frame()?;
        }
        if roll && !same_frame {
            self.close_segment()?;
            self.open_segment(t)?;
        }
        let mut payload = [0u8; MAX_PAYLOAD];
        if let Record::Tracks3d(batch) = record {
            // Tracks of one time fill one frame; a full frame goes out and another starts.
            for track in &batch.tracks {
                let mut frame = match self.tracks.take() {
                    Some(f) => f,
                    None => self.streams.tracks_begin(batch.t_us),
                };
                if !self.streams.tracks_append(&mut frame, track) {
                    self.tracks = Some(frame);
                    self.end_tracks_frame()?;
                    frame = self.streams.tracks_begin(batch.t_us);
                    if !self.streams.tracks_append(&mut frame, track) {
                        return Err(WriteError::RecordTooLarge);
                    }
                }
                self.tracks = Some(frame);
            }
        } else {
            // Room first: the encoding moves the streams' predictors on, so the frame must
            // not fail after it (a failed flush would leave the next records' deltas
            // relative to one never written).
            self.make_room()?;
            let n = self.streams.encode(record, &mut payload).ok_or(WriteError::RecordTooLarge)?;
            let frame = self.frame(record.kind().code(), &payload[..n])?;
            self.count(record.kind(), t, frame);
        }
        if self.config.flush == FlushPolicy::EveryRecord {
            self.flush()?;
        }
        Ok(())
    }

    /// Send the `Tracks3d` frame being filled, if any.
    fn end_tracks_frame(&mut self) -> Result<(), WriteError<W::Error>> {
        if self.tracks.is_none() {
            return Ok(());
        }
        // Room before finishing the frame (see `write`); on failure it stays for a retry.
        self.make_room()?;
        let Some(mut f) = self.tracks.take() else { return Ok(()) };
        let (t, records) = (f.t_us, f.count().div_ceil(MAX_TRACKS));
        let payload = self.streams.tracks_finish(&mut f);
        let mut copy = [0u8; MAX_PAYLOAD];
        copy[..payload.len()].copy_from_slice(payload);
        let len = payload.len();
        let frame = self.frame(Kind::Tracks3d.code(), &copy[..len])?;
        // Readers see the frame as records of at most MAX_TRACKS tracks; count those.
        for k in 0..records {
            self.count(Kind::Tracks3d, t, if k == 0 { frame } else { 0 });
        }
        if self.config.flush == FlushPolicy::EveryRecord {
            self.flush()?;
        }
        Ok(())
    }

    fn count(&mut self, kind: Kind, t: i64, frame: usize) {
        if let Some(s) = &mut self.segment {
            s.records += 1;
            s.t_last = s.t_last.max(t);
            s.bytes += frame as u64;
            if let Some(c) = Kind::ALL.iter().position(|k| *k == kind).and_then(|i| s.counts.get_mut(i)) {
                *c += 1;
            }
        }
    }

    /// Hand everything buffered to the writer and flush it (a `Tracks3d` frame still
    /// being filled waits for the next record of another time, or [`Writer::finish`]).
    pub fn flush(&mut self) -> Result<(), WriteError<W::Error>> {
        self.io.write_all(&self.buffer[..self.len]).map_err(WriteError::Io)?;
        self.len = 0;
        self.io.flush().map_err(WriteError::Io)
    }

    /// Close the open segment, flush, and give the writer back.
    pub fn finish(mut self) -> Result<W, WriteError<W::Error>> {
        self.close()?;
        Ok(self.io)
    }

    /// The sink back without writing what is still buffered: for a sink that failed (a full
    /// disk, an I/O error), whose file then ends at the last complete frame it took — what a
    /// reader recovers, as after a power cut.
    pub fn abandon(self) -> W {
        self.io
    }

    /// Close the open segment and flush, keeping the writer (a later record opens a new
    /// segment). [`Writer::finish`] without giving the sink back — for a large writer
    /// that should not be moved.
    pub fn close(&mut self) -> Result<(), WriteError<W::Error>> {
        self.end_tracks_frame()?;
        self.close_segment()?;
        self.flush()
    }

    /// Flush unless the buffer has room for a frame.
    fn make_room(&mut self) -> Result<(), WriteError<W::Error>> {
        if N - self.len < MAX_FRAME + SYNC.len() {
            self.flush()?;
        }
        Ok(())
    }

    /// Frame `payload` as kind `code` into the buffer (flushing first if needed); returns
    /// the frame's length.
    fn frame(&mut self, code: u8, payload: &[u8]) -> Result<usize, WriteError<W::Error>> {
        if payload.len() > MAX_PAYLOAD {
            return Err(WriteError::RecordTooLarge);
        }
        self.make_room()?;
        self.put_frame(code, payload)
    }

    /// Frame `payload` into the buffer, which has room; the segment's digest takes it
    /// unless it is the trailer.
    fn put_frame(&mut self, code: u8, payload: &[u8]) -> Result<usize, WriteError<W::Error>> {
        let start = self.len;
        let mut at = start;
        let ok = put(&mut self.buffer, &mut at, payload.len() as u64);
        let end = at + 1 + payload.len();
        let (Some(slot), true) = (self.buffer.get_mut(at..end + 4), ok) else { return Err(WriteError::BufferTooSmall) };
        slot[0] = code;
        slot[1..1 + payload.len()].copy_from_slice(payload);
        let crc = CRC32C.checksum(&self.buffer[start..end]);
        self.buffer[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        self.len = end + 4;
        if let Some(sealer) = self.sealer.as_mut().filter(|_| code != SIGNATURE) {
            sealer.absorb(&self.buffer[start..self.len]);
        }
        Ok(self.len - start)
    }

    fn open_segment(&mut self, t0: i64) -> Result<(), WriteError<W::Error>> {
        // Room for the sync marker and the frame, so that the frame does not flush (and
        // perhaps fail) with a lone marker in the buffer.
        if N - self.len < MAX_FRAME + 2 * SYNC.len() {
            self.flush()?;
        }
        self.buffer[self.len..self.len + SYNC.len()].copy_from_slice(&SYNC);
        self.len += SYNC.len();
        if let Some(sealer) = &mut self.sealer {
            sealer.begin();
            if self.next_seq == 0 {
                sealer.absorb(&self.header.encode());
            }
            sealer.absorb(&SYNC);
        }
        let mut payload = [0u8; 24];
        let mut at = 0;
        put(&mut payload, &mut at, u64::from(self.next_seq));
        put(&mut payload, &mut at, zigzag(t0));
        let bytes = self.frame(SEGMENT, &payload[..at])? + SYNC.len();
        self.segment = Some(OpenSegment {
            seq: self.next_seq,
            t0,
            t_last: t0,
            records: 0,
            bytes: bytes as u64,
            counts: [0; Kind::ALL.len()],
        });
        self.next_seq = self.next_seq.wrapping_add(1);
        self.streams.start_segment(t0);
        Ok(())
    }

    fn close_segment(&mut self) -> Result<(), WriteError<W::Error>> {
        let Some(s) = self.segment.take() else { return Ok(()) };
        // seq, records, time span, bytes before the index, then (kind, count) pairs.
        let mut payload = [0u8; MAX_INDEX];
        let mut at = 0;
        put(&mut payload, &mut at, u64::from(s.seq));
        put(&mut payload, &mut at, u64::from(s.records));
        put(&mut payload, &mut at, zigzag(s.t_last.wrapping_sub(s.t0)));
        put(&mut payload, &mut at, s.bytes);
        for (kind, count) in Kind::ALL.iter().zip(s.counts) {
            if count > 0 {
                put(&mut payload, &mut at, u64::from(kind.code()));
                put(&mut payload, &mut at, u64::from(count));
            }
        }
        // The index and the trailer without a flush between them (see MAX_INDEX).
        self.make_room()?;
        self.put_frame(INDEX, &payload[..at])?;
        if let Some(sealer) = &mut self.sealer {
            let trailer = sealer.seal().encode();
            self.put_frame(SIGNATURE, &trailer)?;
        }
        if self.config.flush != FlushPolicy::WhenFull {
            self.flush()?;
        }
        Ok(())
    }
}
