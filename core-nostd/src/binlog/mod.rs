//! The compact 4D log (format v1, `docs/binlog.md`): what leaves the dashcam.
//!
//! A log is a header and a sequence of **segments**. Each segment starts with a sync
//! marker and a segment record (sequence number, start time) and ends with an index
//! record (records per kind, time span, length); it is bounded in duration and record
//! count. Every record is framed as `length · kind · payload · CRC-32C`.
//!
//! Values are quantised integers (mm, µs, 1e-7°, 1e-4 rad, …) and each field is coded as a
//! zigzag varint of its difference to a prediction from the previous record of the same
//! kind in the segment — nothing, the previous value, or the previous value plus the
//! previous change — so a steady 20 Hz pose costs a byte per field. The first record of
//! each kind in a segment predicts from nothing (a keyframe), which is what lets a reader
//! start again after damage: at worst the rest of one segment is lost.
//!
//! [`Writer`] encodes onto any [`embedded_io::Write`] through a bounded buffer with an
//! explicit flush policy; [`Decoder`] is push-based (sans-io): feed it bytes in any
//! chunks and it reports every intact record, the damage, and where it resynchronised.

mod codec;
mod reader;
pub mod signature;
pub mod varint;
mod writer;

pub use codec::{Streams, MAX_FIELDS};
pub use reader::{Decoder, Event, Stats, DECODER_BUFFER};
pub use writer::{FlushPolicy, WriteError, Writer, WriterConfig};

use crc::{Crc, CRC_32_ISCSI};

/// The file's first six bytes.
pub const MAGIC: [u8; 6] = *b"D2SLOG";
/// Format major version.
pub const VERSION_MAJOR: u8 = 1;
/// Format minor version written (1.1 added `Detection3d` and `ClockOffset`; 1.2 the VO
/// session of a `VoPose` and `MountEstimate`; 1.3 the σ of an `EgoPose`; 1.4 the GNSS
/// latency of an `AnchorEstimate`; 1.5 the segments' signature trailers, [`signature`];
/// 1.6 the IMU's `ImuDelta` and `ImuEstimate`; 1.7 a track's `TrackCovariance` and a
/// `Verification`'s decision).
pub const VERSION_MINOR: u8 = 7;
/// Header length in bytes (v1.0).
pub const HEADER_LEN: usize = 48;
/// Marks the start of every segment; a reader looks for it after damage.
pub const SYNC: [u8; 4] = [0xD2, 0x5C, 0x0F, 0xE1];
/// [`FrameMeta`]'s flag of a pose the device dead-reckoned (gyro + wheels, v1.6), not a
/// camera frame: its frame numbers are the dead reckoning's own, at its own rate.
pub const FRAME_DEAD_RECKONED: i64 = 2;
/// [`Verification::decision`] of a window verified within the log's doubt (v1.7).
pub const DECISION_VERIFIED: i64 = 1;
/// [`Verification::decision`] of a window rejected within it.
pub const DECISION_REJECTED: i64 = 2;
/// [`Verification::decision`] of a window the doubt leaves undecided.
pub const DECISION_UNDECIDED: i64 = 3;
/// Largest payload a record may have.
pub const MAX_PAYLOAD: usize = 1024;
/// Longest frame: length varint, kind, payload, CRC.
pub const MAX_FRAME: usize = 2 + 1 + MAX_PAYLOAD + 4;
/// Longest event text, bytes.
pub const MAX_TEXT: usize = 255;
/// Kind code of the segment start record.
pub const SEGMENT: u8 = 0x01;
/// Kind code of the segment index record.
pub const INDEX: u8 = 0x02;

/// CRC-32C (Castagnoli), as the map tile uses.
pub const CRC32C: Crc<u32> = Crc::<u32>::new(&CRC_32_ISCSI);

/// A physical value as an integer number of `unit`s, rounded to the nearest (saturating;
/// NaN → 0). Every quantised field of the log is made this way.
pub fn quantise(value: f64, unit: f64) -> i64 {
    let q = libm::round(value / unit);
    if q.is_nan() {
        0
    } else {
        // `as` saturates at the ends of i64.
        q as i64
    }
}

/// How a field is predicted from the previous record of its kind in the segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// No prediction: the value itself.
    Absolute,
    /// The previous value.
    Delta,
    /// The previous value plus the previous change (constant rate).
    DeltaDelta,
}

/// The log header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    /// Who wrote the log.
    pub device_id: [u8; 16],
    /// Geodetic origin of the ENU frame: latitude, longitude (1e-7°), height (mm).
    pub origin: [i32; 3],
}

impl Header {
    /// The 48 header bytes.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut h = [0u8; HEADER_LEN];
        h[..6].copy_from_slice(&MAGIC);
        h[6] = VERSION_MAJOR;
        h[7] = VERSION_MINOR;
        h[8..10].copy_from_slice(&(HEADER_LEN as u16).to_le_bytes());
        h[12..28].copy_from_slice(&self.device_id);
        for (k, v) in self.origin.iter().enumerate() {
            h[28 + 4 * k..32 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
        // Units as powers of ten: position m, angle rad, time s.
        h[40] = (-3i8) as u8;
        h[41] = (-4i8) as u8;
        h[42] = (-6i8) as u8;
        let crc = CRC32C.checksum(&h[..44]);
        h[44..48].copy_from_slice(&crc.to_le_bytes());
        h
    }

    /// Parse a header; the error says why the bytes are not one.
    pub fn decode(b: &[u8]) -> Result<(Header, usize), HeaderError> {
        if b.len() >= 6 && b[..6] != MAGIC {
            return Err(HeaderError::NotALog);
        }
        let Some(h) = b.get(..HEADER_LEN) else { return Err(HeaderError::TooShort) };
        if h[6] != VERSION_MAJOR {
            return Err(HeaderError::UnsupportedVersion(h[6]));
        }
        let len = usize::from(u16::from_le_bytes([h[8], h[9]]));
        if len < HEADER_LEN {
            return Err(HeaderError::BadChecksum);
        }
        if CRC32C.checksum(&h[..44]) != u32::from_le_bytes([h[44], h[45], h[46], h[47]]) {
            return Err(HeaderError::BadChecksum);
        }
        if [h[40], h[41], h[42]] != [(-3i8) as u8, (-4i8) as u8, (-6i8) as u8] {
            return Err(HeaderError::UnsupportedUnits);
        }
        let mut device_id = [0u8; 16];
        device_id.copy_from_slice(&h[12..28]);
        let i32_at = |at: usize| i32::from_le_bytes([h[at], h[at + 1], h[at + 2], h[at + 3]]);
        Ok((Header { device_id, origin: [i32_at(28), i32_at(32), i32_at(36)] }, len))
    }
}

/// Why a header was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HeaderError {
    /// The magic is not `D2SLOG`: not a dash2sim log at all.
    NotALog,
    /// Fewer bytes than a header.
    TooShort,
    /// A major version this reader does not know.
    UnsupportedVersion(u8),
    /// The header's CRC-32C does not match.
    BadChecksum,
    /// Units other than v1's (mm, 1e-4 rad, µs).
    UnsupportedUnits,
}

impl core::fmt::Display for HeaderError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            HeaderError::NotALog => f.write_str("not a dash2sim log (bad magic)"),
            HeaderError::TooShort => write!(f, "shorter than the {HEADER_LEN}-byte header"),
            HeaderError::UnsupportedVersion(v) => write!(f, "log format version {v} is not supported (this reader: 1)"),
            HeaderError::BadChecksum => f.write_str("the header's CRC-32C does not match"),
            HeaderError::UnsupportedUnits => f.write_str("units other than mm, 1e-4 rad and µs"),
        }
    }
}

impl core::error::Error for HeaderError {}

/// Declares the record kinds: a struct of quantised fields per kind (the first is always
/// `t_us`), its code, each field's prediction mode, and the `Record` enum over them.
macro_rules! records {
    ($(
        $(#[$doc:meta])*
        $name:ident = $code:literal {
            $( $(#[$fdoc:meta])* $field:ident : $mode:ident ),+ $(,)?
        }
    )+) => {
        $(
            $(#[$doc])*
            #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
            #[cfg_attr(feature = "defmt", derive(defmt::Format))]
            pub struct $name {
                $( $(#[$fdoc])* pub $field: i64, )+
            }

            impl $name {
                const MODES: &'static [Mode] = &[$(Mode::$mode),+];

                fn fields(&self, out: &mut [i64; MAX_FIELDS]) -> usize {
                    let values = [$(self.$field),+];
                    out[..values.len()].copy_from_slice(&values);
                    values.len()
                }

                fn from_fields(v: &[i64]) -> Self {
                    let mut it = v.iter().copied();
                    $name { $( $field: it.next().unwrap_or(0), )+ }
                }
            }
        )+

        /// What kind of record.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub enum Kind {
            $( $(#[$doc])* $name, )+
            /// 3D tracks of one time (a batch).
            Tracks3d,
            /// A log message.
            Event,
        }

        impl Kind {
            /// Every kind, in code order.
            pub const ALL: &'static [Kind] = &[$(Kind::$name,)+ Kind::Tracks3d, Kind::Event];

            /// The kind's code in the frame.
            pub const fn code(self) -> u8 {
                match self {
                    $( Kind::$name => $code, )+
                    Kind::Tracks3d => TRACKS3D_CODE,
                    Kind::Event => EVENT_CODE,
                }
            }

            /// The kind with this code, if known.
            pub const fn from_code(code: u8) -> Option<Kind> {
                match code {
                    $( $code => Some(Kind::$name), )+
                    TRACKS3D_CODE => Some(Kind::Tracks3d),
                    EVENT_CODE => Some(Kind::Event),
                    _ => None,
                }
            }

            /// The kind's name as `inspect` prints it.
            pub const fn name(self) -> &'static str {
                match self {
                    $( Kind::$name => stringify!($name), )+
                    Kind::Tracks3d => "Tracks3d",
                    Kind::Event => "Event",
                }
            }

            /// Prediction modes of its fields.
            pub const fn modes(self) -> &'static [Mode] {
                match self {
                    $( Kind::$name => $name::MODES, )+
                    Kind::Tracks3d => TRACKS3D_MODES,
                    Kind::Event => EVENT_MODES,
                }
            }

            /// Fields the kind had in the version that introduced it. The fields a later
            /// minor version appended are left out of a payload, from the end, while they are
            /// 0: a reader takes a missing field as 0, so a device that does not fill one
            /// pays nothing for it (an `EgoPose` without σ stays 11 bytes).
            pub const fn first_fields(self) -> usize {
                match self {
                    Kind::VoPose => 7,
                    Kind::EgoPose => 5,
                    Kind::AnchorEstimate => 11,
                    Kind::Verification => 11,
                    _ => usize::MAX,
                }
            }
        }

        /// One record.
        // No allocator to box the track batch into: a record is a fixed ~0.8 KB value,
        // which is what capacity in the type means here.
        #[allow(clippy::large_enum_variant)]
        #[derive(Clone, Debug, PartialEq, Eq)]
        pub enum Record {
            $( $(#[$doc])* $name($name), )+
            /// 3D tracks of one time.
            Tracks3d(Tracks3d),
            /// A log message.
            Event(EventRecord),
        }

        impl Record {
            /// Its kind.
            pub fn kind(&self) -> Kind {
                match self {
                    $( Record::$name(_) => Kind::$name, )+
                    Record::Tracks3d(_) => Kind::Tracks3d,
                    Record::Event(_) => Kind::Event,
                }
            }

            /// Its time, µs.
            pub fn t_us(&self) -> i64 {
                match self {
                    $( Record::$name(r) => r.t_us, )+
                    Record::Tracks3d(b) => b.t_us,
                    Record::Event(e) => e.t_us,
                }
            }

            /// Move it to another time, µs (a reader re-timing records written before
            /// the first [`ClockOffset`]).
            pub fn set_t_us(&mut self, t_us: i64) {
                match self {
                    $( Record::$name(r) => r.t_us = t_us, )+
                    Record::Tracks3d(b) => b.t_us = t_us,
                    Record::Event(e) => e.t_us = t_us,
                }
            }

            /// The quantised fields in order; returns how many.
            pub fn fields(&self, out: &mut [i64; MAX_FIELDS]) -> usize {
                match self {
                    $( Record::$name(r) => r.fields(out), )+
                    Record::Tracks3d(b) => {
                        out[0] = b.t_us;
                        1
                    }
                    Record::Event(e) => {
                        out[0] = e.t_us;
                        out[1] = i64::from(e.level);
                        2
                    }
                }
            }

            /// The record of `kind` with these fields (as [`Record::fields`] gives them; an
            /// event's text apart). `None` for a [`Tracks3d`] batch, which is not made of
            /// fields, or an event whose level or text does not fit.
            pub fn from_fields(kind: Kind, v: &[i64], text: &[u8]) -> Option<Record> {
                Some(match kind {
                    $( Kind::$name => Record::$name($name::from_fields(v)), )+
                    // Built by the codec, which reads the tracks.
                    Kind::Tracks3d => return None,
                    Kind::Event => Record::Event(EventRecord {
                        t_us: v.first().copied().unwrap_or(0),
                        level: u8::try_from(v.get(1).copied().unwrap_or(0)).ok()?,
                        text: heapless::Vec::from_slice(text).ok()?,
                    }),
                })
            }
        }
    };
}

const EVENT_CODE: u8 = 0x1A;
const EVENT_MODES: &[Mode] = &[Mode::Delta, Mode::Absolute];
const TRACKS3D_CODE: u8 = 0x18;
const TRACKS3D_MODES: &[Mode] = &[Mode::Delta];

/// Tracks in one `Tracks3d` record.
pub const MAX_TRACKS: usize = 8;

/// A 3D track in the ENU frame, as one element of a [`Tracks3d`] record. Each is coded
/// against the previous state of the same id in the segment (position advanced by its
/// velocity), so a standing cone costs two bytes per frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Track3d {
    /// Track id.
    pub id: i64,
    /// Class (see `docs/binlog.md`).
    pub class: i64,
    /// Centre east, mm.
    pub x_mm: i64,
    /// Centre north, mm.
    pub y_mm: i64,
    /// Centre up, mm.
    pub z_mm: i64,
    /// Length, mm.
    pub l_mm: i64,
    /// Width, mm.
    pub w_mm: i64,
    /// Height, mm.
    pub h_mm: i64,
    /// Heading, 1e-4 rad.
    pub yaw_e4: i64,
    /// Velocity east, mm/s.
    pub vx_mm_s: i64,
    /// Velocity north, mm/s.
    pub vy_mm_s: i64,
    /// 1 when static.
    pub is_static: i64,
}

/// The 3D tracks of one time. A writer splits a batch that does not fit one frame into
/// several records of the same time.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Tracks3d {
    /// Time, µs.
    pub t_us: i64,
    /// The tracks, at most [`MAX_TRACKS`].
    pub tracks: heapless::Vec<Track3d, MAX_TRACKS>,
}

records! {
    /// A GNSS fix.
    GnssFix = 0x10 {
        /// Time, µs.
        t_us: DeltaDelta,
        /// Latitude, 1e-7°.
        lat_e7: Delta,
        /// Longitude, 1e-7°.
        lon_e7: Delta,
        /// Height above the ellipsoid, mm.
        alt_mm: Delta,
        /// Speed over ground, mm/s.
        speed_mm_s: Delta,
        /// Course over ground, 1e-4 rad.
        track_e4: Delta,
        /// Horizontal DOP × 100.
        hdop_e2: Absolute,
        /// Satellites used.
        satellites: Absolute,
        /// Fix mode: 0 none, 2 2D, 3 3D.
        mode: Absolute,
    }
    /// Vehicle speed (wheel speed or CAN).
    VehicleSpeed = 0x11 {
        /// Time, µs.
        t_us: DeltaDelta,
        /// Speed, mm/s.
        speed_mm_s: Delta,
        /// Source: 0 wheel, 1 CCVS1, 2 OBD-II, 3 DBC signal, 4 N2K SOG.
        source: Absolute,
    }
    /// A visual-odometry pose (VO units, unknown scale, ×1000).
    VoPose = 0x12 {
        /// Time, µs.
        t_us: DeltaDelta,
        /// x, VO units × 1000.
        x: DeltaDelta,
        /// y, VO units × 1000.
        y: DeltaDelta,
        /// z, VO units × 1000.
        z: DeltaDelta,
        /// Yaw, 1e-4 rad.
        yaw_e4: DeltaDelta,
        /// Pitch, 1e-4 rad.
        pitch_e4: DeltaDelta,
        /// Roll, 1e-4 rad.
        roll_e4: DeltaDelta,
        /// The VO session the pose belongs to (v1.2; 0 in older logs): a VO that lost
        /// track and started again has a new origin, orientation and scale.
        session: Delta,
    }
    /// The anchored ego pose (rear axle) in the header's ENU frame.
    EgoPose = 0x13 {
        /// Time, µs.
        t_us: DeltaDelta,
        /// East, mm.
        x_mm: DeltaDelta,
        /// North, mm.
        y_mm: DeltaDelta,
        /// Up, mm.
        z_mm: DeltaDelta,
        /// Heading, 1e-4 rad counter-clockwise from east.
        yaw_e4: DeltaDelta,
        /// Horizontal 1-σ of the position (DRMS: √(σ_east² + σ_north²)), mm; 0 when not
        /// estimated (v1.3; 0 in older logs; the device writes its anchorer's
        /// `position_sigma_m`, `finish` the solution's).
        sigma_mm: Delta,
    }
    /// The current VO → ENU anchor (Sim(3)) and its quality.
    AnchorEstimate = 0x14 {
        /// Time, µs.
        t_us: Delta,
        /// Scale × 1e6.
        scale_e6: Absolute,
        /// Rotation yaw, 1e-6 rad.
        yaw_e6: Absolute,
        /// Rotation pitch, 1e-6 rad.
        pitch_e6: Absolute,
        /// Rotation roll, 1e-6 rad.
        roll_e6: Absolute,
        /// Translation east, mm.
        tx_mm: Absolute,
        /// Translation north, mm.
        ty_mm: Absolute,
        /// Translation up, mm.
        tz_mm: Absolute,
        /// Observability: 0 none, 1 collinear, 2 observable.
        observability: Absolute,
        /// Anchors in the solution.
        anchors: Absolute,
        /// RMS residual, mm.
        rms_mm: Absolute,
        /// The GNSS receiver's latency (fix time → the VO time it describes) the solution
        /// used, µs (v1.4; 0 in older logs, and when not estimated: a reader applies it the
        /// same way). The device's is coarse (its hypotheses 25 ms apart, refined by a
        /// parabola), `finish`'s the solution's.
        latency_us: Absolute,
    }
    /// A camera frame.
    FrameMeta = 0x15 {
        /// Time, µs.
        t_us: DeltaDelta,
        /// Frame number.
        frame: DeltaDelta,
        /// Flags (bit 0: keyframe of VO; bit 1, [`FRAME_DEAD_RECKONED`]: a dead-reckoned
        /// pose, not a camera frame).
        flags: Absolute,
    }
    /// A 2D detection.
    Detection2d = 0x16 {
        /// Time, µs.
        t_us: Delta,
        /// Frame number.
        frame: Delta,
        /// Class.
        class: Absolute,
        /// Score × 1000.
        score_e3: Absolute,
        /// Left, 0.1 px.
        x_e1: Absolute,
        /// Top, 0.1 px.
        y_e1: Absolute,
        /// Width, 0.1 px.
        w_e1: Absolute,
        /// Height, 0.1 px.
        h_e1: Absolute,
    }
    /// A 2D track's box in one frame.
    Track2d = 0x17 {
        /// Time, µs.
        t_us: Delta,
        /// Track id.
        id: Absolute,
        /// Class.
        class: Absolute,
        /// Score × 1000.
        score_e3: Absolute,
        /// Left, 0.1 px.
        x_e1: Absolute,
        /// Top, 0.1 px.
        y_e1: Absolute,
        /// Width, 0.1 px.
        w_e1: Absolute,
        /// Height, 0.1 px.
        h_e1: Absolute,
    }
    /// A drivable-area / score result.
    Verification = 0x19 {
        /// Time, µs.
        t_us: Delta,
        /// No at-fault collisions × 1e4.
        collisions_e4: Absolute,
        /// Drivable-area compliance × 1e4.
        drivable_e4: Absolute,
        /// Driving-direction compliance × 1e4.
        direction_e4: Absolute,
        /// Making progress × 1e4.
        making_progress_e4: Absolute,
        /// Progress × 1e4.
        progress_e4: Absolute,
        /// TTC within bound × 1e4.
        ttc_e4: Absolute,
        /// Speed-limit compliance × 1e4.
        speed_limit_e4: Absolute,
        /// Comfort × 1e4.
        comfort_e4: Absolute,
        /// Score × 100 (0..10000).
        score_e2: Absolute,
        /// Worst corner outside the drivable area, mm.
        worst_corner_mm: Absolute,
        /// The verdict with the log's doubt (v1.7): 0 not decided (the device's windows,
        /// older logs), 1 verified, 2 rejected, 3 undecided ([`DECISION_VERIFIED`], …).
        decision: Absolute,
        /// The least score within the doubt × 100 (v1.7; with `decision` only).
        score_low_e2: Absolute,
        /// The greatest score within the doubt × 100 (v1.7; with `decision` only).
        score_high_e2: Absolute,
    }
    /// A 3D detection in the camera frame (x forward, y left, z up, metres from the
    /// camera), written for frames the device could not yet place in the world (no
    /// anchored pose), so that offline finishing can place them later.
    Detection3d = 0x1B {
        /// Time, µs.
        t_us: Delta,
        /// Frame number.
        frame: Delta,
        /// Class.
        class: Absolute,
        /// Score × 1000.
        score_e3: Absolute,
        /// Centre forward, mm.
        x_mm: Absolute,
        /// Centre left, mm.
        y_mm: Absolute,
        /// Centre up, mm.
        z_mm: Absolute,
        /// Heading in the camera frame, 1e-4 rad.
        yaw_e4: Absolute,
        /// Length, mm.
        l_mm: Absolute,
        /// Width, mm.
        w_mm: Absolute,
        /// Height, mm.
        h_mm: Absolute,
        /// Covariance of the horizontal centre: xx, mm² (0: not given).
        cov_xx_mm2: Absolute,
        /// Covariance xy, mm².
        cov_xy_mm2: Absolute,
        /// Covariance yy, mm².
        cov_yy_mm2: Absolute,
    }
    /// The device clock → UTC offset from here on: `t_us` is UTC and the device's
    /// monotonic time is `t_us − offset_us`. Records before the first one carry device
    /// time (no fix yet); readers re-time them with the first offset.
    ClockOffset = 0x1C {
        /// Time (UTC), µs.
        t_us: Delta,
        /// UTC − device monotonic time, µs.
        offset_us: Delta,
        /// Why: 0 first fix, 1 drift, 2 GNSS time step, 3 device clock reset.
        reason: Absolute,
    }
    /// The camera's mount on the car as calibrated so far (v1.2): rotation camera → body.
    MountEstimate = 0x1D {
        /// Time, µs.
        t_us: Delta,
        /// Yaw, 1e-6 rad.
        yaw_e6: Absolute,
        /// Pitch, 1e-6 rad.
        pitch_e6: Absolute,
        /// Roll, 1e-6 rad (the nominal mount's: not estimated).
        roll_e6: Absolute,
        /// 1-σ of the yaw, 1e-6 rad.
        sigma_yaw_e6: Absolute,
        /// 1-σ of the pitch, 1e-6 rad.
        sigma_pitch_e6: Absolute,
        /// Straight-driving frames the estimate rests on.
        samples: Absolute,
        /// 1 when calibrated (enough samples and σ small enough), 0 while the nominal
        /// mount still weighs in.
        calibrated: Absolute,
    }
    /// The IMU's samples preintegrated over an interval (v1.6), raw on the sensor's own
    /// axes: no bias removed, gravity included (`imu::preintegrate`).
    ImuDelta = 0x1E {
        /// Time at the interval's end, µs.
        t_us: DeltaDelta,
        /// The interval's length, µs.
        dt_us: Delta,
        /// Rotation over the interval (rotation vector) about the sensor's x, 1e-6 rad.
        dtheta_x_e6: Delta,
        /// About y, 1e-6 rad.
        dtheta_y_e6: Delta,
        /// About z, 1e-6 rad.
        dtheta_z_e6: Delta,
        /// Velocity change from the specific force along the sensor's x (its axes at the
        /// interval's start), mm/s.
        dv_x_mm_s: Delta,
        /// Along y, mm/s.
        dv_y_mm_s: Delta,
        /// Along z, mm/s.
        dv_z_mm_s: Delta,
        /// Samples in the interval.
        samples: Delta,
    }
    /// What the device made of its IMU so far (v1.6), about once a second: the body's
    /// tilt from gravity and the gyro's bias.
    ImuEstimate = 0x1F {
        /// Time, µs.
        t_us: Delta,
        /// The body's pitch (Z-Y-X, x forward, z up; positive nose down), 1e-6 rad.
        pitch_e6: Delta,
        /// The body's roll, 1e-6 rad.
        roll_e6: Delta,
        /// Gyro bias about the body's x, 1e-7 rad/s.
        bias_x_e7: Delta,
        /// About the body's y, 1e-7 rad/s.
        bias_y_e7: Delta,
        /// About the body's z, 1e-7 rad/s.
        bias_z_e7: Delta,
        /// 1-σ of the bias about the vertical, 1e-7 rad/s.
        bias_sigma_e7: Delta,
        /// Standstills the bias rests on.
        standstills: Delta,
        /// GNSS course intervals it rests on.
        courses: Delta,
    }
    /// How far a 3D track's place is in doubt relative to the ego (v1.7), once per track:
    /// the covariance of its horizontal centre. `finish` states it for the tracks it keeps,
    /// from how far the states it made one place of spread around it (the device states
    /// none).
    TrackCovariance = 0x20 {
        /// The time of the track's first state, µs.
        t_us: Delta,
        /// Track id (as in `Tracks3d`).
        id: Absolute,
        /// Covariance east-east, mm².
        cov_xx_mm2: Absolute,
        /// Covariance east-north, mm².
        cov_xy_mm2: Absolute,
        /// Covariance north-north, mm².
        cov_yy_mm2: Absolute,
    }
}

impl Verification {
    /// The window's decision by name (`verified`, `rejected`, `undecided`); none where it
    /// was not decided (a device's window, a log before v1.7).
    pub fn decision_name(&self) -> Option<&'static str> {
        match self.decision {
            DECISION_VERIFIED => Some("verified"),
            DECISION_REJECTED => Some("rejected"),
            DECISION_UNDECIDED => Some("undecided"),
            _ => None,
        }
    }
}

/// A log message: time, level (0 debug … 4 fatal, as `foxglove.Log`), UTF-8 text.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct EventRecord {
    /// Time, µs.
    pub t_us: i64,
    /// Level: 0 unknown, 1 debug, 2 info, 3 warning, 4 error, 5 fatal.
    pub level: u8,
    /// Text, at most [`MAX_TEXT`] bytes.
    pub text: heapless::Vec<u8, MAX_TEXT>,
}

#[cfg(test)]
mod tests;
