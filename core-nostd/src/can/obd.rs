//! OBD-II mode 01 ("show current data") responses (SAE J1979 / ISO 15765-4; docs/conformance.md).
//!
//! A tester asks `02 01 PID` on 0x7DF (or 0x18DB33F1); ECU `n` answers on 0x7E8 + n
//! (or 0x18DAF1xx) with a single ISO-TP frame `len 41 PID A [B C D]`.

use embedded_can::Id;

/// Mode 01 PID 0x0D, vehicle speed in km/h.
pub const VEHICLE_SPEED: u8 = 0x0D;

/// A mode 01 response: which ECU, which PID, and its 1–4 data bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Response {
    /// Responding ECU: 0–7 for 0x7E8–0x7EF, the source address for 29-bit ids.
    pub ecu: u8,
    /// Parameter id.
    pub pid: u8,
    len: u8,
    data: [u8; 4],
}

impl Response {
    /// Decode `frame_data` sent with `id`; `None` when it is not a mode 01 response.
    pub fn decode(id: Id, frame_data: &[u8]) -> Option<Self> {
        let ecu = match id {
            Id::Standard(id) if (0x7E8..=0x7EF).contains(&id.as_raw()) => (id.as_raw() - 0x7E8) as u8,
            Id::Extended(id) if id.as_raw() >> 8 == 0x18_DAF1 => (id.as_raw() & 0xFF) as u8,
            _ => return None,
        };
        // ISO-TP single frame: high nibble 0, low nibble = bytes that follow.
        let (&pci, rest) = frame_data.split_first()?;
        let len = usize::from(pci);
        let body = rest.get(..len)?;
        let (&[mode, pid], values) = body.split_first_chunk::<2>()?;
        if mode != 0x41 || values.is_empty() || values.len() > 4 {
            return None;
        }
        let mut data = [0; 4];
        data.get_mut(..values.len())?.copy_from_slice(values);
        Some(Response { ecu, pid, len: values.len() as u8, data })
    }

    /// The data bytes A, B, C, D (as many as the ECU sent).
    pub fn data(&self) -> &[u8] {
        self.data.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Vehicle speed in km/h when this is PID 0x0D.
    pub fn vehicle_speed_kmh(&self) -> Option<u8> {
        (self.pid == VEHICLE_SPEED).then(|| self.data().first().copied()).flatten()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can::frame::id_from_raw;

    fn standard(raw: u32) -> Id {
        id_from_raw(raw, false).expect("valid")
    }

    #[test]
    fn speed_response_from_the_css_drive() {
        // (1627275000.169400) can0 7E8#03410D3900000000 = 57 km/h.
        let r = Response::decode(standard(0x7E8), &[0x03, 0x41, 0x0D, 0x39, 0, 0, 0, 0]).expect("valid");
        assert_eq!((r.ecu, r.pid, r.data(), r.vehicle_speed_kmh()), (0, 13, &[0x39][..], Some(57)));
    }

    #[test]
    fn generic_shape_and_other_ecus() {
        // RPM (PID 0x0C) from ECU 1: 04 41 0C 1A F8.
        let r = Response::decode(standard(0x7E9), &[0x04, 0x41, 0x0C, 0x1A, 0xF8, 0xAA, 0xAA, 0xAA]).expect("valid");
        assert_eq!((r.ecu, r.pid, r.data(), r.vehicle_speed_kmh()), (1, 12, &[0x1A, 0xF8][..], None));
        let ext = id_from_raw(0x18DA_F110, true).expect("valid");
        assert_eq!(Response::decode(ext, &[0x03, 0x41, 0x0D, 0x10]).expect("valid").ecu, 0x10);
    }

    #[test]
    fn requests_other_modes_and_bad_lengths_are_not_responses() {
        assert_eq!(Response::decode(standard(0x7DF), &[0x02, 0x01, 0x0D, 0, 0, 0, 0, 0]), None);
        assert_eq!(Response::decode(standard(0x7E8), &[0x03, 0x42, 0x0D, 0x39]), None);
        assert_eq!(Response::decode(standard(0x7E8), &[0x07, 0x41, 0x0D, 0x39]), None, "length past the frame");
        assert_eq!(Response::decode(standard(0x7E8), &[0x02, 0x41, 0x0D]), None, "no data byte");
        assert_eq!(Response::decode(standard(0x7E8), &[0x10, 0x14, 0x49, 0x02]), None, "multi-frame");
        assert_eq!(Response::decode(standard(0x7E8), &[]), None);
    }
}
