//! One entry point for bus traffic: frame in, decoded vehicle message out.

use embedded_can::{Frame, Id};

use super::fast_packet::{self, Assembler, Dropped, FrameError, Outcome};
use super::id::J1939Id;
use super::j1939::{self, VehiclePosition, WheelSpeed};
use super::n2k::{self, CogSogRapid, GnssPosition, PositionRapid, Truncated};
use super::obd;
use crate::time::Timestamp;

/// A decoded message.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Message {
    /// NMEA 2000 PGN 129025.
    PositionRapid(PositionRapid),
    /// NMEA 2000 PGN 129026.
    CogSogRapid(CogSogRapid),
    /// NMEA 2000 PGN 129029.
    GnssPosition(GnssPosition),
    /// J1939 PGN 65265.
    WheelSpeed(WheelSpeed),
    /// J1939 PGN 65267.
    VehiclePosition(VehiclePosition),
    /// OBD-II mode 01 response.
    Obd(obd::Response),
}

/// A decoded message with its J1939 / NMEA 2000 header (none for 11-bit OBD-II frames).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Decoded {
    /// Header of a 29-bit frame.
    pub header: Option<J1939Id>,
    /// The message.
    pub message: Message,
}

/// Why a frame of a decoded PGN produced nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error {
    /// Too few bytes for the PGN.
    Truncated(Truncated),
    /// A fast-packet frame was rejected.
    FastPacket(FrameError),
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::Truncated(e) => e.fmt(f),
            Error::FastPacket(e) => e.fmt(f),
        }
    }
}

impl core::error::Error for Error {}

impl From<Truncated> for Error {
    fn from(e: Truncated) -> Self {
        Error::Truncated(e)
    }
}

/// What one frame did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// A message was decoded.
    Decoded(Decoded),
    /// A frame of a decoded PGN was bad.
    Error(Error),
    /// An unfinished fast-packet message was given up.
    Dropped(Dropped),
}

/// Counters over a decoder's life.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stats {
    /// Frames seen.
    pub frames: u32,
    /// Messages decoded.
    pub decoded: u32,
    /// Frames of other PGNs / ids, and remote frames.
    pub ignored: u32,
    /// Frames of decoded PGNs that were too short or malformed.
    pub errors: u32,
    /// Fast-packet messages given up (clash, timeout, eviction).
    pub dropped: u32,
}

/// Frame-to-message decoder for NMEA 2000, J1939 and OBD-II, with fast-packet reassembly.
#[derive(Clone, Debug, Default)]
pub struct Decoder<const SLOTS: usize = 8> {
    fast_packets: Assembler<SLOTS>,
    stats: Stats,
}

impl<const SLOTS: usize> Decoder<SLOTS> {
    /// A decoder whose fast-packet messages time out after `timeout`.
    pub const fn new(timeout: crate::time::Duration) -> Self {
        Decoder {
            fast_packets: Assembler::new(timeout),
            stats: Stats { frames: 0, decoded: 0, ignored: 0, errors: 0, dropped: 0 },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Fast-packet counters so far.
    pub fn fast_packet_stats(&self) -> &fast_packet::Stats {
        self.fast_packets.stats()
    }

    /// Decode one frame received at `now`. `emit` sees every event it caused (at most
    /// `SLOTS` + 2): expired fast-packet messages first, then the frame's own result.
    pub fn decode<F: Frame>(&mut self, now: Timestamp, frame: &F, mut emit: impl FnMut(Event)) {
        self.stats.frames = self.stats.frames.saturating_add(1);
        while let Some(dropped) = self.fast_packets.expire(now) {
            self.stats.dropped = self.stats.dropped.saturating_add(1);
            emit(Event::Dropped(dropped));
        }
        if frame.is_remote_frame() {
            self.stats.ignored = self.stats.ignored.saturating_add(1);
            return;
        }
        let result = match frame.id() {
            Id::Extended(raw) => {
                let header = J1939Id::from_raw(raw.as_raw());
                if let Some(response) = obd::Response::decode(frame.id(), frame.data()) {
                    Some(Ok(Decoded { header: Some(header), message: Message::Obd(response) }))
                } else {
                    self.decode_pgn(now, header, frame.data(), &mut emit)
                        .map(|r| r.map(|message| Decoded { header: Some(header), message }))
                }
            }
            Id::Standard(_) => obd::Response::decode(frame.id(), frame.data())
                .map(|response| Ok(Decoded { header: None, message: Message::Obd(response) })),
        };
        match result {
            Some(Ok(decoded)) => {
                self.stats.decoded = self.stats.decoded.saturating_add(1);
                emit(Event::Decoded(decoded));
            }
            Some(Err(error)) => {
                self.stats.errors = self.stats.errors.saturating_add(1);
                emit(Event::Error(error));
            }
            None => self.stats.ignored = self.stats.ignored.saturating_add(1),
        }
    }

    /// `None` for PGNs not decoded here and for fast-packet frames that did not finish a message.
    fn decode_pgn(
        &mut self,
        now: Timestamp,
        header: J1939Id,
        data: &[u8],
        emit: &mut impl FnMut(Event),
    ) -> Option<Result<Message, Error>> {
        let message = match header.pgn {
            n2k::POSITION_RAPID => PositionRapid::decode(data).map(Message::PositionRapid),
            n2k::COG_SOG_RAPID => CogSogRapid::decode(data).map(Message::CogSogRapid),
            j1939::CCVS1 => WheelSpeed::decode(data).map(Message::WheelSpeed),
            j1939::VEHICLE_POSITION => VehiclePosition::decode(data).map(Message::VehiclePosition),
            pgn if n2k::is_fast_packet(pgn) => {
                let push = self.fast_packets.push(now, pgn, header.source, data);
                if let Some(dropped) = push.dropped {
                    self.stats.dropped = self.stats.dropped.saturating_add(1);
                    emit(Event::Dropped(dropped));
                }
                return match push.outcome {
                    Outcome::Complete(payload) => {
                        Some(GnssPosition::decode(payload).map(Message::GnssPosition).map_err(Error::from))
                    }
                    Outcome::Pending => None,
                    Outcome::Rejected(error) => Some(Err(Error::FastPacket(error))),
                };
            }
            _ => return None,
        };
        Some(message.map_err(Error::from))
    }
}
