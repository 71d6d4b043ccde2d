//! # dash2sim-can
//!
//! The std half of dash2sim's vehicle-bus input. The decoding itself lives in the
//! no_std core ([`dash2sim_core::can`]); this crate brings frames to it and tables for it:
//!
//! | module | concept |
//! |---|---|
//! | [`candump`] | can-utils `candump` text: the three dialects in the wild, and the `-l` writer |
//! | [`source`] | [`FrameSource`]: one trait for replayed files and live SocketCAN |
//! | [`dbc`] | DBC files → [`SignalTable`] of core [`Signal`](dash2sim_core::can::signal::Signal)s |
//!
//! ```
//! use dash2sim_can::{candump::CandumpReader, FrameSource};
//! use dash2sim_core::can::{Decoder, Event, Message};
//!
//! let log = "(1627275000.169400) can0 7E8#03410D3900000000\n";
//! let mut source = CandumpReader::new(log.as_bytes());
//! let mut decoder = Decoder::<8>::default();
//! let record = source.next_frame().expect("one line").expect("valid");
//! let mut speed = None;
//! decoder.decode(record.time.unwrap_or_default(), &record.frame, |event| {
//!     if let Event::Decoded(d) = event {
//!         if let Message::Obd(r) = d.message {
//!             speed = r.vehicle_speed_kmh();
//!         }
//!     }
//! });
//! assert_eq!(speed, Some(57));
//! ```

pub mod candump;
pub mod dbc;
pub mod source;

pub use dbc::SignalTable;
pub use source::{FrameSource, Record};
