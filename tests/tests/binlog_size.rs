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
use dash2sim_export::mcap;
use dash2sim_linux::log::{self, import::ImportRequest};
use dash2sim_sim::datasets::comma::{self, ublox_nmea};
use dash2sim_sim::scenario::write::{import_request, write_scenario};
use dash2sim_sim::scenario::{generate, ScenarioConfig};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dash2sim-binlog-size-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Measure the log at `log_path` against the same content as MCAP (written to
/// `mcap_path`), print the figures and assert the targets.
fn check_size(name: &str, log_path: &Path, mcap_path: &Path) {
    let log = log::read(log_path).expect("a log");
    assert_eq!(log.stats.damaged, 0);
    mcap::write(&log, None, mcap_path, Some(&mcap::ONE_TOPIC_PER_KIND)).expect("mcap");
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
    let nmea = ublox_nmea(&dir.join("expected/live_gnss_ublox.csv")).expect("u-blox CSV");
    let nmea_path = work.join("ublox.nmea");
    std::fs::write(&nmea_path, nmea.raw).expect("write");
    let output = work.join("drive.d2slog");
    let request = ImportRequest {
        output: output.clone(),
        nmea: Some(nmea_path),
        nmea_offset_s: nmea.offset_s,
        can: Some(dir.join("raw_can.candump.log")),
        dbc: vec![dir.join("opendbc-toyota/_toyota_2017.dbc")],
        speed_signal: Some("SPEED.SPEED".parse().expect("signal")),
        speed_unit: dash2sim_linux::ingest::can::SpeedUnit::KilometresPerHour,
        traj: Some(dir.join("expected/global_pose_camera_enu.tum")),
        objects: None,
        origin: Some(comma::origin().expect("origin")),
    };
    log::import::import(&request, &mut |problem| panic!("{problem}")).expect("import");
    let log = log::read(&output).expect("log");
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
    let request = import_request(&scenario, &drive, output.clone()).expect("request");
    log::import::import(&request, &mut |problem| panic!("{problem}")).expect("import");
    let log = log::read(&output).expect("log");
    let tracks = log::views::tracks(&log).count();
    assert!(tracks > 10_000, "{tracks} 3D track records");
    check_size(&format!("work zone ({tracks} tracks)"), &output, &work.join("same.mcap"));
}
