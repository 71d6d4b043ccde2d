//! The one time type of the SDK: signed microseconds.
//!
//! Every stream dash2sim ingests (VO poses, GNSS fixes, CAN frames, detections) carries a
//! [`Timestamp`]. Microseconds in an `i64` cover ±292 000 years exactly, so there is no
//! rounding drift over long drives and no floating point in comparisons (as smoltcp's
//! `Instant`). Conversions from floating-point seconds are checked: NaN, infinities and
//! out-of-range values are rejected instead of saturating silently.

use core::fmt;
use core::ops::{Add, Sub};

/// A point in time, in microseconds since an epoch chosen by the source
/// (device boot, Unix epoch, GPS epoch — the stream says which).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Timestamp {
    micros: i64,
}

/// A signed span of time in microseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Duration {
    micros: i64,
}

/// Largest magnitude in seconds accepted from floating point: beyond 2^53 µs an `f64`
/// no longer represents every microsecond.
const MAX_EXACT_SECS: f64 = 9_007_199_254.740_992;

fn micros_from_secs(secs: f64) -> Option<i64> {
    if !secs.is_finite() || libm::fabs(secs) > MAX_EXACT_SECS {
        return None;
    }
    // In range by the check above, so the cast cannot saturate.
    Some(libm::round(secs * 1e6) as i64)
}

impl Timestamp {
    /// The epoch itself.
    pub const ZERO: Timestamp = Timestamp { micros: 0 };

    /// From whole microseconds.
    pub const fn from_micros(micros: i64) -> Self {
        Timestamp { micros }
    }

    /// From seconds, rounded to the nearest microsecond; `None` for NaN, ±inf or
    /// magnitudes above 2^53 µs (≈ 285 years).
    pub fn from_secs_f64(secs: f64) -> Option<Self> {
        micros_from_secs(secs).map(Timestamp::from_micros)
    }

    /// Microseconds since the epoch.
    pub const fn micros(self) -> i64 {
        self.micros
    }

    /// Seconds since the epoch as `f64` (exact below 2^53 µs).
    pub fn as_secs_f64(self) -> f64 {
        self.micros as f64 * 1e-6
    }

    /// `self - earlier`, or `None` on overflow.
    pub fn checked_duration_since(self, earlier: Timestamp) -> Option<Duration> {
        self.micros.checked_sub(earlier.micros).map(Duration::from_micros)
    }

    /// `self + d`, or `None` on overflow.
    pub fn checked_add(self, d: Duration) -> Option<Timestamp> {
        self.micros.checked_add(d.micros).map(Timestamp::from_micros)
    }
}

impl Duration {
    /// No time at all.
    pub const ZERO: Duration = Duration { micros: 0 };

    /// From whole microseconds.
    pub const fn from_micros(micros: i64) -> Self {
        Duration { micros }
    }

    /// From whole milliseconds (saturating at the `i64` range).
    pub const fn from_millis(millis: i64) -> Self {
        Duration { micros: millis.saturating_mul(1000) }
    }

    /// From seconds, rounded to the nearest microsecond; `None` when not representable.
    pub fn from_secs_f64(secs: f64) -> Option<Self> {
        micros_from_secs(secs).map(Duration::from_micros)
    }

    /// Whole microseconds.
    pub const fn micros(self) -> i64 {
        self.micros
    }

    /// Seconds as `f64`.
    pub fn as_secs_f64(self) -> f64 {
        self.micros as f64 * 1e-6
    }
}

impl Add<Duration> for Timestamp {
    type Output = Timestamp;
    /// Saturating: timestamps from the field never approach the `i64` range, and a
    /// saturated value is still ordered correctly.
    fn add(self, d: Duration) -> Timestamp {
        Timestamp::from_micros(self.micros.saturating_add(d.micros))
    }
}

impl Sub<Duration> for Timestamp {
    type Output = Timestamp;
    fn sub(self, d: Duration) -> Timestamp {
        Timestamp::from_micros(self.micros.saturating_sub(d.micros))
    }
}

impl Sub<Timestamp> for Timestamp {
    type Output = Duration;
    fn sub(self, earlier: Timestamp) -> Duration {
        Duration::from_micros(self.micros.saturating_sub(earlier.micros))
    }
}

impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sign = if self.micros < 0 { "-" } else { "" };
        let abs = self.micros.unsigned_abs();
        write!(f, "{sign}{}.{:06}s", abs / 1_000_000, abs % 1_000_000)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_round_trip_to_the_microsecond() {
        let t = Timestamp::from_secs_f64(46408.547498).expect("finite");
        assert_eq!(t.micros(), 46_408_547_498);
        assert!((t.as_secs_f64() - 46408.547498).abs() < 1e-9);
    }

    #[test]
    fn non_finite_and_huge_seconds_are_rejected() {
        assert_eq!(Timestamp::from_secs_f64(f64::NAN), None);
        assert_eq!(Timestamp::from_secs_f64(f64::INFINITY), None);
        assert_eq!(Timestamp::from_secs_f64(1e300), None);
        assert_eq!(Duration::from_secs_f64(-f64::INFINITY), None);
    }

    #[test]
    fn arithmetic_saturates_instead_of_wrapping() {
        let t = Timestamp::from_micros(i64::MAX - 1);
        assert_eq!((t + Duration::from_micros(10)).micros(), i64::MAX);
        assert_eq!(t.checked_add(Duration::from_micros(10)), None);
        let d = Timestamp::from_micros(1_500_000) - Timestamp::from_micros(500_000);
        assert_eq!(d, Duration::from_millis(1000));
    }

    #[test]
    fn display_shows_signed_seconds() {
        extern crate std;
        use std::string::ToString;
        assert_eq!(Timestamp::from_micros(-1_500_000).to_string(), "-1.500000s");
        assert_eq!(Timestamp::from_micros(2_000_001).to_string(), "2.000001s");
    }
}
