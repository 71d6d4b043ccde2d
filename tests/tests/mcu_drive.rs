//! The MCU example replays an embedded drive (`examples/mcu/drive.d2sin`, `drive.d2smap`);
//! they must be exactly what today's generator, `record --save-inputs` and `map build` make
//! of `dash2sim scenario generate --seed 1 --duration 20 --receiver good`, so that the QEMU
//! run (whose log CI compares byte for byte with the host's) exercises the current code.
//! The drive's IMU samples are as the example's LSM6DSO delivers them: quantised to the
//! sensor's counts and its 25 µs timestamp ticks, so that the samples the example reads
//! through the driver on its replaying I²C bus are the stream's own.
//! The host side of that comparison is checked here too: the replay records a useful log.

use dash2sim_core::geo::Geodetic;
use dash2sim_core::imu::lsm6dso;
use dash2sim_core::time::Timestamp;
use dash2sim_linux::record::{self, Setup, Sources};
use dash2sim_sim::scenario::sensors::GnssModel;
use dash2sim_sim::scenario::write::write_scenario;
use dash2sim_sim::scenario::{generate, ScenarioConfig};
use dash2sim_tests::recorded::scratch;

const REBUILD: &str = "rebuild the stream with DASH2SIM_BLESS=1 cargo test --release -p dash2sim-tests --test mcu_drive \
(the scenario's inputs with its IMU quantised as the LSM6DSO delivers it), the tile with dash2sim scenario generate -o D \
--seed 1 --duration 20 --receiver good --profile ideal && dash2sim map build D/road.osm -o examples/mcu/drive.d2smap \
--origin 60.2711,24.8572";

#[test]
fn the_mcu_example_drive_is_todays_and_records_on_the_host() {
    let root = dash2sim_tests::workspace_root().join("examples/mcu");
    let work = scratch("mcu-drive");
    let scenario =
        generate(&ScenarioConfig { seed: 1, duration_s: 20.0, gnss: GnssModel::good(), ..ScenarioConfig::default() });
    write_scenario(&scenario, &work).expect("scenario");
    let imu = work.join("imu-lsm6dso.csv");
    let mut csv = format!("{}\n", record::sources::IMU_CSV_HEADER);
    for (t, sample) in record::sources::read_imu_csv(&work.join("imu.csv")).expect("the drive's IMU") {
        let ticks = lsm6dso::ticks(Timestamp::from_secs_f64(t).expect("a time"));
        let s = lsm6dso::quantised(&sample);
        let [gx, gy, gz] = s.gyro;
        let [ax, ay, az] = s.accel;
        csv += &format!("{:.6},{gx},{gy},{gz},{ax},{ay},{az}\n", f64::from(ticks) * 25e-6);
    }
    std::fs::write(&imu, csv).expect("write");
    let (stream, counts) =
        record::read_sources(&Sources { imu: Some(imu), ..Sources::scenario(&work) }).expect("sources");
    assert!(counts.imu_samples >= 2000, "20 s at 100 Hz: {counts:?}");
    if std::env::var_os("DASH2SIM_BLESS").is_some() {
        std::fs::write(root.join("drive.d2sin"), &stream).expect("bless drive.d2sin");
    }
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
    assert!(s.imu_samples >= 2000, "{s:?}");
}
