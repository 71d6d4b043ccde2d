//! `dash2sim record`: the arguments, and the recording's summary rendered.

use std::io::IsTerminal as _;
use std::path::PathBuf;

use clap::Args;
use dash2sim_core::geo::Geodetic;
use dash2sim_core::imu::ImuMount;
use dash2sim_core::pipeline::{CameraMount, Issue, RelativeMotion};
use dash2sim_linux::ingest::can::{SignalName, SpeedUnit};
use dash2sim_linux::ingest::origin::parse_origin;
use dash2sim_linux::record::live::{LiveRequest, LiveStatus};
use dash2sim_linux::record::storage::parse_size;
use dash2sim_linux::record::{self, Device, GnssSignalNames, RecordRequest, Sources, SpeedMessage, VoFrame};
use dash2sim_linux::{Error, Result};

/// The recorded files `dash2sim record` reads.
#[derive(Clone, Debug, Default, Args)]
pub struct SourcesArgs {
    /// VO poses of the camera: TUM (device-clock stamps; frame k is the k-th pose), or a CSV
    /// `frame,t_s,x,y,z,qx,qy,qz,qw,session` with each pose's frame number (docs/cli.md).
    #[arg(long)]
    pub vo: Option<PathBuf>,
    /// The GNSS serial capture: `(device seconds) $SENTENCE*CS` per line.
    #[arg(long)]
    pub nmea: Option<PathBuf>,
    /// candump capture of the vehicle bus (device-clock stamps); repeat for a drive split
    /// into several files.
    #[arg(long)]
    pub can: Vec<PathBuf>,
    /// 3D detections in the camera frame (the detections CSV).
    #[arg(long)]
    pub detections: Option<PathBuf>,
    /// 2D detections, MOTChallenge CSV (frames numbered as the VO poses).
    #[arg(long)]
    pub detections2d: Option<PathBuf>,
    /// IMU samples: CSV `t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z` (device seconds,
    /// rad/s, m/s² on the sensor's axes; docs/imu.md).
    #[arg(long)]
    pub imu: Option<PathBuf>,
}

impl From<SourcesArgs> for Sources {
    fn from(a: SourcesArgs) -> Self {
        Sources {
            vo: a.vo,
            nmea: a.nmea,
            can: a.can,
            detections: a.detections,
            detections2d: a.detections2d,
            imu: a.imu,
        }
    }
}

/// Arguments of `dash2sim record` (file sources).
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// Output 4D log.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The recorded inputs.
    #[command(flatten)]
    pub sources: SourcesArgs,
    /// DBC files for `--speed-signal` and `--gnss-signals`.
    #[arg(long)]
    pub dbc: Vec<PathBuf>,
    /// `MESSAGE.SIGNAL` of a DBC carrying the vehicle speed (else `--speed-source`).
    #[arg(long, value_name = "SPEED_SIGNAL")]
    pub speed_signal: Option<SignalName>,
    /// Unit of `--speed-signal`: km/h, m/s or mph.
    #[arg(long, default_value = record::DEFAULT_SPEED_UNIT)]
    pub speed_unit: SpeedUnit,
    /// Built-in speed message when no `--speed-signal` is given.
    #[arg(long, value_parser = dash2sim_args::SpeedMessage::parser(), default_value = "ccvs1")]
    pub speed_source: SpeedMessage,
    /// GNSS from DBC signals (a CAN GNSS module):
    /// `lat=MSG.SIG,lon=MSG.SIG[,valid=MSG.SIG][,accuracy=MSG.SIG][,time=MSG.SIG]` —
    /// degrees; a valid flag (0 = no fix); accuracy in m, taken as 1-σ; UTC in seconds
    /// since 1970. All but `time` from one message.
    #[arg(long, value_name = "GNSS_SIGNALS")]
    pub gnss_signals: Option<GnssSignalNames>,
    /// Map tile to verify against on the way (windows of 15 s); its origin is the log's.
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// ENU origin `LAT,LON[,H]` (default: the map's, else the first GNSS fix).
    #[arg(long, value_name = "LAT,LON[,H]", allow_hyphen_values = true, value_parser = parse_origin)]
    pub origin: Option<Geodetic>,
    /// The dashcam: mount, VO frame, GNSS error model.
    #[command(flatten)]
    pub device: DeviceArgs,
    /// Also write the merged input stream (the core's replay format) here.
    #[arg(long)]
    pub save_inputs: Option<PathBuf>,
    /// Read a saved input stream instead of the file sources (`--save-inputs`; the MCU
    /// example replays the same bytes).
    #[arg(long, conflicts_with_all = ["vo", "nmea", "can", "detections", "detections2d"])]
    pub replay: Option<PathBuf>,
    /// The device id written into the log's header (at most 16 bytes).
    #[arg(long, default_value = record::DEFAULT_DEVICE_ID, value_parser = record::parse_device_id)]
    pub device_id: [u8; 16],
    /// Live: subscribe to the camera process's services (shared memory) under this prefix.
    #[arg(long, num_args = 0..=1, default_missing_value = dash2sim_linux::record::bridge::DEFAULT_PREFIX)]
    pub camera: Option<String>,
    /// Live: the GNSS receiver's serial device (raw mode), or a file of raw NMEA bytes.
    #[arg(long)]
    pub serial: Option<PathBuf>,
    /// Live: the serial device's baud rate.
    #[arg(long, default_value_t = record::DEFAULT_BAUD)]
    pub baud: u32,
    /// Live: a SocketCAN interface.
    #[arg(long, conflicts_with = "can_replay")]
    pub can_iface: Option<String>,
    /// Live: replay a candump capture as the vehicle bus.
    #[arg(long)]
    pub can_replay: Option<PathBuf>,
    /// Live: replay the capture at its own pace.
    #[arg(long)]
    pub realtime: bool,
    /// Live: start a new log file every N minutes (`-o` is then a folder).
    #[arg(long, default_value_t = record::DEFAULT_SEGMENT_MINUTES)]
    pub segment_minutes: f64,
    /// Live: stop after S seconds (else on SIGINT / SIGTERM).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Live: loop recording — the folder's log files stay below SIZE (`64k`, `500M`, `2G`);
    /// the oldest files go first, kept ones (a verified window, SIGUSR1, a `KEEP` file) last
    #[arg(long, value_name = "SIZE", value_parser = parse_size)]
    pub quota: Option<u64>,
    /// Live: keep at least SIZE of the file system free, deleting as for `--quota`
    #[arg(long, value_name = "SIZE", value_parser = parse_size)]
    pub min_free: Option<u64>,
    /// Sign every segment of the log with the device's secret key in FILE (`dash2sim
    /// keygen`); the chain of signatures runs across the rotated files (docs/binlog.md)
    #[arg(long, value_name = "FILE")]
    pub key: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

impl RecordArgs {
    /// The library's request; the live status line only where stderr is a terminal.
    fn request(&self) -> RecordRequest {
        RecordRequest {
            output: self.output.clone(),
            sources: self.sources.clone().into(),
            dbc: self.dbc.clone(),
            speed_signal: self.speed_signal.clone(),
            speed_unit: self.speed_unit,
            speed_source: self.speed_source,
            gnss_signals: self.gnss_signals.clone(),
            map: self.map.clone(),
            origin: self.origin,
            device: self.device.clone().into(),
            save_inputs: self.save_inputs.clone(),
            replay: self.replay.clone(),
            device_id: self.device_id,
            camera: self.camera.clone(),
            serial: self.serial.clone(),
            baud: self.baud,
            can_iface: self.can_iface.clone(),
            can_replay: self.can_replay.clone(),
            realtime: self.realtime,
            segment_minutes: self.segment_minutes,
            seconds: self.seconds,
            quota: self.quota,
            min_free: self.min_free,
            key: self.key.clone(),
            status: std::io::stderr().is_terminal().then_some(status_line as fn(&LiveStatus)),
        }
    }
}

/// How the dashcam is set up: `record` takes it, and `finish` needs the same (the log
/// does not carry it).
#[derive(Debug, Clone, Args)]
pub struct DeviceArgs {
    /// Camera position on the vehicle: `FORWARD,LEFT,UP` from the rear axle on the
    /// ground (m), optionally `,ROLL,PITCH,YAW` (rad, camera → body).
    #[arg(long, default_value = record::DEFAULT_MOUNT, value_parser = record::parse_mount)]
    pub mount: CameraMount,
    /// `gravity`: the VO frame's z is vertical (VIO, levelled VO); `full`: any orientation.
    #[arg(long, value_parser = dash2sim_args::VoFrame::parser(), default_value = "gravity")]
    pub mode: VoFrame,
    /// 1-σ GNSS error model: UERE, m (σ = HDOP × UERE unless the receiver sends GST).
    #[arg(long, default_value_t = record::DEFAULT_UERE_M)]
    pub uere: f64,
    /// The IMU's axes on the camera: `ROLL,PITCH,YAW` (rad, sensor → camera).
    #[arg(long, default_value = "0,0,0", value_parser = record::parse_imu_mount)]
    pub imu_mount: ImuMount,
    /// Where the relative motion comes from: the camera's VO, or gyro + wheels dead
    /// reckoning (`imu-wheels`: a dashcam without VO; needs --imu and a vehicle speed).
    #[arg(long, value_parser = dash2sim_args::RelativeMotion::parser(), default_value = "vo")]
    pub relative_motion: RelativeMotion,
}

impl From<DeviceArgs> for Device {
    fn from(a: DeviceArgs) -> Self {
        Device {
            mount: a.mount,
            mode: a.mode,
            uere: a.uere,
            imu_mount: a.imu_mount,
            relative_motion: a.relative_motion,
        }
    }
}

/// `dash2sim record`: from files, or live.
pub fn run(args: &RecordArgs) -> Result<()> {
    let request = args.request();
    if let Some(live) = record::live_request(&request)? {
        let stop = crate::signals::stop_on_signals()?;
        let live = LiveRequest { keep: Some(crate::signals::keep_on_signal()?), ..live };
        let report = record::record_live(&request, &live, &stop, &mut |warning| eprintln!("{warning}"));
        if request.status.is_some() {
            // The status line ends.
            eprintln!();
        }
        let report = report?;
        if args.json {
            println!("{}", crate::render::json_of(&report)?);
        } else {
            println!(
                "{}: {} files; {} camera frames, {}; {} inputs dropped, {} issues",
                args.output.display(),
                report.files,
                report.frames,
                report.stats,
                report.dropped,
                report.issues
            );
            if report.deleted_files > 0 {
                println!("{} files deleted to stay within --quota / --min-free (index.json)", report.deleted_files);
            }
            if report.write_failures > 0 {
                println!(
                    "the log's writes failed {} times (a full or failing disk): each file ends at its last complete frame, the failure is an event in the next",
                    report.write_failures
                );
            }
        }
        return Ok(());
    }
    let (recording, counts) = record::record_files(&request)?;
    for problem in &counts.problems {
        eprintln!("{problem}");
    }
    std::fs::write(&args.output, &recording.log).map_err(|e| Error::file(&args.output, e))?;
    if args.json {
        println!("{}", crate::render::json_of(&record::file_summary(&recording, &counts))?);
        return Ok(());
    }
    let s = &recording.stats;
    println!(
        "{}: {} bytes, {} records from {} inputs",
        args.output.display(),
        recording.log.len(),
        s.records,
        recording.inputs
    );
    println!(
        "  {} VO poses ({} anchored, {} carried across VO re-initialisations), {} fixes, {} speeds, {} 3D detections placed ({} logged raw), {} 3D track states, {} 2D track states",
        s.vo_poses, s.anchored_frames, s.carried_frames, s.fixes, s.speeds, s.detections_placed, s.detections_raw, s.track_states, s.track2d_states
    );
    if s.windows > 0 {
        println!(
            "  verification: {} of {} windows verified, {} undecided (within the ego's doubt)",
            s.windows_verified, s.windows, s.windows_undecided
        );
    }
    if s.imu_samples > 0 {
        println!("  IMU: {} samples, {} impacts", s.imu_samples, s.impacts);
    }
    if counts.detection2d_frames_without_time > 0 {
        println!(
            "  {} frames of 2D detections skipped: no VO pose or 3D detection gives their time",
            counts.detection2d_frames_without_time
        );
    }
    for issue in Issue::ALL {
        let n = recording.issues.get(issue);
        if n > 0 {
            println!("  {n} × {}", issue.text());
        }
    }
    Ok(())
}

/// The live logger's status line on stderr, written over itself.
fn status_line(s: &LiveStatus) {
    use std::io::Write as _;
    let mut err = std::io::stderr();
    let _ = write!(
        err,
        "\r{} frames, {} fixes, {} speeds, {} 3D track states, {}, {} dropped   ",
        s.frames,
        s.stats.fixes,
        s.stats.speeds,
        s.stats.track_states,
        if s.anchored { "anchored" } else { "not anchored yet" },
        s.dropped
    );
    let _ = err.flush();
}
