//! A recorded input stream: every input the pipeline takes, with its device time, in the
//! order it arrived — so that the same drive can be fed to the pipeline on the host and on
//! a microcontroller (from flash), and the two logs compared byte for byte.
//!
//! Format (little-endian; `docs/pipeline.md`): the magic `D2SIN1`, then entries
//! `kind u8 · device time i64 µs · payload length u16 · payload`:
//!
//! | kind | payload |
//! |---|---|
//! | 1 serial | the bytes as read from the port |
//! | 2 CAN | id u32 (bit 31: 29-bit id), data length u8, data |
//! | 3 VO pose | frame u64, position 3 × f64, rotation 9 × f64 (row-major, camera → VO), VO session u32 (absent in older streams: 0) |
//! | 4 3D detections | frame u64, then per detection: class u16, score f32, x y z yaw l w h f32 (camera frame), covariance xx xy yy f32 (all zero: none) |
//! | 5 2D detections | frame u64, then per detection: class u16, score f32, left top width height f32 |
//! | 6 IMU sample | gyro x y z f32 (rad/s), specific force x y z f32 (m/s²), the sensor's axes |
//!
//! Detections and IMU samples are `f32` on purpose: the stream is what a camera process sends, and half
//! the bytes let a 20 s drive fit a microcontroller's flash. The reader never panics; a
//! malformed entry ends the stream with [`ReplayError`].

use embedded_can::Id;
use embedded_io::Write;
use nalgebra::{Matrix3, Vector3};

use super::{ImageDetection, Pipeline, PipelineError};
use crate::box2d::Box2d;
use crate::box3d::Box3d;
use crate::can::frame::{id_from_raw, raw_id};
use crate::can::CanFrame;
use crate::imu::ImuSample;
use crate::sim3::Pose;
use crate::time::Timestamp;
use crate::track2d::Detection;
use crate::track3d::Detection3d;

/// The stream's first bytes.
pub const MAGIC: [u8; 6] = *b"D2SIN1";
/// Bytes of an entry's head: kind, time, length.
pub const ENTRY_HEAD: usize = 1 + 8 + 2;
/// Bytes of one 3D detection.
pub const DETECTION3D_LEN: usize = 2 + 4 + 7 * 4 + 3 * 4;
/// Bytes of one 2D detection.
pub const DETECTION2D_LEN: usize = 2 + 4 + 4 * 4;
/// Bytes of an IMU entry's payload.
pub const IMU_LEN: usize = 6 * 4;
/// Bytes of a VO entry's payload.
pub const VO_LEN: usize = 8 + 12 * 8 + 4;
/// Bytes of a VO entry's payload in streams written before the session was added.
const VO_LEN_WITHOUT_SESSION: usize = 8 + 12 * 8;

/// Entry kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum EntryKind {
    /// Serial bytes.
    Serial = 1,
    /// A CAN frame.
    Can = 2,
    /// A VO pose.
    Vo = 3,
    /// 3D detections of a frame.
    Detections3d = 4,
    /// 2D detections of a frame.
    Detections2d = 5,
    /// An IMU sample.
    Imu = 6,
}

/// One input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Input<'a> {
    /// Serial bytes.
    Serial(&'a [u8]),
    /// A CAN frame.
    Can(CanFrame),
    /// A VO pose of a frame.
    Vo(u64, u32, Pose),
    /// 3D detections of a frame (decode with [`detections3d`]).
    Detections3d(u64, &'a [u8]),
    /// 2D detections of a frame (decode with [`detections2d`]).
    Detections2d(u64, &'a [u8]),
    /// An IMU sample.
    Imu(ImuSample),
}

/// Why the stream could not be read on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplayError {
    /// The stream does not start with [`MAGIC`].
    NotAnInputStream,
    /// An entry at this offset is cut short.
    Truncated(usize),
    /// An entry at this offset has an unknown kind or a payload of the wrong size.
    Malformed(usize),
}

impl core::fmt::Display for ReplayError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ReplayError::NotAnInputStream => f.write_str("not a dash2sim input stream (bad magic)"),
            ReplayError::Truncated(at) => write!(f, "entry at byte {at} is cut short"),
            ReplayError::Malformed(at) => write!(f, "entry at byte {at} is malformed"),
        }
    }
}

impl core::error::Error for ReplayError {}

fn f64_at(b: &[u8], at: usize) -> Option<f64> {
    Some(f64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

fn f32_at(b: &[u8], at: usize) -> Option<f64> {
    Some(f64::from(f32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?)))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

/// Reads entries from a stream held in memory (flash on a microcontroller).
#[derive(Clone, Debug)]
pub struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    /// A reader over `bytes`, which must start with [`MAGIC`].
    pub fn new(bytes: &'a [u8]) -> Result<Self, ReplayError> {
        if bytes.get(..MAGIC.len()) != Some(&MAGIC[..]) {
            return Err(ReplayError::NotAnInputStream);
        }
        Ok(Reader { bytes, at: MAGIC.len() })
    }

    /// The next entry: device time and input; `None` at the end.
    pub fn next_input(&mut self) -> Option<Result<(Timestamp, Input<'a>), ReplayError>> {
        let start = self.at;
        let rest = self.bytes.get(start..)?;
        if rest.is_empty() {
            return None;
        }
        let Some(head) = rest.get(..ENTRY_HEAD) else {
            self.at = self.bytes.len();
            return Some(Err(ReplayError::Truncated(start)));
        };
        let kind = head[0];
        let t = Timestamp::from_micros(i64::from_le_bytes([
            head[1], head[2], head[3], head[4], head[5], head[6], head[7], head[8],
        ]));
        let len = usize::from(u16::from_le_bytes([head[9], head[10]]));
        let Some(payload) = rest.get(ENTRY_HEAD..ENTRY_HEAD + len) else {
            self.at = self.bytes.len();
            return Some(Err(ReplayError::Truncated(start)));
        };
        self.at = start + ENTRY_HEAD + len;
        let malformed = ReplayError::Malformed(start);
        let input = match kind {
            1 => Some(Input::Serial(payload)),
            2 => can_frame(payload).map(Input::Can),
            3 => vo(payload).map(|(frame, session, pose)| Input::Vo(frame, session, pose)),
            4 => u64_at(payload, 0)
                .filter(|_| (len - 8) % DETECTION3D_LEN == 0)
                .map(|frame| Input::Detections3d(frame, &payload[8..])),
            5 => u64_at(payload, 0)
                .filter(|_| (len - 8) % DETECTION2D_LEN == 0)
                .map(|frame| Input::Detections2d(frame, &payload[8..])),
            6 => imu(payload).map(Input::Imu),
            _ => None,
        };
        Some(match input {
            Some(input) => Ok((t, input)),
            None => {
                self.at = self.bytes.len();
                Err(malformed)
            }
        })
    }
}

fn can_frame(p: &[u8]) -> Option<CanFrame> {
    let raw = u32::from_le_bytes(p.get(..4)?.try_into().ok()?);
    let dlc = usize::from(*p.get(4)?);
    let data = p.get(5..5 + dlc).filter(|d| d.len() + 5 == p.len())?;
    let id = id_from_raw(raw & 0x1FFF_FFFF, raw & 0x8000_0000 != 0)?;
    CanFrame::data_frame(id, data)
}

fn imu(p: &[u8]) -> Option<ImuSample> {
    if p.len() != IMU_LEN {
        return None;
    }
    let v = |k: usize| f32_at(p, 4 * k);
    Some(ImuSample { gyro: [v(0)?, v(1)?, v(2)?], accel: [v(3)?, v(4)?, v(5)?] })
}

fn vo(p: &[u8]) -> Option<(u64, u32, Pose)> {
    let session = match p.len() {
        VO_LEN => u32::from_le_bytes(p.get(VO_LEN_WITHOUT_SESSION..VO_LEN)?.try_into().ok()?),
        VO_LEN_WITHOUT_SESSION => 0,
        _ => return None,
    };
    let frame = u64_at(p, 0)?;
    let v = |k: usize| f64_at(p, 8 + 8 * k);
    let translation = Vector3::new(v(0)?, v(1)?, v(2)?);
    let mut rotation = Matrix3::zeros();
    for r in 0..3 {
        for c in 0..3 {
            rotation[(r, c)] = v(3 + 3 * r + c)?;
        }
    }
    Some((frame, session, Pose { rotation, translation }))
}

/// Decode the 3D detections of an entry into `out` (as many as fit); returns how many
/// did not fit.
pub fn detections3d<const N: usize>(bytes: &[u8], out: &mut heapless::Vec<Detection3d, N>) -> usize {
    out.clear();
    let mut excess = 0;
    for d in bytes.chunks_exact(DETECTION3D_LEN) {
        let f = |k: usize| f32_at(d, 6 + 4 * k).unwrap_or(f64::NAN);
        let cov = [f(7), f(8), f(9)];
        let detection = Detection3d {
            class: u16_at(d, 0).unwrap_or(u16::MAX),
            score: f32_at(d, 2).unwrap_or(f64::NAN),
            bbox: Box3d { x: f(0), y: f(1), z: f(2), yaw: f(3), l: f(4), w: f(5), h: f(6) },
            position_covariance: (cov != [0.0; 3]).then_some(cov),
        };
        if out.push(detection).is_err() {
            excess += 1;
        }
    }
    excess
}

/// Decode the 2D detections of an entry into `out`; returns how many did not fit.
pub fn detections2d<const N: usize>(bytes: &[u8], out: &mut heapless::Vec<ImageDetection, N>) -> usize {
    out.clear();
    let mut excess = 0;
    for d in bytes.chunks_exact(DETECTION2D_LEN) {
        let f = |k: usize| f32_at(d, 6 + 4 * k).unwrap_or(f64::NAN);
        let detection = ImageDetection {
            class: u16_at(d, 0).unwrap_or(u16::MAX),
            detection: Detection {
                bbox: Box2d { x: f(0), y: f(1), w: f(2), h: f(3) },
                score: f32_at(d, 2).unwrap_or(f64::NAN),
            },
        };
        if out.push(detection).is_err() {
            excess += 1;
        }
    }
    excess
}

/// Feed one input to a pipeline.
pub fn feed<W: Write, const T3: usize, const T2: usize, const BUF: usize>(
    pipeline: &mut Pipeline<'_, W, T3, T2, BUF>,
    t: Timestamp,
    input: &Input<'_>,
) -> Result<(), PipelineError<W::Error>> {
    match input {
        Input::Serial(bytes) => pipeline.push_serial(t, bytes),
        Input::Can(frame) => pipeline.push_can(t, frame),
        Input::Vo(frame, session, pose) => pipeline.push_vo(t, *frame, *session, pose),
        Input::Imu(sample) => pipeline.push_imu(t, sample),
        Input::Detections3d(frame, bytes) => {
            let mut out: heapless::Vec<Detection3d, T3> = heapless::Vec::new();
            // Beyond T3 the pipeline would count them as refused; so do we.
            let _ = detections3d(bytes, &mut out);
            pipeline.push_detections(t, *frame, &out)
        }
        Input::Detections2d(frame, bytes) => {
            let mut out: heapless::Vec<ImageDetection, T2> = heapless::Vec::new();
            let _ = detections2d(bytes, &mut out);
            pipeline.push_detections2d(t, *frame, &out)
        }
    }
}

/// Writes an input stream (the host side: `dash2sim record --save-inputs`, the MCU
/// example's embedded drive, tests).
#[derive(Debug)]
pub struct Recorder<W: Write> {
    io: W,
}

impl<W: Write> Recorder<W> {
    /// Start a stream: the magic goes out at once.
    pub fn new(mut io: W) -> Result<Self, W::Error> {
        io.write_all(&MAGIC)?;
        Ok(Recorder { io })
    }

    fn entry(&mut self, kind: EntryKind, t: Timestamp, parts: &[&[u8]]) -> Result<(), W::Error> {
        let len: usize = parts.iter().map(|p| p.len()).sum();
        let len = u16::try_from(len).unwrap_or(u16::MAX);
        self.io.write_all(&[kind as u8])?;
        self.io.write_all(&t.micros().to_le_bytes())?;
        self.io.write_all(&len.to_le_bytes())?;
        let mut left = usize::from(len);
        for p in parts {
            let n = p.len().min(left);
            self.io.write_all(&p[..n])?;
            left -= n;
        }
        Ok(())
    }

    /// Serial bytes (at most 65 535 per entry; longer chunks are split).
    pub fn serial(&mut self, t: Timestamp, bytes: &[u8]) -> Result<(), W::Error> {
        for chunk in bytes.chunks(usize::from(u16::MAX)) {
            self.entry(EntryKind::Serial, t, &[chunk])?;
        }
        Ok(())
    }

    /// A CAN frame.
    pub fn can<F: embedded_can::Frame>(&mut self, t: Timestamp, frame: &F) -> Result<(), W::Error> {
        let extended = matches!(frame.id(), Id::Extended(_));
        let raw = raw_id(frame.id()) | if extended { 0x8000_0000 } else { 0 };
        let data = frame.data();
        self.entry(EntryKind::Can, t, &[&raw.to_le_bytes(), &[data.len() as u8], data])
    }

    /// A VO pose of VO session `session`.
    pub fn vo(&mut self, t: Timestamp, frame: u64, session: u32, pose: &Pose) -> Result<(), W::Error> {
        let mut p = [0u8; VO_LEN];
        p[..8].copy_from_slice(&frame.to_le_bytes());
        let values = pose.translation.iter().copied().chain((0..9).map(|k| pose.rotation[(k / 3, k % 3)]));
        for (k, v) in values.enumerate() {
            p[8 + 8 * k..16 + 8 * k].copy_from_slice(&v.to_le_bytes());
        }
        p[VO_LEN_WITHOUT_SESSION..].copy_from_slice(&session.to_le_bytes());
        self.entry(EntryKind::Vo, t, &[&p])
    }

    /// An IMU sample (stored as `f32`: a MEMS sensor's 16-bit counts fit exactly).
    pub fn imu(&mut self, t: Timestamp, sample: &ImuSample) -> Result<(), W::Error> {
        let mut p = [0u8; IMU_LEN];
        for (k, v) in sample.gyro.iter().chain(&sample.accel).enumerate() {
            p[4 * k..4 * k + 4].copy_from_slice(&(*v as f32).to_le_bytes());
        }
        self.entry(EntryKind::Imu, t, &[&p])
    }

    /// The 3D detections of a frame (at most 1 400 per entry).
    pub fn detections3d(&mut self, t: Timestamp, frame: u64, detections: &[Detection3d]) -> Result<(), W::Error> {
        let n = detections.len().min((usize::from(u16::MAX) - 8) / DETECTION3D_LEN);
        let len = (8 + n * DETECTION3D_LEN) as u16;
        self.io.write_all(&[EntryKind::Detections3d as u8])?;
        self.io.write_all(&t.micros().to_le_bytes())?;
        self.io.write_all(&len.to_le_bytes())?;
        self.io.write_all(&frame.to_le_bytes())?;
        for d in &detections[..n] {
            let b = &d.bbox;
            let [xx, xy, yy] = d.position_covariance.unwrap_or([0.0; 3]);
            self.io.write_all(&d.class.to_le_bytes())?;
            for v in [d.score, b.x, b.y, b.z, b.yaw, b.l, b.w, b.h, xx, xy, yy] {
                self.io.write_all(&(v as f32).to_le_bytes())?;
            }
        }
        Ok(())
    }

    /// The 2D detections of a frame (at most 2 900 per entry).
    pub fn detections2d(&mut self, t: Timestamp, frame: u64, detections: &[ImageDetection]) -> Result<(), W::Error> {
        let n = detections.len().min((usize::from(u16::MAX) - 8) / DETECTION2D_LEN);
        let len = (8 + n * DETECTION2D_LEN) as u16;
        self.io.write_all(&[EntryKind::Detections2d as u8])?;
        self.io.write_all(&t.micros().to_le_bytes())?;
        self.io.write_all(&len.to_le_bytes())?;
        self.io.write_all(&frame.to_le_bytes())?;
        for d in &detections[..n] {
            let b = &d.detection.bbox;
            self.io.write_all(&d.class.to_le_bytes())?;
            for v in [d.detection.score, b.x, b.y, b.w, b.h] {
                self.io.write_all(&(v as f32).to_le_bytes())?;
            }
        }
        Ok(())
    }

    /// The sink so far (a host keeping inputs in a `Vec` bounds it by its length).
    pub fn get_ref(&self) -> &W {
        &self.io
    }

    /// Flush and give the sink back.
    pub fn finish(mut self) -> Result<W, W::Error> {
        self.io.flush()?;
        Ok(self.io)
    }
}
