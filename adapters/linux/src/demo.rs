//! `dash2sim demo`: the Dash2Sim pipeline end to end on a generated work-zone drive.
//!
//! 1. generate the drive (`scenario`): VO, GNSS, wheel speed, 3D detections, the road as OSM;
//! 2. anchor the VO track to GNSS and wheel speed (`anchor`, gravity-aligned) — the
//!    metric, geo-referenced ego trajectory — and measure it against the truth;
//! 3. track the 3D detections (`track3d`) and measure the tracks (motmetrics' metrics);
//! 4. build the map tile from the road's OSM and verify the recovered log as nuPlan would;
//! 5. write the compact 4D log (GNSS, speed, VO, anchored ego, anchor estimates, 3D tracks,
//!    the verification result, events);
//! 6. export it for Foxglove (MCAP), evo (TUM) and QGIS (GeoJSON).
//!
//! The generated VO has positions only, so the anchored ego's heading is its direction of
//! travel. The receiver is a good one (σ 1–2 m, errors correlated over 2 s, no multipath): with the
//! generator's default phone-grade GNSS the anchorer rightly declines to commit within
//! 40 s. Detections go to the world through the true ego pose, as `scenario eval` does, so
//! that tracking is judged on its own.

use std::path::Path;

use dash2sim_core::anchor::{AnchorConfig, AnchorMode, Observability};
use dash2sim_core::binlog::{AnchorEstimate, EventRecord, Header, Record, Verification, VoPose, MAX_TEXT};
use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use dash2sim_core::obb::PACIFICA;
use serde_json::json;

use crate::evaluate::{self, Align, Relation};
use crate::logfile::{self, quantise};
use crate::scenario::actors::Class;
use crate::scenario::evaluate::evaluate_tracking;
use crate::scenario::sensors::GnssModel;
use crate::scenario::write::write_scenario;
use crate::scenario::{generate, tracker_classes, tracker_config, ScenarioConfig};
use crate::trajectory::{self, Format, Trajectory};

/// The GNSS σ the anchorer is told, m.
const SIGMA_M: f64 = 2.0;

fn step(n: u32, text: &str) {
    eprintln!("[{n}/6] {text}");
}

fn event(t_us: i64, level: u8, text: &str) -> Record {
    let mut e = EventRecord { t_us, level, ..EventRecord::default() };
    for b in text.bytes().take(MAX_TEXT) {
        let _ = e.text.push(b);
    }
    Record::Event(e)
}

fn write_file(path: &Path, text: &str) -> Result<(), String> {
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
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

    step(1, &format!("generating a {duration_s:.0} s work-zone drive (seed {seed}) into {}", drive.display()));
    let scenario = generate(&config);
    write_scenario(&scenario, &drive).map_err(|e| format!("{}: {e}", drive.display()))?;

    step(2, "anchoring the VO track to GNSS and wheel speed");
    let gnss = Trajectory::read(&drive.join("gnss.tum"), Format::Tum).map_err(|e| e.to_string())?;
    let speed = crate::anchoring::read_speed_csv(&drive.join("speed.csv"))?;
    let anchor_config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let frames = crate::anchoring::replay(&scenario.vo, &gnss, &speed, SIGMA_M, anchor_config)?;
    let mut anchored = crate::anchoring::anchored_trajectory(&scenario.vo, &frames);
    if anchored.is_empty() {
        return Err("the anchorer never became observable on this drive".to_owned());
    }
    // The generated VO carries positions only: the ego's heading is its direction of travel.
    let positions: Vec<_> = anchored.poses.iter().map(|p| p.translation).collect();
    for (k, pose) in anchored.poses.iter_mut().enumerate() {
        let (a, b) = (positions[k.saturating_sub(1)], positions[(k + 1).min(positions.len() - 1)]);
        pose.rotation = dash2sim_core::sim3::rotation_z((b.y - a.y).atan2(b.x - a.x));
    }
    let anchored_path = out.join("anchored.tum");
    trajectory::write_file(&anchored, &anchored_path, Format::Tum)
        .map_err(|e| format!("{}: {e}", anchored_path.display()))?;
    let (truth, estimate) =
        evaluate::load_pair(&drive.join("ego.tum"), &anchored_path, Format::Tum, 0.01).map_err(|e| e.to_string())?;
    let ape = evaluate::ape(&truth, &estimate, Align::None, Relation::Trans).map_err(|e| e.to_string())?;
    let observable_at = frames.iter().find(|f| f.quality.observability == Observability::Observable).map(|f| f.t);

    step(3, "tracking the 3D detections");
    let classes = tracker_classes();
    let tracking = evaluate_tracking::<64>(&scenario, tracker_config(&classes));
    let mut csv = format!("{}\n", crate::objects::HEADER);
    for (frame, o) in &tracking.tracks {
        let Some(f) = usize::try_from(*frame).ok().and_then(|i| scenario.frames.get(i.wrapping_sub(1))) else {
            continue;
        };
        let class = Class::from_id(o.class).map_or("other", Class::name);
        let v = [o.velocity[0], o.velocity[1]];
        let row = crate::objects::ObjectRow::from_box(f.ego.t, o.id, class, &o.bbox, v, o.is_static);
        csv += &crate::objects::line(*frame, &row, true);
    }
    let tracks_path = out.join("tracks.csv");
    write_file(&tracks_path, &csv)?;

    step(4, "building the map tile from the road's OSM and verifying the recovered drive");
    let osm = crate::osm::read(&drive.join("road.osm")).map_err(|e| e.to_string())?;
    let origin = Geodetic::new(lat, lon, height).map_err(|e| e.to_string())?;
    let tile = crate::map_tile::encode(&crate::map_tile::from_osm(&osm, Some(origin), &mut Vec::new()), 50.0);
    let map_path = out.join("road.map");
    std::fs::write(&map_path, &tile).map_err(|e| format!("{}: {e}", map_path.display()))?;
    let map = MapView::parse(&tile).map_err(|e| e.to_string())?;
    let ego: Vec<(f64, dash2sim_core::obb::Pose2)> = anchored
        .stamps
        .iter()
        .zip(&anchored.poses)
        .map(|(t, p)| {
            let yaw = p.rotation[(1, 0)].atan2(p.rotation[(0, 0)]);
            (*t, dash2sim_core::obb::Pose2::new(p.translation.x, p.translation.y, yaw))
        })
        .collect();
    let agents = crate::verify::read_objects(&tracks_path)?;
    let recovered = crate::verify::replay(map, &ego, &agents, false, PACIFICA)?.scores;
    let truth_ego: Vec<(f64, dash2sim_core::obb::Pose2)> = scenario
        .frames
        .iter()
        .map(|f| (f.ego.t, dash2sim_core::obb::Pose2::new(f.ego.x, f.ego.y, f.ego.heading)))
        .collect();
    let truth_agents = crate::verify::read_objects(&drive.join("objects.csv"))?;
    let reference = crate::verify::replay(map, &truth_ego, &truth_agents, false, PACIFICA)?.scores;

    step(5, "writing the compact 4D log");
    let mut records = Vec::new();
    logfile::import::nmea_records(&drive.join("gnss.nmea"), -crate::scenario::write::START_UNIX_S, &mut records)?;
    logfile::import::traj_records(&anchored_path, &mut records)?;
    logfile::import::object_records(&tracks_path, &mut records)?;
    for (t, v) in &speed {
        records.push(Record::VehicleSpeed(dash2sim_core::binlog::VehicleSpeed {
            t_us: quantise(*t, 1e-6),
            speed_mm_s: quantise(*v, 1e-3),
            source: 0,
        }));
    }
    for (t, p) in scenario.vo.stamps.iter().zip(&scenario.vo.poses) {
        let r = &p.rotation;
        records.push(Record::VoPose(VoPose {
            t_us: quantise(*t, 1e-6),
            x: quantise(p.translation.x, 1e-3),
            y: quantise(p.translation.y, 1e-3),
            z: quantise(p.translation.z, 1e-3),
            yaw_e4: quantise(r[(1, 0)].atan2(r[(0, 0)]), 1e-4),
            pitch_e4: quantise((-r[(2, 0)]).clamp(-1.0, 1.0).asin(), 1e-4),
            roll_e4: quantise(r[(2, 1)].atan2(r[(2, 2)]), 1e-4),
        }));
    }
    // The anchor once a second.
    let mut next_anchor = f64::NEG_INFINITY;
    for f in &frames {
        let Some(e) = f.estimate.filter(|_| f.t >= next_anchor) else { continue };
        next_anchor = f.t + 1.0;
        let r = &e.rotation;
        records.push(Record::AnchorEstimate(AnchorEstimate {
            t_us: quantise(f.t, 1e-6),
            scale_e6: quantise(e.scale, 1e-6),
            yaw_e6: quantise(r[(1, 0)].atan2(r[(0, 0)]), 1e-6),
            pitch_e6: quantise((-r[(2, 0)]).clamp(-1.0, 1.0).asin(), 1e-6),
            roll_e6: quantise(r[(2, 1)].atan2(r[(2, 2)]), 1e-6),
            tx_mm: quantise(e.translation.x, 1e-3),
            ty_mm: quantise(e.translation.y, 1e-3),
            tz_mm: quantise(e.translation.z, 1e-3),
            observability: match f.quality.observability {
                Observability::Observable => 2,
                Observability::Collinear => 1,
                _ => 0,
            },
            anchors: i64::from(f.quality.anchors_used),
            rms_mm: quantise(f.quality.rms_residual_m, 1e-3),
        }));
    }
    let t_end = scenario.frames.last().map_or(0.0, |f| f.ego.t);
    let s = &recovered;
    records.push(Record::Verification(Verification {
        t_us: quantise(t_end, 1e-6),
        collisions_e4: quantise(s.no_at_fault_collisions, 1e-4),
        drivable_e4: quantise(s.drivable_area, 1e-4),
        direction_e4: quantise(s.driving_direction, 1e-4),
        making_progress_e4: quantise(s.making_progress, 1e-4),
        progress_e4: quantise(s.progress, 1e-4),
        ttc_e4: quantise(s.ttc, 1e-4),
        speed_limit_e4: quantise(s.speed_limit, 1e-4),
        comfort_e4: quantise(s.comfort, 1e-4),
        score_e2: quantise(s.score, 1e-2),
        worst_corner_mm: quantise(s.worst_corner.min(1e6), 1e-3),
    }));
    records.push(event(0, 2, &format!("dash2sim demo: seed {seed}, {duration_s:.0} s work zone")));
    if let Some(t) = observable_at {
        records.push(event(quantise(t, 1e-6), 2, "anchor observable: metric, geo-referenced poses from here"));
    }
    let verdict = if s.verified { "verified" } else { "not verified" };
    records.push(event(quantise(t_end, 1e-6), 2, &format!("verification: score {:.1}, {verdict}", s.score)));
    let header = Header {
        device_id: *b"dash2sim-demo\0\0\0",
        origin: [quantise(lat, 1e-7) as i32, quantise(lon, 1e-7) as i32, quantise(height, 1e-3) as i32],
    };
    let bytes = logfile::import::encode(&header, &mut records)?;
    let log_path = out.join("drive.d2slog");
    std::fs::write(&log_path, &bytes).map_err(|e| format!("{}: {e}", log_path.display()))?;

    step(6, "exporting MCAP (Foxglove), TUM (evo) and GeoJSON (QGIS)");
    let log = logfile::decode(&bytes, &log_path.display().to_string()).map_err(|e| e.to_string())?;
    let mcap_path = out.join("drive.mcap");
    let messages: u64 = logfile::mcap_export::write(&log, Some(&map), &mcap_path, None)?.values().sum();
    write_file(&out.join("ego.tum"), &logfile::export::tum(&log))?;
    write_file(&out.join("drive.geojson"), &logfile::export::geojson(&log)?.to_string())?;

    let minutes = duration_s / 60.0;
    let summary = json!({
        "seed": seed,
        "duration_s": duration_s,
        "anchoring": {
            "observable_after_s": observable_at,
            "anchored_frames": anchored.len(),
            "frames": scenario.vo.len(),
            "ape_rmse_m": ape.stats.rmse,
            "ape_max_m": ape.stats.max,
        },
        "tracking": {
            "mota": tracking.metric("mota"),
            "idf1": tracking.metric("idf1"),
            "rmse_detections_m": tracking.rmse_detections,
            "rmse_filtered_m": tracking.rmse_filtered,
            "static_accuracy": tracking.static_accuracy(),
        },
        "verification": {
            "recovered": {"score": recovered.score, "verified": recovered.verified,
                          "drivable_area": recovered.drivable_area, "driving_direction": recovered.driving_direction,
                          "ttc": recovered.ttc, "worst_corner_m": recovered.worst_corner},
            "ground_truth": {"score": reference.score, "verified": reference.verified},
        },
        "log": {"records": log.records.len(), "bytes": bytes.len(), "bytes_per_minute": bytes.len() as f64 / minutes, "damaged": log.stats.damaged},
        "mcap_messages": messages,
        "files": ["drive/", "anchored.tum", "tracks.csv", "road.map", "drive.d2slog", "drive.mcap", "ego.tum", "drive.geojson"],
    });
    write_file(&out.join("summary.json"), &summary.to_string())?;
    if as_json {
        println!("{summary}");
        return Ok(());
    }
    println!("dash2sim demo — {duration_s:.0} s work zone, seed {seed}, everything in {}", out.display());
    println!(
        "  anchoring     observable after {}, {} of {} frames anchored, APE {:.2} m RMSE ({:.2} m max) against the truth",
        observable_at.map_or_else(|| "never".to_owned(), |t| format!("{t:.1} s")),
        anchored.len(),
        scenario.vo.len(),
        ape.stats.rmse,
        ape.stats.max
    );
    println!(
        "  tracking      MOTA {:.3}, IDF1 {:.3}, position error {:.2} m → {:.2} m filtered, static/dynamic {:.1} %",
        tracking.metric("mota"),
        tracking.metric("idf1"),
        tracking.rmse_detections,
        tracking.rmse_filtered,
        100.0 * tracking.static_accuracy()
    );
    println!(
        "  verification  recovered drive {:.1} ({}), ground truth {:.1} ({})",
        recovered.score,
        verdict,
        reference.score,
        if reference.verified { "verified" } else { "not verified" }
    );
    println!(
        "  4D log        {} records, {} bytes ({:.0} bytes per minute); MCAP {} messages",
        log.records.len(),
        bytes.len(),
        bytes.len() as f64 / minutes,
        messages
    );
    println!("  open {} in Foxglove; `dash2sim inspect {}`", mcap_path.display(), log_path.display());
    Ok(())
}
