//! A generated work-zone drive recorded through the on-device pipeline from the forms a
//! device sees (VO poses, the GNSS serial capture, wheel speed as CAN frames, 3D and 2D
//! detections), and the same drive judged the other ways: the offline anchorer on the
//! same inputs, the tracker fed with the true ego pose.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use dash2sim_core::anchor::{AnchorConfig, AnchorMode};
use dash2sim_core::geo::Geodetic;
use dash2sim_core::pipeline::mount::camera_in_world;
use dash2sim_linux::log::{self, LogContents};
use dash2sim_linux::record::{self, Recording, Setup};
use dash2sim_linux::trajectory::Trajectory;
use dash2sim_sim::scenario::evaluate::evaluate_tracking;
use dash2sim_sim::scenario::judge::{judge_log, truth_at, LogJudgement};
use dash2sim_sim::scenario::sensors::GnssModel;
use dash2sim_sim::scenario::write::write_scenario;
use dash2sim_sim::scenario::{generate, tracker_classes, tracker_config, Scenario, ScenarioConfig};

/// A fresh scratch folder.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dash2sim-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// The road's map tile in the scenario's ENU frame.
pub fn road_tile(scenario: &Scenario, drive: &Path) -> Vec<u8> {
    let [lat, lon, h] = scenario.config.origin;
    let osm = dash2sim_linux::ingest::osm::read(&drive.join("road.osm")).expect("road.osm");
    let origin = Geodetic::new(lat, lon, h).expect("origin");
    dash2sim_linux::ingest::map_tile::encode(
        &dash2sim_linux::ingest::map_tile::from_osm(&osm, Some(origin), &mut Vec::new()),
        dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M,
    )
}

/// What recording one generated drive measured.
#[derive(Debug)]
pub struct Outcome {
    /// The scenario.
    pub scenario: Scenario,
    /// The pipeline's output.
    pub recording: Recording,
    /// The log, decoded.
    pub log: LogContents,
    /// The log against the truth.
    pub judged: LogJudgement,
    /// Ego RMSE of the log and of the offline anchorer (`dash2sim anchor`'s replay on the
    /// same inputs: VO, the fixes at their receive times with the σ their HDOP states,
    /// wheel speed), over the frames both anchored, and how many.
    pub ape: (f64, f64, usize),
    /// Frames anchored by the pipeline and by the offline anchorer.
    pub anchored: (usize, usize),
    /// MOTA and IDF1 of the tracker fed the true ego pose.
    pub tracks_truth_pose: (f64, f64),
}

fn rmse<'a>(errors: impl Iterator<Item = &'a f64>) -> f64 {
    let (sum, n) = errors.fold((0.0, 0), |(s, n), e| (s + e * e, n + 1));
    (sum / f64::from(n.max(1))).sqrt()
}

/// A generated drive recorded through the pipeline, with its files.
#[derive(Debug)]
pub struct Recorded {
    /// The scenario.
    pub scenario: Scenario,
    /// Scratch folder; the drive's files are in `work/drive`.
    pub work: PathBuf,
    /// The road's map tile.
    pub tile: Vec<u8>,
    /// The pipeline's output.
    pub recording: Recording,
    /// The log, decoded.
    pub log: LogContents,
    /// The pipeline's setup.
    pub setup: Setup,
}

/// Generate drive `seed` (good receiver) and record it through the pipeline.
pub fn record_scenario(seed: u64, duration_s: f64) -> Recorded {
    let config = ScenarioConfig { seed, duration_s, gnss: GnssModel::good(), ..ScenarioConfig::default() };
    record_config(&config, &format!("recorded-{seed}"))
}

/// Generate the drive `config` describes and record it through the pipeline (the demo's
/// device, the road's tile as its map), in the scratch folder `name`.
pub fn record_config(config: &ScenarioConfig, name: &str) -> Recorded {
    let scenario = generate(config);
    let work = scratch(name);
    let drive = work.join("drive");
    write_scenario(&scenario, &drive).expect("write scenario");
    let [lat, lon, h] = scenario.config.origin;
    let (stream, _) = record::read_sources(&record::Sources::scenario(&drive)).expect("sources");
    let tile = road_tile(&scenario, &drive);
    let setup =
        Setup::work_zone(Geodetic::new(lat, lon, h).expect("origin"), Some(tile.clone()), *b"dash2sim-test\0\0\0");
    let recording = record::run_stream(&stream, &setup).expect("record");
    let log = log::decode(&recording.log, name).expect("log");
    Recorded { scenario, work, tile, recording, log, setup }
}

/// Generate drive `seed` (good receiver), record it through the pipeline and judge it.
pub fn record_drive(seed: u64, duration_s: f64) -> Outcome {
    let Recorded { scenario, work, recording, log, setup, .. } = record_scenario(seed, duration_s);
    let judged = judge_log(&scenario, &log);

    let mut gnss = Trajectory::default();
    for fix in &scenario.gnss {
        gnss.stamps.push(fix.t_receive);
        gnss.poses.push(dash2sim_core::sim3::Pose {
            translation: dash2sim_core::nalgebra::Vector3::from(fix.enu),
            ..dash2sim_core::sim3::Pose::identity()
        });
    }
    // The receiver's σ as the NMEA capture states it: HDOP (one decimal) × the UERE.
    let sigmas: Vec<f64> = scenario.gnss.iter().map(|f| (f.reported_sigma / 2.5 * 10.0).round() / 10.0 * 2.5).collect();
    let config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let frames =
        dash2sim_verify::anchoring::replay_with_sigmas(&scenario.vo.poses, &gnss, &sigmas, &scenario.speed, config)
            .expect("replay");
    let mut offline = HashMap::new();
    for (k, ((t, pose), f)) in scenario.vo.poses.stamps.iter().zip(&scenario.vo.poses.poses).zip(&frames).enumerate() {
        let Some(anchor) = f.estimate else { continue };
        let body = setup.mount.body_pose(&camera_in_world(&anchor, pose));
        let truth = truth_at(&scenario, *t).expect("frame");
        offline.insert(k, (body.translation.x - truth.x).hypot(body.translation.y - truth.y));
    }
    // Compared on the frames both anchored (they become observable at different fixes).
    let common: Vec<usize> = judged.ego_errors.keys().filter(|k| offline.contains_key(k)).copied().collect();
    let ape =
        (rmse(common.iter().map(|k| &judged.ego_errors[k])), rmse(common.iter().map(|k| &offline[k])), common.len());
    let anchored = (judged.ego_errors.len(), offline.len());
    let classes = tracker_classes();
    let truth = evaluate_tracking::<64>(&scenario, tracker_config(&classes));
    let tracks_truth_pose = (truth.metric("mota"), truth.metric("idf1"));
    let _ = std::fs::remove_dir_all(&work);
    Outcome { scenario, recording, log, judged, ape, anchored, tracks_truth_pose }
}
