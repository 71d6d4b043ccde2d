//! J1939 vehicle speed and position (SAE J1939-71; docs/conformance.md).
//!
//! J1939 marks 0xFB00.. (16-bit) and 0xFB00_0000.. (32-bit) as error / not available
//! rather than only all ones, so those ranges decode to `None`.

use super::bytes::array;
use super::n2k::Truncated;

/// PGN 65265, Cruise Control / Vehicle Speed 1 (CCVS1).
pub const CCVS1: u32 = 65_265;
/// PGN 65267, Vehicle Position 1 (VP1).
pub const VEHICLE_POSITION: u32 = 65_267;

fn u16_valid(data: &[u8], offset: usize) -> Option<u16> {
    array(data, offset).map(u16::from_le_bytes).filter(|&v| v < 0xFB00)
}

fn u32_valid(data: &[u8], offset: usize) -> Option<u32> {
    array(data, offset).map(u32::from_le_bytes).filter(|&v| v < 0xFB00_0000)
}

/// PGN 65265: the wheel-based vehicle speed (SPN 84).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelSpeed {
    /// km/h (1/256 km/h on the wire).
    pub speed_kmh: Option<f64>,
}

impl WheelSpeed {
    /// Decode bytes 1–2 of a CCVS1 payload.
    pub fn decode(data: &[u8]) -> Result<Self, Truncated> {
        if data.len() < 3 {
            return Err(Truncated { pgn: CCVS1, len: data.len(), needed: 3 });
        }
        Ok(WheelSpeed { speed_kmh: u16_valid(data, 1).map(|v| f64::from(v) / 256.0) })
    }
}

/// PGN 65267: latitude and longitude (SPN 584/585).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VehiclePosition {
    /// Degrees (1e-7° with −210° offset on the wire).
    pub latitude: Option<f64>,
    /// Degrees.
    pub longitude: Option<f64>,
}

impl VehiclePosition {
    /// Decode an 8-byte VP1 payload.
    pub fn decode(data: &[u8]) -> Result<Self, Truncated> {
        if data.len() < 8 {
            return Err(Truncated { pgn: VEHICLE_POSITION, len: data.len(), needed: 8 });
        }
        let degrees = |raw: u32| f64::from(raw) / 1e7 - 210.0;
        Ok(VehiclePosition { latitude: u32_valid(data, 0).map(degrees), longitude: u32_valid(data, 4).map(degrees) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wheel_speed_is_bytes_1_and_2_in_256ths_of_km_h() {
        // 0x3200 / 256 = 50 km/h.
        assert_eq!(WheelSpeed::decode(&[0xFF, 0x00, 0x32, 0xFF]).expect("valid").speed_kmh, Some(50.0));
        assert_eq!(WheelSpeed::decode(&[0xFF, 0x80, 0x00]).expect("valid").speed_kmh, Some(0.5));
        assert_eq!(WheelSpeed::decode(&[0xFF, 0x00, 0xFB]).expect("valid").speed_kmh, None, "error range");
        assert!(WheelSpeed::decode(&[0xFF, 0x00]).is_err());
    }

    #[test]
    fn vehicle_position_removes_the_offset() {
        // 56.1° N 10.2° E: (56.1 + 210) / 1e-7 = 2 661 000 000.
        let mut data = [0u8; 8];
        data[..4].copy_from_slice(&2_661_000_000u32.to_le_bytes());
        data[4..].copy_from_slice(&2_202_000_000u32.to_le_bytes());
        let p = VehiclePosition::decode(&data).expect("valid");
        assert!((p.latitude.expect("valid") - 56.1).abs() < 1e-9);
        assert!((p.longitude.expect("valid") - 10.2).abs() < 1e-9);
        data[4..].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(VehiclePosition::decode(&data).expect("valid").longitude, None);
        assert!(VehiclePosition::decode(&data[..7]).is_err());
    }
}
