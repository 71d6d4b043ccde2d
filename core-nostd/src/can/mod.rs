//! Vehicle bus: CAN frame ids, NMEA 2000 fast packets, PGN and OBD-II decoders, DBC
//! signal extraction — no allocation, no I/O.
//!
//! Frames come in through [`embedded_can::Frame`] (any HAL's or socketcan's frames, or
//! the owned [`CanFrame`] the replay readers produce). [`Decoder`] turns them into
//! [`Message`]s; [`signal`] reads DBC-defined signals for vendor buses.

mod bytes;
pub mod decoder;
pub mod fast_packet;
pub mod frame;
pub mod id;
pub mod j1939;
pub mod n2k;
pub mod obd;
pub mod signal;

pub use decoder::{Decoded, Decoder, Event, Message};
pub use frame::CanFrame;
pub use id::J1939Id;
