//! One NMEA 0183 sentence: checksum, talker, type and a zero-copy field cursor.
//!
//! `$TTSSS,f1,f2,...*HH` — `TT` the talker (GP, GN, …), `SSS` the sentence type,
//! `HH` the XOR of every byte between `$` and `*`. Proprietary sentences are `$P` followed
//! by a manufacturer code. Once [`Sentence::parse`] has succeeded no accessor panics.

/// Who sent a sentence. Total: unknown talkers keep their two bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Talker {
    /// GPS.
    Gps,
    /// Any combination of systems (GN).
    Gnss,
    /// GLONASS.
    Glonass,
    /// Galileo.
    Galileo,
    /// BeiDou (GB or BD).
    Beidou,
    /// QZSS (GQ).
    Qzss,
    /// NavIC / IRNSS (GI).
    Navic,
    /// A proprietary sentence (`$P...`).
    Proprietary,
    /// Any other talker (instruments, AIS, ...).
    Other([u8; 2]),
}

/// Why a line is not a usable sentence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SentenceError {
    /// Does not start with `$`/`!` or the address is shorter than 5 characters.
    Malformed,
    /// No `*HH` at the end.
    MissingChecksum,
    /// The checksum does not match.
    BadChecksum {
        /// Sent in the sentence.
        expected: u8,
        /// Computed over the bytes.
        computed: u8,
    },
}

impl core::fmt::Display for SentenceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SentenceError::Malformed => f.write_str("malformed sentence"),
            SentenceError::MissingChecksum => f.write_str("missing checksum"),
            SentenceError::BadChecksum { expected, computed } => {
                write!(f, "bad checksum: sentence says {expected:02X}, bytes give {computed:02X}")
            }
        }
    }
}

impl core::error::Error for SentenceError {}

/// A checked sentence borrowing the line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sentence<'a> {
    /// Who sent it.
    pub talker: Talker,
    /// The type, e.g. `b"GGA"`; for proprietary sentences the manufacturer code and
    /// anything after it up to the first comma (e.g. `b"UBX"`, `b"GRME"`).
    pub kind: &'a [u8],
    /// Everything after the address, without the checksum (starts after the comma).
    pub fields: &'a [u8],
}

fn hex(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b - b'0'),
        b'A'..=b'F' => Some(b - b'A' + 10),
        b'a'..=b'f' => Some(b - b'a' + 10),
        _ => None,
    }
}

impl<'a> Sentence<'a> {
    /// Check and split a line (as delivered by the framer). With `require_checksum`
    /// false, a sentence without `*HH` is accepted (a bad one never is).
    pub fn parse(line: &'a [u8], require_checksum: bool) -> Result<Sentence<'a>, SentenceError> {
        let (&start, body) = line.split_first().ok_or(SentenceError::Malformed)?;
        if start != b'$' && start != b'!' {
            return Err(SentenceError::Malformed);
        }
        let body = match body.iter().rposition(|&b| b == b'*') {
            Some(star) if body.len() == star + 3 => {
                let expected = match (hex(body[star + 1]), hex(body[star + 2])) {
                    (Some(h), Some(l)) => (h << 4) | l,
                    _ => return Err(SentenceError::MissingChecksum),
                };
                let data = &body[..star];
                let computed = data.iter().fold(0u8, |acc, &b| acc ^ b);
                if computed != expected {
                    return Err(SentenceError::BadChecksum { expected, computed });
                }
                data
            }
            _ if require_checksum => return Err(SentenceError::MissingChecksum),
            _ => body,
        };
        let comma = body.iter().position(|&b| b == b',').unwrap_or(body.len());
        let address = &body[..comma];
        let fields = body.get(comma + 1..).unwrap_or(&[]);
        if address.first() == Some(&b'P') {
            return Ok(Sentence { talker: Talker::Proprietary, kind: &address[1..], fields });
        }
        if address.len() < 5 {
            return Err(SentenceError::Malformed);
        }
        let talker = match [address[0], address[1]] {
            [b'G', b'P'] => Talker::Gps,
            [b'G', b'N'] => Talker::Gnss,
            [b'G', b'L'] => Talker::Glonass,
            [b'G', b'A'] => Talker::Galileo,
            [b'G', b'B'] | [b'B', b'D'] => Talker::Beidou,
            [b'G', b'Q'] | [b'Q', b'Z'] => Talker::Qzss,
            [b'G', b'I'] => Talker::Navic,
            other => Talker::Other(other),
        };
        Ok(Sentence { talker, kind: &address[2..], fields })
    }

    /// A cursor over the comma-separated fields.
    pub fn cursor(&self) -> Fields<'a> {
        Fields { rest: Some(self.fields), index: 0 }
    }
}

/// Iterates fields; a missing field reads as empty, so parsers never index out of range.
#[derive(Clone, Debug)]
pub struct Fields<'a> {
    rest: Option<&'a [u8]>,
    /// 1-based index of the field read last.
    index: u8,
}

/// A field that is present but not what its position requires.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FieldError {
    /// 1-based field index.
    pub index: u8,
}

impl core::fmt::Display for FieldError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "field {} is malformed", self.index)
    }
}

impl core::error::Error for FieldError {}

impl<'a> Fields<'a> {
    /// The next raw field (empty when the sentence has ended).
    pub fn next_raw(&mut self) -> &'a [u8] {
        self.index = self.index.saturating_add(1);
        match self.rest {
            None => &[],
            Some(rest) => match rest.iter().position(|&b| b == b',') {
                Some(i) => {
                    self.rest = rest.get(i + 1..);
                    &rest[..i]
                }
                None => {
                    self.rest = None;
                    rest
                }
            },
        }
    }

    /// Skip `n` fields.
    pub fn skip(&mut self, n: usize) {
        for _ in 0..n {
            self.next_raw();
        }
    }

    /// The next field as a finite `f64`; `Ok(None)` when empty.
    pub fn f64(&mut self) -> Result<Option<f64>, FieldError> {
        let raw = self.next_raw();
        if raw.is_empty() {
            return Ok(None);
        }
        exact_decimal(raw).map(Some).ok_or(FieldError { index: self.index })
    }

    /// The next field as an unsigned integer; `Ok(None)` when empty.
    pub fn u32(&mut self) -> Result<Option<u32>, FieldError> {
        let raw = self.next_raw();
        if raw.is_empty() {
            return Ok(None);
        }
        let bad = FieldError { index: self.index };
        let mut v: u32 = 0;
        for &b in raw {
            let d = b.checked_sub(b'0').filter(|d| *d <= 9).ok_or(bad)?;
            v = v.checked_mul(10).and_then(|v| v.checked_add(u32::from(d))).ok_or(bad)?;
        }
        Ok(Some(v))
    }

    /// The next field's first byte; `None` when empty.
    pub fn char(&mut self) -> Option<u8> {
        self.next_raw().first().copied()
    }
}

/// Powers of ten exactly representable in `f64`.
const POW10: [f64; 16] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15];

/// `[-+]digits[.digits]`, the only form NMEA 0183 numbers take. Up to 15 digits it is
/// converted exactly: the mantissa and the power of ten are both exact in `f64`, so one
/// division rounds correctly — the same value `str::parse` gives (Clinger's fast path).
/// Fraction digits past the fifteenth are dropped (a part in 10¹⁵: no receiver resolves
/// it), which spares a device the general parser and its tables (13 KB of flash). `None`
/// for any other form (an exponent, two dots, no digit) or more than 15 integer digits.
fn exact_decimal(raw: &[u8]) -> Option<f64> {
    let (negative, digits) = match raw.split_first()? {
        (b'-', rest) => (true, rest),
        (b'+', rest) => (false, rest),
        _ => (false, raw),
    };
    // One pass: digits into the mantissa, counting those after the (single) dot.
    let mut mantissa: u64 = 0;
    let mut count = 0usize;
    let mut frac_len = 0usize;
    let mut seen_dot = false;
    for &b in digits {
        if b == b'.' && !seen_dot {
            seen_dot = true;
            continue;
        }
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        if count == 15 {
            if seen_dot {
                continue;
            }
            return None;
        }
        mantissa = mantissa * 10 + u64::from(d);
        count += 1;
        frac_len += usize::from(seen_dot);
    }
    if count == 0 {
        return None;
    }
    let v = mantissa as f64 / POW10[frac_len];
    Some(if negative { -v } else { v })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn exact_decimal_equals_the_standard_parser(int in 0u64..100_000_000, frac in 0u64..10_000_000, digits in 0usize..8, negative: bool) {
            extern crate std;
            use std::format;
            let text = if digits == 0 { format!("{int}") } else { format!("{int}.{:0width$}", frac % 10u64.pow(digits as u32), width = digits) };
            let text = if negative { format!("-{text}") } else { text };
            let expected: f64 = text.parse().expect("number");
            prop_assert_eq!(exact_decimal(text.as_bytes()).map(f64::to_bits), Some(expected.to_bits()));
        }
    }

    #[test]
    fn exact_decimal_keeps_fifteen_digits_and_refuses_other_forms() {
        assert_eq!(exact_decimal(b"1234567890.1234567"), Some(1234567890.12345), "15 digits kept");
        assert_eq!(exact_decimal(b"1234567890123456"), None, "16 integer digits");
        assert_eq!(exact_decimal(b"1e5"), None);
        assert_eq!(exact_decimal(b"."), None);
        assert_eq!(exact_decimal(b"1.2.3"), None);
        assert_eq!(exact_decimal(b"4807.038"), Some(4807.038));
    }

    #[test]
    fn checksum_talker_and_fields() {
        let s = Sentence::parse(b"$GPGGA,165007.000,4143.6058,N,08338.0778,W,1,06,1.5,204.3,M,-33.7,M,,0000*67", true)
            .expect("valid");
        assert_eq!(s.talker, Talker::Gps);
        assert_eq!(s.kind, b"GGA");
        let mut c = s.cursor();
        assert_eq!(c.f64(), Ok(Some(165007.0)));
        c.skip(4);
        assert_eq!(c.u32(), Ok(Some(1)));
        c.skip(6);
        assert_eq!(c.next_raw(), b"");
        assert_eq!(c.next_raw(), b"0000");
        assert_eq!(c.next_raw(), b"", "past the end reads empty");
    }

    #[test]
    fn bad_missing_and_proprietary() {
        let computed = b"GPGGA,1".iter().fold(0, |acc, b| acc ^ b);
        assert_eq!(Sentence::parse(b"$GPGGA,1*00", true), Err(SentenceError::BadChecksum { expected: 0, computed }));
        assert_eq!(Sentence::parse(b"$GPGGA,1", true), Err(SentenceError::MissingChecksum));
        assert!(Sentence::parse(b"$GPGGA,1", false).is_ok());
        let p = Sentence::parse(b"$PGRME,15.0,M,45.0,M,25.0,M", false).expect("proprietary");
        assert_eq!((p.talker, p.kind), (Talker::Proprietary, &b"GRME"[..]));
        assert_eq!(Sentence::parse(b"$GP", false), Err(SentenceError::Malformed));
        assert_eq!(Sentence::parse(b"GPGGA", false), Err(SentenceError::Malformed));
        let other = Sentence::parse(b"$SDDPT,1.0,0.0", false).expect("instrument");
        assert_eq!(other.talker, Talker::Other(*b"SD"));
    }
}
