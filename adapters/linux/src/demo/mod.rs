//! `dash2sim demo`: the whole product on a generated work-zone drive, by its own path.
//!
//! 1. generate the drive (`scenario`) and its road as OpenStreetMap;
//! 2. build the map tile from the road's OSM;
//! 3. `record`, live (the `live` module): the camera process (`dash2sim scenario publish`, a child
//!    process) publishes frames, VO poses and detections over shared memory and writes the
//!    GNSS receiver's NMEA and the wheel-speed CAN frames into FIFOs at their rates; the
//!    logger subscribes and reads them, runs the on-device pipeline (anchoring, 3D/2D
//!    tracking, verification per 15 s window) and writes the 4D log. No ground truth goes
//!    in. `--offline` reads the same drive from its files instead (one process, repeatable);
//! 4. `finish`: the log re-anchored offline with street-imagery anchors (simulated matches
//!    every 50 m, σ 0.3 m), tracks smoothed, verified per window;
//! 5. `verify` the true drive, the online log and the finished log, channel-insensitive
//!    and channel-sensitive;
//! 6. judge the online and the finished log against the truth the generator knows
//!    (anchoring error and scale, 3D tracks by motmetrics' metrics);
//! 7. `export`: MCAP (Foxglove), TUM (evo), GeoJSON (QGIS) and the nuPlan database and map;
//! 8. `plot` the drive.
//!
//! `--data DIR` runs the real recordings of a data folder instead ([`crate::recordings`]).
//!
//! The receiver is a good one (σ 1–2 m, errors correlated over 2 s, no multipath): with the
//! generator's default phone-grade GNSS the anchorer rightly declines to commit within 40 s.

mod data;
mod live;
mod progress;
mod summary;

use std::path::{Path, PathBuf};

use dash2sim_core::binlog::Record;
use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{Pose2, PACIFICA};
use serde_json::{json, Value};

use crate::logfile::{self, LogContents};
use crate::record::{self, Setup};
use crate::scenario::evaluate::evaluate_tracking;
use crate::scenario::judge::{judge_log, LogJudgement};
use crate::scenario::sensors::GnssModel;
use crate::scenario::street::street_anchors;
use crate::scenario::write::write_scenario;
use crate::scenario::{generate, tracker_classes, tracker_config, Driver, Scenario, ScenarioConfig};
use progress::Progress;

/// `dash2sim demo` arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(short, long, default_value = "demo-output")]
    pub output: PathBuf,
    /// Seed of the generated drive.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Length of the drive, s (10–50).
    #[arg(long, default_value_t = 40.0)]
    pub duration: f64,
    /// `careful` (the corpus's drives: the log verifies) or `careless` (changes lanes inside
    /// the taper and hits its drums: a log the verifier must reject).
    #[arg(long, value_enum, default_value = "careful")]
    pub driver: Driver,
    /// Record from the drive's files in this process (repeatable, no shared memory) instead
    /// of from a live camera process, serial FIFO and CAN FIFO.
    #[arg(long)]
    pub offline: bool,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress on stderr.
    #[arg(short, long)]
    pub quiet: bool,
    /// Run the real recordings of this data folder instead of a generated drive: the
    /// comma2k19 minute and the CSS CANedge drive (without a value: `$DASH2SIM_DATA`,
    /// else `../shared/data`).
    #[arg(long, value_name = "DIR")]
    #[allow(clippy::option_option)]
    pub data: Option<Option<PathBuf>>,
}

/// `dash2sim demo`.
pub fn run(args: &DemoArgs) -> Result<(), String> {
    let progress = Progress::new(args.quiet);
    if !(args.duration.is_finite() && (10.0..=50.0).contains(&args.duration)) {
        return Err(format!("--duration {} must be between 10 and 50 seconds", args.duration));
    }
    if let Some(dir) = &args.data {
        let dir = dir.clone().unwrap_or_else(crate::recordings::default_dir);
        std::fs::create_dir_all(&args.output).map_err(|e| format!("{}: {e}", args.output.display()))?;
        let summary = data::run(&dir, &args.output, &progress)?;
        write_file(&args.output.join("summary.json"), summary.to_string())?;
        if args.json {
            println!("{summary}");
        } else {
            summary::print_data(&summary);
        }
        let failed: Vec<String> = summary["recordings"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|r| Some(format!("{}: {}", r["name"].as_str()?, r["error"].as_str()?)))
            .collect();
        return if failed.is_empty() { Ok(()) } else { Err(failed.join("; ")) };
    }
    let summary = generated(args, &progress)?;
    write_file(&args.output.join("summary.json"), summary.to_string())?;
    if args.json {
        println!("{summary}");
    } else {
        summary::print(&summary);
    }
    Ok(())
}

fn write_file(path: &Path, contents: impl AsRef<[u8]>) -> Result<(), String> {
    std::fs::write(path, contents).map_err(|e| format!("{}: {e}", path.display()))
}

/// How a log recorded from the drive fares: judged against the truth, verified both ways.
struct Judged {
    judgement: LogJudgement,
    insensitive: Value,
    sensitive: Value,
}

/// Every metric of `verify` on `ego`, in both channel modes.
fn verify_both(
    map: MapView<'_>,
    ego: &[(f64, Pose2)],
    agents: &crate::verify::AgentsByTime,
) -> Result<(Value, Value), String> {
    let mode = |sensitive| -> Result<Value, String> {
        let v = crate::verify::replay(map, ego, agents, sensitive, PACIFICA)?;
        Ok(crate::verify::report_json(&v, sensitive))
    };
    Ok((mode(false)?, mode(true)?))
}

fn judge(scenario: &Scenario, log: &LogContents, name: &str, map: MapView<'_>) -> Result<Judged, String> {
    let (ego, agents) = crate::verify::from_contents(log, name, &map)?;
    let (insensitive, sensitive) = verify_both(map, &ego, &agents)?;
    Ok(Judged { judgement: judge_log(scenario, log), insensitive, sensitive })
}

/// The drive time (s from its first frame) of log time `t_us`, through the frame numbers.
fn drive_time(log: &LogContents, t_us: i64) -> Option<f64> {
    let first = log.records.iter().find_map(|r| match r {
        Record::FrameMeta(f) if f.frame == 1 => Some(f.t_us),
        _ => None,
    })?;
    Some((t_us - first) as f64 * 1e-6)
}

/// The online anchor's scale at the end of the drive against the VO's true scale then.
fn online_scale(scenario: &Scenario, log: &LogContents) -> Option<(f64, f64)> {
    let (t_us, scale) = log.records.iter().rev().find_map(|r| match r {
        Record::AnchorEstimate(a) if a.observability == 2 => Some((a.t_us, a.scale_e6 as f64 * 1e-6)),
        _ => None,
    })?;
    let truth = scenario.config.vo.scale_at(drive_time(log, t_us)?);
    Some((scale, scale / truth - 1.0))
}

/// Distinct 3D tracks per class name.
fn tracks_by_class(log: &LogContents) -> std::collections::BTreeMap<&'static str, usize> {
    let mut ids: std::collections::BTreeMap<&'static str, std::collections::BTreeSet<i64>> = Default::default();
    for (_, track) in logfile::export::tracks(log) {
        ids.entry(logfile::export::class_name(track.class)).or_default().insert(track.id);
    }
    ids.into_iter().map(|(class, set)| (class, set.len())).collect()
}

/// The device's verification windows (its records), as `{score, verified}`.
fn device_windows(log: &LogContents) -> Vec<Value> {
    log.records
        .iter()
        .filter_map(|r| match r {
            Record::Verification(v) => Some(json!({"score": v.score_e2 as f64 / 100.0, "verified": v.score_e2 > 9000})),
            _ => None,
        })
        .collect()
}

/// `finish`'s windows in the same form (channel-insensitive, as the device scores them).
fn finished_windows(report: &Value) -> Vec<Value> {
    report["verification"]["windows"]
        .as_array()
        .map(|windows| {
            windows
                .iter()
                .map(|w| {
                    let v = &w["channel_insensitive"];
                    json!({"score": v["score"], "verified": v["verified"]})
                })
                .collect()
        })
        .unwrap_or_default()
}

fn judged_json(t: &LogJudgement) -> Value {
    json!({
        "ape_rmse_m": t.ego_rmse,
        "ape_max_m": t.ego_max,
        "observable_after_s": t.first_anchored_s,
        "anchored_frames": t.ego_errors.len(),
        "mota": t.tracks.0,
        "idf1": t.tracks.1,
        "mota_anchored_frames": t.tracks_anchored.0,
        "idf1_anchored_frames": t.tracks_anchored.1,
        "mota_seen_from_ego": t.tracks_relative.0,
        "idf1_seen_from_ego": t.tracks_relative.1,
    })
}

/// The generated drive through the product; the summary.
fn generated(args: &DemoArgs, progress: &Progress) -> Result<Value, String> {
    const STEPS: u32 = 8;
    let (out, seed, duration_s) = (&args.output, args.seed, args.duration);
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let drive_dir = out.join("drive");
    let config =
        ScenarioConfig { seed, duration_s, gnss: GnssModel::good(), driver: args.driver, ..ScenarioConfig::default() };
    let [lat, lon, height] = config.origin;
    let origin = Geodetic::new(lat, lon, height).map_err(|e| e.to_string())?;

    progress.step(
        1,
        STEPS,
        &format!("generating a {duration_s:.0} s work-zone drive (seed {seed}) into {}", drive_dir.display()),
    );
    let scenario = generate(&config);
    write_scenario(&scenario, &drive_dir).map_err(|e| format!("{}: {e}", drive_dir.display()))?;

    progress.step(2, STEPS, "building the map tile from the road's OpenStreetMap");
    let osm = crate::osm::read(&drive_dir.join("road.osm")).map_err(|e| e.to_string())?;
    let tile = crate::map_tile::encode(
        &crate::map_tile::from_osm(&osm, Some(origin), &mut Vec::new()),
        crate::map_tile::DEFAULT_CELL_M,
    );
    let map_path = out.join("road.map");
    write_file(&map_path, &tile)?;
    let map = MapView::parse(&tile).map_err(|e| e.to_string())?;

    let log_path = out.join("drive.d2slog");
    let _ = std::fs::remove_file(&log_path);
    let setup = Setup::work_zone(origin, Some(tile.clone()), *b"dash2sim-demo\0\0\0");
    let recording = if args.offline {
        progress.step(
            3,
            STEPS,
            "recording from the drive's files: the on-device pipeline over VO, NMEA, CAN and detections",
        );
        let (stream, _) = record::read_sources(&record::Sources::scenario(&drive_dir))?;
        let recording = record::run_stream(&stream, &setup)?;
        write_file(&log_path, &recording.log)?;
        json!({"mode": "offline", "inputs": recording.inputs, "pipeline": record::summary(&recording)})
    } else {
        progress.step(
            3,
            STEPS,
            "recording live: the camera process publishes over shared memory, GNSS arrives as NMEA on a FIFO, speed as CAN frames",
        );
        let bar = progress.bar(duration_s.ceil() as u64, "s of the drive");
        let drive = live::Drive { seed, seconds: duration_s, driver: args.driver };
        let live = live::record(drive, out, &log_path, &setup, &bar)?;
        bar.finish_and_clear();
        let r = &live.report;
        json!({"mode": "live", "frames_published": live.published, "frames_received": r.frames,
               "inputs_dropped": r.dropped, "issues": r.issues, "wall_s": live.seconds,
               "pipeline": record::stats_json(&r.stats)})
    };
    let log = logfile::read(&log_path).map_err(|e| e.to_string())?;
    let log_bytes = log.bytes;

    progress.step(
        4,
        STEPS,
        "finishing: the whole drive re-anchored with street-imagery anchors, tracks smoothed, verified per window",
    );
    let spinner = progress.spinner("solving");
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
    spinner.finish_and_clear();
    let finished_path = out.join("finished.d2slog");
    let header = log.header.ok_or("the recorded log has no header")?;
    let finished_bytes = logfile::import::encode_in_order(&header, &finished.records)?;
    write_file(&finished_path, &finished_bytes)?;
    let finished_log = logfile::decode(&finished_bytes, "finished").map_err(|e| e.to_string())?;

    progress.step(5, STEPS, "verifying the true drive, the online log and the finished log (both channel modes)");
    let truth_ego: Vec<(f64, Pose2)> =
        scenario.frames.iter().map(|f| (f.ego.t, Pose2::new(f.ego.x, f.ego.y, f.ego.heading))).collect();
    let truth_agents = crate::verify::read_objects(&drive_dir.join("objects.csv"))?;
    let (truth_insensitive, truth_sensitive) = verify_both(map, &truth_ego, &truth_agents)?;
    let online = judge(&scenario, &log, "the online log", map)?;
    let finished_judged = judge(&scenario, &finished_log, "the finished log", map)?;

    progress.step(6, STEPS, "judging the logs against the truth (anchoring, 3D tracks)");
    let classes = tracker_classes();
    let truth_tracking = evaluate_tracking::<64>(&scenario, tracker_config(&classes));
    let frame_times: Vec<f64> = scenario.frames.iter().map(|f| f.ego.t).collect();
    let true_mean_scale =
        frame_times.iter().map(|t| scenario.config.vo.scale_at(*t)).sum::<f64>() / frame_times.len().max(1) as f64;
    let finished_scale = finished.report["anchoring"]["scale"].as_f64().unwrap_or(f64::NAN);

    progress.step(7, STEPS, "exporting MCAP (Foxglove), TUM (evo), GeoJSON (QGIS) and the nuPlan database and map");
    let mcap_path = out.join("drive.mcap");
    let messages: u64 = logfile::mcap_export::write(&log, Some(&map), &mcap_path, None)?.values().sum();
    let finished_mcap = out.join("finished.mcap");
    logfile::mcap_export::write(&finished_log, Some(&map), &finished_mcap, None)?;
    write_file(&out.join("ego.tum"), logfile::export::tum(&log))?;
    write_file(&out.join("finished.tum"), logfile::export::tum(&finished_log))?;
    write_file(&out.join("drive.geojson"), logfile::export::geojson(&log)?.to_string())?;
    let nuplan_dir = out.join("nuplan");
    let _ = std::fs::remove_dir_all(&nuplan_dir);
    let nuplan = crate::nuplan::export(&crate::nuplan::NuplanRequest {
        log: &finished_log,
        log_name: &finished_path.display().to_string(),
        tile: &tile,
        map_name: &logfile::export::map_name("road"),
        out: &nuplan_dir,
        scene_s: 5.0,
    });

    progress.step(8, STEPS, "drawing the drive (plot.png, plot.svg)");
    for name in ["plot.png", "plot.svg"] {
        crate::plot::plot(&crate::plot::PlotArgs {
            log: log_path.clone(),
            map: Some(map_path.clone()),
            finished: Some(finished_path.clone()),
            output: out.join(name),
        })?;
    }

    let minutes = duration_s / 60.0;
    let file = |name: &str| out.join(name).display().to_string();
    let mut files = vec![
        json!({"what": "the generated drive (truth, sensor streams, road OSM)", "path": file("drive")}),
        json!({"what": "map tile", "path": file("road.map")}),
        json!({"what": "the device's 4D log", "path": file("drive.d2slog")}),
        json!({"what": "street-imagery anchors", "path": file("anchors.csv")}),
        json!({"what": "the finished 4D log", "path": file("finished.d2slog")}),
        json!({"what": "MCAP for Foxglove (the device's log)", "path": file("drive.mcap")}),
        json!({"what": "MCAP for Foxglove (finished)", "path": file("finished.mcap")}),
        json!({"what": "TUM for evo (the device's log)", "path": file("ego.tum")}),
        json!({"what": "TUM for evo (finished)", "path": file("finished.tum")}),
        json!({"what": "GeoJSON for QGIS", "path": file("drive.geojson")}),
        json!({"what": "the picture", "path": file("plot.png")}),
        json!({"what": "the picture (vector)", "path": file("plot.svg")}),
        json!({"what": "this summary", "path": file("summary.json")}),
    ];
    let nuplan_json = match &nuplan {
        Ok(n) => {
            files.push(json!({"what": "nuPlan log database", "path": n.db.display().to_string()}));
            files.push(json!({"what": "nuPlan map (GeoPackage)", "path": n.gpkg.display().to_string()}));
            json!({"db": n.db.display().to_string(), "map": n.gpkg.display().to_string(), "scenes": n.scenes,
                   "ego_states": n.ego_states})
        }
        // A short drive makes too few scenes: said, not fatal.
        Err(e) => json!({"error": e}),
    };
    let (online_scale, online_scale_error) =
        online_scale(&scenario, &log).map_or((None, None), |(s, e)| (Some(s), Some(e)));
    Ok(json!({
        "seed": seed,
        "duration_s": duration_s,
        "driver": args.driver.name(),
        "recording": recording,
        "anchoring": {
            "online": {
                "observable_after_s": online.judgement.first_anchored_s,
                "anchored_frames": online.judgement.ego_errors.len(),
                "frames": scenario.frames.len(),
                "ape_rmse_m": online.judgement.ego_rmse,
                "ape_max_m": online.judgement.ego_max,
                "scale_at_end": online_scale,
                "scale_error": online_scale_error,
            },
            "finished": {
                "anchors_used": finished.report["anchors"]["used"],
                "ape_rmse_m": finished_judged.judgement.ego_rmse,
                "ape_max_m": finished_judged.judgement.ego_max,
                "scale": finished_scale,
                "scale_sigma_relative": finished.report["anchoring"]["scale_sigma_relative"],
                "true_mean_scale": true_mean_scale,
                "scale_error": finished_scale / true_mean_scale - 1.0,
            },
        },
        "tracking": {
            "online": judged_json(&online.judgement),
            "finished": judged_json(&finished_judged.judgement),
            "tracker_fed_true_pose": {"mota": truth_tracking.metric("mota"), "idf1": truth_tracking.metric("idf1")},
            "tracks_by_class": tracks_by_class(&log),
            "finished_tracks_by_class": tracks_by_class(&finished_log),
        },
        "verification": {
            "ground_truth": {"channel_insensitive": truth_insensitive, "channel_sensitive": truth_sensitive},
            "online": {"channel_insensitive": online.insensitive, "channel_sensitive": online.sensitive},
            "finished": {"channel_insensitive": finished_judged.insensitive, "channel_sensitive": finished_judged.sensitive},
            "windows_on_device": device_windows(&log),
            "windows_finished": finished_windows(&finished.report),
        },
        "log": {"records": log.records.len(), "bytes": log_bytes, "bytes_per_minute": log_bytes as f64 / minutes,
                "damaged": log.stats.damaged, "finished_bytes": finished_bytes.len()},
        "mcap_messages": messages,
        "nuplan": nuplan_json,
        "files": files,
    }))
}
