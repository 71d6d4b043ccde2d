//! The 29-bit identifier of J1939 and NMEA 2000 (docs/conformance.md): priority, PGN, source and
//! destination share one extended CAN id.

/// PDU format values below this address one device (PDU1); from it on they broadcast.
const PDU2_FIRST_FORMAT: u32 = 240;

/// Destination meaning "every device".
pub const GLOBAL_ADDRESS: u8 = 0xFF;

/// A split J1939 / NMEA 2000 identifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct J1939Id {
    /// Priority, 0 (highest) to 7.
    pub priority: u8,
    /// Parameter group number (18 bits; PDU1 PGNs have their low byte cleared).
    pub pgn: u32,
    /// Source address.
    pub source: u8,
    /// Destination address; [`GLOBAL_ADDRESS`] for broadcast (every PDU2 PGN).
    pub destination: u8,
}

impl J1939Id {
    /// Split a 29-bit identifier (higher bits are ignored).
    pub const fn from_raw(raw: u32) -> Self {
        let raw = raw & 0x1FFF_FFFF;
        let priority = ((raw >> 26) & 0x7) as u8;
        let source = (raw & 0xFF) as u8;
        let pgn = (raw >> 8) & 0x3_FFFF;
        let pdu_format = (pgn >> 8) & 0xFF;
        if pdu_format < PDU2_FIRST_FORMAT {
            J1939Id { priority, pgn: pgn & 0x3_FF00, source, destination: (pgn & 0xFF) as u8 }
        } else {
            J1939Id { priority, pgn, source, destination: GLOBAL_ADDRESS }
        }
    }

    /// The 29-bit identifier again.
    pub const fn to_raw(self) -> u32 {
        let mut pgn = self.pgn & 0x3_FFFF;
        if (pgn >> 8) & 0xFF < PDU2_FIRST_FORMAT {
            pgn = (pgn & 0x3_FF00) | self.destination as u32;
        }
        ((self.priority as u32 & 0x7) << 26) | (pgn << 8) | self.source as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pdu2_broadcast_keeps_the_group_extension() {
        // candumpSample2: 09F8027F = priority 2, PGN 129026, source 127.
        let id = J1939Id::from_raw(0x09F8_027F);
        assert_eq!(id, J1939Id { priority: 2, pgn: 129_026, source: 127, destination: 255 });
        assert_eq!(id.to_raw(), 0x09F8_027F);
    }

    #[test]
    fn pdu1_moves_the_low_byte_to_the_destination() {
        // candumpSample1: 18EEFF01 = address claim (60928) to everyone from 1;
        // 18EA2301 = ISO request (59904) to 0x23.
        assert_eq!(J1939Id::from_raw(0x18EE_FF01), J1939Id { priority: 6, pgn: 60_928, source: 1, destination: 255 });
        let request = J1939Id::from_raw(0x18EA_2301);
        assert_eq!(request, J1939Id { priority: 6, pgn: 59_904, source: 1, destination: 0x23 });
        assert_eq!(request.to_raw(), 0x18EA_2301);
    }

    #[test]
    fn data_page_bits_are_part_of_the_pgn() {
        // 0x0CFEF100 (CSS J1939 log): CCVS1 65265 from 0; 0x19F20101: PGN 127489 + DP.
        assert_eq!(J1939Id::from_raw(0x0CFE_F100).pgn, 65_265);
        assert_eq!(J1939Id::from_raw(0x09F2_0101).pgn, 127_489);
    }

    #[test]
    fn round_trip_for_every_pdu_format() {
        for pf in 0..=255u32 {
            let raw = (3 << 26) | (1 << 24) | (pf << 16) | (0x42 << 8) | 0x17;
            assert_eq!(J1939Id::from_raw(raw).to_raw(), raw, "pf {pf}");
        }
    }
}
