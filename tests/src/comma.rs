//! The comma2k19 minute in the forms a device sees: the real u-blox fixes as the NMEA a
//! receiver would send (from comma's CSV: UTC, position, speed, course), stamped with the
//! device's receive time (`t_boot`).

use std::path::{Path, PathBuf};

use dash2sim_core::binlog::Record;
use dash2sim_linux::logfile::{self, LogContents};
use dash2sim_linux::record::{self, DeviceArgs, ModeArg, RecordArgs};
use dash2sim_linux::scenario::vo::VoModel;
use dash2sim_linux::trajectory::{self, Format, Trajectory};

fn nmea_line(body: &str) -> String {
    let checksum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{checksum:02X}\r\n")
}

fn angle(deg: f64, width: usize, hemispheres: [char; 2]) -> (String, char) {
    let a = deg.abs();
    let whole = a.floor();
    let minutes = (a - whole) * 60.0;
    (format!("{:0width$}{minutes:09.6}", whole as u32), if deg >= 0.0 { hemispheres[0] } else { hemispheres[1] })
}

/// comma's u-blox CSV as GGA + RMC sentences (UTC from its millisecond stamps, HDOP 0.9):
/// the raw NMEA text, the same as a serial capture (`(t_boot) sentence` per line), and
/// the offset boot time − UTC of the first fix, s.
pub fn ublox_nmea(csv: &Path) -> (String, String, f64) {
    let text = std::fs::read_to_string(csv).expect("live_gnss_ublox.csv");
    let (mut raw, mut stamped) = (String::new(), String::new());
    let mut offset = None;
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().expect("number")).collect();
        let [t_boot, lat, lon, speed, utc_ms, alt, bearing] = v[..] else { panic!("7 columns") };
        offset.get_or_insert(t_boot - utc_ms / 1000.0);
        let secs = utc_ms / 1000.0;
        let day = (secs / 86_400.0).floor();
        let tod = secs - day * 86_400.0;
        let hms = format!("{:02}{:02}{:05.2}", (tod / 3600.0) as u32, ((tod % 3600.0) / 60.0) as u32, tod % 60.0);
        // 2018-08-02 (the drive's date), as ddmmyy.
        let (la, ns) = angle(lat, 2, ['N', 'S']);
        let (lo, ew) = angle(lon, 3, ['E', 'W']);
        for sentence in [
            nmea_line(&format!("GPGGA,{hms},{la},{ns},{lo},{ew},1,10,0.9,{alt:.2},M,0.0,M,,")),
            nmea_line(&format!("GPRMC,{hms},A,{la},{ns},{lo},{ew},{:.3},{bearing:.2},020818,,,A", speed / 0.514_444)),
        ] {
            stamped += &format!("({t_boot:.6}) {sentence}");
            raw += &sentence;
        }
    }
    (raw, stamped, offset.expect("rows"))
}

/// The comma2k19 minute recorded by `dash2sim record`, as the pipeline test and the
/// finishing test use it.
#[derive(Debug)]
pub struct RecordedMinute {
    /// comma's fused camera poses (ENU around [`ORIGIN`]).
    pub truth: Trajectory,
    /// The log file.
    pub path: PathBuf,
    /// The log as read.
    pub log: LogContents,
    /// Device time of every record, s (see [`device_times`]).
    pub device: Vec<f64>,
}

/// The ENU origin of comma's poses.
pub const ORIGIN: [f64; 3] = [37.721000009, -122.472299089, 31.6392];

/// The mount for these poses: the camera's axes (x forward, y right, z down), and the ego
/// taken at the camera so that positions compare with the poses.
pub fn mount() -> String {
    format!("0,0,0,{},0,0", std::f64::consts::PI)
}

/// HDOP 0.9 × 2.78 m = the anchoring test's σ of 2.5 m.
pub const UERE: f64 = 2.5 / 0.9;

/// Record the minute: the real u-blox fixes as a serial capture, the real Toyota CAN
/// through the DBC (0xB4 SPEED), and VO made from the fused poses by `model`.
pub fn record_minute(dir: &Path, work: &Path, model: &VoModel) -> RecordedMinute {
    let truth = Trajectory::read(&dir.join("expected/global_pose_camera_enu.tum"), Format::Tum).expect("poses");
    let vo_path = work.join("vo.tum");
    trajectory::write_file(&model.make_vo(&truth), &vo_path, Format::Tum).expect("vo");
    let (_, stamped, _) = ublox_nmea(&dir.join("expected/live_gnss_ublox.csv"));
    let nmea_path = work.join("ublox.serial.log");
    std::fs::write(&nmea_path, stamped).expect("write");
    let [lat, lon, h] = ORIGIN;
    let args = RecordArgs {
        output: work.join("comma.d2slog"),
        sources: record::Sources {
            vo: Some(vo_path),
            nmea: Some(nmea_path),
            can: Some(dir.join("raw_can.candump.log")),
            ..record::Sources::default()
        },
        dbc: vec![dir.join("opendbc-toyota/_toyota_2017.dbc")],
        speed_signal: Some("SPEED.SPEED".to_owned()),
        speed_unit: "km/h".to_owned(),
        speed_source: record::SpeedArg::Ccvs1,
        map: None,
        origin: Some(format!("{lat},{lon},{h}")),
        device: DeviceArgs { mount: mount(), mode: ModeArg::Full, uere: UERE },
        save_inputs: None,
        replay: None,
        device_id: "dash2sim-record".to_owned(),
        camera: None,
        serial: None,
        baud: 115_200,
        can_iface: None,
        can_replay: None,
        realtime: false,
        segment_minutes: 10.0,
        seconds: None,
        json: true,
    };
    record::run(&args).expect("record");
    let log = logfile::read(&args.output).expect("log");
    let device = device_times(&log.records);
    RecordedMinute { truth, path: args.output, log, device }
}

/// Device time of every record: UTC minus the clock offset in force when it was written
/// (records before the first offset were moved onto UTC with it by the reader).
pub fn device_times(records: &[Record]) -> Vec<f64> {
    let mut offset = records.iter().find_map(|r| if let Record::ClockOffset(c) = r { Some(c.offset_us) } else { None });
    assert!(offset.is_some(), "UTC from the fixes");
    records
        .iter()
        .map(|r| {
            if let Record::ClockOffset(c) = r {
                offset = Some(c.offset_us);
            }
            (r.t_us() - offset.unwrap_or(0)) as f64 * 1e-6
        })
        .collect()
}
