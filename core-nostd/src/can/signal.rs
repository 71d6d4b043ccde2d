//! DBC-defined signals, extracted from classic CAN frames.
//!
//! The std side parses a DBC file into [`Signal`]s (validated once); this side only reads
//! bits. A DBC start bit is the least significant bit for Intel (little-endian) signals
//! and the most significant bit, in the byte-wise "sawtooth" numbering, for Motorola
//! (big-endian) ones. Both are read with one 64-bit load and a shift.

/// Bits in a classic CAN payload.
const FRAME_BITS: u16 = 64;

/// Byte order of a signal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ByteOrder {
    /// Little-endian (`@1` in DBC).
    Intel,
    /// Big-endian (`@0` in DBC).
    Motorola,
}

/// A signal's role in a multiplexed message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Multiplex {
    /// Always present.
    Plain,
    /// Selects which multiplexed signals are present (`M`).
    Multiplexor,
    /// Present only when the multiplexor equals this value (`m<value>`).
    Multiplexed(u64),
}

/// A signal definition that does not fit a classic CAN frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SignalError {
    /// Length 0 or above 64 bits.
    BadLength(u16),
    /// Some bits lie outside the 8 bytes of a classic frame.
    OutsideFrame {
        /// DBC start bit.
        start_bit: u16,
        /// Length in bits.
        length: u16,
    },
    /// Factor or offset is not finite.
    NotFinite,
}

impl core::fmt::Display for SignalError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SignalError::BadLength(len) => write!(f, "signal length {len} outside 1..=64"),
            SignalError::OutsideFrame { start_bit, length } => {
                write!(f, "signal {start_bit}|{length} does not fit 8 bytes")
            }
            SignalError::NotFinite => write!(f, "factor or offset is not finite"),
        }
    }
}

impl core::error::Error for SignalError {}

/// One signal: where its bits are and how they scale.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Signal {
    /// The DBC start bit.
    pub start_bit: u16,
    /// Length in bits, 1–64.
    pub length: u16,
    /// Byte order.
    pub byte_order: ByteOrder,
    /// Two's complement.
    pub signed: bool,
    /// Physical = raw × factor + offset.
    pub factor: f64,
    /// See `factor`.
    pub offset: f64,
    /// Multiplexing role.
    pub multiplex: Multiplex,
    /// Shift of the signal's least significant bit in the frame read as one 64-bit word
    /// (little-endian load for Intel, big-endian for Motorola).
    shift: u16,
    /// Bytes the frame must carry for every bit of the signal to be present.
    bytes_needed: u16,
}

impl Signal {
    /// Validate a definition.
    pub fn new(
        start_bit: u16,
        length: u16,
        byte_order: ByteOrder,
        signed: bool,
        factor: f64,
        offset: f64,
        multiplex: Multiplex,
    ) -> Result<Self, SignalError> {
        if !(1..=64).contains(&length) {
            return Err(SignalError::BadLength(length));
        }
        if !factor.is_finite() || !offset.is_finite() {
            return Err(SignalError::NotFinite);
        }
        let outside = SignalError::OutsideFrame { start_bit, length };
        let (shift, last_bit) = match byte_order {
            ByteOrder::Intel => (start_bit, start_bit.checked_add(length - 1).ok_or(outside)?),
            ByteOrder::Motorola => {
                // Position counted from the most significant bit of byte 0.
                let msb = (start_bit / 8) * 8 + (7 - start_bit % 8);
                let lsb = msb.checked_add(length - 1).ok_or(outside)?;
                if lsb >= FRAME_BITS {
                    return Err(outside);
                }
                // The byte holding the lsb, in little-endian bit numbering, bounds the frame.
                (FRAME_BITS - 1 - lsb, (lsb / 8) * 8)
            }
        };
        if last_bit >= FRAME_BITS || start_bit >= FRAME_BITS {
            return Err(outside);
        }
        Ok(Signal {
            start_bit,
            length,
            byte_order,
            signed,
            factor,
            offset,
            multiplex,
            shift,
            bytes_needed: last_bit / 8 + 1,
        })
    }

    /// The raw integer, sign-extended when signed; `None` when the frame is too short.
    pub fn raw(&self, data: &[u8]) -> Option<i128> {
        if data.len() < usize::from(self.bytes_needed) {
            return None;
        }
        let mut bytes = [0u8; 8];
        let n = data.len().min(8);
        bytes.get_mut(..n)?.copy_from_slice(data.get(..n)?);
        let word = match self.byte_order {
            ByteOrder::Intel => u64::from_le_bytes(bytes),
            ByteOrder::Motorola => u64::from_be_bytes(bytes),
        };
        let mask = u64::MAX >> (64 - self.length);
        let raw = (word >> self.shift) & mask;
        let sign_bit = 1u64 << (self.length - 1);
        Some(if self.signed && raw & sign_bit != 0 {
            i128::from(raw) - (1i128 << self.length)
        } else {
            i128::from(raw)
        })
    }

    /// The physical value; `None` when the frame is too short.
    pub fn value(&self, data: &[u8]) -> Option<f64> {
        self.raw(data).map(|raw| raw as f64 * self.factor + self.offset)
    }
}

/// Call `emit(index, value)` for every signal of a message present in `data`: plain
/// signals, the multiplexor, and the multiplexed signals it selects. Signals whose bits
/// the frame does not carry are skipped; the count of those is returned.
pub fn decode_message(signals: &[Signal], data: &[u8], mut emit: impl FnMut(usize, f64)) -> usize {
    let selector = signals
        .iter()
        .find(|s| s.multiplex == Multiplex::Multiplexor)
        .and_then(|s| s.raw(data))
        .and_then(|raw| u64::try_from(raw).ok());
    let mut missing = 0;
    for (index, signal) in signals.iter().enumerate() {
        if let Multiplex::Multiplexed(value) = signal.multiplex {
            if selector != Some(value) {
                continue;
            }
        }
        match signal.value(data) {
            Some(value) => emit(index, value),
            None => missing += 1,
        }
    }
    missing
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signal(start: u16, len: u16, order: ByteOrder, signed: bool) -> Signal {
        Signal::new(start, len, order, signed, 1.0, 0.0, Multiplex::Plain).expect("valid")
    }

    /// Bit-by-bit reference, the way the DBC format defines the numbering.
    fn reference(s: &Signal, data: &[u8; 8]) -> u64 {
        let bit = |pos: u16| u64::from(data[usize::from(pos / 8)] >> (pos % 8) & 1);
        let mut value = 0u64;
        match s.byte_order {
            ByteOrder::Intel => {
                for i in 0..s.length {
                    value |= bit(s.start_bit + i) << i;
                }
            }
            ByteOrder::Motorola => {
                let mut pos = s.start_bit;
                for _ in 0..s.length {
                    value = value << 1 | bit(pos);
                    pos = if pos.is_multiple_of(8) { pos + 15 } else { pos - 1 };
                }
            }
        }
        value
    }

    #[test]
    fn toyota_wheel_speed_motorola() {
        // comma2k19 0xAA WHEEL_SPEEDS: WHEEL_SPEED_FR 6|15@0+ (0.01,-67.67) km/h.
        let fr = Signal::new(6, 15, ByteOrder::Motorola, false, 0.01, -67.67, Multiplex::Plain).expect("valid");
        let data = [0x1B, 0x52, 0x1B, 0x48, 0x1B, 0x2F, 0x1B, 0x38];
        assert_eq!(fr.raw(&data), Some(0x1B52));
        assert!((fr.value(&data).expect("valid") - (f64::from(0x1B52) * 0.01 - 67.67)).abs() < 1e-12);
        assert_eq!(fr.raw(&data[..1]), None, "second byte missing");
    }

    #[test]
    fn intel_signed_with_factor() {
        // 12-bit signed at bit 4: raw 0xF9C = -100.
        let s = Signal::new(4, 12, ByteOrder::Intel, true, 0.5, 1.0, Multiplex::Plain).expect("valid");
        let data = [0xC0, 0xF9];
        assert_eq!(s.raw(&data), Some(-100));
        assert_eq!(s.value(&data), Some(-49.0));
    }

    #[test]
    fn full_width_signals() {
        let data = [0x81, 2, 3, 4, 5, 6, 7, 0x88];
        assert_eq!(signal(0, 64, ByteOrder::Intel, false).raw(&data), Some(i128::from(u64::from_le_bytes(data))));
        assert_eq!(signal(7, 64, ByteOrder::Motorola, false).raw(&data), Some(i128::from(u64::from_be_bytes(data))));
        assert_eq!(signal(0, 64, ByteOrder::Intel, true).raw(&data), Some(i128::from(i64::from_le_bytes(data))));
    }

    #[test]
    fn every_position_matches_the_bitwise_definition() {
        let data = [0xA5, 0x3C, 0x0F, 0xF0, 0x96, 0x69, 0x12, 0xED];
        let mut checked = 0;
        for order in [ByteOrder::Intel, ByteOrder::Motorola] {
            for start in 0..64 {
                for len in 1..=64 {
                    let Ok(s) = Signal::new(start, len, order, false, 1.0, 0.0, Multiplex::Plain) else { continue };
                    assert_eq!(s.raw(&data), Some(i128::from(reference(&s, &data))), "{order:?} {start}|{len}");
                    checked += 1;
                }
            }
        }
        // Every Intel start/length pair that fits (2080) and as many Motorola ones.
        assert_eq!(checked, 2 * 2080);
    }

    #[test]
    fn definitions_outside_the_frame_are_rejected() {
        let bad = |start, len, order| {
            Signal::new(start, len, order, false, 1.0, 0.0, Multiplex::Plain).expect_err("rejected")
        };
        assert_eq!(bad(60, 8, ByteOrder::Intel), SignalError::OutsideFrame { start_bit: 60, length: 8 });
        assert_eq!(bad(56, 9, ByteOrder::Motorola), SignalError::OutsideFrame { start_bit: 56, length: 9 });
        assert_eq!(bad(0, 0, ByteOrder::Intel), SignalError::BadLength(0));
        assert_eq!(bad(0, 65, ByteOrder::Intel), SignalError::BadLength(65));
        assert!(Signal::new(0, 8, ByteOrder::Intel, false, f64::NAN, 0.0, Multiplex::Plain).is_err());
    }

    #[test]
    fn multiplexed_signals_follow_their_selector() {
        let signals = [
            Signal::new(0, 8, ByteOrder::Intel, false, 1.0, 0.0, Multiplex::Multiplexor).expect("valid"),
            Signal::new(8, 8, ByteOrder::Intel, false, 1.0, 0.0, Multiplex::Multiplexed(1)).expect("valid"),
            Signal::new(8, 16, ByteOrder::Intel, false, 1.0, 0.0, Multiplex::Multiplexed(2)).expect("valid"),
            Signal::new(56, 8, ByteOrder::Intel, false, 1.0, 0.0, Multiplex::Plain).expect("valid"),
        ];
        let mut seen = heapless::Vec::<(usize, f64), 4>::new();
        let missing = decode_message(&signals, &[2, 0x34, 0x12], |i, v| seen.push((i, v)).expect("valid"));
        assert_eq!(seen.as_slice(), &[(0, 2.0), (2, 4660.0)]);
        assert_eq!(missing, 1, "the plain signal in byte 7 is not in a 3-byte frame");
    }
}
