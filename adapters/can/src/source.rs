//! One trait for every place frames come from: a candump file being replayed or a live
//! SocketCAN interface. Consumers (the CLI, the recorder) do not care which.

use std::fmt;
use std::time::{Duration as StdDuration, SystemTime, UNIX_EPOCH};

use dash2sim_core::can::CanFrame;
use dash2sim_core::time::Timestamp;

/// Linux interface names are at most 15 bytes (IFNAMSIZ − 1).
pub type InterfaceName = heapless::String<15>;

/// A received frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Record {
    /// Receive time (Unix or boot time, whatever the log or socket gave); `None` when
    /// the log has no timestamps.
    pub time: Option<Timestamp>,
    /// Interface, e.g. `can0`.
    pub interface: InterfaceName,
    /// The frame.
    pub frame: CanFrame,
}

/// What is wrong with a line of a capture (candump text, [`crate::candump`]). It lives with
/// the errors a source reports: the text format depends on the sources, not the other way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParseError {
    /// `(seconds.micro)` malformed.
    BadTimestamp,
    /// Interface name missing or longer than 15 bytes.
    BadInterface,
    /// Identifier not hex or too large for its width.
    BadId,
    /// `[n]` malformed or above 8.
    BadLength,
    /// A data byte is not two hex digits.
    BadData,
    /// `[n]` disagrees with the bytes that follow.
    LengthMismatch {
        /// Announced.
        announced: usize,
        /// Present.
        found: usize,
    },
    /// More than 8 data bytes.
    TooManyBytes,
    /// A CAN FD frame (`##`).
    CanFd,
    /// Not a candump line at all.
    Unrecognized,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParseError::BadTimestamp => write!(f, "malformed timestamp"),
            ParseError::BadInterface => write!(f, "missing or over-long interface name"),
            ParseError::BadId => write!(f, "malformed CAN id"),
            ParseError::BadLength => write!(f, "malformed data length"),
            ParseError::BadData => write!(f, "malformed data byte"),
            ParseError::LengthMismatch { announced, found } => {
                write!(f, "length [{announced}] but {found} data bytes")
            }
            ParseError::TooManyBytes => write!(f, "more than 8 data bytes"),
            ParseError::CanFd => write!(f, "CAN FD frames are not supported"),
            ParseError::Unrecognized => write!(f, "not a candump line"),
        }
    }
}

impl std::error::Error for ParseError {}

/// Why one frame could not be read. The source stays usable after it.
#[derive(Debug)]
pub struct SourceError {
    /// 1-based line of a replayed file.
    pub line: Option<u64>,
    /// What went wrong.
    pub kind: SourceErrorKind,
}

/// What went wrong.
#[derive(Debug)]
pub enum SourceErrorKind {
    /// A line that is not candump output.
    Parse(ParseError),
    /// Reading failed.
    Io(std::io::Error),
    /// The socket delivered a frame this crate does not handle (CAN FD, error frame).
    Unsupported(&'static str),
}

impl fmt::Display for SourceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(line) = self.line {
            write!(f, "line {line}: ")?;
        }
        match &self.kind {
            SourceErrorKind::Parse(e) => e.fmt(f),
            SourceErrorKind::Io(e) => e.fmt(f),
            SourceErrorKind::Unsupported(what) => write!(f, "unsupported frame: {what}"),
        }
    }
}

impl std::error::Error for SourceError {}

/// A stream of frames.
pub trait FrameSource {
    /// The next frame, `None` at the end of a replay. A bad line or frame is an `Err`;
    /// calling again continues after it.
    fn next_frame(&mut self) -> Option<Result<Record, SourceError>>;
}

/// A live SocketCAN interface.
#[derive(Debug)]
pub struct SocketCanSource {
    socket: socketcan::CanSocket,
    interface: InterfaceName,
}

impl SocketCanSource {
    /// Open `interface` (e.g. `can0`, `vcan0`).
    pub fn open(interface: &str) -> std::io::Result<Self> {
        use socketcan::Socket;
        let name = InterfaceName::try_from(interface)
            .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "interface name too long"))?;
        Ok(SocketCanSource { socket: socketcan::CanSocket::open(interface)?, interface: name })
    }
}

/// Microseconds since the Unix epoch of a system time (0 before 1970).
fn unix_timestamp(time: SystemTime) -> Timestamp {
    let since = time.duration_since(UNIX_EPOCH).unwrap_or(StdDuration::ZERO);
    Timestamp::from_micros(i64::try_from(since.as_micros()).unwrap_or(i64::MAX))
}

impl FrameSource for SocketCanSource {
    fn next_frame(&mut self) -> Option<Result<Record, SourceError>> {
        use socketcan::Socket;
        let error = |kind| Some(Err(SourceError { line: None, kind }));
        match self.socket.read_frame_with_timestamp() {
            Ok((socketcan::CanFrame::Error(_), _)) => error(SourceErrorKind::Unsupported("error frame")),
            Ok((frame, time)) => match CanFrame::from_frame(&frame) {
                Some(frame) => {
                    Some(Ok(Record { time: Some(unix_timestamp(time)), interface: self.interface.clone(), frame }))
                }
                None => error(SourceErrorKind::Unsupported("more than 8 data bytes")),
            },
            Err(e) => error(SourceErrorKind::Io(e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn system_times_become_unix_microseconds() {
        let t = UNIX_EPOCH + StdDuration::from_micros(1_627_275_000_169_400);
        assert_eq!(unix_timestamp(t), Timestamp::from_micros(1_627_275_000_169_400));
        assert_eq!(unix_timestamp(UNIX_EPOCH - StdDuration::from_secs(1)), Timestamp::from_micros(0));
    }

    /// Needs a real or virtual CAN interface (`ip link add vcan0 type vcan`); the
    /// machines this runs on usually have none (no AF_CAN), and then it says so.
    #[test]
    fn live_socketcan_source_reads_what_another_socket_sends() {
        use socketcan::{EmbeddedFrame, Socket};
        let interface = std::env::var("DASH2SIM_CAN_INTERFACE").unwrap_or_else(|_| "vcan0".into());
        let mut source = match SocketCanSource::open(&interface) {
            Ok(source) => source,
            Err(e) => {
                println!("skipped: no CAN interface {interface} ({e})");
                return;
            }
        };
        let sender = socketcan::CanSocket::open(&interface).expect("second socket");
        let id = dash2sim_core::can::frame::id_from_raw(0x09F8_0102, true).expect("29-bit");
        let sent = socketcan::CanFrame::new(id, &[0x36, 0x72, 0x9A, 0x16]).expect("frame");
        sender.write_frame(&sent).expect("send");
        let record = source.next_frame().expect("live").expect("frame");
        assert_eq!(record.interface.as_str(), interface);
        assert_eq!(record.frame, CanFrame::from_frame(&sent).expect("classic"));
        assert!(record.time.is_some());
    }
}
