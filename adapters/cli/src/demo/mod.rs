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
//! `--data DIR` runs the real recordings of a data folder instead ([`dash2sim_sim::datasets`]).
//!
//! The receiver is a good one (σ 1–2 m, errors correlated over 2 s, no multipath): with the
//! generator's default phone-grade GNSS the anchorer rightly declines to commit within 40 s.

mod data;
mod live;
mod progress;
mod summary;

use std::path::{Path, PathBuf};

use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use serde_json::{json, Value};

use dash2sim_finish::FinishReport;
use dash2sim_linux::log::{self, LogContents};
use dash2sim_linux::record::{self, Setup};
use dash2sim_linux::{Error, Result};
use dash2sim_sim::fidelity::drive::{assess, Anchors, Recorded};
use dash2sim_sim::scenario::evaluate::evaluate_tracking;
use dash2sim_sim::scenario::judge::LogJudgement;
use dash2sim_sim::scenario::profile::{Profile, Receiver};
use dash2sim_sim::scenario::write::{road_tile, write_scenario};
use dash2sim_sim::scenario::{generate, tracker_classes, tracker_config, Driver, ScenarioConfig};
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
    /// Length of the drive, s (10–600; live, the recording takes as long as the drive).
    #[arg(long, default_value_t = 40.0)]
    pub duration: f64,
    /// `careful` (the corpus's drives: the log verifies), `careless` (changes lanes inside
    /// the taper and hits its drums), or another kind of bad driving the verifier must
    /// reject: `shoulder`, `oncoming`, `speeding`, `tailgating`, `harsh`; `knife-edge` is
    /// careful on the edge (docs/scenario.md).
    #[arg(long, value_parser = dash2sim_args::Driver::parser(), default_value = "careful")]
    pub driver: Driver,
    /// How far the sensors are from ideal (docs/scenario.md): `ideal` (the old, kind
    /// simulator), `typical` (a consumer dashcam) or `hard`.
    #[arg(long, value_parser = dash2sim_args::Profile::parser(), default_value = "typical")]
    pub profile: Profile,
    /// Finishing's street-imagery anchors: `street` (simulated from the true path every
    /// 50 m) or `none` (GNSS and wheel speed only).
    #[arg(long, value_parser = dash2sim_args::Anchors::parser(), default_value = "street")]
    pub anchors: Anchors,
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
pub fn run(args: &DemoArgs) -> Result<()> {
    let progress = Progress::new(args.quiet);
    let longest = dash2sim_sim::scenario::command::MAX_DURATION_S;
    if !(args.duration.is_finite() && (10.0..=longest).contains(&args.duration)) {
        return Err(Error::invalid(format!("--duration {} must be between 10 and {longest} seconds", args.duration)));
    }
    if let Some(dir) = &args.data {
        let dir = dir.clone().unwrap_or_else(dash2sim_sim::datasets::default_dir);
        std::fs::create_dir_all(&args.output).map_err(|e| Error::file(&args.output, e))?;
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
        return if failed.is_empty() { Ok(()) } else { Err(Error::invalid(failed.join("; "))) };
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

fn write_file(path: &Path, contents: impl AsRef<[u8]>) -> Result<()> {
    std::fs::write(path, contents).map_err(|e| Error::file(path, e))
}

/// Distinct 3D tracks per class name.
fn tracks_by_class(log: &LogContents) -> std::collections::BTreeMap<&'static str, usize> {
    let mut ids: std::collections::BTreeMap<&'static str, std::collections::BTreeSet<i64>> = Default::default();
    for (_, track) in log::export::tracks(log) {
        ids.entry(dash2sim_core::class::name_of(track.class)).or_default().insert(track.id);
    }
    ids.into_iter().map(|(class, set)| (class, set.len())).collect()
}

/// `finish`'s windows in the same form (channel-insensitive, as the device scores them).
fn finished_windows(report: &FinishReport) -> Vec<Value> {
    let windows = report.verification.as_ref().map_or(&[][..], |v| &v.windows[..]);
    windows
        .iter()
        .map(|w| json!({"score": w.channel_insensitive.score, "verified": w.channel_insensitive.verified}))
        .collect()
}

/// The generated drive through the product; the summary.
fn generated(args: &DemoArgs, progress: &Progress) -> Result<Value> {
    const STEPS: u32 = 7;
    let (out, seed, duration_s) = (&args.output, args.seed, args.duration);
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, e))?;
    let drive_dir = out.join("drive");
    let config =
        ScenarioConfig { duration_s, driver: args.driver, ..ScenarioConfig::drive(seed, args.profile, Receiver::Good) };
    let [lat, lon, height] = config.origin;
    let origin = Geodetic::new(lat, lon, height).map_err(Error::other)?;

    progress.step(
        1,
        STEPS,
        &format!(
            "generating a {duration_s:.0} s work-zone drive (seed {seed}, {} sensor profile) into {}",
            args.profile.name(),
            drive_dir.display()
        ),
    );
    let scenario = generate(&config);
    write_scenario(&scenario, &drive_dir).map_err(|e| Error::file(&drive_dir, e))?;

    progress.step(2, STEPS, "building the map tile from the road's OpenStreetMap");
    let tile = road_tile(&drive_dir, origin)?;
    let map_path = out.join("road.map");
    write_file(&map_path, &tile)?;
    let map = MapView::parse(&tile).map_err(Error::other)?;

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
        let drive = live::Drive { seed, seconds: duration_s, driver: args.driver, profile: args.profile };
        let live = live::record(drive, out, &log_path, &setup, &bar)?;
        bar.finish_and_clear();
        let r = &live.report;
        json!({"mode": "live", "frames_published": live.published, "frames_received": r.frames,
               "inputs_dropped": r.dropped, "issues": r.issues, "wall_s": live.seconds,
               "pipeline": r.stats})
    };
    let log = log::read(&log_path).map_err(Error::other)?;
    let log_bytes = log.bytes;

    progress.step(
        4,
        STEPS,
        match args.anchors {
            Anchors::Street => "finishing: the whole drive re-anchored with street-imagery anchors (simulated from the true path), tracks smoothed, verified per window",
            Anchors::None => "finishing: the whole drive re-anchored with GNSS and wheel speed, tracks smoothed, verified per window",
        },
    );
    let spinner =
        progress.spinner("solving; verifying the true drive, the online log and the finished log (both channel modes)");
    let anchors_path = out.join("anchors.csv");
    let _ = std::fs::remove_file(&anchors_path);
    let log_name = log_path.display().to_string();
    let recorded = Recorded {
        scenario: &scenario,
        drive_dir: &drive_dir,
        log: &log,
        log_name: &log_name,
        tile: &tile,
        setup: &setup,
    };
    let assessed = assess(&recorded, args.anchors, &anchors_path, None, Default::default())?;
    spinner.finish_and_clear();
    let finished_path = out.join("finished.d2slog");
    write_file(&finished_path, &assessed.finished_bytes)?;
    let finished_log = &assessed.finished_log;

    progress.step(5, STEPS, "judging the logs against the truth (anchoring, 3D tracks)");
    let classes = tracker_classes();
    let truth_tracking = evaluate_tracking::<64>(&scenario, tracker_config(&classes));

    progress.step(6, STEPS, "exporting MCAP (Foxglove), TUM (evo), GeoJSON (QGIS) and the nuPlan database and map");
    let mcap_path = out.join("drive.mcap");
    let messages: u64 = log::mcap_export::write(&log, Some(&map), &mcap_path, None)?.values().sum();
    let finished_mcap = out.join("finished.mcap");
    log::mcap_export::write(finished_log, Some(&map), &finished_mcap, None)?;
    write_file(&out.join("ego.tum"), log::export::tum(&log))?;
    write_file(&out.join("finished.tum"), log::export::tum(finished_log))?;
    write_file(&out.join("drive.geojson"), log::export::geojson(&log)?.to_string())?;
    let nuplan_dir = out.join("nuplan");
    let _ = std::fs::remove_dir_all(&nuplan_dir);
    let nuplan = dash2sim_export::nuplan::export(&dash2sim_export::nuplan::NuplanRequest {
        log: finished_log,
        log_name: &finished_path.display().to_string(),
        tile: &tile,
        map_name: &dash2sim_export::nuplan::map_name("road"),
        out: &nuplan_dir,
        scene_s: 5.0,
    });

    progress.step(7, STEPS, "drawing the drive (plot.png, plot.svg)");
    for name in ["plot.png", "plot.svg"] {
        dash2sim_verify::plot::plot(&dash2sim_verify::plot::PlotRequest {
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
    if assessed.anchors_text.is_some() {
        files.insert(
            3,
            json!({"what": "street-imagery anchors (simulated from the true path)", "path": file("anchors.csv")}),
        );
    }
    let nuplan_json = match &nuplan {
        Ok(n) => {
            files.push(json!({"what": "nuPlan log database", "path": n.db.display().to_string()}));
            files.push(json!({"what": "nuPlan map (GeoPackage)", "path": n.gpkg.display().to_string()}));
            json!({"db": n.db.display().to_string(), "map": n.gpkg.display().to_string(), "scenes": n.scenes,
                   "ego_states": n.ego_states})
        }
        // A short drive makes too few scenes: said, not fatal.
        Err(e) => json!({"error": e.to_string()}),
    };
    let (online_scale, online_scale_error) = assessed.online_scale.map_or((None, None), |(s, e)| (Some(s), Some(e)));
    let (online, finished) = (&assessed.online, &assessed.finished);
    let (finished_scale, true_mean_scale, finished_scale_error) = assessed.finished_scale;
    // A log without ego poses (never anchored) has nothing verified: null.
    let both = |b: Option<&dash2sim_sim::fidelity::drive::BothModes>| {
        b.map(|b| json!({"channel_insensitive": b.insensitive, "channel_sensitive": b.sensitive}))
            .unwrap_or_else(|| json!({"channel_insensitive": null, "channel_sensitive": null}))
    };
    Ok(json!({
        "seed": seed,
        "duration_s": duration_s,
        "driver": args.driver.name(),
        "profile": args.profile.name(),
        "anchors": args.anchors.name(),
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
                "anchors_used": assessed.finish_report.anchors.used,
                "ape_rmse_m": finished.judgement.ego_rmse,
                "ape_max_m": finished.judgement.ego_max,
                "scale": finished_scale,
                "scale_sigma_relative": assessed.finish_report.anchoring.scale_sigma_relative,
                "true_mean_scale": true_mean_scale,
                "scale_error": finished_scale_error,
            },
        },
        "tracking": {
            "online": judged_json(&online.judgement),
            "finished": judged_json(&finished.judgement),
            "tracker_fed_true_pose": {"mota": truth_tracking.metric("mota"), "idf1": truth_tracking.metric("idf1")},
            "tracks_by_class": tracks_by_class(&log),
            "finished_tracks_by_class": tracks_by_class(finished_log),
        },
        "verification": {
            "ground_truth": both(Some(&assessed.truth)),
            "online": both(online.verification.as_ref()),
            "finished": both(finished.verification.as_ref()),
            "windows_on_device": assessed.windows,
            "windows_finished": finished_windows(&assessed.finish_report),
        },
        "log": {"records": log.records.len(), "bytes": log_bytes, "bytes_per_minute": log_bytes as f64 / minutes,
                "damaged": log.stats.damaged, "finished_bytes": assessed.finished_bytes.len()},
        "mcap_messages": messages,
        "nuplan": nuplan_json,
        "files": files,
    }))
}

/// A judgement's figures as the demo's summary gives them.
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
