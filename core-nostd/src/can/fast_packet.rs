//! NMEA 2000 fast-packet reassembly (as canboat does it; docs/conformance.md): messages of up
//! to 223 bytes sent as up to 32 frames. Byte 0 of every frame is `sequence << 5 | index`;
//! frame 0 carries the total length in byte 1 and 6 payload bytes, later frames 7.
//!
//! Messages are kept in a fixed number of slots keyed by (PGN, source, sequence), so two
//! senders — or two messages of one sender — may interleave. Frames may arrive in any
//! order. A message is dropped, and reported, when a frame index repeats before it is
//! complete (a sequence clash: the sender reused the sequence number, so the old message
//! lost frames), when its frames stop for longer than the timeout, or when every slot is
//! busy and it is the oldest.

use crate::time::{Duration, Timestamp};

/// Longest fast-packet message: 6 bytes in frame 0 and 7 in each of 31 more.
pub const MAX_MESSAGE_LEN: usize = 6 + 31 * 7;

/// ISO 11783-3 says consecutive frames of a message come within 750 ms.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_millis(750);

/// Why a frame was not accepted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// Frame 0 needs 2 bytes, later frames 1.
    TooShort,
    /// Frame 0 announced more than [`MAX_MESSAGE_LEN`] bytes (or zero).
    BadLength(u8),
    /// A frame index past the end of the announced length.
    IndexBeyondLength {
        /// Frame index (0–31).
        index: u8,
        /// The announced length.
        length: u8,
    },
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::TooShort => write!(f, "fast-packet frame too short"),
            FrameError::BadLength(len) => write!(f, "fast-packet length {len} outside 1..={MAX_MESSAGE_LEN}"),
            FrameError::IndexBeyondLength { index, length } => {
                write!(f, "fast-packet frame {index} beyond announced length {length}")
            }
        }
    }
}

impl core::error::Error for FrameError {}

/// Why an unfinished message was given up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DropReason {
    /// A frame index arrived twice: the sender reused the sequence number.
    SequenceClash,
    /// No frame for longer than the timeout.
    TimedOut,
    /// All slots busy; this was the oldest message.
    Evicted,
}

/// An unfinished message that was given up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Dropped {
    /// Its PGN.
    pub pgn: u32,
    /// Its sender.
    pub source: u8,
    /// Frames received of it.
    pub frames_received: u8,
    /// Why.
    pub reason: DropReason,
}

/// What one frame did.
#[derive(Debug, PartialEq, Eq)]
pub enum Outcome<'a> {
    /// The message is complete: its payload (exactly the announced length).
    Complete(&'a [u8]),
    /// Stored; more frames are needed.
    Pending,
    /// The frame itself was rejected.
    Rejected(FrameError),
}

/// What one [`Assembler::push`] did, plus an older message it had to give up, if any.
#[derive(Debug, PartialEq, Eq)]
pub struct Push<'a> {
    /// The effect of the frame.
    pub outcome: Outcome<'a>,
    /// A message dropped to make room for this frame (clash or eviction).
    pub dropped: Option<Dropped>,
}

/// Counters over the assembler's life.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stats {
    /// Messages completed.
    pub completed: u32,
    /// Frames rejected.
    pub rejected_frames: u32,
    /// Messages dropped on a sequence clash.
    pub clashed: u32,
    /// Messages dropped after the timeout.
    pub timed_out: u32,
    /// Messages evicted for lack of slots.
    pub evicted: u32,
}

#[derive(Clone, Copy, Debug)]
struct Slot {
    in_use: bool,
    pgn: u32,
    source: u8,
    sequence: u8,
    /// Announced length, 0 until frame 0 arrived.
    length: u8,
    /// Bit i set: frame i stored.
    received: u32,
    last_frame: Timestamp,
    data: [u8; MAX_MESSAGE_LEN],
}

impl Slot {
    const EMPTY: Slot = Slot {
        in_use: false,
        pgn: 0,
        source: 0,
        sequence: 0,
        length: 0,
        received: 0,
        last_frame: Timestamp::from_micros(0),
        data: [0; MAX_MESSAGE_LEN],
    };

    fn frames_needed(&self) -> u32 {
        // 6 bytes in frame 0, then 7 per frame.
        1 + (u32::from(self.length).saturating_sub(6)).div_ceil(7)
    }

    /// Frame 0 arrived and so did every frame up to the announced length. Frames an
    /// out-of-order sender placed past that length do not count.
    fn is_complete(&self) -> bool {
        let all = (1u64 << self.frames_needed()) - 1;
        self.length != 0 && u64::from(self.received) & all == all
    }

    fn matches(&self, pgn: u32, source: u8, sequence: u8) -> bool {
        self.in_use && self.pgn == pgn && self.source == source && self.sequence == sequence
    }

    /// Free the slot and describe what was lost.
    fn drop_message(&mut self, reason: DropReason) -> Dropped {
        self.in_use = false;
        Dropped { pgn: self.pgn, source: self.source, frames_received: self.received.count_ones() as u8, reason }
    }
}

/// Fast-packet reassembler with `SLOTS` messages in flight (about 240 bytes each).
#[derive(Clone, Debug)]
pub struct Assembler<const SLOTS: usize = 8> {
    slots: [Slot; SLOTS],
    timeout: Duration,
    stats: Stats,
}

impl<const SLOTS: usize> Default for Assembler<SLOTS> {
    fn default() -> Self {
        Self::new(DEFAULT_TIMEOUT)
    }
}

impl<const SLOTS: usize> Assembler<SLOTS> {
    /// An empty assembler giving up messages whose frames pause longer than `timeout`.
    pub const fn new(timeout: Duration) -> Self {
        Assembler {
            slots: [Slot::EMPTY; SLOTS],
            timeout,
            stats: Stats { completed: 0, rejected_frames: 0, clashed: 0, timed_out: 0, evicted: 0 },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Give up one message whose frames stopped before `now` − timeout. Call until it
    /// returns `None` (at most `SLOTS` times) to report every expired message.
    pub fn expire(&mut self, now: Timestamp) -> Option<Dropped> {
        let timeout = self.timeout;
        let slot = self
            .slots
            .iter_mut()
            .find(|s| s.in_use && now.checked_duration_since(s.last_frame).is_some_and(|gap| gap > timeout))?;
        self.stats.timed_out = self.stats.timed_out.saturating_add(1);
        Some(slot.drop_message(DropReason::TimedOut))
    }

    /// Store one frame of `pgn` from `source` received at `now`.
    pub fn push(&mut self, now: Timestamp, pgn: u32, source: u8, frame: &[u8]) -> Push<'_> {
        let Some((&header, payload)) = frame.split_first() else {
            return self.reject(FrameError::TooShort);
        };
        let sequence = header >> 5;
        let index = header & 0x1F;
        let (length, payload) = if index == 0 {
            match payload.split_first() {
                Some((&len, _)) if len == 0 || usize::from(len) > MAX_MESSAGE_LEN => {
                    return self.reject(FrameError::BadLength(len));
                }
                Some((&len, rest)) => (len, rest),
                None => return self.reject(FrameError::TooShort),
            }
        } else {
            (0, payload)
        };
        if payload.is_empty() {
            return self.reject(FrameError::TooShort);
        }

        let (position, dropped) = self.slot_for(pgn, source, sequence, index);
        let Some(slot) = self.slots.get_mut(position) else {
            // Only when SLOTS == 0: nothing can ever be stored.
            return Push { outcome: Outcome::Pending, dropped };
        };
        if !slot.in_use {
            *slot = Slot { in_use: true, pgn, source, sequence, length: 0, received: 0, ..*slot };
        }
        if index == 0 {
            slot.length = length;
        }
        if slot.length != 0 && u32::from(index) >= slot.frames_needed() {
            let length = slot.length;
            if slot.received == 0 {
                slot.in_use = false;
            }
            return Push { dropped, ..self.reject(FrameError::IndexBeyondLength { index, length }) };
        }
        let offset = if index == 0 { 0 } else { 6 + 7 * (usize::from(index) - 1) };
        let end = (offset + payload.len()).min(MAX_MESSAGE_LEN);
        if let (Some(target), Some(bytes)) = (slot.data.get_mut(offset..end), payload.get(..end - offset)) {
            target.copy_from_slice(bytes);
        }
        slot.received |= 1 << index;
        slot.last_frame = now;

        if !slot.is_complete() {
            return Push { outcome: Outcome::Pending, dropped };
        }
        // The slot is free for the next message; its bytes stay valid while borrowed.
        slot.in_use = false;
        self.stats.completed = self.stats.completed.saturating_add(1);
        let Some(slot) = self.slots.get(position) else {
            return Push { outcome: Outcome::Pending, dropped };
        };
        Push { outcome: Outcome::Complete(slot.data.get(..usize::from(slot.length)).unwrap_or(&[])), dropped }
    }

    /// The slot for a frame: its message's, a free one, or the oldest (dropped).
    fn slot_for(&mut self, pgn: u32, source: u8, sequence: u8, index: u8) -> (usize, Option<Dropped>) {
        if let Some(i) = self.slots.iter().position(|s| s.matches(pgn, source, sequence)) {
            let slot = &mut self.slots[i];
            if slot.received & (1 << index) == 0 {
                return (i, None);
            }
            self.stats.clashed = self.stats.clashed.saturating_add(1);
            return (i, Some(slot.drop_message(DropReason::SequenceClash)));
        }
        if let Some(i) = self.slots.iter().position(|s| !s.in_use) {
            return (i, None);
        }
        let Some(oldest) = (0..SLOTS).min_by_key(|&i| self.slots[i].last_frame) else {
            return (0, None);
        };
        self.stats.evicted = self.stats.evicted.saturating_add(1);
        (oldest, Some(self.slots[oldest].drop_message(DropReason::Evicted)))
    }

    fn reject(&mut self, error: FrameError) -> Push<'_> {
        self.stats.rejected_frames = self.stats.rejected_frames.saturating_add(1);
        Push { outcome: Outcome::Rejected(error), dropped: None }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PGN: u32 = 129_029;

    fn t(ms: i64) -> Timestamp {
        Timestamp::from_micros(ms * 1000)
    }

    /// Split `payload` into fast-packet frames with sequence `seq`.
    fn frames(seq: u8, payload: &[u8]) -> heapless::Vec<[u8; 8], 32> {
        let mut out = heapless::Vec::new();
        let mut first = [0xFF; 8];
        first[0] = seq << 5;
        first[1] = payload.len() as u8;
        let head = payload.len().min(6);
        first[2..2 + head].copy_from_slice(&payload[..head]);
        out.push(first).expect("valid");
        for (i, chunk) in payload[head..].chunks(7).enumerate() {
            let mut frame = [0xFF; 8];
            frame[0] = seq << 5 | (i as u8 + 1);
            frame[1..1 + chunk.len()].copy_from_slice(chunk);
            out.push(frame).expect("valid");
        }
        out
    }

    fn payload(len: usize) -> [u8; MAX_MESSAGE_LEN] {
        core::array::from_fn(|i| if i < len { (i * 7 + 3) as u8 } else { 0 })
    }

    #[test]
    fn in_order_frames_reassemble_exactly_the_announced_length() {
        let data = payload(43);
        let mut fp = Assembler::<4>::default();
        let frames = frames(3, &data[..43]);
        assert_eq!(frames.len(), 7);
        for frame in &frames[..6] {
            assert_eq!(fp.push(t(0), PGN, 7, frame).outcome, Outcome::Pending);
        }
        assert_eq!(fp.push(t(1), PGN, 7, &frames[6]).outcome, Outcome::Complete(&data[..43]));
        assert_eq!(fp.stats().completed, 1);
    }

    #[test]
    fn any_order_and_interleaved_senders_work() {
        let a = payload(223);
        let b = payload(20);
        let fa = frames(1, &a[..223]);
        let fb = frames(1, &b[..20]);
        assert_eq!(fa.len(), 32);
        let mut fp = Assembler::<2>::default();
        let mut done = 0;
        // Reverse order for A, B (another source, same PGN and sequence) in between.
        for (i, frame) in fa.iter().rev().enumerate() {
            if let Some(fb) = fb.get(i) {
                if let Outcome::Complete(got) = fp.push(t(0), PGN, 2, fb).outcome {
                    assert_eq!(got, &b[..20]);
                    done += 1;
                }
            }
            if let Outcome::Complete(got) = fp.push(t(0), PGN, 1, frame).outcome {
                assert_eq!(got, &a[..223]);
                done += 1;
            }
        }
        assert_eq!(done, 2);
    }

    #[test]
    fn a_repeated_index_drops_the_old_message_and_starts_again() {
        let data = payload(30);
        let f = frames(5, &data[..30]);
        let mut fp = Assembler::<2>::default();
        fp.push(t(0), PGN, 9, &f[0]);
        fp.push(t(0), PGN, 9, &f[1]);
        // Frame 2 lost; the sender starts its next message with the same sequence.
        let push = fp.push(t(100), PGN, 9, &f[0]);
        assert_eq!(push.outcome, Outcome::Pending);
        assert_eq!(
            push.dropped,
            Some(Dropped { pgn: PGN, source: 9, frames_received: 2, reason: DropReason::SequenceClash })
        );
        for frame in &f[1..4] {
            fp.push(t(100), PGN, 9, frame);
        }
        assert_eq!(fp.push(t(100), PGN, 9, &f[4]).outcome, Outcome::Complete(&data[..30]));
        assert_eq!(fp.stats().clashed, 1);
    }

    #[test]
    fn silent_messages_time_out_and_full_tables_evict_the_oldest() {
        let data = payload(30);
        let f = frames(0, &data[..30]);
        let mut fp = Assembler::<2>::default();
        fp.push(t(0), PGN, 1, &f[0]);
        fp.push(t(500), PGN, 2, &f[0]);
        assert_eq!(fp.expire(t(700)), None);
        assert_eq!(fp.expire(t(800)).map(|d| (d.source, d.reason)), Some((1, DropReason::TimedOut)));
        assert_eq!(fp.expire(t(800)), None);
        fp.push(t(900), PGN, 3, &f[0]);
        let push = fp.push(t(950), PGN, 4, &f[0]);
        assert_eq!(push.dropped.map(|d| (d.source, d.reason)), Some((2, DropReason::Evicted)));
        assert_eq!((fp.stats().timed_out, fp.stats().evicted), (1, 1));
    }

    #[test]
    fn malformed_frames_are_rejected_without_disturbing_others() {
        let mut fp = Assembler::<2>::default();
        let data = payload(8);
        let f = frames(2, &data[..8]);
        fp.push(t(0), PGN, 1, &f[0]);
        assert_eq!(fp.push(t(0), PGN, 1, &[]).outcome, Outcome::Rejected(FrameError::TooShort));
        assert_eq!(fp.push(t(0), PGN, 1, &[0x00]).outcome, Outcome::Rejected(FrameError::TooShort));
        assert_eq!(fp.push(t(0), PGN, 1, &[0x00, 224, 1]).outcome, Outcome::Rejected(FrameError::BadLength(224)));
        assert_eq!(fp.push(t(0), PGN, 1, &[0x00, 0, 1]).outcome, Outcome::Rejected(FrameError::BadLength(0)));
        assert_eq!(
            fp.push(t(0), PGN, 1, &[0x45, 1, 2]).outcome,
            Outcome::Rejected(FrameError::IndexBeyondLength { index: 5, length: 8 })
        );
        assert_eq!(fp.push(t(0), PGN, 1, &f[1]).outcome, Outcome::Complete(&data[..8]));
        assert_eq!(fp.stats().rejected_frames, 5);
    }

    #[test]
    fn a_stray_late_frame_does_not_complete_a_short_message() {
        // Frame 5 of something else arrives first; then a 2-frame message with the same key.
        let data = payload(10);
        let f = frames(0, &data[..10]);
        let mut fp = Assembler::<2>::default();
        assert_eq!(fp.push(t(0), PGN, 1, &[0x05, 1, 2, 3, 4, 5, 6, 7]).outcome, Outcome::Pending);
        assert_eq!(fp.push(t(0), PGN, 1, &f[0]).outcome, Outcome::Pending);
        assert_eq!(fp.push(t(0), PGN, 1, &f[1]).outcome, Outcome::Complete(&data[..10]));
    }
}
