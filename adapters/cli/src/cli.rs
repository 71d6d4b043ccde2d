//! The `dash2sim` command line (docs/cli.md). `main.rs` only calls [`run`].
//!
//! Every subcommand has `--help`; `--json` prints machine-readable JSON on stdout;
//! errors go to stderr with a non-zero exit status.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use dash2sim_core::traj::{Delta, RpePairs, Statistics};
use serde_json::json;

use dash2sim_core::geo::Geodetic;
use dash2sim_linux::ingest::can::{SignalName, SpeedUnit};
use dash2sim_linux::ingest::map_tile::parse_bbox;
use dash2sim_linux::ingest::origin::parse_origin;
use dash2sim_linux::sync::DEFAULT_MAX_DIFF_S;
use dash2sim_linux::trajectory::Format;
use dash2sim_linux::{Error, Result};
use dash2sim_verify::evaluate::{self, Align, Evaluation, Relation};

/// dash2sim: metric, geo-referenced 4D driving logs from a dashcam.
#[derive(Debug, Parser)]
// The about line is the one `dash2sim-linux` described itself with when it held the binary
// (the move into this crate changes no output; tests/golden).
#[command(
    name = "dash2sim",
    version,
    about = "std adapters and the dash2sim command line: trajectory files, exports, shared memory",
    long_about = None
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Trajectory evaluation with evo's definitions (APE, RPE).
    #[command(subcommand)]
    Traj(TrajCommand),
    /// Anchor a VO trajectory (unknown scale) to GNSS positions and wheel speed.
    Anchor(crate::anchor::AnchorArgs),
    /// NMEA 0183 captures.
    #[command(subcommand)]
    Nmea(NmeaCommand),
    /// CAN captures (candump): NMEA 2000, J1939, OBD-II and DBC-defined signals.
    #[command(subcommand)]
    Can(CanCommand),
    /// Track 2D detections (MOTChallenge CSV; id column may be -1) with the ByteTrack-style
    /// tracker; tracks are written as MOTChallenge CSV.
    Track2d {
        /// Detections.
        detections: PathBuf,
        /// Output tracks.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Multi-object tracking evaluation (MOTChallenge files).
    #[command(subcommand)]
    Mot(MotCommand),
    /// Generated work-zone drives: ground truth and sensor streams (docs/scenario.md).
    #[command(subcommand)]
    Scenario(ScenarioCommand),
    /// Map tiles from OpenStreetMap (docs/map-tile.md).
    #[command(subcommand)]
    Map(MapCommand),
    /// The whole product on a generated work-zone drive: a camera process publishing over
    /// shared memory, GNSS as NMEA and speed as CAN frames, `record`, `finish`, `verify`,
    /// the exports (MCAP, TUM, GeoJSON, nuPlan) and `plot` (docs/demo.md).
    Demo(crate::demo::DemoArgs),
    /// Turn existing recordings (NMEA capture, candump log with DBC files, trajectory,
    /// objects) into a 4D log, in time order (docs/binlog.md).
    Import(ImportArgs),
    /// Run the on-device pipeline over recorded inputs (VO, the GNSS serial capture, the
    /// vehicle bus, 3D and 2D detections) and write the 4D log (docs/pipeline.md).
    Record(Box<crate::record::RecordArgs>),
    /// Finish a device's log offline: re-anchor the whole drive at once from VO, GNSS,
    /// wheel speed and optional external anchors, smooth the 3D tracks, verify per window
    /// (docs/finishing.md).
    Finish(Box<crate::finish::FinishArgs>),
    /// Draw a drive: bird's-eye view (map lanes, GNSS fixes, online and finished ego, 3D
    /// tracks by class) above speed and verification over time (docs/plot.md).
    Plot(crate::plot::PlotArgs),
    /// What a 4D log holds: header, records per type, time span, gaps, damage, bytes.
    Inspect {
        /// The log, or a live recording's folder.
        log: PathBuf,
        /// Check every segment's signature against this public key (64 hex digits, or the
        /// `.pub` file of `keygen`): ok / unsigned / bad signature / chain broken / another
        /// key, per segment; a folder's files are checked in recording order, one chain.
        /// Exits with failure when a segment is not ok.
        #[arg(long, value_name = "PUB")]
        verify_key: Option<String>,
        /// Also list the log's events: time, level and text of every message the device
        /// wrote (refused inputs, anchoring, dropped inputs, …).
        #[arg(long)]
        events: bool,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// A new device key pair for signed logs: PREFIX.key (secret, for `record --key`) and
    /// PREFIX.pub (for `inspect --verify-key`, `finish --require-signed`).
    Keygen {
        /// Where the two files go: PREFIX.key and PREFIX.pub.
        #[arg(short, long, value_name = "PREFIX")]
        output: PathBuf,
    },
    /// Export a 4D log: MCAP with Foxglove schemas, TUM (evo), GeoJSON (QGIS), nuPlan
    /// (log database and map; docs/nuplan.md).
    Export(Box<crate::export::ExportArgs>),
    /// Replay a recorded ego trajectory against a map tile and score it as nuPlan would;
    /// a log is verified above 90 (docs/verify.md).
    Verify(crate::verify::VerifyArgs),
}

#[derive(Debug, clap::Args)]
struct ImportArgs {
    /// Output log.
    #[arg(short, long)]
    output: PathBuf,
    /// NMEA 0183 capture → GNSS fixes.
    #[arg(long)]
    nmea: Option<PathBuf>,
    /// Seconds added to NMEA (UTC) times to put them on the other sources' clock.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    nmea_offset: f64,
    /// candump log → vehicle speeds (NMEA 2000 SOG, J1939 CCVS1, OBD-II 0x0D, DBC).
    #[arg(long)]
    can: Option<PathBuf>,
    /// DBC files for the CAN log (repeatable).
    #[arg(long)]
    dbc: Vec<PathBuf>,
    /// The DBC signal carrying vehicle speed, `MESSAGE.SIGNAL`.
    #[arg(long, value_name = "MESSAGE.SIGNAL")]
    speed_signal: Option<SignalName>,
    /// Unit of that signal: km/h, m/s or mph.
    #[arg(long, default_value = "km/h")]
    speed_unit: SpeedUnit,
    /// TUM trajectory (ENU around --origin, rear axle) → ego poses.
    #[arg(long)]
    traj: Option<PathBuf>,
    /// Objects CSV (the scenario format) → 3D tracks.
    #[arg(long)]
    objects: Option<PathBuf>,
    /// ENU origin `LAT,LON[,H]` of the header; default: the first GNSS fix.
    #[arg(long, value_name = "LAT,LON[,H]", allow_hyphen_values = true, value_parser = parse_origin)]
    origin: Option<Geodetic>,
}

#[derive(Debug, Subcommand)]
enum MapCommand {
    /// Build a map tile from an OSM file (.osm XML or .osm.pbf): drivable highway ways →
    /// lanes in a local ENU frame, with a grid index.
    Build {
        /// The OpenStreetMap file.
        osm: PathBuf,
        /// Output tile.
        #[arg(short, long)]
        output: PathBuf,
        /// ENU origin `LAT,LON[,H]` (degrees, metres above the ellipsoid), kept in the tile
        /// (a log recorded with the tile takes it); default: the centre of the roads, height 0.
        #[arg(long, value_name = "LAT,LON[,H]", allow_hyphen_values = true, value_parser = parse_origin)]
        origin: Option<Geodetic>,
        /// Keep only the part inside `WEST,SOUTH,EAST,NORTH` (degrees, as osmium and the
        /// OSM API order them); ways are cut at the box.
        #[arg(long, value_name = "W,S,E,N", allow_hyphen_values = true, value_parser = parse_bbox)]
        bbox: Option<[f64; 4]>,
        /// Grid cell size, metres.
        #[arg(long, default_value_t = dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M)]
        cell: f64,
    },
    /// Describe a map tile: origin, source counts, lanes, lane-km, bytes.
    Info {
        /// The tile.
        map: PathBuf,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Print every lane of a tile as JSON in its ENU frame: centreline, width, speed
    /// limit, neighbours, successors, area polygon (for inspection and cross-checks).
    Lanes {
        /// The tile.
        map: PathBuf,
    },
    /// Check the ego footprint (nuPlan's Pacifica) at each pose of a TUM file against the
    /// drivable area, and time the check per pose (the fastest of several passes).
    Check {
        /// The tile.
        map: PathBuf,
        /// Rear-axle poses, TUM, in the tile's ENU frame.
        #[arg(long)]
        poses: PathBuf,
        /// Passes over the poses; the fastest is reported.
        #[arg(long, default_value_t = 5)]
        passes: u32,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Write a tile's roads (or an OpenStreetMap file's, built into a tile around their
    /// centre) in another format: OpenDRIVE 1.7 (docs/openscenario.md).
    Export {
        /// The tile or OpenStreetMap file.
        map: PathBuf,
        /// OpenDRIVE output.
        #[arg(long, value_name = "F.xodr")]
        opendrive: PathBuf,
    },
}

#[derive(Debug, Subcommand)]
enum ScenarioCommand {
    /// Generate a drive and write its truth and sensor streams to a folder (TUM, NMEA,
    /// CSV, MOTChallenge, OSM).
    Generate {
        /// Output folder (created if missing).
        #[arg(short, long)]
        output: PathBuf,
        /// The seed that names the scenario.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Length of the drive, seconds.
        #[arg(long, default_value_t = 40.0)]
        duration: f64,
        /// The GNSS receiver: `phone` (σ 3–10 m, multipath) or `good` (σ 1–2 m, the demo's).
        #[arg(long, value_parser = dash2sim_args::Receiver::parser(), default_value = "phone")]
        receiver: dash2sim_sim::scenario::profile::Receiver,
        /// How far the sensors are from ideal (docs/scenario.md): `ideal` (the old, kind
        /// simulator), `typical` (a consumer dashcam) or `hard`.
        #[arg(long, value_parser = dash2sim_args::Profile::parser(), default_value = "typical")]
        profile: dash2sim_sim::scenario::profile::Profile,
        /// How the ego is driven: `careful`, `careless` (clips the taper's drums),
        /// `shoulder`, `oncoming`, `speeding`, `tailgating`, `harsh`, `knife-edge`; `both` or
        /// `all` write one folder per driver under OUTPUT (docs/scenario.md).
        #[arg(long, value_parser = dash2sim_sim::scenario::Drivers::parse, default_value = "careful")]
        driver: dash2sim_sim::scenario::Drivers,
    },
    /// Be the camera process: publish a generated drive over shared memory (iceoryx2) at its
    /// frame rate, and optionally the GNSS receiver's NMEA and the wheel-speed CAN frames
    /// to a serial device, FIFO or file (docs/bridge.md). Prints `N frames published` (with
    /// `--json`, what was published per kind).
    Publish(dash2sim_args::PublishArgs),
    /// Generate a corpus of device logs as a fleet uploads them: drives of several seeds,
    /// lengths, regions and drivers recorded through the pipeline, each with its map tile,
    /// some damaged on purpose (docs/fleet.md).
    Corpus(crate::scenario::CorpusArgs),
    /// Run many generated drives through the product (generate → record from the device's
    /// files → finish → verify truth, online and finished, both channel modes) in parallel
    /// and measure how often each log's verdict equals the truth's: runs.csv, runs.jsonl,
    /// summary.json, sweep.png (docs/fidelity.md).
    Sweep(crate::scenario::SweepArgs),
    /// Run the 3D track manager over a generated drive and judge it: MOTA/IDF1 at 2 m,
    /// position RMSE of detections, filtered and smoothed tracks, static/dynamic accuracy.
    Eval {
        /// The seed that names the scenario.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Length of the drive, seconds.
        #[arg(long, default_value_t = 40.0)]
        duration: f64,
        /// How far the sensors are from ideal: `ideal`, `typical` or `hard`.
        #[arg(long, value_parser = dash2sim_args::Profile::parser(), default_value = "typical")]
        profile: dash2sim_sim::scenario::profile::Profile,
        /// Missed frames before a track is dropped (AB3DMOT: 2).
        #[arg(long, default_value_t = 4)]
        max_age: u32,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Debug, Subcommand)]
enum MotCommand {
    /// CLEAR-MOT and identity metrics of TEST against GT with motmetrics' definitions
    /// (IoU distance, pairs with IoU < 1 − max-distance never match).
    Eval {
        /// Ground truth, MOTChallenge CSV (`frame,id,left,top,width,height,conf,...`).
        gt: PathBuf,
        /// Tracker output, same format.
        test: PathBuf,
        /// Largest 1 − IoU that may match (motmetrics' `distth`).
        #[arg(long, default_value_t = 0.5)]
        max_distance: f64,
        /// Print JSON (motmetrics' metric names) on stdout.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Debug, Subcommand)]
enum CanCommand {
    /// Decode a candump capture (any of its three text dialects): one message per line
    /// and a summary; problems on stderr with their line numbers.
    Decode {
        /// The capture.
        file: PathBuf,
        /// DBC files for vendor-specific ids (repeatable; later files win on equal ids).
        #[arg(long = "dbc", value_name = "F.dbc")]
        dbc: Vec<PathBuf>,
        /// JSON lines on stdout.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Debug, Subcommand)]
enum NmeaCommand {
    /// Decode a capture: one fix per epoch (gpsd TPV names) and a summary; problems on
    /// stderr with their line numbers.
    Decode {
        /// The capture (raw receiver output).
        file: PathBuf,
        /// JSON lines on stdout.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Debug, Subcommand)]
enum TrajCommand {
    /// Absolute pose error of EST against REF.
    Ape(ApeArgs),
    /// Relative pose error of EST against REF.
    Rpe(RpeArgs),
}

#[derive(Debug, Args)]
struct CommonArgs {
    /// Reference trajectory (ground truth).
    reference: PathBuf,
    /// Estimated trajectory.
    estimate: PathBuf,
    /// File format (`euroc`: reference is an EuRoC ground-truth CSV, estimate TUM).
    #[arg(long, value_parser = dash2sim_args::Format::parser(), default_value = "tum")]
    format: Format,
    /// Alignment of the estimate to the reference before measuring.
    #[arg(long, value_parser = dash2sim_args::Align::parser(), default_value = "none")]
    align: Align,
    /// Which pose error to measure.
    #[arg(long, short = 'r', value_parser = dash2sim_args::Relation::parser(), default_value = "trans")]
    pose_relation: Relation,
    /// Largest timestamp difference for association, s.
    #[arg(long, default_value_t = DEFAULT_MAX_DIFF_S)]
    max_diff: f64,
    /// Added to the estimate's timestamps before association, s (evo's `--t_offset`): e.g.
    /// `-1780300800` to compare a log's export (UTC) with a generated drive's truth (seconds
    /// from its start, 2026-06-01T08:00:00Z).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    t_offset: f64,
    /// Print JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Args)]
struct ApeArgs {
    #[command(flatten)]
    common: CommonArgs,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum DeltaUnit {
    /// Frames (poses).
    Frames,
    /// Metres of travelled path.
    M,
}

#[derive(Debug, Args)]
struct RpeArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// Pair spacing, in `--unit`.
    #[arg(long, default_value_t = 1.0)]
    delta: f64,
    /// Unit of `--delta`.
    #[arg(long, value_enum, default_value = "frames")]
    unit: DeltaUnit,
    /// Use every pair at that spacing, not only consecutive ones.
    #[arg(long)]
    all_pairs: bool,
    /// Choose metre-spaced pairs on the reference path (evo's default is the estimate's).
    #[arg(long)]
    pairs_from_reference: bool,
}

/// Parse the process arguments and run; the exit code tells success.
pub fn run() -> ExitCode {
    let cli = Cli::parse();
    // Output piped into `head` ends the process quietly, as for any Unix tool, instead of a
    // panic in `println!` (Rust ignores SIGPIPE by default). Logs are closed before any
    // command prints, so nothing is lost. Not for the camera process: its FIFOs' reader (a
    // logger) may be killed and come back, and a write to a FIFO without one is an error it
    // counts, not the end of the camera.
    if !matches!(cli.command, Command::Scenario(ScenarioCommand::Publish(_))) {
        sigpipe::reset();
    }
    let result = match cli.command {
        Command::Traj(TrajCommand::Ape(args)) => traj_ape(&args),
        Command::Traj(TrajCommand::Rpe(args)) => traj_rpe(&args),
        Command::Anchor(args) => crate::anchor::run(&args),
        Command::Nmea(NmeaCommand::Decode { file, json }) => crate::decode::nmea(&file, json),
        Command::Can(CanCommand::Decode { file, dbc, json }) => crate::decode::can(&file, &dbc, json),
        Command::Track2d { detections, output } => track2d(&detections, &output),
        Command::Mot(MotCommand::Eval { gt, test, max_distance, json }) => mot_eval(&gt, &test, max_distance, json),
        Command::Scenario(ScenarioCommand::Generate { output, seed, duration, receiver, profile, driver }) => {
            crate::scenario::generate_to(seed, duration, profile, receiver, driver, &output)
        }
        Command::Scenario(ScenarioCommand::Publish(args)) => dash2sim_sim::scenario::publish::run(&(&args).into())
            .map(|published| println!("{}", args.render(&published))),
        Command::Scenario(ScenarioCommand::Corpus(args)) => crate::scenario::corpus(&args),
        Command::Scenario(ScenarioCommand::Sweep(args)) => crate::scenario::sweep(&args),
        Command::Scenario(ScenarioCommand::Eval { seed, duration, profile, max_age, json }) => {
            crate::scenario::eval(seed, duration, profile, max_age, json)
        }
        Command::Map(MapCommand::Build { osm, output, origin, bbox, cell }) => {
            crate::map::build(&osm, &output, origin, bbox, cell)
        }
        Command::Map(MapCommand::Info { map, json }) => crate::map::info(&map, json),
        Command::Map(MapCommand::Lanes { map }) => crate::map::lanes(&map),
        Command::Map(MapCommand::Export { map, opendrive }) => crate::map::export(&map, &opendrive),
        Command::Map(MapCommand::Check { map, poses, passes, json }) => crate::map::check(&map, &poses, passes, json),
        Command::Import(a) => import(&dash2sim_linux::log::import::ImportRequest {
            output: a.output,
            nmea: a.nmea,
            nmea_offset_s: a.nmea_offset,
            can: a.can,
            dbc: a.dbc,
            speed_signal: a.speed_signal,
            speed_unit: a.speed_unit,
            traj: a.traj,
            objects: a.objects,
            origin: a.origin,
        }),
        Command::Demo(args) => crate::demo::run(&args),
        Command::Record(args) => crate::record::run(&args),
        Command::Finish(args) => crate::finish::run(&args),
        Command::Plot(args) => crate::plot::run(args),
        Command::Inspect { log, verify_key: Some(key), json, .. } => crate::inspect::verify_key(&log, &key, json),
        Command::Inspect { log, events, json, verify_key: None } => crate::inspect::run(&log, events, json),
        Command::Keygen { output } => crate::inspect::keygen(&output),
        Command::Export(args) => crate::export::run(*args),
        Command::Verify(a) => crate::verify::run(&a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("dash2sim: error: {}", dash2sim_args::errors::message(&e));
            ExitCode::FAILURE
        }
    }
}

fn traj_ape(args: &ApeArgs) -> Result<()> {
    let c = &args.common;
    check_max_diff(c.max_diff)?;
    let (r, e) = load_pair(c)?;
    let eval = evaluate::ape(&r, &e, c.align, c.pose_relation).map_err(eval_error)?;
    report("APE", c, &eval, None);
    Ok(())
}

fn traj_rpe(args: &RpeArgs) -> Result<()> {
    let c = &args.common;
    check_max_diff(c.max_diff)?;
    let delta = match args.unit {
        DeltaUnit::Frames if args.delta >= 1.0 && args.delta.fract() == 0.0 && args.delta < 1e9 => {
            Delta::Frames(args.delta as usize)
        }
        DeltaUnit::Frames => {
            return Err(Error::invalid(format!("--delta {} is not a whole number of frames ≥ 1", args.delta)))
        }
        DeltaUnit::M if args.delta.is_finite() && args.delta > 0.0 => Delta::Metres(args.delta),
        DeltaUnit::M => return Err(Error::invalid(format!("--delta {} m must be positive", args.delta))),
    };
    let pairs = RpePairs { delta, all_pairs: args.all_pairs, from_reference: args.pairs_from_reference };
    let (r, e) = load_pair(c)?;
    let eval = evaluate::rpe(&r, &e, c.align, c.pose_relation, pairs).map_err(eval_error)?;
    report("RPE", c, &eval, Some(args));
    Ok(())
}

fn load_pair(
    c: &CommonArgs,
) -> Result<(dash2sim_linux::trajectory::Trajectory, dash2sim_linux::trajectory::Trajectory)> {
    if !c.t_offset.is_finite() {
        return Err(Error::invalid(format!("--t-offset {} must be a number of seconds", c.t_offset)));
    }
    let association = evaluate::Association { max_diff: c.max_diff, t_offset: c.t_offset };
    evaluate::load_pair(&c.reference, &c.estimate, c.format, association).map_err(eval_error)
}

/// A comparison's error; where too few poses matched and the files' spans are known, the
/// flag that shifts the estimate's times is named beside the offsets the message suggests.
fn eval_error(e: evaluate::EvalError) -> Error {
    match e {
        evaluate::EvalError::TooFewMatches { spans: Some(_), .. } => {
            Error::invalid(format!("{e} (the time offset is --t-offset)"))
        }
        other => Error::other(other),
    }
}

fn mot_eval(gt: &std::path::Path, test: &std::path::Path, max_distance: f64, as_json: bool) -> Result<()> {
    if !(0.0..=1.0).contains(&max_distance) {
        return Err(Error::invalid(format!("--max-distance {max_distance} must be within [0, 1]")));
    }
    let (gt, test) =
        (dash2sim_linux::ingest::motchallenge::read_mot(gt)?, dash2sim_linux::ingest::motchallenge::read_mot(test)?);
    let summary = dash2sim_verify::mot::summarize(&dash2sim_verify::mot::compare(&gt, &test, max_distance));
    if as_json {
        println!("{}", crate::render::json_of(&summary)?);
    } else {
        for (name, value) in &summary.values {
            println!("{name:>20}  {value}");
        }
    }
    Ok(())
}

/// `dash2sim track2d`: the problems of the file and the summary on stderr.
fn track2d(detections: &std::path::Path, output: &std::path::Path) -> Result<()> {
    let rows = dash2sim_linux::ingest::motchallenge::read_mot(detections)?;
    let (tracks, stats, skipped) = dash2sim_linux::record::track2d::track(&rows);
    for (_, message) in &skipped {
        eprintln!("{}: {message}", detections.display());
    }
    dash2sim_linux::ingest::motchallenge::write_mot(output, &tracks).map_err(|e| Error::file(output, e))?;
    let ids: std::collections::BTreeSet<i64> = tracks.iter().map(|r| r.id).collect();
    eprintln!(
        "{} frames, {} detections → {} tracks, {} boxes; rejected {} detections, dropped {}, {} rows out of order, {} track candidates dropped",
        stats.frames,
        rows.len(),
        ids.len(),
        tracks.len(),
        stats.rejected_detections,
        stats.dropped_detections,
        skipped.len(),
        stats.dropped_tracks
    );
    Ok(())
}

/// `dash2sim import`: the captures' problems on stderr, what was written on stdout.
fn import(request: &dash2sim_linux::log::import::ImportRequest) -> Result<()> {
    let imported = dash2sim_linux::log::import::import(request, &mut |problem| eprintln!("{problem}"))?;
    let counts: Vec<String> = imported.by_kind.iter().map(|(k, v)| format!("{v} {k}")).collect();
    println!(
        "{}: {} records ({}) over {:.1} s, {} bytes ({:.0} bytes per minute)",
        request.output.display(),
        imported.records,
        counts.join(", "),
        imported.span_s,
        imported.bytes,
        imported.bytes as f64 / (imported.span_s / 60.0).max(1e-9)
    );
    Ok(())
}

fn check_max_diff(max_diff: f64) -> Result<()> {
    if max_diff.is_finite() && max_diff >= 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(format!("--max-diff {max_diff} must be a non-negative number of seconds")))
    }
}

/// Statistics with evo's key names.
pub fn stats_json(s: &Statistics) -> serde_json::Value {
    json!({"rmse": s.rmse, "mean": s.mean, "median": s.median, "std": s.std, "min": s.min, "max": s.max, "sse": s.sse})
}

fn report(metric: &str, c: &CommonArgs, eval: &Evaluation, rpe: Option<&RpeArgs>) {
    let name = |v: Option<clap::builder::PossibleValue>| v.map(|v| v.get_name().to_owned()).unwrap_or_default();
    let relation = name(dash2sim_args::Relation::from(c.pose_relation).to_possible_value());
    let align = name(dash2sim_args::Align::from(c.align).to_possible_value());
    if c.json {
        let mut out = json!({
            "metric": metric.to_lowercase(),
            "pose_relation": relation,
            "align": align,
            "alignment": evaluate::Alignment::from(&eval.alignment),
            "stats": stats_json(&eval.stats),
            "n": eval.n,
            "matched": eval.matched,
        });
        if let Some(r) = rpe {
            out["delta"] = json!(r.delta);
            out["delta_unit"] = json!(if r.unit == DeltaUnit::M { "m" } else { "frames" });
            out["all_pairs"] = json!(r.all_pairs);
        }
        println!("{out}");
        return;
    }
    println!("{metric} ({relation}), alignment: {align}, {} values from {} matched poses", eval.n, eval.matched);
    if c.align != Align::None {
        let t = &eval.alignment;
        println!("  s = {:.9}", t.scale);
        println!("  t = [{:.6}, {:.6}, {:.6}]", t.translation.x, t.translation.y, t.translation.z);
    }
    let s = &eval.stats;
    for (name, v) in [
        ("max", s.max),
        ("mean", s.mean),
        ("median", s.median),
        ("min", s.min),
        ("rmse", s.rmse),
        ("sse", s.sse),
        ("std", s.std),
    ] {
        println!("{name:>10}\t{v:.6}");
    }
}
