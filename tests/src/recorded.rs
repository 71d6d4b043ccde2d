//! A generated work-zone drive recorded through the on-device pipeline from the forms a
//! device sees (VO poses, the GNSS serial capture, wheel speed as CAN frames, 3D and 2D
//! detections), and the same drive judged the other ways: the offline anchorer on the
//! same inputs, the tracker fed with the true ego pose.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use dash2sim_core::anchor::{AnchorConfig, AnchorMode};
use dash2sim_core::binlog::Record;
use dash2sim_core::box3d::Box3d;
use dash2sim_core::geo::Geodetic;
use dash2sim_core::obb::Pose2;
use dash2sim_core::pipeline::mount::camera_in_world;
use dash2sim_core::pipeline::{CameraMount, GnssErrorModel, SpeedSource};
use dash2sim_linux::logfile::{self, LogContents};
use dash2sim_linux::record::{self, RecordArgs, Recording, Setup};
use dash2sim_linux::scenario::actors::Class;
use dash2sim_linux::scenario::evaluate::{evaluate_tracking, score_tracks};
use dash2sim_linux::scenario::sensors::GnssModel;
use dash2sim_linux::scenario::write::write_scenario;
use dash2sim_linux::scenario::{generate, tracker_classes, tracker_config, Scenario, ScenarioConfig};
use dash2sim_linux::trajectory::Trajectory;

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
    let osm = dash2sim_linux::osm::read(&drive.join("road.osm")).expect("road.osm");
    let origin = Geodetic::new(lat, lon, h).expect("origin");
    dash2sim_linux::map_tile::encode(&dash2sim_linux::map_tile::from_osm(&osm, Some(origin), &mut Vec::new()), 50.0)
}

/// `dash2sim record`'s arguments for a drive written to `drive`.
pub fn record_args(drive: &Path, output: PathBuf) -> RecordArgs {
    RecordArgs {
        output,
        vo: Some(drive.join("vo.tum")),
        nmea: Some(drive.join("gnss.serial.log")),
        can: Some(drive.join("speed.can.log")),
        dbc: Vec::new(),
        speed_signal: None,
        speed_unit: "km/h".to_owned(),
        speed_source: record::SpeedArg::Ccvs1,
        detections: Some(drive.join("detections3d.csv")),
        detections2d: Some(drive.join("det2d.txt")),
        map: None,
        origin: None,
        mount: "1.8,0,1.3".to_owned(),
        mode: record::ModeArg::Gravity,
        uere: 2.5,
        save_inputs: None,
        json: false,
    }
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
    /// Ego (rear axle) position RMSE of the log against the truth, m, and poses compared
    /// (the frames both the pipeline and the offline anchorer anchored).
    pub ape: (f64, usize),
    /// Frames anchored by the pipeline and by the offline anchorer.
    pub anchored: (usize, usize),
    /// The same for the offline anchorer (`dash2sim anchor`'s replay) on the same inputs:
    /// VO, the fixes at their receive times with the σ their HDOP states, wheel speed.
    pub ape_offline: (f64, usize),
    /// MOTA and IDF1 of the log's 3D tracks (2 m gate), over every frame.
    pub tracks: (f64, f64),
    /// The same over the frames with an anchored pose.
    pub tracks_anchored: (f64, f64),
    /// The same with each frame's tracks moved from the anchored to the true ego pose
    /// (the tracker's own error, without the anchoring's).
    pub tracks_relative: (f64, f64),
    /// MOTA and IDF1 of the tracker fed the true ego pose.
    pub tracks_truth_pose: (f64, f64),
}

/// The truth ego pose of the frame at device time `t` (10 Hz frames from 0).
fn truth_at(scenario: &Scenario, t: f64) -> Option<Pose2> {
    let k = (t * scenario.config.frame_rate_hz).round() as usize;
    scenario.frames.get(k).filter(|f| (f.ego.t - t).abs() < 1e-3).map(|f| Pose2::new(f.ego.x, f.ego.y, f.ego.heading))
}

fn rmse(errors: &[f64]) -> (f64, usize) {
    ((errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt(), errors.len())
}

/// Generate drive `seed` (good receiver), record it through the pipeline and judge it.
pub fn record_drive(seed: u64, duration_s: f64) -> Outcome {
    let scenario = generate(&ScenarioConfig { seed, duration_s, gnss: GnssModel::good(), ..ScenarioConfig::default() });
    let work = scratch(&format!("recorded-{seed}"));
    let drive = work.join("drive");
    write_scenario(&scenario, &drive).expect("write scenario");
    let [lat, lon, h] = scenario.config.origin;
    let (stream, _) = record::read_sources(&record_args(&drive, work.join("drive.d2slog"))).expect("sources");
    let setup = Setup {
        origin: Geodetic::new(lat, lon, h).expect("origin"),
        mount: CameraMount::default(),
        mode: AnchorMode::GravityAligned,
        gnss: GnssErrorModel::default(),
        speed: Some(SpeedSource::Ccvs1),
        map: Some(road_tile(&scenario, &drive)),
        device_id: *b"dash2sim-test\0\0\0",
    };
    let recording = record::run_stream(&stream, &setup).expect("record");
    let log = logfile::decode(&recording.log, "recorded").expect("log");
    let offset = log
        .records
        .iter()
        .find_map(|r| if let Record::ClockOffset(c) = r { Some(c.offset_us) } else { None })
        .expect("a clock offset");
    let device = |t_us: i64| (t_us - offset) as f64 * 1e-6;

    let mut pipeline_errors = HashMap::new();
    let mut ego_poses = HashMap::new();
    for r in &log.records {
        if let Record::EgoPose(p) = r {
            let t = device(p.t_us);
            let truth = truth_at(&scenario, t).expect("a frame at every ego pose");
            let frame = (t * scenario.config.frame_rate_hz).round() as usize;
            let (x, y) = (p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3);
            pipeline_errors.insert(frame, (x - truth.x).hypot(y - truth.y));
            ego_poses.insert(frame as u32 + 1, (Pose2::new(x, y, p.yaw_e4 as f64 * 1e-4), truth));
        }
    }

    // The offline anchorer on the same inputs: VO, the fixes at their receive times, wheel speed.
    let mut gnss = Trajectory::default();
    for fix in &scenario.gnss {
        gnss.stamps.push(fix.t_receive);
        gnss.poses.push(dash2sim_core::sim3::Pose {
            translation: dash2sim_core::nalgebra::Vector3::from(fix.enu),
            ..dash2sim_core::sim3::Pose::identity()
        });
    }
    // The receiver's σ as the NMEA capture states it: HDOP (one decimal) × the UERE.
    let sigmas: Vec<f64> = scenario.gnss.iter().map(|f| (f.sigma / 2.5 * 10.0).round() / 10.0 * 2.5).collect();
    let config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let frames = dash2sim_linux::anchoring::replay_with_sigmas(&scenario.vo, &gnss, &sigmas, &scenario.speed, config)
        .expect("replay");
    let mut offline_errors = HashMap::new();
    for (k, ((t, pose), f)) in scenario.vo.stamps.iter().zip(&scenario.vo.poses).zip(&frames).enumerate() {
        let Some(anchor) = f.estimate else { continue };
        let body = setup.mount.body_pose(&camera_in_world(&anchor, pose));
        let truth = truth_at(&scenario, *t).expect("frame");
        offline_errors.insert(k, (body.translation.x - truth.x).hypot(body.translation.y - truth.y));
    }
    // Compared on the frames both anchored (they become observable at different fixes).
    let common: Vec<usize> = pipeline_errors.keys().filter(|k| offline_errors.contains_key(k)).copied().collect();
    let ape = rmse(&common.iter().map(|k| pipeline_errors[k]).collect::<Vec<_>>());
    let ape_offline = rmse(&common.iter().map(|k| offline_errors[k]).collect::<Vec<_>>());
    let anchored = (pipeline_errors.len(), offline_errors.len());

    // 3D tracks of the log, by frame, against the truth.
    let mut reported: HashMap<u32, Vec<(u32, u16, Box3d)>> = HashMap::new();
    for (t_us, t) in logfile::export::tracks(&log) {
        let frame = (device(t_us) * scenario.config.frame_rate_hz).round() as u32 + 1;
        let name = logfile::export::class_name(t.class);
        let class = Class::ALL.iter().find(|c| c.name() == name).map_or(u16::MAX, |c| *c as u16);
        let bbox = Box3d {
            x: t.x_mm as f64 * 1e-3,
            y: t.y_mm as f64 * 1e-3,
            z: t.z_mm as f64 * 1e-3,
            yaw: t.yaw_e4 as f64 * 1e-4,
            l: t.l_mm as f64 * 1e-3,
            w: t.w_mm as f64 * 1e-3,
            h: t.h_mm as f64 * 1e-3,
        };
        reported.entry(frame).or_default().push((u32::try_from(t.id).unwrap_or(u32::MAX), class, bbox));
    }
    let figures =
        |s: &dash2sim_linux::mot::Summary| (s.get("mota").unwrap_or(f64::NAN), s.get("idf1").unwrap_or(f64::NAN));
    let tracks = figures(&score_tracks(&scenario, &reported));
    // The same on the frames the pipeline had an anchored pose for.
    let mut anchored_only = scenario.clone();
    anchored_only.frames.retain(|f| pipeline_errors.contains_key(&(f.index as usize - 1)));
    let tracks_anchored = figures(&score_tracks(&anchored_only, &reported));
    // The same tracks seen from the ego: moved from the anchored pose of their frame to the
    // true one, which takes the anchoring error out and leaves the tracker's.
    let relative: HashMap<u32, Vec<(u32, u16, Box3d)>> = reported
        .iter()
        .filter_map(|(frame, tracks)| {
            let (anchored, truth) = ego_poses.get(frame)?;
            let moved = tracks
                .iter()
                .map(|(id, class, b)| {
                    let (dx, dy) = (b.x - anchored.x, b.y - anchored.y);
                    let (s, c) = (truth.heading - anchored.heading).sin_cos();
                    let bbox = Box3d { x: truth.x + c * dx - s * dy, y: truth.y + s * dx + c * dy, ..*b };
                    (*id, *class, bbox)
                })
                .collect();
            Some((*frame, moved))
        })
        .collect();
    let tracks_relative = figures(&score_tracks(&anchored_only, &relative));
    let classes = tracker_classes();
    let truth = evaluate_tracking::<64>(&scenario, tracker_config(&classes));
    let tracks_truth_pose = (truth.metric("mota"), truth.metric("idf1"));
    let _ = std::fs::remove_dir_all(&work);
    Outcome {
        scenario,
        recording,
        log,
        ape,
        anchored,
        ape_offline,
        tracks,
        tracks_anchored,
        tracks_relative,
        tracks_truth_pose,
    }
}
