//! Inputs defined by DBC signals rather than a standard: the vehicle speed of a proprietary
//! bus, and GNSS from a CAN module that neither NMEA 2000 nor J1939 describes (CSS
//! Electronics' CANmod.gps, a logger's built-in receiver). The std side finds the signals
//! in a DBC file once; here frames are only matched by id and their bits read.

use embedded_can::{Frame, Id};

use crate::can::signal::{ByteOrder, Multiplex, Signal};
use crate::time::{Duration, Timestamp};

/// A frame id as a DBC names it: the raw 11- or 29-bit value and which of the two.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameId {
    /// Raw id.
    pub id: u32,
    /// Whether the id is 29-bit.
    pub extended: bool,
}

impl FrameId {
    /// Whether `frame` is a data frame with this id.
    pub fn matches<F: Frame>(&self, frame: &F) -> bool {
        let same = match frame.id() {
            Id::Standard(s) => !self.extended && u32::from(s.as_raw()) == self.id,
            Id::Extended(e) => self.extended && e.as_raw() == self.id,
        };
        same && !frame.is_remote_frame()
    }
}

/// GNSS as DBC signals. A module sends each epoch as a burst of frames: the time of the
/// fix shortly before its position. The position frame makes the fix; the time is taken
/// from the latest time frame when it came at most [`EPOCH_GAP`] before.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssSignals {
    /// The frame with latitude and longitude (and the optional validity and accuracy).
    pub position: FrameId,
    /// Latitude, degrees.
    pub latitude: Signal,
    /// Longitude, degrees.
    pub longitude: Signal,
    /// Zero when the module has no fix (else every position is taken as a fix).
    pub valid: Option<Signal>,
    /// Horizontal accuracy, m, taken as the fix's 1-σ (else σ is the default's).
    pub accuracy: Option<Signal>,
    /// UTC of the fix as seconds since 1970 in its own frame (else the fix carries no time
    /// and the log stays on the device clock).
    pub time: Option<(FrameId, Signal)>,
}

impl GnssSignals {
    /// CSS Electronics' CANmod.gps with its factory ids, as its `canmod-gps.dbc` defines
    /// gnss_time (id 2) and gnss_pos (id 3): for a device that parses no DBC.
    pub fn canmod_gps() -> Option<Self> {
        let intel = |start_bit, length, factor, offset| {
            Signal::new(start_bit, length, ByteOrder::Intel, false, factor, offset, Multiplex::Plain).ok()
        };
        Some(GnssSignals {
            position: FrameId { id: 3, extended: false },
            latitude: intel(1, 28, 1e-6, -90.0)?,
            longitude: intel(29, 29, 1e-6, -180.0)?,
            valid: Some(intel(0, 1, 1.0, 0.0)?),
            accuracy: Some(intel(58, 6, 1.0, 0.0)?),
            time: Some((FrameId { id: 2, extended: false }, intel(8, 40, 1e-3, 1_577_840_400.0)?)),
        })
    }
}

/// How long before its position frame an epoch's time frame may come.
pub const EPOCH_GAP: Duration = Duration::from_millis(500);

/// What a frame of a [`GnssSignals`] source said.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GnssFrame {
    /// The UTC of the coming fix.
    Time(Timestamp),
    /// A position.
    Position {
        /// Latitude, degrees.
        lat: f64,
        /// Longitude, degrees.
        lon: f64,
        /// Whether the module calls it a fix.
        valid: bool,
        /// 1-σ horizontal error, m.
        sigma_m: Option<f64>,
    },
    /// A frame of the source whose signals the payload does not carry (too short) or
    /// whose time is out of range.
    Unreadable,
}

impl GnssSignals {
    /// Read `frame` if it is one of this source's; `None` for every other frame.
    pub fn read<F: Frame>(&self, frame: &F) -> Option<GnssFrame> {
        let data = frame.data();
        if self.position.matches(frame) {
            let position = self.latitude.value(data).zip(self.longitude.value(data));
            let valid = match self.valid {
                Some(v) => v.value(data).map(|x| x != 0.0),
                None => Some(true),
            };
            let sigma_m = self.accuracy.and_then(|a| a.value(data)).filter(|s| s.is_finite() && *s > 0.0);
            return Some(match (position, valid) {
                (Some((lat, lon)), Some(valid)) => GnssFrame::Position { lat, lon, valid, sigma_m },
                _ => GnssFrame::Unreadable,
            });
        }
        let (id, signal) = self.time?;
        if !id.matches(frame) {
            return None;
        }
        Some(match signal.value(data).and_then(Timestamp::from_secs_f64) {
            Some(utc) => GnssFrame::Time(utc),
            None => GnssFrame::Unreadable,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can::CanFrame;

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(embedded_can::StandardId::new(id).expect("id"), data).expect("frame")
    }

    #[test]
    fn a_canmod_position_frame_of_the_css_drive_reads_as_cantools_decodes_it() {
        let canmod = GnssSignals::canmod_gps().expect("valid signals");
        // The 3BA199E2 drive's first frames: cantools gives PositionValid 0, 56.098655 N,
        // 10.218348 E, accuracy 29 m, and Epoch 1627274470.6 s for the time frame.
        let position = crate::pipeline::tests::canmod_position(56.098_655, 10.218_348, false, 29);
        let GnssFrame::Position { lat, lon, valid, sigma_m } = canmod.read(&position).expect("ours") else {
            panic!("a position")
        };
        assert!((lat - 56.098_655).abs() < 1e-9 && (lon - 10.218_348).abs() < 1e-9, "{lat} {lon}");
        assert!(!valid);
        assert_eq!(sigma_m, Some(29.0));
        let time = crate::pipeline::tests::canmod_time(1_627_274_470_600_000);
        assert_eq!(canmod.read(&time), Some(GnssFrame::Time(Timestamp::from_micros(1_627_274_470_600_000))));
    }

    #[test]
    fn other_frames_are_not_the_sources_and_short_ones_are_unreadable() {
        let canmod = GnssSignals::canmod_gps().expect("valid signals");
        assert_eq!(canmod.read(&frame(4, &[0; 8])), None);
        assert_eq!(canmod.read(&frame(3, &[0; 4])), Some(GnssFrame::Unreadable));
        assert_eq!(canmod.read(&frame(2, &[0; 2])), Some(GnssFrame::Unreadable));
        let extended = CanFrame::new(embedded_can::ExtendedId::new(3).expect("id"), &[0; 8]).expect("frame");
        assert_eq!(canmod.read(&extended), None, "an extended id 3 is another frame");
        let no_time = GnssSignals { time: None, ..canmod };
        assert_eq!(no_time.read(&frame(2, &[0; 6])), None);
    }
}
