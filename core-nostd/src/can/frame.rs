//! An owned classic CAN frame, so replayed and live frames share one type.
//!
//! Decoders take any [`embedded_can::Frame`]; this is the one the std readers produce
//! (and what the MCU keeps in its queues): 13 bytes of payload and header, `Copy`.

use embedded_can::{ExtendedId, Id, StandardId};

/// Largest payload of a classic CAN frame.
pub const MAX_DATA_LEN: usize = 8;

/// A classic (non-FD) CAN data or remote frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CanFrame {
    id: Id,
    remote: bool,
    len: u8,
    data: [u8; MAX_DATA_LEN],
}

impl CanFrame {
    /// Copy any [`embedded_can::Frame`] (e.g. a socketcan frame) into an owned one.
    /// `None` when it carries more than 8 bytes (CAN FD is not supported).
    pub fn from_frame<F: embedded_can::Frame>(frame: &F) -> Option<Self> {
        if frame.is_remote_frame() {
            Self::remote(frame.id(), frame.dlc())
        } else {
            Self::data_frame(frame.id(), frame.data())
        }
    }

    /// A data frame; `None` when `data` is longer than 8 bytes.
    pub fn data_frame(id: Id, data: &[u8]) -> Option<Self> {
        let mut bytes = [0u8; MAX_DATA_LEN];
        bytes.get_mut(..data.len())?.copy_from_slice(data);
        Some(CanFrame { id, remote: false, len: u8::try_from(data.len()).ok()?, data: bytes })
    }

    /// A remote frame requesting `dlc` bytes; `None` when `dlc` > 8.
    pub fn remote(id: Id, dlc: usize) -> Option<Self> {
        let len = u8::try_from(dlc).ok().filter(|&len| usize::from(len) <= MAX_DATA_LEN)?;
        Some(CanFrame { id, remote: true, len, data: [0; MAX_DATA_LEN] })
    }

    /// The identifier as a number (11 or 29 significant bits).
    pub fn raw_id(&self) -> u32 {
        raw_id(self.id)
    }
}

/// The identifier of `id` as a number (11 or 29 significant bits).
pub fn raw_id(id: Id) -> u32 {
    match id {
        Id::Standard(id) => u32::from(id.as_raw()),
        Id::Extended(id) => id.as_raw(),
    }
}

/// An [`Id`] from a number and the extended flag; `None` when it does not fit.
pub fn id_from_raw(raw: u32, extended: bool) -> Option<Id> {
    if extended {
        ExtendedId::new(raw).map(Id::Extended)
    } else {
        StandardId::new(u16::try_from(raw).ok()?).map(Id::Standard)
    }
}

impl embedded_can::Frame for CanFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        Self::data_frame(id.into(), data)
    }

    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        Self::remote(id.into(), dlc)
    }

    fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    fn is_remote_frame(&self) -> bool {
        self.remote
    }

    fn id(&self) -> Id {
        self.id
    }

    fn dlc(&self) -> usize {
        usize::from(self.len)
    }

    fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            self.data.get(..usize::from(self.len)).unwrap_or(&[])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_can::Frame;

    #[test]
    fn data_frames_keep_their_bytes_and_reject_fd_lengths() {
        let id = id_from_raw(0x09F8_0102, true).expect("valid");
        let frame = CanFrame::new(id, &[1, 2, 3]).expect("valid");
        assert_eq!(frame.data(), &[1, 2, 3]);
        assert_eq!(frame.dlc(), 3);
        assert!(frame.is_extended());
        assert_eq!(frame.raw_id(), 0x09F8_0102);
        assert!(CanFrame::new(id, &[0; 9]).is_none());
    }

    #[test]
    fn remote_frames_have_a_length_but_no_data() {
        let id = id_from_raw(0x7DF, false).expect("valid");
        let frame = CanFrame::new_remote(id, 8).expect("valid");
        assert!(frame.is_remote_frame() && frame.is_standard());
        assert_eq!((frame.dlc(), frame.data()), (8, &[][..]));
        assert!(CanFrame::new_remote(id, 9).is_none());
    }

    #[test]
    fn ids_must_fit_their_width() {
        assert!(id_from_raw(0x800, false).is_none());
        assert!(id_from_raw(0x2000_0000, true).is_none());
        assert_eq!(raw_id(id_from_raw(0x7FF, false).expect("valid")), 0x7FF);
    }
}
