//! The board the pipeline meets, through the traits a real one gives: the GNSS receiver's
//! UART as [`embedded_io::Read`] + [`embedded_io::ReadReady`], the vehicle bus as
//! [`embedded_can::nb::Can`], a monotonic timer, the camera process's link, and the log's
//! storage as an [`embedded_io::Write`] sink (an SD card or flash in a unit).
//!
//! Under QEMU the board replays a recorded input stream embedded in the binary
//! (`drive.d2sin`, the core's replay format): each peripheral holds data only when the
//! stream's next entry is its own, so the pipeline sees the inputs in exactly the order and
//! with exactly the times the host's `dash2sim record --replay` feeds them. The sink is a
//! file on the host, written through semihosting.

use dash2sim_core::can::CanFrame;
use dash2sim_core::pipeline::replay::{Input, Reader};
use dash2sim_core::sim3::Pose;
use dash2sim_core::time::Timestamp;

/// What the camera process sends.
pub enum CameraMessage<'a> {
    /// The VO pose of a frame.
    Vo(u64, u32, Pose),
    /// The 3D detections of a frame (replay encoding).
    Detections3d(u64, &'a [u8]),
    /// The 2D detections of a frame (replay encoding).
    Detections2d(u64, &'a [u8]),
}

/// The replayed board.
pub struct ReplayBoard {
    reader: Reader<'static>,
    current: Option<(Timestamp, Input<'static>)>,
    /// Serial bytes of the current entry already read.
    serial_at: usize,
    /// The stream was malformed at the end (reported, not replayed).
    pub malformed: bool,
}

impl ReplayBoard {
    /// A board replaying `stream`.
    pub fn new(stream: &'static [u8]) -> Option<Self> {
        let mut board =
            ReplayBoard { reader: Reader::new(stream).ok()?, current: None, serial_at: 0, malformed: false };
        board.advance();
        Some(board)
    }

    fn advance(&mut self) {
        self.serial_at = 0;
        self.current = match self.reader.next_input() {
            Some(Ok(entry)) => Some(entry),
            Some(Err(_)) => {
                self.malformed = true;
                None
            }
            None => None,
        };
    }

    /// The monotonic timer: the device time of the data now arriving; `None` when the
    /// recording is over.
    pub fn now(&self) -> Option<Timestamp> {
        self.current.map(|(t, _)| t)
    }

    /// The GNSS receiver's UART.
    pub fn uart(&mut self) -> Uart<'_> {
        Uart(self)
    }

    /// The CAN controller.
    pub fn can(&mut self) -> CanBus<'_> {
        CanBus(self)
    }

    /// A message from the camera process, if one is waiting.
    pub fn camera(&mut self) -> Option<CameraMessage<'static>> {
        let message = match self.current? {
            (_, Input::Vo(frame, session, pose)) => CameraMessage::Vo(frame, session, pose),
            (_, Input::Detections3d(frame, bytes)) => CameraMessage::Detections3d(frame, bytes),
            (_, Input::Detections2d(frame, bytes)) => CameraMessage::Detections2d(frame, bytes),
            _ => return None,
        };
        self.advance();
        Some(message)
    }
}

/// The UART: bytes of the receiver's NMEA stream.
pub struct Uart<'b>(&'b mut ReplayBoard);

impl embedded_io::ErrorType for Uart<'_> {
    type Error = core::convert::Infallible;
}

impl embedded_io::ReadReady for Uart<'_> {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(matches!(self.0.current, Some((_, Input::Serial(_)))))
    }
}

impl embedded_io::Read for Uart<'_> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let Some((_, Input::Serial(bytes))) = self.0.current else { return Ok(0) };
        let rest = bytes.get(self.0.serial_at..).unwrap_or(&[]);
        let n = rest.len().min(buf.len());
        buf[..n].copy_from_slice(&rest[..n]);
        self.0.serial_at += n;
        if self.0.serial_at >= bytes.len() {
            self.0.advance();
        }
        Ok(n)
    }
}

/// The CAN controller.
pub struct CanBus<'b>(&'b mut ReplayBoard);

/// A replayed bus never fails.
#[derive(Debug)]
pub struct BusError;

impl embedded_can::Error for BusError {
    fn kind(&self) -> embedded_can::ErrorKind {
        embedded_can::ErrorKind::Other
    }
}

impl embedded_can::nb::Can for CanBus<'_> {
    type Frame = CanFrame;
    type Error = BusError;

    fn transmit(&mut self, _: &CanFrame) -> nb::Result<Option<CanFrame>, BusError> {
        // The logger only listens.
        Err(nb::Error::Other(BusError))
    }

    fn receive(&mut self) -> nb::Result<CanFrame, BusError> {
        let Some((_, Input::Can(frame))) = self.0.current else { return Err(nb::Error::WouldBlock) };
        self.0.advance();
        Ok(frame)
    }
}

/// A file on the host, written through semihosting: the stand-in for an SD card.
pub struct HostFile {
    fd: usize,
}

/// The host refused a semihosting call.
#[derive(Debug)]
pub struct HostError;

impl core::fmt::Display for HostError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("the host refused a semihosting call")
    }
}

impl core::error::Error for HostError {}

impl embedded_io::Error for HostError {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::Other
    }
}

impl HostFile {
    /// Create (truncate) `path`, which must end with a NUL byte.
    pub fn create(path: &str) -> Option<Self> {
        let name = path.as_bytes();
        // SAFETY: SYS_OPEN reads `len` bytes of a NUL-terminated name the host keeps no reference to.
        let fd = unsafe {
            cortex_m_semihosting::syscall!(
                OPEN,
                name.as_ptr(),
                cortex_m_semihosting::nr::open::W_TRUNC_BINARY,
                name.len() - 1
            )
        } as isize;
        (fd >= 0).then_some(HostFile { fd: fd as usize })
    }
}

impl embedded_io::ErrorType for HostFile {
    type Error = HostError;
}

impl embedded_io::Write for HostFile {
    fn write(&mut self, buf: &[u8]) -> Result<usize, HostError> {
        if buf.is_empty() {
            return Ok(0);
        }
        // SAFETY: SYS_WRITE reads `len` bytes of `buf` and returns how many it did not write.
        let left = unsafe { cortex_m_semihosting::syscall!(WRITE, self.fd, buf.as_ptr(), buf.len()) };
        match buf.len().checked_sub(left) {
            Some(0) | None => Err(HostError),
            Some(written) => Ok(written),
        }
    }

    fn flush(&mut self) -> Result<(), HostError> {
        Ok(())
    }
}

impl Drop for HostFile {
    fn drop(&mut self) {
        // SAFETY: closes the descriptor this value owns.
        unsafe {
            cortex_m_semihosting::syscall!(CLOSE, self.fd);
        }
    }
}
