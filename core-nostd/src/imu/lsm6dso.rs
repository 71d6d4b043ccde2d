//! A register driver for ST's LSM6DSO (a consumer 6-axis MEMS IMU of the kind dashcams
//! carry) over embedded-hal 1.0 I²C: identification, configuration, and FIFO reads with
//! the sensor's own timestamps.
//!
//! The sensor batches gyro and accelerometer words into its FIFO at the output data rate,
//! with a timestamp word per batch (25 µs ticks of its own clock); [`Lsm6dso::read_fifo`]
//! drains it and pairs each gyro word with the accelerometer word of the same batch into
//! an [`ImuSample`] stamped with the sensor's time, extended past the 32-bit counter's
//! wrap. Nothing is allocated and every loop is bounded by the FIFO's size.
//!
//! Its faults are errors of their own, so that the caller can say what happened and go on:
//! a wrong `WHO_AM_I` ([`Error::WrongDevice`]: another chip, or none, at the address), a
//! NACK ([`Error::NoAcknowledge`]: nothing answers), any other bus error ([`Error::Bus`]),
//! and a FIFO overrun ([`Error::FifoOverrun`]: the caller read too late and samples were
//! lost; the ones still there were delivered).
//!
//! Register map and sensitivities: ST, *LSM6DSO datasheet* DS12140 rev. 4 (tables 2, 18,
//! and §9) and application note AN5192 (FIFO, timestamps).

use embedded_hal::i2c::{ErrorKind, I2c};

use super::{ImuSample, GRAVITY};
use crate::time::Timestamp;

/// The I²C address with SA0 low.
pub const ADDRESS_LOW: u8 = 0x6A;
/// The I²C address with SA0 high.
pub const ADDRESS_HIGH: u8 = 0x6B;
/// What `WHO_AM_I` reads on an LSM6DSO.
pub const WHO_AM_I_VALUE: u8 = 0x6C;
/// Microseconds per timestamp tick (25 µs, DS12140 §6.4; the chip's ±1.5 % trim is not
/// applied).
pub const TIMESTAMP_TICK_US: i64 = 25;
/// FIFO words the sensor holds (9 KB / 7 B per word).
pub const FIFO_WORDS: u16 = 512;

/// The registers the driver uses (DS12140 §9).
#[allow(missing_docs)]
pub mod reg {
    pub const FIFO_CTRL3: u8 = 0x09;
    pub const FIFO_CTRL4: u8 = 0x0A;
    pub const WHO_AM_I: u8 = 0x0F;
    pub const CTRL1_XL: u8 = 0x10;
    pub const CTRL2_G: u8 = 0x11;
    pub const CTRL3_C: u8 = 0x12;
    pub const CTRL10_C: u8 = 0x19;
    pub const FIFO_STATUS1: u8 = 0x3A;
    pub const FIFO_DATA_OUT_TAG: u8 = 0x78;
}

/// FIFO word tags (DS12140 table 113), in bits 7..3 of a word's tag byte.
#[allow(missing_docs)]
pub mod tag {
    pub const GYRO: u8 = 0x01;
    pub const ACCEL: u8 = 0x02;
    pub const TIMESTAMP: u8 = 0x04;
}

/// Output data rates both sensors run at, and their FIFO batch rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DataRate {
    /// 52 Hz.
    Hz52,
    /// 104 Hz (comma's EON samples at about this).
    Hz104,
    /// 208 Hz.
    Hz208,
}

impl DataRate {
    const fn code(self) -> u8 {
        match self {
            DataRate::Hz52 => 0b0011,
            DataRate::Hz104 => 0b0100,
            DataRate::Hz208 => 0b0101,
        }
    }
}

/// The sensor's configuration: rates and full scales a car needs (±16 g survives a crash,
/// ±500 °/s any turn a car makes at 0.0175 °/s per count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Output data rate of both sensors.
    pub rate: DataRate,
}

impl Default for Config {
    fn default() -> Self {
        Config { rate: DataRate::Hz104 }
    }
}

/// m/s² per count at ±16 g (0.488 mg/LSB), in `f32`: the sensor's 16-bit counts times it
/// are what an `f32` holds, as the replay stream and a Cortex-M's single-precision FPU do,
/// so a sample read through the driver and one read back from a recording are the same.
const ACCEL_SCALE: f32 = (0.488e-3 * GRAVITY) as f32;
/// rad/s per count at ±500 °/s (17.5 m°/s per LSB), in `f32` (see [`ACCEL_SCALE`]).
const GYRO_SCALE: f32 = (17.5e-3 * core::f64::consts::PI / 180.0) as f32;

/// A sample as the sensor's counts: gyro, accelerometer (rounded to the nearest count,
/// saturating at the full scale).
pub fn counts(sample: &ImuSample) -> [[i16; 3]; 2] {
    // `as` saturates a float beyond i16's range and makes NaN 0.
    let count = |v: f64, scale: f32| libm::roundf(v as f32 / scale) as i16;
    [sample.gyro.map(|v| count(v, GYRO_SCALE)), sample.accel.map(|v| count(v, ACCEL_SCALE))]
}

/// A sample from the sensor's counts: gyro, accelerometer.
pub fn from_counts(gyro: [i16; 3], accel: [i16; 3]) -> ImuSample {
    ImuSample {
        gyro: gyro.map(|c| f64::from(f32::from(c) * GYRO_SCALE)),
        accel: accel.map(|c| f64::from(f32::from(c) * ACCEL_SCALE)),
    }
}

/// A sample as the sensor would have delivered it: quantised to its counts.
pub fn quantised(sample: &ImuSample) -> ImuSample {
    let [gyro, accel] = counts(sample);
    from_counts(gyro, accel)
}

/// The sensor's 32-bit timestamp counter at `t` (its ticks since the device's time 0).
pub fn ticks(t: Timestamp) -> u32 {
    (t.micros() / TIMESTAMP_TICK_US) as u32
}

/// What went wrong on the bus or in the sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// `WHO_AM_I` read this instead of 0x6C: another chip at the address.
    WrongDevice(u8),
    /// No device acknowledged (none at the address, or it is not powered).
    NoAcknowledge,
    /// Another bus error.
    Bus(E),
    /// The FIFO overflowed before it was read: samples were lost. The ones it still held
    /// were delivered; this many.
    FifoOverrun {
        /// Samples delivered by the read that found the overrun.
        delivered: u16,
    },
}

impl<E: core::fmt::Debug> core::fmt::Display for Error<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::WrongDevice(id) => write!(f, "WHO_AM_I reads 0x{id:02X}, not an LSM6DSO's 0x6C"),
            Error::NoAcknowledge => f.write_str("the IMU does not acknowledge on the bus"),
            Error::Bus(e) => write!(f, "I2C bus error: {e:?}"),
            Error::FifoOverrun { delivered } => {
                write!(f, "IMU FIFO overrun: samples lost ({delivered} still read)")
            }
        }
    }
}

impl<E: core::fmt::Debug> core::error::Error for Error<E> {}

/// The driver: the bus, the address, and the FIFO's partial batch.
#[derive(Debug)]
pub struct Lsm6dso<I> {
    i2c: I,
    address: u8,
    /// The latest timestamp word, extended to 64 bits (ticks).
    time: Option<u64>,
    gyro: Option<[i16; 3]>,
    accel: Option<[i16; 3]>,
}

impl<I: I2c> Lsm6dso<I> {
    /// A driver for the sensor at `address` ([`ADDRESS_LOW`] or [`ADDRESS_HIGH`]); nothing
    /// is sent until [`Lsm6dso::init`].
    pub fn new(i2c: I, address: u8) -> Self {
        Lsm6dso { i2c, address, time: None, gyro: None, accel: None }
    }

    /// The bus back.
    pub fn release(self) -> I {
        self.i2c
    }

    /// Check the chip, reset it and start both sensors with the FIFO in continuous mode,
    /// a timestamp in every batch.
    pub fn init(&mut self, config: Config) -> Result<(), Error<I::Error>> {
        let id = self.read_register(reg::WHO_AM_I)?;
        if id != WHO_AM_I_VALUE {
            return Err(Error::WrongDevice(id));
        }
        // Block data update, address auto-increment, software reset.
        self.write_register(reg::CTRL3_C, 0b0100_0101)?;
        let odr = config.rate.code() << 4;
        // Accelerometer: ±16 g (FS_XL = 01); gyro: ±500 °/s (FS_G = 01).
        self.write_register(reg::CTRL1_XL, odr | 0b0100)?;
        self.write_register(reg::CTRL2_G, odr | 0b0100)?;
        self.write_register(reg::CTRL10_C, 0b0010_0000)?;
        // Both sensors batched at their data rate.
        self.write_register(reg::FIFO_CTRL3, config.rate.code() << 4 | config.rate.code())?;
        // A timestamp every batch (DEC_TS_BATCH = 01), continuous mode (110).
        self.write_register(reg::FIFO_CTRL4, 0b0100_0110)?;
        self.time = None;
        self.gyro = None;
        self.accel = None;
        Ok(())
    }

    /// Drain the FIFO: every complete sample to `each` with the sensor's time (since its
    /// counter started, which a device starts with its own clock). Returns how many were
    /// delivered, or the overrun.
    pub fn read_fifo(&mut self, mut each: impl FnMut(Timestamp, ImuSample)) -> Result<u16, Error<I::Error>> {
        let mut status = [0u8; 2];
        self.read_registers(reg::FIFO_STATUS1, &mut status)?;
        let words = (u16::from(status[1] & 0b11) << 8 | u16::from(status[0])).min(FIFO_WORDS);
        let overrun = status[1] & 0b0100_0000 != 0;
        let mut delivered = 0u16;
        for _ in 0..words {
            let mut word = [0u8; 7];
            self.read_registers(reg::FIFO_DATA_OUT_TAG, &mut word)?;
            let [t, x0, x1, y0, y1, z0, z1] = word;
            let axes = [i16::from_le_bytes([x0, x1]), i16::from_le_bytes([y0, y1]), i16::from_le_bytes([z0, z1])];
            match t >> 3 {
                tag::TIMESTAMP => {
                    let ticks = u32::from_le_bytes([x0, x1, y0, y1]);
                    self.time = Some(extend(self.time, ticks));
                    self.gyro = None;
                    self.accel = None;
                }
                tag::GYRO => self.gyro = Some(axes),
                tag::ACCEL => self.accel = Some(axes),
                _ => {}
            }
            if let (Some(time), Some(g), Some(a)) = (self.time, self.gyro, self.accel) {
                self.gyro = None;
                self.accel = None;
                let micros = i64::try_from(time).unwrap_or(i64::MAX).saturating_mul(TIMESTAMP_TICK_US);
                each(Timestamp::from_micros(micros), from_counts(g, a));
                delivered = delivered.saturating_add(1);
            }
        }
        if overrun {
            return Err(Error::FifoOverrun { delivered });
        }
        Ok(delivered)
    }

    fn read_register(&mut self, register: u8) -> Result<u8, Error<I::Error>> {
        let mut value = [0u8];
        self.read_registers(register, &mut value)?;
        Ok(value[0])
    }

    fn read_registers(&mut self, register: u8, into: &mut [u8]) -> Result<(), Error<I::Error>> {
        self.i2c.write_read(self.address, &[register], into).map_err(bus_error)
    }

    fn write_register(&mut self, register: u8, value: u8) -> Result<(), Error<I::Error>> {
        self.i2c.write(self.address, &[register, value]).map_err(bus_error)
    }
}

fn bus_error<E: embedded_hal::i2c::Error>(e: E) -> Error<E> {
    match e.kind() {
        ErrorKind::NoAcknowledge(_) => Error::NoAcknowledge,
        _ => Error::Bus(e),
    }
}

/// A 32-bit tick count after `previous` (64-bit), across the counter's wrap.
fn extend(previous: Option<u64>, ticks: u32) -> u64 {
    let Some(p) = previous else { return u64::from(ticks) };
    let high = p & !0xFFFF_FFFF;
    let candidate = high | u64::from(ticks);
    if candidate < p {
        candidate.saturating_add(1 << 32)
    } else {
        candidate
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use embedded_hal::i2c::NoAcknowledgeSource;
    use embedded_hal_mock::eh1::i2c::{Mock, Transaction};
    use std::vec;

    const A: u8 = ADDRESS_LOW;

    fn init_transactions() -> [Transaction; 7] {
        [
            Transaction::write_read(A, vec![0x0F], vec![0x6C]),
            Transaction::write(A, vec![0x12, 0x45]),
            Transaction::write(A, vec![0x10, 0x44]),
            Transaction::write(A, vec![0x11, 0x44]),
            Transaction::write(A, vec![0x19, 0x20]),
            Transaction::write(A, vec![0x09, 0x44]),
            Transaction::write(A, vec![0x0A, 0x46]),
        ]
    }

    fn word(tag: u8, bytes: [u8; 6]) -> Transaction {
        let mut w = vec![tag << 3];
        w.extend_from_slice(&bytes);
        Transaction::write_read(A, vec![0x78], w)
    }

    fn axes(x: i16, y: i16, z: i16) -> [u8; 6] {
        let (x, y, z) = (x.to_le_bytes(), y.to_le_bytes(), z.to_le_bytes());
        [x[0], x[1], y[0], y[1], z[0], z[1]]
    }

    fn timestamp(ticks: u32) -> [u8; 6] {
        let t = ticks.to_le_bytes();
        [t[0], t[1], t[2], t[3], 0, 0]
    }

    #[test]
    fn init_identifies_and_configures_the_sensor_with_exactly_these_writes() {
        let mut bus = Mock::new(&init_transactions());
        let mut imu = Lsm6dso::new(bus.clone(), A);
        assert_eq!(imu.init(Config::default()), Ok(()));
        bus.done();
    }

    #[test]
    fn a_wrong_who_am_i_is_refused_before_anything_is_written() {
        let mut bus = Mock::new(&[Transaction::write_read(A, vec![0x0F], vec![0x6A])]);
        let mut imu = Lsm6dso::new(bus.clone(), A);
        assert_eq!(imu.init(Config::default()), Err(Error::WrongDevice(0x6A)));
        bus.done();
    }

    #[test]
    fn a_nack_and_a_bus_error_are_told_apart() {
        let nack = Transaction::write_read(A, vec![0x0F], vec![0])
            .with_error(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
        let mut bus = Mock::new(&[nack]);
        assert_eq!(Lsm6dso::new(bus.clone(), A).init(Config::default()), Err(Error::NoAcknowledge));
        bus.done();
        let lost = Transaction::write_read(A, vec![0x3A], vec![0, 0]).with_error(ErrorKind::ArbitrationLoss);
        let mut bus = Mock::new(&[lost]);
        assert_eq!(Lsm6dso::new(bus.clone(), A).read_fifo(|_, _| {}), Err(Error::Bus(ErrorKind::ArbitrationLoss)));
        bus.done();
    }

    #[test]
    fn fifo_words_pair_into_samples_stamped_with_the_sensor_s_time() {
        let mut t = vec![Transaction::write_read(A, vec![0x3A], vec![7, 0])];
        t.push(word(tag::TIMESTAMP, timestamp(40_000)));
        t.push(word(tag::GYRO, axes(100, -200, 1000)));
        t.push(word(tag::ACCEL, axes(0, 0, 2049)));
        t.push(word(tag::TIMESTAMP, timestamp(40_385)));
        t.push(word(tag::ACCEL, axes(10, 0, 2049)));
        t.push(word(tag::GYRO, axes(0, 0, 0)));
        // A batch cut off by the read: kept for the next.
        t.push(word(tag::TIMESTAMP, timestamp(40_770)));
        let mut bus = Mock::new(&t);
        let mut imu = Lsm6dso::new(bus.clone(), A);
        let mut got = heapless::Vec::<(Timestamp, ImuSample), 4>::new();
        assert_eq!(imu.read_fifo(|t, s| got.push((t, s)).unwrap_or_default()), Ok(2));
        bus.done();
        assert_eq!(got.len(), 2);
        let (t0, s0) = got[0];
        assert_eq!(t0, Timestamp::from_micros(1_000_000));
        assert!((s0.gyro[2] - 1000.0 * 17.5e-3 * core::f64::consts::PI / 180.0).abs() < 1e-6);
        assert!((s0.accel[2] - 2049.0 * 0.488e-3 * GRAVITY).abs() < 1e-5, "1 g: {}", s0.accel[2]);
        assert_eq!(got[1].0, Timestamp::from_micros(40_385 * 25));
        // What the driver delivers is what a recording keeps (f32) and reads back, and its
        // counts are the sensor's.
        assert_eq!(counts(&s0), [[100, -200, 1000], [0, 0, 2049]]);
        assert!(s0.gyro.iter().chain(&s0.accel).all(|v| f64::from(*v as f32) == *v));
        assert_eq!(quantised(&s0), s0);
    }

    #[test]
    fn an_overrun_delivers_what_is_left_and_says_so() {
        let t = [
            Transaction::write_read(A, vec![0x3A], vec![3, 0b0100_0000]),
            word(tag::TIMESTAMP, timestamp(5)),
            word(tag::GYRO, axes(1, 2, 3)),
            word(tag::ACCEL, axes(4, 5, 6)),
        ];
        let mut bus = Mock::new(&t);
        let mut n = 0;
        assert_eq!(Lsm6dso::new(bus.clone(), A).read_fifo(|_, _| n += 1), Err(Error::FifoOverrun { delivered: 1 }));
        assert_eq!(n, 1);
        bus.done();
    }

    #[test]
    fn the_timestamp_goes_on_across_the_counter_s_wrap() {
        assert_eq!(extend(None, 7), 7);
        assert_eq!(extend(Some(0xFFFF_FF00), 0x10), 0x1_0000_0010);
        assert_eq!(extend(Some(0x1_0000_0010), 0x20), 0x1_0000_0020);
    }

    #[test]
    fn a_fifo_count_beyond_the_fifo_is_bounded() {
        // 0x3FF words claimed: the driver reads the FIFO's 512 and no more (a 513th read
        // would find the mock with no transaction left, and fail the test).
        let mut t = vec![Transaction::write_read(A, vec![0x3A], vec![0xFF, 0b11])];
        for _ in 0..FIFO_WORDS {
            t.push(word(0x1F, [0; 6]));
        }
        let mut bus = Mock::new(&t);
        assert_eq!(Lsm6dso::new(bus.clone(), A).read_fifo(|_, _| {}), Ok(0));
        bus.done();
    }
}
