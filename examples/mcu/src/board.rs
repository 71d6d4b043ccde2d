//! The board the pipeline meets, through the traits a real one gives: the GNSS receiver's
//! UART as [`embedded_io::Read`] + [`embedded_io::ReadReady`], the vehicle bus as
//! [`embedded_can::nb::Can`], the IMU's I²C bus as [`embedded_hal::i2c::I2c`] (an LSM6DSO
//! answers on it, read by the core's driver), a monotonic timer, the camera process's
//! link, and the log's storage as an [`embedded_io::Write`] sink (an SD card or flash in a
//! unit).
//!
//! Under QEMU the board replays a recorded input stream embedded in the binary
//! (`drive.d2sin`, the core's replay format): each peripheral holds data only when the
//! stream's next entry is its own, so the pipeline sees the inputs in exactly the order and
//! with exactly the times the host's `dash2sim record --replay` feeds them. QEMU emulates
//! no accelerometer: the I²C bus answers as an LSM6DSO would, serving the stream's IMU
//! samples as FIFO words (a timestamp, the gyro's and the accelerometer's counts) one
//! sample at a time, when the stream's next entry is one. The sink is a file on the host,
//! written through semihosting.

use core::cell::RefCell;

use dash2sim_core::can::CanFrame;
use dash2sim_core::imu::lsm6dso;
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
    /// FIFO words of the current IMU sample already read (timestamp, gyro, accelerometer).
    fifo_at: u8,
    /// The stream was malformed at the end (reported, not replayed).
    pub malformed: bool,
}

impl ReplayBoard {
    /// A board replaying `stream`.
    pub fn new(stream: &'static [u8]) -> Option<Self> {
        let mut board = ReplayBoard {
            reader: Reader::new(stream).ok()?,
            current: None,
            serial_at: 0,
            fifo_at: 0,
            malformed: false,
        };
        board.advance();
        Some(board)
    }

    fn advance(&mut self) {
        self.serial_at = 0;
        self.fifo_at = 0;
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

    /// Whether the IMU has a sample in its FIFO.
    pub fn imu_ready(&self) -> bool {
        matches!(self.current, Some((_, Input::Imu(_))))
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

/// The IMU's I²C bus: an LSM6DSO at [`lsm6dso::ADDRESS_LOW`] whose FIFO holds the stream's
/// current IMU sample (3 words), if it is one. Shares the board with its other peripherals.
pub struct ImuBus<'b>(pub &'b RefCell<ReplayBoard>);

/// Nothing answers at that address.
#[derive(Debug)]
pub struct Nack;

impl embedded_hal::i2c::Error for Nack {
    fn kind(&self) -> embedded_hal::i2c::ErrorKind {
        embedded_hal::i2c::ErrorKind::NoAcknowledge(embedded_hal::i2c::NoAcknowledgeSource::Address)
    }
}

impl embedded_hal::i2c::ErrorType for ImuBus<'_> {
    type Error = Nack;
}

/// A FIFO word: its tag (the sensor's tag in bits 7..3) and six data bytes.
fn word(tag: u8, data: [u8; 6]) -> [u8; 7] {
    let [a, b, c, d, e, f] = data;
    [tag << 3, a, b, c, d, e, f]
}

fn axes(v: [i16; 3]) -> [u8; 6] {
    let [x, y, z] = v.map(i16::to_le_bytes);
    [x[0], x[1], y[0], y[1], z[0], z[1]]
}

impl ReplayBoard {
    /// The register read at `register` into `into`, as the sensor answers it.
    fn read_register(&mut self, register: u8, into: &mut [u8]) {
        into.fill(0);
        let sample = match self.current {
            Some((t, Input::Imu(sample))) => Some((t, sample)),
            _ => None,
        };
        match register {
            lsm6dso::reg::WHO_AM_I => into.fill(lsm6dso::WHO_AM_I_VALUE),
            lsm6dso::reg::FIFO_STATUS1 => {
                let words = sample.map_or(0, |_| 3 - self.fifo_at);
                if let Some(first) = into.first_mut() {
                    *first = words;
                }
            }
            lsm6dso::reg::FIFO_DATA_OUT_TAG => {
                let Some((t, sample)) = sample else { return };
                let [tg, ta] = lsm6dso::counts(&sample);
                let bytes = match self.fifo_at {
                    0 => {
                        // The sensor's counter runs from the board's power-up: 25 µs ticks.
                        let [a, b, c, d] = lsm6dso::ticks(t).to_le_bytes();
                        word(lsm6dso::tag::TIMESTAMP, [a, b, c, d, 0, 0])
                    }
                    1 => word(lsm6dso::tag::GYRO, axes(tg)),
                    _ => word(lsm6dso::tag::ACCEL, axes(ta)),
                };
                let n = into.len().min(bytes.len());
                into[..n].copy_from_slice(&bytes[..n]);
                self.fifo_at += 1;
                if self.fifo_at == 3 {
                    self.advance();
                }
            }
            _ => {}
        }
    }
}

impl embedded_hal::i2c::I2c for ImuBus<'_> {
    fn transaction(&mut self, address: u8, operations: &mut [embedded_hal::i2c::Operation<'_>]) -> Result<(), Nack> {
        if address != lsm6dso::ADDRESS_LOW {
            return Err(Nack);
        }
        let mut board = self.0.borrow_mut();
        // A write of one byte selects the register the following read starts at; a longer
        // write sets registers (the configuration), which the replay needs not keep.
        let mut register = None;
        for operation in operations.iter_mut() {
            match operation {
                embedded_hal::i2c::Operation::Write(bytes) => register = (bytes.len() == 1).then(|| bytes[0]),
                embedded_hal::i2c::Operation::Read(into) => {
                    if let Some(r) = register {
                        board.read_register(r, into);
                    }
                }
            }
        }
        Ok(())
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
