//! `dash2sim demo`: the on-device pipeline end to end on a generated work-zone drive.
//!
//! 1. generate the drive (`scenario`) and write it in the forms a device sees: VO poses of
//!    the camera, the GNSS receiver's serial capture, wheel speed as J1939 CAN frames, 3D
//!    detections in the camera frame, 2D detections — and the road as OpenStreetMap;
//! 2. build the map tile from the road's OSM;
//! 3. `record`: the core `Pipeline` reads those inputs in receive-time order — NMEA framing,
//!    CAN decoding, the device clock → UTC, anchoring VO to GNSS and wheel speed, 3D
//!    tracking through the anchored ego pose, 2D tracking, verification per 15 s window —
//!    and writes the 4D log. No ground truth goes in;
//! 4. `finish`: the log re-anchored offline with street-imagery anchors (simulated matches
//!    every 50 m, σ 0.3 m), tracks smoothed, verified per window;
//! 5. judge the online and the finished log against the truth the generator knows
//!    (anchoring error, 3D tracks by motmetrics' metrics), and verify the recovered drives
//!    and the true drive;
//! 6. export the log for Foxglove (MCAP), evo (TUM) and QGIS (GeoJSON).
//!
//! The receiver is a good one (σ 1–2 m, errors correlated over 2 s, no multipath): with the
//! generator's default phone-grade GNSS the anchorer rightly declines to commit within 40 s.

use std::path::Path;

use dash2sim_core::binlog::Record;
use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use dash2sim_core::obb::PACIFICA;
use serde_json::json;

use crate::logfile;
use crate::record::{self, Setup};
use crate::scenario::evaluate::evaluate_tracking;
use crate::scenario::judge::judge_log;
use crate::scenario::sensors::GnssModel;
use crate::scenario::street::street_anchors;
use crate::scenario::write::write_scenario;
use crate::scenario::{generate, tracker_classes, tracker_config, ScenarioConfig};

const STEPS: u32 = 7;

fn step(n: u32, text: &str) {
    eprintln!("[{n}/{STEPS}] {text}");
}

fn write_file(path: &Path, text: &str) -> Result<(), String> {
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

fn verdict(verified: bool) -> &'static str {
    if verified {
        "verified"
    } else {
        "not verified"
    }
}

/// `dash2sim demo`.
pub fn run(out: &Path, seed: u64, duration_s: f64, as_json: bool) -> Result<(), String> {
    if !(duration_s.is_finite() && (10.0..=50.0).contains(&duration_s)) {
        return Err(format!("--duration {duration_s} must be between 10 and 50 seconds"));
    }
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let drive = out.join("drive");
    let config = ScenarioConfig { seed, duration_s, gnss: GnssModel::good(), ..ScenarioConfig::default() };
    let [lat, lon, height] = config.origin;
    let origin = Geodetic::new(lat, lon, height).map_err(|e| e.to_string())?;

    step(1, &format!("generating a {duration_s:.0} s work-zone drive (seed {seed}) into {}", drive.display()));
    let scenario = generate(&config);
    write_scenario(&scenario, &drive).map_err(|e| format!("{}: {e}", drive.display()))?;

    step(2, "building the map tile from the road's OpenStreetMap");
    let osm = crate::osm::read(&drive.join("road.osm")).map_err(|e| e.to_string())?;
    let tile = crate::map_tile::encode(&crate::map_tile::from_osm(&osm, Some(origin), &mut Vec::new()), 50.0);
    let map_path = out.join("road.map");
    std::fs::write(&map_path, &tile).map_err(|e| format!("{}: {e}", map_path.display()))?;
    let map = MapView::parse(&tile).map_err(|e| e.to_string())?;

    step(3, "recording: the on-device pipeline over VO, the GNSS serial capture, CAN and the detections");
    let log_path = out.join("drive.d2slog");
    let (stream, _) = record::read_sources(&record::Sources::scenario(&drive))?;
    let setup = Setup::work_zone(origin, Some(tile.clone()), *b"dash2sim-demo\0\0\0");
    let recording = record::run_stream(&stream, &setup)?;
    std::fs::write(&log_path, &recording.log).map_err(|e| format!("{}: {e}", log_path.display()))?;

    let log = logfile::decode(&recording.log, &log_path.display().to_string()).map_err(|e| e.to_string())?;
    step(4, "finishing: the whole drive re-anchored with street-imagery anchors, tracks smoothed, verified per window");
    let anchors_path = out.join("anchors.csv");
    let anchors_text = street_anchors(&scenario, &log, 50.0, 0.3, seed);
    write_file(&anchors_path, &anchors_text)?;
    let anchor_file = crate::finish::anchors::parse(&anchors_text)
        .map_err(|(line, why)| format!("{}:{line}: {why}", anchors_path.display()))?;
    let finished = crate::finish::finish(
        &log,
        &log_path.display().to_string(),
        Some((&anchors_path.display().to_string(), &anchor_file)),
        Some(&tile),
        setup.mount,
        crate::finish::solve::Settings { gravity_aligned: true, ..Default::default() },
        setup.gnss.uere_m,
    )?;
    let finished_path = out.join("finished.d2slog");
    let header = log.header.ok_or("the recorded log has no header")?;
    let finished_bytes = logfile::import::encode_in_order(&header, &finished.records)?;
    std::fs::write(&finished_path, &finished_bytes).map_err(|e| format!("{}: {e}", finished_path.display()))?;
    let finished_log = logfile::decode(&finished_bytes, "finished").map_err(|e| e.to_string())?;

    step(5, "judging the logs against the truth and verifying the recovered and the true drive");
    let judged = judge_log(&scenario, &log);
    let judged_finished = judge_log(&scenario, &finished_log);
    let classes = tracker_classes();
    let truth_tracking = evaluate_tracking::<64>(&scenario, tracker_config(&classes));
    let (ego, agents) = crate::verify::from_log(&log_path, &map)?;
    let recovered = crate::verify::replay(map, &ego, &agents, false, PACIFICA)?.scores;
    let truth_ego: Vec<(f64, dash2sim_core::obb::Pose2)> = scenario
        .frames
        .iter()
        .map(|f| (f.ego.t, dash2sim_core::obb::Pose2::new(f.ego.x, f.ego.y, f.ego.heading)))
        .collect();
    let truth_agents = crate::verify::read_objects(&drive.join("objects.csv"))?;
    let reference = crate::verify::replay(map, &truth_ego, &truth_agents, false, PACIFICA)?.scores;
    let windows: Vec<_> = log
        .records
        .iter()
        .filter_map(|r| match r {
            Record::Verification(v) => Some(json!({"score": v.score_e2 as f64 / 100.0, "verified": v.score_e2 > 9000})),
            _ => None,
        })
        .collect();

    step(6, "exporting MCAP (Foxglove), TUM (evo) and GeoJSON (QGIS)");
    let mcap_path = out.join("drive.mcap");
    let messages: u64 = logfile::mcap_export::write(&log, Some(&map), &mcap_path, None)?.values().sum();
    write_file(&out.join("ego.tum"), &logfile::export::tum(&log))?;
    write_file(&out.join("drive.geojson"), &logfile::export::geojson(&log)?.to_string())?;

    step(7, "drawing the drive (plot.png, plot.svg)");
    for name in ["plot.png", "plot.svg"] {
        crate::plot::plot(&crate::plot::PlotArgs {
            log: log_path.clone(),
            map: Some(map_path.clone()),
            finished: Some(finished_path.clone()),
            output: out.join(name),
        })?;
    }

    let minutes = duration_s / 60.0;
    let observable_after = judged.first_anchored_s;
    let s = &recording.stats;
    let summary = json!({
        "seed": seed,
        "duration_s": duration_s,
        "pipeline": record::summary(&recording),
        "anchoring": {
            "observable_after_s": observable_after,
            "anchored_frames": s.anchored_frames,
            "frames": scenario.frames.len(),
            "ape_rmse_m": judged.ego_rmse,
            "ape_max_m": judged.ego_max,
        },
        "tracking": {
            "mota": judged.tracks.0,
            "idf1": judged.tracks.1,
            "mota_anchored_frames": judged.tracks_anchored.0,
            "idf1_anchored_frames": judged.tracks_anchored.1,
            "mota_seen_from_ego": judged.tracks_relative.0,
            "idf1_seen_from_ego": judged.tracks_relative.1,
            "mota_true_pose": truth_tracking.metric("mota"),
            "idf1_true_pose": truth_tracking.metric("idf1"),
            "track_states_by_class": judged.tracks_by_class,
        },
        "finished": {
            "ape_rmse_m": judged_finished.ego_rmse,
            "ape_max_m": judged_finished.ego_max,
            "mota": judged_finished.tracks.0,
            "idf1": judged_finished.tracks.1,
            "report": finished.report,
        },
        "verification": {
            "windows": windows,
            "recovered": {"score": recovered.score, "verified": recovered.verified,
                          "drivable_area": recovered.drivable_area, "driving_direction": recovered.driving_direction,
                          "ttc": recovered.ttc, "comfort": recovered.comfort, "worst_corner_m": recovered.worst_corner},
            "ground_truth": {"score": reference.score, "verified": reference.verified},
        },
        "log": {"records": log.records.len(), "bytes": recording.log.len(),
                "bytes_per_minute": recording.log.len() as f64 / minutes, "damaged": log.stats.damaged},
        "mcap_messages": messages,
        "files": ["drive/", "road.map", "drive.d2slog", "anchors.csv", "finished.d2slog", "drive.mcap", "ego.tum", "drive.geojson", "plot.png", "plot.svg", "summary.json"],
    });
    write_file(&out.join("summary.json"), &summary.to_string())?;
    if as_json {
        println!("{summary}");
        return Ok(());
    }
    println!("dash2sim demo — {duration_s:.0} s work zone, seed {seed}, everything in {}", out.display());
    println!(
        "  pipeline      {} inputs → {} records: {} VO poses, {} fixes, {} speeds, {} 3D detections, {} issues",
        recording.inputs,
        s.records,
        s.vo_poses,
        s.fixes,
        s.speeds,
        s.detections_placed + s.detections_raw,
        recording.issues.total()
    );
    println!(
        "  anchoring     observable after {}, {} of {} frames anchored, APE {:.2} m RMSE ({:.2} m max) against the truth",
        observable_after.map_or_else(|| "never".to_owned(), |t| format!("{t:.1} s")),
        s.anchored_frames,
        scenario.frames.len(),
        judged.ego_rmse,
        judged.ego_max
    );
    println!(
        "  tracking      MOTA {:.3}, IDF1 {:.3} against the truth (anchored frames {:.3} / {:.3}; seen from the ego {:.3} / {:.3}; tracker fed the true pose {:.3} / {:.3})",
        judged.tracks.0,
        judged.tracks.1,
        judged.tracks_anchored.0,
        judged.tracks_anchored.1,
        judged.tracks_relative.0,
        judged.tracks_relative.1,
        truth_tracking.metric("mota"),
        truth_tracking.metric("idf1")
    );
    let drive = &finished.report["verification"]["drive"];
    let score_of = |v: &serde_json::Value| {
        format!(
            "{:.1} ({})",
            v["score"].as_f64().unwrap_or(f64::NAN),
            verdict(v["verified"].as_bool().unwrap_or(false))
        )
    };
    println!(
        "  finishing     {} street-imagery anchors used: APE {:.2} m RMSE ({:.2} m max), MOTA {:.3}, IDF1 {:.3}; scale {:.4} ± {:.3} %",
        finished.report["anchors"]["used"],
        judged_finished.ego_rmse,
        judged_finished.ego_max,
        judged_finished.tracks.0,
        judged_finished.tracks.1,
        finished.report["anchoring"]["scale"].as_f64().unwrap_or(f64::NAN),
        100.0 * finished.report["anchoring"]["scale_sigma_relative"].as_f64().unwrap_or(f64::NAN),
    );
    println!(
        "  verification  on the device: {} of {} windows verified; recovered drive {:.1} ({}); finished {} channel-insensitive, {} channel-sensitive; ground truth {:.1} ({})",
        s.windows_verified,
        s.windows,
        recovered.score,
        verdict(recovered.verified),
        score_of(&drive["channel_insensitive"]),
        score_of(&drive["channel_sensitive"]),
        reference.score,
        verdict(reference.verified)
    );
    println!(
        "  4D log        {} records, {} bytes ({:.0} bytes per minute); MCAP {} messages",
        log.records.len(),
        recording.log.len(),
        recording.log.len() as f64 / minutes,
        messages
    );
    println!(
        "  open {} in Foxglove; `dash2sim inspect {}`; finished log {}; picture {}",
        mcap_path.display(),
        log_path.display(),
        finished_path.display(),
        out.join("plot.png").display()
    );
    Ok(())
}
