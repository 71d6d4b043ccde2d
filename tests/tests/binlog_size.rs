//! How compact the 4D log is, against the same content as MCAP with zstd chunks (one
//! topic per record kind, Foxglove JSON messages), on two drives:
//!
//! * the comma2k19 minute (`../shared/data/comma2k19`): u-blox GNSS at 10 Hz (written as
//!   NMEA from comma's CSV and imported through `--nmea`), CAN speeds (0xB4 SPEED through
//!   the Toyota DBC), fused poses at 20 Hz;
//! * a generated 40 s work-zone drive with its 3D tracks (`dash2sim scenario generate`).
//!
//! Targets (issue #6): the log ≤ 1/3 of the MCAP; ego poses ≤ 12 bytes on average.

use std::path::{Path, PathBuf};

use dash2sim_core::binlog::Kind;
use dash2sim_linux::logfile::{self, import::ImportRequest, mcap_export};
use dash2sim_linux::scenario::write::{import_request, write_scenario};
use dash2sim_linux::scenario::{generate, ScenarioConfig};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dash2sim-binlog-size-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

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

/// comma's u-blox CSV as GGA + RMC sentences (UTC from its millisecond stamps).
fn ublox_nmea(csv: &Path) -> (String, f64) {
    let text = std::fs::read_to_string(csv).expect("live_gnss_ublox.csv");
    let mut out = String::new();
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
        out += &nmea_line(&format!("GPGGA,{hms},{la},{ns},{lo},{ew},1,10,0.9,{alt:.2},M,0.0,M,,"));
        out +=
            &nmea_line(&format!("GPRMC,{hms},A,{la},{ns},{lo},{ew},{:.3},{bearing:.2},020818,,,A", speed / 0.514_444));
    }
    (out, offset.expect("rows"))
}

/// Measure the log at `log_path` against the same content as MCAP (written to
/// `mcap_path`), print the figures and assert the targets.
fn check_size(name: &str, log_path: &Path, mcap_path: &Path) {
    let log = logfile::read(log_path).expect("a log");
    assert_eq!(log.stats.damaged, 0);
    mcap_export::write(&log, None, mcap_path, Some(&mcap_export::ONE_TOPIC_PER_KIND)).expect("mcap");
    let (a, b) = log.stats.time_span.expect("records");
    let minutes = (b - a) as f64 / 60e6;
    let i = Kind::ALL.iter().position(|k| *k == Kind::EgoPose).expect("kind");
    let pose_bytes = log.stats.bytes[i] as f64 / log.stats.records[i].max(1) as f64;
    let (log_bytes, mcap_bytes) = (log.bytes, std::fs::metadata(mcap_path).expect("mcap").len());
    let report = format!(
        "{name}: {minutes:.2} min, log {log_bytes} B ({:.0} B/min), MCAP zstd {mcap_bytes} B ({:.0} B/min), ratio {:.3}, ego pose {pose_bytes:.2} B",
        log_bytes as f64 / minutes,
        mcap_bytes as f64 / minutes,
        log_bytes as f64 / mcap_bytes as f64
    );
    println!("{report}");
    assert!(log_bytes * 3 <= mcap_bytes, "{report}");
    assert!(pose_bytes <= 12.0, "{report}");
}

#[test]
fn the_comma2k19_minute_is_a_third_of_its_mcap() {
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    let work = scratch("comma");
    let (nmea, offset) = ublox_nmea(&dir.join("expected/live_gnss_ublox.csv"));
    let nmea_path = work.join("ublox.nmea");
    std::fs::write(&nmea_path, nmea).expect("write");
    let output = work.join("drive.d2slog");
    let request = ImportRequest {
        output: output.clone(),
        nmea: Some(nmea_path),
        nmea_offset_s: offset,
        can: Some(dir.join("raw_can.candump.log")),
        dbc: vec![dir.join("opendbc-toyota/_toyota_2017.dbc")],
        speed_signal: Some("SPEED.SPEED".to_owned()),
        speed_unit: 1.0 / 3.6,
        traj: Some(dir.join("expected/global_pose_camera_enu.tum")),
        objects: None,
        origin: Some("37.721000009,-122.472299089,31.6392".to_owned()),
    };
    logfile::import::run(&request).expect("import");
    let log = logfile::read(&output).expect("log");
    let count = |kind: Kind| log.records.iter().filter(|r| r.kind() == kind).count();
    assert_eq!((count(Kind::GnssFix), count(Kind::VehicleSpeed), count(Kind::EgoPose)), (579, 2487, 1200));
    check_size("comma2k19", &output, &work.join("same.mcap"));
}

#[test]
fn a_work_zone_drive_with_3d_tracks_is_a_third_of_its_mcap() {
    let work = scratch("scenario");
    let drive = work.join("drive");
    let scenario = generate(&ScenarioConfig { seed: 1, duration_s: 40.0, ..ScenarioConfig::default() });
    write_scenario(&scenario, &drive).expect("scenario");
    let output = work.join("drive.d2slog");
    let request = import_request(&scenario, &drive, output.clone());
    logfile::import::run(&request).expect("import");
    let log = logfile::read(&output).expect("log");
    let tracks = logfile::export::tracks(&log).count();
    assert!(tracks > 10_000, "{tracks} 3D track records");
    check_size(&format!("work zone ({tracks} tracks)"), &output, &work.join("same.mcap"));
}
