//! Numbers written as decimal text through integer formatting.
//!
//! The pipeline's events say how many seconds, degrees and per cent; `{:.2}` on an `f64`
//! would link core's float formatting (Grisu and Dragon4 with their tables, about 8 KiB)
//! into a device whose flash is counted in bytes. [`Decimal`] rounds to a fixed number of
//! decimals (half away from zero) and writes integers. It never panics: what does not fit
//! in 64 bits is written saturated. Public for firmware that prints its own figures (the MCU
//! example does).

use core::fmt;

/// Powers of ten up to the most decimals [`Decimal`] writes.
const UNITS: [u64; 7] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000];

/// `value` written with a fixed number of decimals, as `format!("{value:.N}")` would but
/// for ties and the last digit of values near 2⁵³ (rounded half away from zero here, in
/// binary there), and with `+` before a non-negative value when [`Decimal::signed`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decimal {
    value: f64,
    decimals: usize,
    plus: bool,
}

impl Decimal {
    /// `value` with `decimals` (at most 6) digits after the point.
    pub fn new(value: f64, decimals: usize) -> Self {
        Decimal { value, decimals: decimals.min(UNITS.len() - 1), plus: false }
    }

    /// The same, with `+` before a non-negative value.
    pub fn signed(value: f64, decimals: usize) -> Self {
        Decimal { plus: true, ..Decimal::new(value, decimals) }
    }
}

impl fmt::Display for Decimal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sign = if self.value.is_sign_negative() {
            "-"
        } else if self.plus {
            "+"
        } else {
            ""
        };
        if self.value.is_nan() {
            return f.write_str("NaN");
        }
        if self.value.is_infinite() {
            return write!(f, "{sign}inf");
        }
        let unit = UNITS.get(self.decimals).copied().unwrap_or(1);
        // `as` saturates: a value beyond u64 is written as its largest.
        let scaled = libm::round(libm::fabs(self.value) * unit as f64) as u64;
        if self.decimals == 0 {
            return write!(f, "{sign}{scaled}");
        }
        write!(f, "{sign}{}.{:0width$}", scaled / unit, scaled % unit, width = self.decimals)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::format;

    use super::Decimal;

    #[test]
    fn writes_what_float_formatting_writes() {
        for (value, decimals) in [
            (0.0, 1),
            (5.3, 1),
            (-2.71, 2),
            (-0.001, 2),
            (-0.0, 1),
            (1234.5678, 4),
            (0.004, 2),
            (99.996, 2),
            (7.0, 3),
            (1e6, 2),
        ] {
            assert_eq!(format!("{}", Decimal::new(value, decimals)), format!("{value:.decimals$}"), "{value}");
        }
        assert_eq!(format!("{}", Decimal::signed(2.5, 2)), format!("{:+.2}", 2.5));
        assert_eq!(format!("{}", Decimal::signed(-0.25, 2)), format!("{:+.2}", -0.25));
        assert_eq!(format!("{}", Decimal::signed(0.0, 2)), format!("{:+.2}", 0.0));
    }

    #[test]
    fn ties_go_away_from_zero() {
        // 5.25 is exact in binary: float formatting rounds it to even, "5.2".
        assert_eq!(format!("{}", Decimal::new(5.25, 1)), "5.3");
        assert_eq!(format!("{}", Decimal::new(-0.125, 2)), "-0.13");
    }

    #[test]
    fn odd_values_are_written_not_panicked_on() {
        assert_eq!(format!("{}", Decimal::new(f64::NAN, 2)), "NaN");
        assert_eq!(format!("{}", Decimal::new(f64::INFINITY, 2)), format!("{:.2}", f64::INFINITY));
        assert_eq!(format!("{}", Decimal::new(f64::NEG_INFINITY, 1)), format!("{:.1}", f64::NEG_INFINITY));
        assert_eq!(format!("{}", Decimal::new(1e300, 2)), "184467440737095516.15");
        assert_eq!(format!("{}", Decimal::new(1.5, 99)), "1.500000");
    }
}
