//! The demo: the whole product on a generated work-zone drive, by its own path, and what it
//! came to as a typed [`DemoReport`] (`dash2sim demo` renders it, human or `--json`).
//!
//! 1. generate the drive ([`crate::scenario`]) and its road as OpenStreetMap;
//! 2. build the map tile from the road's OSM;
//! 3. `record`, live ([`live`]): the camera process (`dash2sim scenario publish`, a child
//!    process) publishes frames, VO poses and detections over shared memory and writes the
//!    GNSS receiver's NMEA and the wheel-speed CAN frames into FIFOs at their rates; the
//!    logger subscribes and reads them, runs the on-device pipeline (anchoring, 3D/2D
//!    tracking, verification per 15 s window) and writes the 4D log. No ground truth goes
//!    in. Offline, the same drive is read from its files instead (one process, repeatable);
//! 4. `finish`: the log re-anchored offline with street-imagery anchors (simulated matches
//!    every 50 m, σ 0.3 m), tracks smoothed, verified per window;
//! 5. `verify` the true drive, the online log and the finished log, channel-insensitive
//!    and channel-sensitive;
//! 6. judge the online and the finished log against the truth the generator knows
//!    (anchoring error and scale, 3D tracks by motmetrics' metrics) — where the sweep
//!    judges its drives ([`crate::fidelity::drive::assess`]);
//! 7. export: MCAP (Foxglove), TUM (evo), GeoJSON (QGIS) and the nuPlan database and map;
//! 8. plot the drive.
//!
//! [`data`] runs the real recordings of a data folder instead ([`crate::datasets`]).
//!
//! The receiver is a good one (σ 1–2 m, errors correlated over 2 s, no multipath): with the
//! generator's default phone-grade GNSS the anchorer rightly declines to commit within 40 s.
//!
//! ```no_run
//! use dash2sim_sim::demo::{self, DemoRequest, Recording, Silent};
//! let request = DemoRequest {
//!     output: "demo-output".into(),
//!     seed: 1,
//!     duration_s: 20.0,
//!     driver: Default::default(),
//!     profile: Default::default(),
//!     anchors: Default::default(),
//!     recording: Recording::Offline,
//! };
//! let report = demo::run(&request, &Silent)?;
//! assert!(report.anchoring.finished.ape_rmse_m < 1.0);
//! # Ok::<(), dash2sim_sim::Error>(())
//! ```

pub mod data;
pub mod live;
mod report;

pub use report::{
    AnchoringReport, DemoReport, FinishedAnchoring, JudgedFigures, LogFigures, MotFigures, NuplanOutcome,
    OnlineAnchoring, RecordingReport, TrackingReport, Verdicts, VerificationReport, WindowVerdict,
};

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use serde::Serialize;

use crate::datasets::OutputFile;
use crate::fidelity::drive::{assess, Anchors, Assessment, Recorded};
use crate::scenario::evaluate::evaluate_tracking;
use crate::scenario::profile::{Profile, Receiver};
use crate::scenario::write::{road_tile, write_scenario};
use crate::scenario::{generate, tracker_classes, tracker_config, Driver, ScenarioConfig};
use crate::{Error, Field, Result};
use dash2sim_finish::FinishReport;
use dash2sim_linux::log::{self, LogContents};
use dash2sim_linux::record::{self, Setup};

/// What the demo says as it goes; the caller draws it (the library never prints).
pub trait Progress: Sync {
    /// Step `n` of `of` begins.
    fn step(&self, n: u32, of: u32, text: &str);
    /// Long work begins: `len` units of `text` (a bar), or of unknown length (`None`: a
    /// spinner saying `text`).
    fn begin(&self, len: Option<u64>, text: &str);
    /// The long work is at `position` of its units.
    fn at(&self, position: u64);
    /// The long work has ended.
    fn end(&self);
    /// Something the user should know that is not an error (a recording skipped or failed
    /// while the others run).
    fn note(&self, text: &str);
}

/// A [`Progress`] that says nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {
    fn step(&self, _: u32, _: u32, _: &str) {}
    fn begin(&self, _: Option<u64>, _: &str) {}
    fn at(&self, _: u64) {}
    fn end(&self) {}
    fn note(&self, _: &str) {}
}

/// How the drive is recorded.
#[derive(Clone, Copy, Debug)]
pub enum Recording {
    /// Live, as on a dashcam: a camera process publishes the drive ([`live`]).
    Live {
        /// How to start it.
        camera: live::CameraCommand,
    },
    /// From the drive's files, in this process (repeatable, no shared memory).
    Offline,
}

/// The longest drive the demo generates, s.
pub const MAX_DURATION_S: f64 = crate::scenario::command::MAX_DURATION_S;
/// The shortest, s: a verification window and a half.
pub const MIN_DURATION_S: f64 = 10.0;

/// What to run.
#[derive(Clone, Debug)]
pub struct DemoRequest {
    /// Output folder.
    pub output: PathBuf,
    /// Seed of the generated drive.
    pub seed: u64,
    /// Length of the drive, s ([`MIN_DURATION_S`]–[`MAX_DURATION_S`]).
    pub duration_s: f64,
    /// Who drives.
    pub driver: Driver,
    /// How far the sensors are from ideal.
    pub profile: Profile,
    /// Finishing's street-imagery anchors.
    pub anchors: Anchors,
    /// Live or from files.
    pub recording: Recording,
}

/// The summary file the demo writes into its output folder.
pub const SUMMARY_FILE: &str = "summary.json";

/// `report` as `summary.json` holds it, and `--json` prints it: its keys sorted.
pub fn summary_json(report: &impl Serialize) -> Result<String> {
    Ok(serde_json::to_value(report).map_err(Error::other)?.to_string())
}

fn write_file(path: &Path, contents: impl AsRef<[u8]>) -> Result<()> {
    std::fs::write(path, contents).map_err(|e| Error::file(path, e))
}

/// Distinct 3D tracks per class name.
fn tracks_by_class(log: &LogContents) -> BTreeMap<&'static str, usize> {
    let mut ids: BTreeMap<&'static str, BTreeSet<i64>> = BTreeMap::new();
    for (_, track) in log::views::tracks(log) {
        ids.entry(dash2sim_core::class::name_of(track.class)).or_default().insert(track.id);
    }
    ids.into_iter().map(|(class, set)| (class, set.len())).collect()
}

/// `finish`'s windows (channel-insensitive, as the device scores them).
fn finished_windows(report: &FinishReport) -> Vec<WindowVerdict> {
    let windows = report.verification.as_ref().map_or(&[][..], |v| &v.windows[..]);
    windows
        .iter()
        .map(|w| WindowVerdict { score: w.channel_insensitive.score, verified: w.channel_insensitive.verified })
        .collect()
}

/// The demo's steps, as its progress counts them.
const STEPS: u32 = 7;

/// Run the demo on the generated drive `request` asks for, into its output folder (with
/// `summary.json`); what it came to.
pub fn run(request: &DemoRequest, progress: &dyn Progress) -> Result<DemoReport> {
    let (out, seed, duration_s) = (&request.output, request.seed, request.duration_s);
    if !(duration_s.is_finite() && (MIN_DURATION_S..=MAX_DURATION_S).contains(&duration_s)) {
        return Err(Error::request(
            Field::Duration,
            format!("{duration_s} must be between {MIN_DURATION_S} and {MAX_DURATION_S} seconds"),
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, e))?;
    let drive_dir = out.join("drive");
    let config = ScenarioConfig {
        duration_s,
        driver: request.driver,
        ..ScenarioConfig::drive(seed, request.profile, Receiver::Good)
    };
    let [lat, lon, height] = config.origin;
    let origin = Geodetic::new(lat, lon, height).map_err(Error::other)?;

    progress.step(
        1,
        STEPS,
        &format!(
            "generating a {duration_s:.0} s work-zone drive (seed {seed}, {} sensor profile) into {}",
            request.profile.name(),
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
    let recording = record_drive(request, progress, &drive_dir, &log_path, &setup)?;
    let log = log::read(&log_path).map_err(Error::other)?;

    progress.step(
        4,
        STEPS,
        match request.anchors {
            Anchors::Street => "finishing: the whole drive re-anchored with street-imagery anchors (simulated from the true path), tracks smoothed, verified per window",
            Anchors::None => "finishing: the whole drive re-anchored with GNSS and wheel speed, tracks smoothed, verified per window",
        },
    );
    progress.begin(None, "solving; verifying the true drive, the online log and the finished log (both channel modes)");
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
    let assessed = assess(&recorded, request.anchors, &anchors_path, None, Default::default());
    progress.end();
    let assessed = assessed?;
    let finished_path = out.join("finished.d2slog");
    write_file(&finished_path, &assessed.finished_bytes)?;
    let finished_log = &assessed.finished_log;

    progress.step(5, STEPS, "judging the logs against the truth (anchoring, 3D tracks)");
    let classes = tracker_classes();
    let truth_tracking = evaluate_tracking::<64>(&scenario, tracker_config(&classes));

    progress.step(6, STEPS, "exporting MCAP (Foxglove), TUM (evo), GeoJSON (QGIS) and the nuPlan database and map");
    let (messages, nuplan) = export_logs(out, &log, finished_log, &finished_path, &map, &tile)?;

    progress.step(7, STEPS, "drawing the drive (plot.png, plot.svg)");
    for name in ["plot.png", "plot.svg"] {
        dash2sim_verify::plot::plot(&dash2sim_verify::plot::PlotRequest {
            log: log_path.clone(),
            map: Some(map_path.clone()),
            finished: Some(finished_path.clone()),
            output: out.join(name),
        })?;
    }

    let (files, nuplan) = output_files(out, assessed.anchors_text.is_some(), nuplan);
    let (online, finished) = (&assessed.online, &assessed.finished);
    let report = DemoReport {
        seed,
        duration_s,
        driver: request.driver,
        profile: request.profile,
        anchors: request.anchors,
        recording,
        anchoring: anchoring_report(&assessed, scenario.frames.len()),
        tracking: TrackingReport {
            online: (&online.judgement).into(),
            finished: (&finished.judgement).into(),
            tracker_fed_true_pose: MotFigures {
                mota: truth_tracking.metric("mota"),
                idf1: truth_tracking.metric("idf1"),
            },
            tracks_by_class: tracks_by_class(&log),
            finished_tracks_by_class: tracks_by_class(finished_log),
        },
        verification: VerificationReport {
            ground_truth: Some(&assessed.truth).into(),
            online: online.verification.as_ref().into(),
            finished: finished.verification.as_ref().into(),
            windows_on_device: assessed.windows.clone(),
            windows_finished: finished_windows(&assessed.finish_report),
        },
        log: LogFigures {
            records: log.records.len(),
            bytes: log.bytes,
            bytes_per_minute: log.bytes as f64 / (duration_s / 60.0),
            damaged: log.stats.damaged,
            finished_bytes: assessed.finished_bytes.len(),
        },
        mcap_messages: messages,
        nuplan,
        files,
    };
    write_file(&out.join(SUMMARY_FILE), summary_json(&report)?)?;
    Ok(report)
}

/// Step 3: the drive recorded from its files or live (a camera process over shared memory,
/// NMEA on a FIFO, CAN frames), its log written to `log_path`.
fn record_drive(
    request: &DemoRequest,
    progress: &dyn Progress,
    drive_dir: &Path,
    log_path: &Path,
    setup: &Setup,
) -> Result<RecordingReport> {
    Ok(match &request.recording {
        Recording::Offline => {
            progress.step(
                3,
                STEPS,
                "recording from the drive's files: the on-device pipeline over VO, NMEA, CAN and detections",
            );
            let (stream, _) = record::read_sources(&record::Sources::scenario(drive_dir))?;
            let recording = record::run_stream(&stream, setup)?;
            write_file(log_path, &recording.log)?;
            RecordingReport::Offline { inputs: recording.inputs, pipeline: record::summary(&recording) }
        }
        Recording::Live { camera } => {
            progress.step(
                3,
                STEPS,
                "recording live: the camera process publishes over shared memory, GNSS arrives as NMEA on a FIFO, speed as CAN frames",
            );
            progress.begin(Some(request.duration_s.ceil() as u64), "s of the drive");
            let drive = live::Drive {
                seed: request.seed,
                seconds: request.duration_s,
                driver: request.driver,
                profile: request.profile,
            };
            let live = live::record(drive, *camera, &request.output, log_path, setup, progress);
            progress.end();
            let live = live?;
            let r = &live.report;
            RecordingReport::Live {
                frames_published: live.published,
                frames_received: r.frames,
                inputs_dropped: r.dropped,
                issues: r.issues,
                wall_s: live.seconds,
                pipeline: r.stats,
            }
        }
    })
}

/// Step 6: the device's and the finished log exported (MCAP, TUM, GeoJSON; the finished one
/// to nuPlan, whose failure is reported, not fatal). The MCAP messages written, and nuPlan's
/// outcome.
fn export_logs(
    out: &Path,
    log: &LogContents,
    finished_log: &LogContents,
    finished_path: &Path,
    map: &MapView<'_>,
    tile: &[u8],
) -> Result<(u64, Result<dash2sim_export::nuplan::NuplanExport>)> {
    let messages: u64 = dash2sim_export::mcap::write(log, Some(map), &out.join("drive.mcap"), None)?.values().sum();
    dash2sim_export::mcap::write(finished_log, Some(map), &out.join("finished.mcap"), None)?;
    write_file(&out.join("ego.tum"), dash2sim_export::tum::tum(log))?;
    write_file(&out.join("finished.tum"), dash2sim_export::tum::tum(finished_log))?;
    write_file(&out.join("drive.geojson"), dash2sim_export::geojson::geojson(log)?.to_string())?;
    let nuplan_dir = out.join("nuplan");
    let _ = std::fs::remove_dir_all(&nuplan_dir);
    let nuplan = dash2sim_export::nuplan::export(&dash2sim_export::nuplan::NuplanRequest {
        log: finished_log,
        log_name: &finished_path.display().to_string(),
        tile,
        map_name: &dash2sim_export::nuplan::map_name("road"),
        out: &nuplan_dir,
        scene_s: 5.0,
    });

    Ok((messages, nuplan))
}

/// What the demo wrote, for its summary, and nuPlan's outcome (its two files when written).
fn output_files(
    out: &Path,
    with_anchors: bool,
    nuplan: Result<dash2sim_export::nuplan::NuplanExport>,
) -> (Vec<OutputFile>, NuplanOutcome) {
    let file = |what, name: &str| OutputFile::new(what, out, name);
    let mut files = vec![
        file("the generated drive (truth, sensor streams, road OSM)", "drive"),
        file("map tile", "road.map"),
        file("the device's 4D log", "drive.d2slog"),
        file("the finished 4D log", "finished.d2slog"),
        file("MCAP for Foxglove (the device's log)", "drive.mcap"),
        file("MCAP for Foxglove (finished)", "finished.mcap"),
        file("TUM for evo (the device's log)", "ego.tum"),
        file("TUM for evo (finished)", "finished.tum"),
        file("GeoJSON for QGIS", "drive.geojson"),
        file("the picture", "plot.png"),
        file("the picture (vector)", "plot.svg"),
        file("this summary", SUMMARY_FILE),
    ];
    if with_anchors {
        files.insert(3, file("street-imagery anchors (simulated from the true path)", "anchors.csv"));
    }
    let nuplan = match nuplan {
        Ok(n) => {
            files.push(OutputFile { what: "nuPlan log database", path: n.db.display().to_string() });
            files.push(OutputFile { what: "nuPlan map (GeoPackage)", path: n.gpkg.display().to_string() });
            NuplanOutcome::Written {
                db: n.db.display().to_string(),
                map: n.gpkg.display().to_string(),
                scenes: n.scenes,
                ego_states: n.ego_states,
            }
        }
        Err(e) => NuplanOutcome::NotWritten { error: e.to_string() },
    };
    (files, nuplan)
}

/// How the device's log and the finished one are anchored against the truth.
fn anchoring_report(assessed: &Assessment, frames: usize) -> AnchoringReport {
    let (online, finished) = (&assessed.online, &assessed.finished);
    let (finished_scale, true_mean_scale, finished_scale_error) = assessed.finished_scale;
    AnchoringReport {
        online: OnlineAnchoring {
            observable_after_s: online.judgement.first_anchored_s,
            anchored_frames: online.judgement.ego_errors.len(),
            frames,
            ape_rmse_m: online.judgement.ego_rmse,
            ape_max_m: online.judgement.ego_max,
            scale_at_end: assessed.online_scale.map(|(scale, _)| scale),
            scale_error: assessed.online_scale.map(|(_, error)| error),
        },
        finished: FinishedAnchoring {
            anchors_used: assessed.finish_report.anchors.used,
            ape_rmse_m: finished.judgement.ego_rmse,
            ape_max_m: finished.judgement.ego_max,
            scale: finished_scale,
            scale_sigma_relative: assessed.finish_report.anchoring.scale_sigma_relative,
            true_mean_scale,
            scale_error: finished_scale_error,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// A [`Progress`] that keeps what it was told.
    #[derive(Default)]
    struct Told(Mutex<Vec<String>>);

    impl Told {
        fn push(&self, text: String) {
            self.0.lock().expect("not poisoned").push(text);
        }
    }

    impl Progress for Told {
        fn step(&self, n: u32, of: u32, _: &str) {
            self.push(format!("step {n}/{of}"));
        }
        fn begin(&self, len: Option<u64>, _: &str) {
            self.push(format!("begin {len:?}"));
        }
        fn at(&self, position: u64) {
            self.push(format!("at {position}"));
        }
        fn end(&self) {
            self.push("end".to_owned());
        }
        fn note(&self, text: &str) {
            self.push(format!("note {text}"));
        }
    }

    fn request(output: PathBuf, duration_s: f64) -> DemoRequest {
        DemoRequest {
            output,
            seed: 3,
            duration_s,
            driver: Driver::Careful,
            profile: Profile::Ideal,
            anchors: Anchors::Street,
            recording: Recording::Offline,
        }
    }

    #[test]
    fn an_offline_demo_reports_its_steps_its_files_and_the_summary_it_wrote() {
        let dir = std::env::temp_dir().join(format!("dash2sim-demo-lib-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let told = Told::default();
        let report = run(&request(dir.clone(), 12.0), &told).expect("the demo runs");
        let told = told.0.into_inner().expect("not poisoned");
        let steps: Vec<&String> = told.iter().filter(|t| t.starts_with("step")).collect();
        assert_eq!(steps, (1..=7).map(|n| format!("step {n}/7")).collect::<Vec<_>>().iter().collect::<Vec<_>>());
        assert!(told.windows(2).any(|w| w == ["begin None", "end"]), "finishing's spinner: {told:?}");
        assert!(matches!(report.recording, RecordingReport::Offline { inputs, .. } if inputs > 0));
        assert_eq!(report.recording.pipeline().vo_poses, report.anchoring.online.frames as u64);
        for file in &report.files {
            assert!(Path::new(&file.path).exists(), "{} ({}) was not written", file.path, file.what);
        }
        let written = std::fs::read_to_string(dir.join(SUMMARY_FILE)).expect("summary.json");
        assert_eq!(written, summary_json(&report).expect("JSON"));
        let json: serde_json::Value = serde_json::from_str(&written).expect("summary.json parses");
        assert_eq!(json["driver"], "careful");
        assert_eq!(json["recording"]["mode"], "offline");
        assert_eq!(json["anchoring"]["finished"]["anchors_used"], report.anchoring.finished.anchors_used);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_drive_too_short_or_too_long_is_refused_as_the_drive_s_length() {
        for seconds in [5.0, 601.0, f64::NAN] {
            let dir = std::env::temp_dir().join(format!("dash2sim-demo-lib-short-{}", std::process::id()));
            let e = run(&request(dir.clone(), seconds), &Silent).expect_err("refused");
            assert!(matches!(e, Error::Request { field: Field::Duration, .. }), "{e}");
            assert!(!dir.exists(), "nothing is written for a refused request");
        }
    }
}
