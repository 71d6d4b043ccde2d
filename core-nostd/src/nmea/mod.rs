//! NMEA 0183 from a GNSS receiver's serial port: sans-io, zero-copy, no allocation.
//!
//! [`framer`] cuts a byte stream into sentences, [`sentence`] checks and splits one,
//! [`messages`] decodes the fields, [`epoch`] merges an epoch's sentences into a
//! [`GnssFix`]. [`Decoder`] chains them and counts what it saw and rejected.

pub mod epoch;
pub mod framer;
pub mod messages;
pub mod sentence;

pub use epoch::{EpochAssembler, FixMode, GnssFix};
pub use framer::{Feed, FrameError, Framer};
pub use messages::{Message, MessageError};
pub use sentence::{Sentence, SentenceError, Talker};

/// What a [`Decoder`] has seen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Sentences decoded into a known message.
    pub decoded: u32,
    /// Well-formed sentences of types not decoded (TXT, proprietary, AIS…).
    pub unknown: u32,
    /// Rejected: bad checksum.
    pub bad_checksum: u32,
    /// Rejected: missing checksum (when required) or malformed address.
    pub malformed: u32,
    /// Rejected: a field out of range or not a number.
    pub bad_fields: u32,
    /// Dropped by the framer (too long, binary, interrupted).
    pub dropped: u32,
}

/// The outcome of one sentence, for callers that report problems (with their position).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event<'a> {
    /// A decoded message; `fix` is the previous epoch when this sentence started a new one.
    Message {
        /// The message.
        message: Message<'a>,
        /// A finished epoch, if any (lent by the decoder until the next sentence).
        fix: Option<&'a GnssFix>,
    },
    /// A sentence that failed its checksum or was malformed.
    BadSentence(SentenceError),
    /// A sentence whose fields could not be decoded.
    BadFields(MessageError),
}

/// Sentence-level decoder with epoch assembly. Feed it lines from a [`Framer`].
#[derive(Clone, Debug, Default)]
pub struct Decoder {
    /// Accept sentences without a checksum (older or cheap receivers).
    pub allow_missing_checksum: bool,
    assembler: EpochAssembler,
    stats: DecoderStats,
}

impl Decoder {
    /// A decoder that accepts sentences without checksums but rejects wrong ones.
    pub fn new() -> Self {
        Decoder { allow_missing_checksum: true, ..Self::default() }
    }

    /// Counters so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// The epoch being assembled.
    pub fn current(&self) -> &GnssFix {
        self.assembler.current()
    }

    /// Count a sentence the framer dropped.
    pub fn note_dropped(&mut self) {
        self.stats.dropped = self.stats.dropped.saturating_add(1);
    }

    /// Decode one line.
    pub fn line<'a>(&'a mut self, line: &'a [u8]) -> Event<'a> {
        let sentence = match Sentence::parse(line, !self.allow_missing_checksum) {
            Ok(s) => s,
            Err(e) => {
                match e {
                    SentenceError::BadChecksum { .. } => {
                        self.stats.bad_checksum = self.stats.bad_checksum.saturating_add(1)
                    }
                    _ => self.stats.malformed = self.stats.malformed.saturating_add(1),
                }
                return Event::BadSentence(e);
            }
        };
        match messages::parse(&sentence) {
            Ok(message) => {
                if matches!(message, Message::Unknown(_) | Message::Proprietary(_)) {
                    self.stats.unknown = self.stats.unknown.saturating_add(1);
                } else {
                    self.stats.decoded = self.stats.decoded.saturating_add(1);
                }
                let fix = self.assembler.push(&message);
                Event::Message { message, fix }
            }
            Err(e) => {
                self.stats.bad_fields = self.stats.bad_fields.saturating_add(1);
                Event::BadFields(e)
            }
        }
    }

    /// The last epoch, at the end of the input.
    pub fn finish(&mut self) -> Option<GnssFix> {
        self.assembler.finish()
    }
}

/// What a [`Stream`] reports for each sentence or damaged stretch of bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StreamEvent<'a> {
    /// A complete sentence and what the decoder made of it.
    Sentence(Event<'a>),
    /// A started sentence the framer dropped.
    Dropped(FrameError),
}

/// A [`Framer`] and a [`Decoder`] together: bytes from the serial port in, one event per
/// sentence out, in order.
#[derive(Clone, Debug, Default)]
pub struct Stream<const N: usize = 128> {
    /// The framer (for its counters).
    pub framer: Framer<N>,
    /// The decoder (for its counters, the current epoch and `finish`).
    pub decoder: Decoder,
}

impl<const N: usize> Stream<N> {
    /// A stream that accepts sentences without checksums (see [`Decoder::new`]).
    pub fn new() -> Self {
        Stream { framer: Framer::new(), decoder: Decoder::new() }
    }

    /// Feed a chunk of any size; `on_event` is called for every sentence it completes.
    // Inlined so the event is built in the caller's frame rather than moved into it.
    #[inline(always)]
    pub fn feed(&mut self, mut input: &[u8], mut on_event: impl FnMut(StreamEvent<'_>)) {
        loop {
            match self.framer.feed(input) {
                Feed::Consumed => return,
                Feed::Sentence { line, remaining } => {
                    on_event(StreamEvent::Sentence(self.decoder.line(line)));
                    input = remaining;
                }
                Feed::Dropped { error, remaining } => {
                    self.decoder.note_dropped();
                    on_event(StreamEvent::Dropped(error));
                    input = remaining;
                }
            }
        }
    }
}
