//! The MCU example replays an embedded drive (`examples/mcu/drive.d2sin`, `drive.d2smap`);
//! they must be exactly what today's generator, `record --save-inputs` and `map build` make
//! of `dash2sim scenario generate --seed 1 --duration 20 --receiver good`, so that the QEMU
//! run (whose log CI compares byte for byte with the host's) exercises the current code.
//! The host side of that comparison is checked here too: the replay records a useful log.

use dash2sim_core::geo::Geodetic;
use dash2sim_linux::record::{self, Setup, Sources};
use dash2sim_linux::sim::scenario::sensors::GnssModel;
use dash2sim_linux::sim::scenario::write::write_scenario;
use dash2sim_linux::sim::scenario::{generate, ScenarioConfig};
use dash2sim_tests::recorded::scratch;

const REBUILD: &str =
    "rebuild them: dash2sim scenario generate -o D --seed 1 --duration 20 --receiver good --profile ideal && \
dash2sim map build D/road.osm -o examples/mcu/drive.d2smap --origin 60.2711,24.8572 && \
dash2sim record -o /tmp/x.d2slog --vo D/vo.csv --nmea D/gnss.serial.log --can D/speed.can.log \
--detections D/detections3d.csv --detections2d D/det2d.txt --save-inputs examples/mcu/drive.d2sin";

#[test]
fn the_mcu_example_drive_is_todays_and_records_on_the_host() {
    let root = dash2sim_tests::workspace_root().join("examples/mcu");
    let work = scratch("mcu-drive");
    let scenario =
        generate(&ScenarioConfig { seed: 1, duration_s: 20.0, gnss: GnssModel::good(), ..ScenarioConfig::default() });
    write_scenario(&scenario, &work).expect("scenario");
    // Without the drive's IMU: the MCU example reads none yet (issue #54's embedded-hal part
    // is its driver on a replaying I2C bus, not built).
    let (stream, _) = record::read_sources(&Sources { imu: None, ..Sources::scenario(&work) }).expect("sources");
    let committed = std::fs::read(root.join("drive.d2sin")).expect("drive.d2sin");
    assert!(stream == committed, "examples/mcu/drive.d2sin is stale; {REBUILD}");
    let osm = dash2sim_linux::ingest::osm::read(&work.join("road.osm")).expect("osm");
    let origin = Geodetic::new(60.2711, 24.8572, 0.0).expect("origin");
    let tile = dash2sim_linux::ingest::map_tile::encode(
        &dash2sim_linux::ingest::map_tile::from_osm(&osm, Some(origin), &mut Vec::new()),
        dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M,
    );
    let committed_tile = std::fs::read(root.join("drive.d2smap")).expect("drive.d2smap");
    assert!(tile == committed_tile, "examples/mcu/drive.d2smap is stale; {REBUILD}");

    let recording =
        record::run_stream(&committed, &Setup::work_zone(origin, Some(committed_tile), *b"dash2sim-mcu\0\0\0\0"))
            .expect("record");
    let s = recording.stats;
    println!("host replay of the MCU drive: {s:?}, {} bytes", recording.log.len());
    assert_eq!(recording.issues.total(), 0);
    assert!(s.anchored_frames > 100 && s.track_states > 100 && s.windows >= 1, "{s:?}");
}
