//! Sans-io line framer: feed arbitrary byte chunks from a serial port, get sentences.
//!
//! A sentence starts at `$` or `!` and ends at LF (a preceding CR is dropped). Bytes
//! outside a sentence are junk and counted; a sentence interrupted by a new `$`/`!`, by a
//! non-printable byte or by running past the buffer is dropped and counted — the bytes
//! after it are framed normally, so good data around damage is kept. Nothing allocates:
//! the buffer is `N` bytes inside the framer.

/// Why a started sentence was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// Longer than the framer's buffer: rejected before any parsing.
    TooLong,
    /// A non-printable byte inside the sentence (binary noise).
    Binary,
    /// A new `$`/`!` arrived before the line ended (a torn sentence).
    Interrupted,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FrameError::TooLong => "sentence longer than the framer's buffer",
            FrameError::Binary => "non-printable byte inside a sentence",
            FrameError::Interrupted => "sentence interrupted by the start of another",
        })
    }
}

impl core::error::Error for FrameError {}

/// What one call to [`Framer::feed`] produced.
#[derive(Debug, PartialEq, Eq)]
pub enum Feed<'s, 'i> {
    /// All input consumed, no complete sentence yet.
    Consumed,
    /// A complete sentence (without CR/LF); `remaining` is the unread input.
    Sentence {
        /// The sentence bytes, from `$`/`!` up to (excluding) the line end.
        line: &'s [u8],
        /// Input not yet consumed.
        remaining: &'i [u8],
    },
    /// A started sentence was dropped; `remaining` is the unread input.
    Dropped {
        /// Why.
        error: FrameError,
        /// Input not yet consumed.
        remaining: &'i [u8],
    },
}

/// Counters kept by the framer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FramerStats {
    /// Sentences delivered.
    pub sentences: u32,
    /// Bytes outside any sentence (junk between lines, binary protocols).
    pub junk_bytes: u32,
    /// Sentences dropped as too long.
    pub too_long: u32,
    /// Sentences dropped for binary bytes.
    pub binary: u32,
    /// Sentences dropped because another started.
    pub interrupted: u32,
}

/// A line framer with an `N`-byte sentence buffer (NMEA allows 82; receivers write up
/// to ~120 for high-precision and proprietary sentences).
#[derive(Clone, Debug)]
pub struct Framer<const N: usize = 128> {
    buf: [u8; N],
    len: usize,
    in_sentence: bool,
    /// Skipping the rest of an over-long or binary sentence until the next line end.
    skipping: bool,
    stats: FramerStats,
}

impl<const N: usize> Default for Framer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Framer<N> {
    /// An empty framer.
    pub const fn new() -> Self {
        Framer {
            buf: [0; N],
            len: 0,
            in_sentence: false,
            skipping: false,
            stats: FramerStats { sentences: 0, junk_bytes: 0, too_long: 0, binary: 0, interrupted: 0 },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &FramerStats {
        &self.stats
    }

    fn drop_sentence(&mut self, error: FrameError) {
        match error {
            FrameError::TooLong => self.stats.too_long = self.stats.too_long.saturating_add(1),
            FrameError::Binary => self.stats.binary = self.stats.binary.saturating_add(1),
            FrameError::Interrupted => self.stats.interrupted = self.stats.interrupted.saturating_add(1),
        }
        self.len = 0;
        self.in_sentence = false;
    }

    /// Consume bytes until a sentence completes, one is dropped, or the input ends.
    /// Call again with `remaining` until [`Feed::Consumed`].
    pub fn feed<'s, 'i>(&'s mut self, input: &'i [u8]) -> Feed<'s, 'i> {
        let mut i = 0;
        while i < input.len() {
            // Fast path inside a sentence: copy the run of ordinary printable bytes.
            if self.in_sentence && !self.skipping {
                let run = input[i..].iter().position(|&b| !(0x20..0x7f).contains(&b) || b == b'$' || b == b'!');
                let run = run.unwrap_or(input.len() - i);
                let room = N - self.len;
                if run > room {
                    self.drop_sentence(FrameError::TooLong);
                    self.skipping = true;
                    return Feed::Dropped { error: FrameError::TooLong, remaining: &input[i + room + 1..] };
                }
                self.buf[self.len..self.len + run].copy_from_slice(&input[i..i + run]);
                self.len += run;
                i += run;
                if i >= input.len() {
                    break;
                }
            }
            let b = input[i];
            i += 1;
            let rest = input.get(i..).unwrap_or(&[]);
            if b == b'$' || b == b'!' {
                let interrupted = self.in_sentence && self.len > 0;
                self.skipping = false;
                self.in_sentence = true;
                if interrupted {
                    self.drop_sentence(FrameError::Interrupted);
                    self.in_sentence = true;
                    self.buf[0] = b;
                    self.len = 1;
                    return Feed::Dropped { error: FrameError::Interrupted, remaining: rest };
                }
                self.buf[0] = b;
                self.len = 1;
                continue;
            }
            if b == b'\n' {
                if self.skipping || !self.in_sentence {
                    self.skipping = false;
                    if !self.in_sentence {
                        continue;
                    }
                }
                self.in_sentence = false;
                let mut end = self.len;
                if end > 0 && self.buf[end - 1] == b'\r' {
                    end -= 1;
                }
                self.len = 0;
                self.stats.sentences = self.stats.sentences.saturating_add(1);
                return Feed::Sentence { line: &self.buf[..end], remaining: rest };
            }
            if self.skipping {
                continue;
            }
            if !self.in_sentence {
                if b != b'\r' {
                    self.stats.junk_bytes = self.stats.junk_bytes.saturating_add(1);
                }
                continue;
            }
            let printable = (0x20..0x7f).contains(&b) || b == b'\r';
            if !printable {
                self.drop_sentence(FrameError::Binary);
                self.skipping = true;
                return Feed::Dropped { error: FrameError::Binary, remaining: rest };
            }
            if self.len >= N {
                self.drop_sentence(FrameError::TooLong);
                self.skipping = true;
                return Feed::Dropped { error: FrameError::TooLong, remaining: rest };
            }
            self.buf[self.len] = b;
            self.len += 1;
        }
        Feed::Consumed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collect(framer: &mut Framer<32>, chunks: &[&[u8]]) -> ([[u8; 32]; 8], [usize; 8], usize, usize) {
        let mut lines = [[0u8; 32]; 8];
        let mut lens = [0usize; 8];
        let (mut n, mut dropped) = (0, 0);
        for chunk in chunks {
            let mut input: &[u8] = chunk;
            loop {
                match framer.feed(input) {
                    Feed::Consumed => break,
                    Feed::Sentence { line, remaining } => {
                        lines[n][..line.len()].copy_from_slice(line);
                        lens[n] = line.len();
                        n += 1;
                        input = remaining;
                    }
                    Feed::Dropped { remaining, .. } => {
                        dropped += 1;
                        input = remaining;
                    }
                }
            }
        }
        (lines, lens, n, dropped)
    }

    #[test]
    fn sentences_split_across_chunks_and_line_endings() {
        let mut f = Framer::<32>::new();
        let (lines, lens, n, dropped) = collect(&mut f, &[b"junk$GPGGA,1", b"23*00\r\n$GPR", b"MC*11\n"]);
        assert_eq!((n, dropped), (2, 0));
        assert_eq!(&lines[0][..lens[0]], b"$GPGGA,123*00");
        assert_eq!(&lines[1][..lens[1]], b"$GPRMC*11");
        assert_eq!(f.stats().junk_bytes, 4);
    }

    #[test]
    fn damage_is_dropped_and_the_rest_kept() {
        let mut f = Framer::<32>::new();
        let long = [b'A'; 40];
        let (lines, lens, n, dropped) =
            collect(&mut f, &[b"$GPGGA,torn$GPGLL,ok\n$", &long, b"\n$GPVTG,\x01bin\n$GPZDA,fine\n"]);
        assert_eq!(dropped, 3);
        assert_eq!(n, 2);
        assert_eq!(&lines[0][..lens[0]], b"$GPGLL,ok");
        assert_eq!(&lines[1][..lens[1]], b"$GPZDA,fine");
        let s = f.stats();
        assert_eq!((s.interrupted, s.too_long, s.binary), (1, 1, 1));
    }

    /// Every sentence and drop, as (kind, bytes) in order, plus the counters.
    fn trace<const N: usize>(
        chunks: impl Iterator<Item = impl AsRef<[u8]>>,
    ) -> (heapless::Vec<(u8, heapless::Vec<u8, 64>), 64>, FramerStats) {
        let mut framer = Framer::<N>::new();
        let mut out = heapless::Vec::new();
        for chunk in chunks {
            let mut input = chunk.as_ref();
            loop {
                match framer.feed(input) {
                    Feed::Consumed => break,
                    Feed::Sentence { line, remaining } => {
                        let _ = out.push((b'S', heapless::Vec::from_slice(line).unwrap_or_default()));
                        input = remaining;
                    }
                    Feed::Dropped { error, remaining } => {
                        let _ = out.push((error as u8, heapless::Vec::new()));
                        input = remaining;
                    }
                }
            }
        }
        (out, *framer.stats())
    }

    proptest::proptest! {
        /// Chunking does not matter (the run copy and the byte-wise path agree): the same
        /// input framed at once and one byte at a time gives the same sentences, drops
        /// and counters (bytes drawn from the ones that matter: starts, line ends, binary).
        #[test]
        fn whole_input_and_single_bytes_frame_alike(bytes in proptest::collection::vec(
            proptest::sample::select(&b"$!\r\n\x01\x7fAAAAAAAB,,,*0"[..]), 0..200)) {
            let whole = trace::<6>(core::iter::once(&bytes[..]));
            let single = trace::<6>(bytes.chunks(1));
            proptest::prop_assert_eq!(whole, single);
        }
    }
}
