//! NMEA 2000 GNSS messages (canboat's `canboat.json`; docs/conformance.md). Angles in degrees as
//! canboat prints them; `None` where the sender said "not available".
//!
//! Decimal resolutions are applied by dividing by an exact power of ten, never by
//! multiplying with an inexact one, so 379220534 × 1e-7° becomes the double nearest
//! 37.9220534 and prints as the decimal on the wire.

use super::bytes::{array, i16_at, i32_at, i64_at, u16_at, u32_at, u8_at};

/// PGN 129025, Position Rapid Update.
pub const POSITION_RAPID: u32 = 129_025;
/// PGN 129026, COG & SOG Rapid Update.
pub const COG_SOG_RAPID: u32 = 129_026;
/// PGN 129029, GNSS Position Data (fast packet).
pub const GNSS_POSITION: u32 = 129_029;

/// A message too short for its PGN.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Truncated {
    /// The PGN.
    pub pgn: u32,
    /// Bytes present.
    pub len: usize,
    /// Bytes needed.
    pub needed: usize,
}

impl core::fmt::Display for Truncated {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "PGN {} needs {} bytes, got {}", self.pgn, self.needed, self.len)
    }
}

impl core::error::Error for Truncated {}

fn need(pgn: u32, data: &[u8], needed: usize) -> Result<(), Truncated> {
    if data.len() < needed {
        Err(Truncated { pgn, len: data.len(), needed })
    } else {
        Ok(())
    }
}

/// PGN 129025.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PositionRapid {
    /// Latitude, degrees (1e-7° on the wire).
    pub latitude: Option<f64>,
    /// Longitude, degrees.
    pub longitude: Option<f64>,
}

impl PositionRapid {
    /// Decode an 8-byte payload.
    pub fn decode(data: &[u8]) -> Result<Self, Truncated> {
        need(POSITION_RAPID, data, 8)?;
        Ok(PositionRapid {
            latitude: i32_at(data, 0).map(|v| f64::from(v) / 1e7),
            longitude: i32_at(data, 4).map(|v| f64::from(v) / 1e7),
        })
    }
}

/// The reference of a course over ground.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CogReference {
    /// True north.
    True,
    /// Magnetic north.
    Magnetic,
    /// Error (2).
    Error,
    /// Null (3).
    Null,
}

impl CogReference {
    fn from_bits(bits: u8) -> Self {
        match bits & 0x3 {
            0 => CogReference::True,
            1 => CogReference::Magnetic,
            2 => CogReference::Error,
            _ => CogReference::Null,
        }
    }

    /// canboat's name for it.
    pub fn name(self) -> &'static str {
        match self {
            CogReference::True => "True",
            CogReference::Magnetic => "Magnetic",
            CogReference::Error => "Error",
            CogReference::Null => "Null",
        }
    }
}

/// PGN 129026.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CogSogRapid {
    /// Sequence id tying messages of one fix together.
    pub sid: Option<u8>,
    /// North reference of `cog`.
    pub cog_reference: CogReference,
    /// Course over ground, degrees (1e-4 rad on the wire).
    pub cog: Option<f64>,
    /// Speed over ground, m/s.
    pub sog: Option<f64>,
}

impl CogSogRapid {
    /// Decode an 8-byte payload.
    pub fn decode(data: &[u8]) -> Result<Self, Truncated> {
        need(COG_SOG_RAPID, data, 6)?;
        Ok(CogSogRapid {
            sid: u8_at(data, 0),
            cog_reference: CogReference::from_bits(data[1]),
            cog: u16_at(data, 2).map(|v| (f64::from(v) / 1e4).to_degrees()),
            sog: u16_at(data, 4).map(|v| f64::from(v) / 100.0),
        })
    }
}

/// PGN 129029. Reference stations after the fixed part are counted, not decoded.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GnssPosition {
    /// Sequence id.
    pub sid: Option<u8>,
    /// Days since 1970-01-01.
    pub date: Option<u16>,
    /// Seconds since midnight UTC in units of 0.1 ms.
    pub time: Option<u32>,
    /// Latitude, degrees (1e-16° on the wire).
    pub latitude: Option<f64>,
    /// Longitude, degrees.
    pub longitude: Option<f64>,
    /// Height above the WGS84 ellipsoid, metres (1e-6 m on the wire).
    pub altitude: Option<f64>,
    /// Constellations, canboat's "GNSS type" lookup (0–15).
    pub gnss_type: u8,
    /// Fix method, canboat's "Method" lookup (0–15; 0 = no fix).
    pub method: u8,
    /// Integrity checking, 0–3.
    pub integrity: u8,
    /// Satellites used.
    pub satellites: Option<u8>,
    /// Horizontal dilution of precision.
    pub hdop: Option<f64>,
    /// Position dilution of precision.
    pub pdop: Option<f64>,
    /// Geoid height above the ellipsoid, metres.
    pub geoidal_separation: Option<f64>,
    /// Reference stations listed after the fixed part.
    pub reference_stations: Option<u8>,
}

/// The fixed part of PGN 129029.
const GNSS_POSITION_LEN: usize = 43;

impl GnssPosition {
    /// Decode a reassembled payload (at least 43 bytes).
    pub fn decode(data: &[u8]) -> Result<Self, Truncated> {
        need(GNSS_POSITION, data, GNSS_POSITION_LEN)?;
        let type_method = array::<1>(data, 31).map_or(0, |[b]| b);
        Ok(GnssPosition {
            sid: u8_at(data, 0),
            date: u16_at(data, 1),
            time: u32_at(data, 3),
            latitude: i64_at(data, 7).map(|v| v as f64 / 1e16),
            longitude: i64_at(data, 15).map(|v| v as f64 / 1e16),
            altitude: i64_at(data, 23).map(|v| v as f64 / 1e6),
            gnss_type: type_method & 0x0F,
            method: type_method >> 4,
            integrity: array::<1>(data, 32).map_or(0, |[b]| b & 0x3),
            satellites: u8_at(data, 33),
            hdop: i16_at(data, 34).map(|v| f64::from(v) / 100.0),
            pdop: i16_at(data, 36).map(|v| f64::from(v) / 100.0),
            geoidal_separation: i32_at(data, 38).map(|v| f64::from(v) / 100.0),
            reference_stations: u8_at(data, 42),
        })
    }

    /// Seconds since the Unix epoch, when both date and time are given.
    pub fn unix_time(&self) -> Option<f64> {
        Some(f64::from(self.date?) * 86_400.0 + f64::from(self.time?) * 1e-4)
    }

    /// canboat's name for [`Self::gnss_type`].
    pub fn gnss_type_name(&self) -> Option<&'static str> {
        [
            "GPS",
            "GLONASS",
            "GPS+GLONASS",
            "GPS+SBAS/WAAS",
            "GPS+SBAS/WAAS+GLONASS",
            "Chayka",
            "integrated",
            "surveyed",
            "Galileo",
        ]
        .get(usize::from(self.gnss_type))
        .copied()
    }

    /// canboat's name for [`Self::method`].
    pub fn method_name(&self) -> Option<&'static str> {
        [
            "no GNSS",
            "GNSS fix",
            "DGNSS fix",
            "Precise GNSS",
            "RTK Fixed Integer",
            "RTK float",
            "Estimated (DR) mode",
            "Manual Input",
            "Simulate mode",
        ]
        .get(usize::from(self.method))
        .copied()
    }

    /// canboat's name for [`Self::integrity`].
    pub fn integrity_name(&self) -> Option<&'static str> {
        ["No integrity checking", "Safe", "Caution"].get(usize::from(self.integrity)).copied()
    }
}

/// Whether `pgn` is sent as a fast packet. Only the PGNs decoded here are listed; every
/// other PGN is passed through as single frames.
pub fn is_fast_packet(pgn: u32) -> bool {
    pgn == GNSS_POSITION
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn position_rapid_matches_canboat() {
        // gpsd nmea2000 log: 09F80102#36729A16021AB80D → 37.9220534, 23.0169090.
        let p = PositionRapid::decode(&[0x36, 0x72, 0x9A, 0x16, 0x02, 0x1A, 0xB8, 0x0D]).expect("valid");
        assert!((p.latitude.expect("valid") - 37.922_053_4).abs() < 1e-12);
        assert!((p.longitude.expect("valid") - 23.016_909_0).abs() < 1e-12);
        assert_eq!(PositionRapid::decode(&[0; 7]), Err(Truncated { pgn: POSITION_RAPID, len: 7, needed: 8 }));
        let none = PositionRapid::decode(&[0xFF, 0xFF, 0xFF, 0x7F, 0xFF, 0xFF, 0xFF, 0x7F]).expect("valid");
        assert_eq!((none.latitude, none.longitude), (None, None));
    }

    #[test]
    fn cog_sog_in_degrees_and_metres_per_second() {
        // candumpSample2: 00 FC FF FF 00 00 FF FF → SID 0, True, no COG, SOG 0.00.
        let m = CogSogRapid::decode(&[0x00, 0xFC, 0xFF, 0xFF, 0x00, 0x00, 0xFF, 0xFF]).expect("valid");
        assert_eq!(m, CogSogRapid { sid: Some(0), cog_reference: CogReference::True, cog: None, sog: Some(0.0) });
        // COG 31416 × 1e-4 rad = 180.0004°, SOG 1234 → 12.34 m/s, magnetic.
        let m = CogSogRapid::decode(&[7, 0xFD, 0xB8, 0x7A, 0xD2, 0x04, 0xFF, 0xFF]).expect("valid");
        assert_eq!(m.cog_reference, CogReference::Magnetic);
        assert!((m.cog.expect("valid") - 180.000_420_9).abs() < 1e-6);
        assert!((m.sog.expect("valid") - 12.34).abs() < 1e-12);
    }

    #[test]
    fn gnss_position_fixed_part() {
        let mut data = [0u8; 43];
        data[0] = 1;
        data[1..3].copy_from_slice(&15_765u16.to_le_bytes()); // 2013-03-01
        data[3..7].copy_from_slice(&700_960_000u32.to_le_bytes()); // 19:28:16
        data[7..15].copy_from_slice(&424_967_536_000_000_000i64.to_le_bytes());
        data[15..23].copy_from_slice(&(-715_836_771_000_000_000i64).to_le_bytes());
        data[23..31].copy_from_slice(&86_504_058i64.to_le_bytes());
        data[31] = 0x13; // GPS+SBAS/WAAS, GNSS fix
        data[32] = 0xFC;
        data[33] = 9;
        data[34..36].copy_from_slice(&(-1i16).to_le_bytes());
        data[36..38].copy_from_slice(&i16::MAX.to_le_bytes());
        data[38..42].copy_from_slice(&(-3363i32).to_le_bytes());
        let m = GnssPosition::decode(&data).expect("valid");
        assert_eq!((m.sid, m.date, m.time, m.satellites), (Some(1), Some(15_765), Some(700_960_000), Some(9)));
        assert!((m.latitude.expect("valid") - 42.496_753_6).abs() < 1e-12);
        assert!((m.longitude.expect("valid") + 71.583_677_1).abs() < 1e-12);
        assert!((m.altitude.expect("valid") - 86.504_058).abs() < 1e-9);
        assert_eq!(
            (m.gnss_type_name(), m.method_name(), m.integrity_name()),
            (Some("GPS+SBAS/WAAS"), Some("GNSS fix"), Some("No integrity checking"))
        );
        assert_eq!((m.hdop, m.pdop), (Some(-0.01), None));
        assert!((m.geoidal_separation.expect("valid") + 33.63).abs() < 1e-12);
        assert_eq!(m.unix_time(), Some(15_765.0 * 86_400.0 + 70_096.0));
        assert!(GnssPosition::decode(&data[..42]).is_err());
    }
}
