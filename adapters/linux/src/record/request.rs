//! What a recording is asked to do: [`RecordRequest`], the device's setup, and the typed
//! values they hold. Each value written as text (a mount, a speed unit, a DBC signal's name,
//! the GNSS signals, a device id) has its parser here, with its errors in the library's
//! words: a front end parses once (the command line in its argument parser, Python in its
//! call) and hands the library types.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dash2sim_core::anchor::AnchorMode;
use dash2sim_core::geo::Geodetic;
use dash2sim_core::imu::ImuMount;
use dash2sim_core::pipeline::{CameraMount, RelativeMotion};

use crate::ingest::can::{SignalName, SpeedUnit};
use crate::numbers::comma_separated;
use crate::{Error, Field, Result};

/// The recorded files `record` reads (see [`super::sources`] for their forms).
#[derive(Clone, Debug, Default)]
pub struct Sources {
    /// VO poses of the camera: TUM (device-clock stamps; frame k is the k-th pose), or a CSV
    /// `frame,t_s,x,y,z,qx,qy,qz,qw,session` with each pose's frame number.
    pub vo: Option<PathBuf>,
    /// The GNSS serial capture: `(device seconds) $SENTENCE*CS` per line.
    pub nmea: Option<PathBuf>,
    /// candump captures of the vehicle bus (device-clock stamps), in order.
    pub can: Vec<PathBuf>,
    /// 3D detections in the camera frame (the detections CSV).
    pub detections: Option<PathBuf>,
    /// 2D detections, MOTChallenge CSV (frames numbered as the VO poses).
    pub detections2d: Option<PathBuf>,
    /// IMU samples: a CSV `t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z` (device
    /// seconds, rad/s and m/s² on the sensor's axes; [`super::sources::IMU_CSV_HEADER`]).
    pub imu: Option<PathBuf>,
}

impl Sources {
    /// The files `dash2sim scenario generate` writes into `dir` (a folder generated before
    /// the simulator had an IMU has no `imu.csv`, and is recorded without one).
    pub fn scenario(dir: &Path) -> Self {
        let imu = dir.join("imu.csv");
        Sources {
            vo: Some(dir.join("vo.csv")),
            nmea: Some(dir.join("gnss.serial.log")),
            can: vec![dir.join("speed.can.log")],
            detections: Some(dir.join("detections3d.csv")),
            detections2d: Some(dir.join("det2d.txt")),
            imu: imu.exists().then_some(imu),
        }
    }
}

/// The unit of a DBC speed signal when none is named.
pub const DEFAULT_SPEED_UNIT: &str = "km/h";
/// The device id a recording's header gets when none is named.
pub const DEFAULT_DEVICE_ID: &str = "dash2sim-record";
/// The GNSS serial device's baud rate when none is named.
pub const DEFAULT_BAUD: u32 = 115_200;
/// A live recording's file length when none is named, minutes.
pub const DEFAULT_SEGMENT_MINUTES: f64 = 10.0;
/// The camera's place on the car when none is named (`FORWARD,LEFT,UP`, m), as written.
pub const DEFAULT_MOUNT: &str = "1.8,0,1.3";
/// [`DEFAULT_MOUNT`]'s position, m.
pub const DEFAULT_MOUNT_M: [f64; 3] = [1.8, 0.0, 1.3];
/// The GNSS error model's UERE when none is named, m.
pub const DEFAULT_UERE_M: f64 = 2.5;

/// A recording: where the log goes, what it is recorded from (files, a saved input stream,
/// or live sources) and how the device is set up. `dash2sim record` fills it from its
/// arguments; [`RecordRequest::from_files`] gives the defaults.
#[derive(Clone, Debug)]
pub struct RecordRequest {
    /// The 4D log (a folder of segments when live).
    pub output: PathBuf,
    /// The recorded inputs.
    pub sources: Sources,
    /// DBC files for `speed_signal` and `gnss_signals`.
    pub dbc: Vec<PathBuf>,
    /// The DBC signal carrying the vehicle speed (else `speed_source`).
    pub speed_signal: Option<SignalName>,
    /// Unit of `speed_signal`.
    pub speed_unit: SpeedUnit,
    /// Built-in speed message when no `speed_signal` is given.
    pub speed_source: SpeedMessage,
    /// GNSS from DBC signals (a CAN GNSS module).
    pub gnss_signals: Option<GnssSignalNames>,
    /// Map tile to verify against on the way (windows of 15 s); its origin is the log's.
    pub map: Option<PathBuf>,
    /// The ENU origin (default: the map's, else the first GNSS fix).
    pub origin: Option<Geodetic>,
    /// The dashcam: mount, VO frame, GNSS error model.
    pub device: Device,
    /// Also write the merged input stream (the core's replay format) here.
    pub save_inputs: Option<PathBuf>,
    /// Read a saved input stream instead of the file sources.
    pub replay: Option<PathBuf>,
    /// The device id written into the log's header ([`parse_device_id`]).
    pub device_id: [u8; 16],
    /// Live: subscribe to the camera process's services (shared memory) under this prefix.
    pub camera: Option<String>,
    /// Live: the GNSS receiver's serial device (raw mode), or a file of raw NMEA bytes.
    pub serial: Option<PathBuf>,
    /// Live: the serial device's baud rate.
    pub baud: u32,
    /// Live: a SocketCAN interface.
    pub can_iface: Option<String>,
    /// Live: replay a candump capture as the vehicle bus.
    pub can_replay: Option<PathBuf>,
    /// Live: replay the capture at its own pace.
    pub realtime: bool,
    /// Live: start a new log file every N minutes (`output` is then a folder).
    pub segment_minutes: f64,
    /// Live: stop after S seconds (else on SIGINT / SIGTERM).
    pub seconds: Option<f64>,
    /// Live: the folder's log files stay below this many bytes ([`super::storage::parse_size`]):
    /// the oldest unprotected files are deleted first (loop recording).
    pub quota: Option<u64>,
    /// Live: keep at least this many bytes of the file system free, deleting as for the
    /// quota.
    pub min_free: Option<u64>,
    /// Sign every segment with the device's secret key in this file (`dash2sim keygen`).
    pub key: Option<PathBuf>,
    /// Live: told how the recording goes twice a second (a status line), if set.
    #[cfg(feature = "bridge")]
    pub status: Option<fn(&super::live::LiveStatus)>,
}

impl RecordRequest {
    /// A recording from `sources` into `output` with the defaults for everything else (the
    /// command line's defaults are these constants).
    pub fn from_files(output: &Path, sources: Sources) -> Self {
        RecordRequest {
            output: output.to_path_buf(),
            sources,
            dbc: Vec::new(),
            speed_signal: None,
            speed_unit: SpeedUnit::KilometresPerHour,
            speed_source: SpeedMessage::Ccvs1,
            gnss_signals: None,
            map: None,
            origin: None,
            device: Device::default(),
            save_inputs: None,
            replay: None,
            device_id: padded_id(DEFAULT_DEVICE_ID),
            camera: None,
            serial: None,
            baud: DEFAULT_BAUD,
            can_iface: None,
            can_replay: None,
            realtime: false,
            segment_minutes: DEFAULT_SEGMENT_MINUTES,
            seconds: None,
            quota: None,
            min_free: None,
            key: None,
            #[cfg(feature = "bridge")]
            status: None,
        }
    }
}

/// The built-in vehicle-speed message, when no DBC signal is named.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpeedMessage {
    /// J1939 CCVS1 wheel-based speed.
    Ccvs1,
    /// OBD-II PID 0x0D responses.
    Obd,
}

/// How the dashcam is set up: `record` takes it, and `finish` needs the same (the log
/// does not carry it).
#[derive(Debug, Clone)]
pub struct Device {
    /// The camera's place on the vehicle ([`parse_mount`]).
    pub mount: CameraMount,
    /// The VO frame: gravity-aligned or any orientation.
    pub mode: VoFrame,
    /// 1-σ GNSS error model: UERE, m (σ = HDOP × UERE unless the receiver sends GST).
    pub uere: f64,
    /// The IMU's axes on the camera (sensor → camera rotation).
    pub imu_mount: ImuMount,
    /// Where the relative motion comes from: the camera's VO, or gyro + wheels.
    pub relative_motion: RelativeMotion,
}

impl Default for Device {
    fn default() -> Self {
        Device {
            mount: CameraMount { position: DEFAULT_MOUNT_M, roll_pitch_yaw: [0.0; 3] },
            mode: VoFrame::Gravity,
            uere: DEFAULT_UERE_M,
            imu_mount: ImuMount::default(),
            relative_motion: RelativeMotion::Vo,
        }
    }
}

impl Device {
    /// The device as given, checked: the UERE must be a positive number of metres.
    pub fn check(&self) -> Result<&Device> {
        if !(self.uere.is_finite() && self.uere > 0.0) {
            return Err(Error::request(Field::Uere, format!("{} must be a positive number of metres", self.uere)));
        }
        Ok(self)
    }
}

/// What the VO frame is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VoFrame {
    /// 7-DoF Sim(3).
    Full,
    /// Yaw, scale, translation.
    Gravity,
}

impl VoFrame {
    /// The anchorer's mode for this frame.
    pub fn anchor_mode(self) -> AnchorMode {
        match self {
            VoFrame::Full => AnchorMode::Full,
            VoFrame::Gravity => AnchorMode::GravityAligned,
        }
    }
}

/// A camera mount written `FORWARD,LEFT,UP[,ROLL,PITCH,YAW]`: the camera's place from the
/// rear axle on the ground (m), and optionally its rotation (rad, camera → body).
pub fn parse_mount(text: &str) -> Result<CameraMount> {
    let v = comma_separated(text, "FORWARD,LEFT,UP[,ROLL,PITCH,YAW] numbers")?;
    match v[..] {
        [f, l, u] => Ok(CameraMount { position: [f, l, u], roll_pitch_yaw: [0.0; 3] }),
        [f, l, u, r, p, y] => Ok(CameraMount { position: [f, l, u], roll_pitch_yaw: [r, p, y] }),
        _ => {
            Err(Error::invalid(format!("expected 3 or 6 numbers (FORWARD,LEFT,UP[,ROLL,PITCH,YAW]), not {}", v.len())))
        }
    }
}

/// An IMU mount written `ROLL,PITCH,YAW`: the rotation from the sensor's axes to the
/// camera's (rad).
pub fn parse_imu_mount(text: &str) -> Result<ImuMount> {
    match comma_separated(text, "ROLL,PITCH,YAW numbers (rad)")?[..] {
        [r, p, y] => Ok(ImuMount { roll_pitch_yaw: [r, p, y] }),
        ref v => Err(Error::invalid(format!("expected 3 numbers, ROLL,PITCH,YAW (rad), not {}", v.len()))),
    }
}

/// A device id for a log's header: at most 16 bytes, padded with zeros.
pub fn parse_device_id(text: &str) -> Result<[u8; 16]> {
    if text.len() > 16 {
        return Err(Error::invalid(format!("{text:?} is {} bytes, longer than the header's 16", text.len())));
    }
    Ok(padded_id(text))
}

/// `text`'s bytes padded with zeros to 16 (cut at 16).
fn padded_id(text: &str) -> [u8; 16] {
    let mut id = [0u8; 16];
    let n = text.len().min(16);
    id[..n].copy_from_slice(&text.as_bytes()[..n]);
    id
}

/// The DBC signals a CAN GNSS module's fixes are read from, written
/// `lat=MSG.SIG,lon=MSG.SIG[,valid=MSG.SIG][,accuracy=MSG.SIG][,time=MSG.SIG]`: degrees; a
/// valid flag (0 = no fix); accuracy in m, taken as 1-σ; UTC in seconds since 1970. They are
/// found in the DBC files when the recording starts ([`super::gnss_signals`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GnssSignalNames {
    /// The latitude.
    pub lat: SignalName,
    /// The longitude (in the latitude's message).
    pub lon: SignalName,
    /// The valid flag (in the latitude's message).
    pub valid: Option<SignalName>,
    /// The accuracy (in the latitude's message).
    pub accuracy: Option<SignalName>,
    /// The UTC time (in any message).
    pub time: Option<SignalName>,
}

impl std::str::FromStr for GnssSignalNames {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        let mut found: BTreeMap<&str, SignalName> = BTreeMap::new();
        for pair in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (key, name) =
                pair.split_once('=').ok_or_else(|| Error::invalid(format!("{pair:?} is not KEY=MESSAGE.SIGNAL")))?;
            if !matches!(key, "lat" | "lon" | "valid" | "accuracy" | "time") {
                return Err(Error::invalid(format!("unknown key {key:?} (lat, lon, valid, accuracy, time)")));
            }
            if found.insert(key, name.parse()?).is_some() {
                return Err(Error::invalid(format!("{key} given twice")));
            }
        }
        let mut take = |key: &str| found.remove(key);
        let required = |name: Option<SignalName>, key: &str| {
            name.ok_or_else(|| Error::invalid(format!("{key}=MESSAGE.SIGNAL is required")))
        };
        let (lat, lon) = (take("lat"), take("lon"));
        let names = GnssSignalNames {
            lat: required(lat, "lat")?,
            lon: required(lon, "lon")?,
            valid: take("valid"),
            accuracy: take("accuracy"),
            time: take("time"),
        };
        if names.lon.message != names.lat.message {
            return Err(Error::invalid("lat and lon must be in one message"));
        }
        for (key, name) in [("valid", &names.valid), ("accuracy", &names.accuracy)] {
            if name.as_ref().is_some_and(|n| n.message != names.lat.message) {
                return Err(Error::invalid(format!(
                    "{key} must be in the latitude's message (the fix is read from one frame)"
                )));
            }
        }
        Ok(names)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_mount_as_written_is_the_default_mount() {
        let written = parse_mount(DEFAULT_MOUNT).expect("the default mount parses");
        assert_eq!(written, CameraMount { position: DEFAULT_MOUNT_M, roll_pitch_yaw: [0.0; 3] });
        assert_eq!(RecordRequest::from_files(Path::new("out.d2slog"), Sources::default()).device.mount, written);
    }

    #[test]
    fn mounts_take_three_or_six_numbers_and_an_imu_mount_three() {
        let tilted = parse_mount("1,0,1.2,0,0.1,0").expect("six numbers");
        assert_eq!((tilted.position, tilted.roll_pitch_yaw), ([1.0, 0.0, 1.2], [0.0, 0.1, 0.0]));
        for bad in ["1,2", "1,2,3,4", "1,2,x", "1,2,inf"] {
            assert!(parse_mount(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_imu_mount("0, 0.5,-1").expect("three").roll_pitch_yaw, [0.0, 0.5, -1.0]);
        for bad in ["0,0", "0,0,0,0", "0,nan,0", ""] {
            assert!(parse_imu_mount(bad).is_err(), "{bad}");
        }
    }
}
