//! `dash2sim scenario`: generate, publish, corpus, sweep and eval — the arguments, and what
//! each gives rendered.

use std::path::{Path, PathBuf};

use clap::Args;
use dash2sim_core::track3d::Config3d;
use dash2sim_linux::{Error, Result};
use dash2sim_sim::fidelity::drive::Anchors;
use dash2sim_sim::fidelity::rows::{parse_seeds, SweepRequest};
use dash2sim_sim::fidelity::sweep;
use dash2sim_sim::scenario::command::config;
use dash2sim_sim::scenario::corpus::{self, CorpusRequest};
use dash2sim_sim::scenario::evaluate::evaluate_tracking;
use dash2sim_sim::scenario::profile::{Profile, Receiver};
use dash2sim_sim::scenario::write::{origin_option, write_scenario, START_UNIX_S};
use dash2sim_sim::scenario::{generate, tracker_classes, tracker_config, Drivers, Frame, ScenarioConfig};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

/// `dash2sim scenario corpus` arguments.
#[derive(Debug, Clone, Args)]
pub struct CorpusArgs {
    /// Output folder: `drive-NNNN.d2slog` with `drive-NNNN.map` beside each, and `corpus.json`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// How many logs.
    #[arg(long, default_value_t = 200)]
    pub logs: usize,
    /// Every this many logs, one is damaged (0: none), cycling through the kinds of damage.
    #[arg(long, default_value_t = 10)]
    pub damaged_every: usize,
    /// Seed of the first drive; the others follow.
    #[arg(long, default_value_t = 1)]
    pub first_seed: u64,
    /// How far the sensors are from ideal: `ideal`, `typical` or `hard` (docs/scenario.md).
    #[arg(long, value_parser = dash2sim_args::Profile::parser(), default_value = "typical")]
    pub profile: Profile,
    /// No progress on stderr.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `dash2sim scenario sweep` arguments.
#[derive(Debug, Clone, Args)]
pub struct SweepArgs {
    /// Seeds, `A-B` (both included) or one seed.
    #[arg(long, value_parser = parse_seeds)]
    pub seeds: std::ops::RangeInclusive<u64>,
    /// Drive each seed `careful`, `careless`, `both`, `all` or one other kind: `shoulder`,
    /// `oncoming`, `speeding`, `tailgating`, `harsh`, `knife-edge` (docs/scenario.md).
    #[arg(long, value_parser = Drivers::parse, default_value = "both")]
    pub driver: Drivers,
    /// How far the sensors are from ideal: `ideal`, `typical` or `hard` (docs/scenario.md).
    #[arg(long, value_parser = dash2sim_args::Profile::parser(), default_value = "typical")]
    pub profile: Profile,
    /// The GNSS receiver: `good` (σ 1–2 m) or `phone` (σ 3–10 m).
    #[arg(long, value_parser = dash2sim_args::Receiver::parser(), default_value = "good")]
    pub receiver: Receiver,
    /// Finishing's anchors: `street` (simulated from the true path every 50 m) or `none`.
    #[arg(long, value_parser = dash2sim_args::Anchors::parser(), default_value = "street")]
    pub anchors: Anchors,
    /// Tell finishing the receiver's true latency instead of estimating it: an oracle that
    /// bounds what a better latency estimate could gain (the summary is marked as one).
    #[arg(long)]
    pub oracle_latency: bool,
    /// Where the device's relative motion comes from: the camera's `vo`, or `imu-wheels`
    /// (the camera publishes no VO: gyro + wheels dead reckoning from the drive's IMU).
    #[arg(long, value_parser = dash2sim_args::RelativeMotion::parser(), default_value = "vo")]
    pub relative_motion: dash2sim_core::pipeline::RelativeMotion,
    /// Decide each log with this many σ of doubt (`verify --decide-at`).
    #[arg(long, value_name = "K", default_value_t = dash2sim_verify::decide::DEFAULT_DECIDE_AT)]
    pub decide_at: f64,
    /// σ of the place relative to the ego of each object whose log states none, m along one axis (`verify --object-sigma`)
    #[arg(long, value_name = "M", default_value_t = dash2sim_verify::decide::DEFAULT_OBJECT_SIGMA_M)]
    pub object_sigma: f64,
    /// Length of each drive, s.
    #[arg(long, default_value_t = 40.0)]
    pub duration: f64,
    /// Drives run at once (default: one per core).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Output folder: runs.csv, runs.jsonl, summary.json, sweep.png.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress on stderr.
    #[arg(short, long)]
    pub quiet: bool,
    /// Keep each drive's files (generated streams, logs, anchors) under `OUTPUT/drives/`.
    #[arg(long)]
    pub keep: bool,
}

/// `dash2sim scenario generate`: drive `seed` written to `dir` (one folder per driver, named
/// after it, when there are several), and what each holds.
pub fn generate_to(
    seed: u64,
    duration_s: f64,
    profile: Profile,
    receiver: Receiver,
    drivers: Drivers,
    dir: &Path,
) -> Result<()> {
    let several = drivers.list().len() > 1;
    for &driver in drivers.list() {
        let dir = if several { dir.join(driver.name()) } else { dir.to_path_buf() };
        generate_one(&ScenarioConfig { driver, ..config(seed, duration_s, profile, receiver)? }, &dir)?;
    }
    Ok(())
}

fn generate_one(config: &ScenarioConfig, dir: &Path) -> Result<()> {
    let scenario = generate(config);
    let (seed, profile, receiver) = (config.seed, config.profile, config.receiver);
    let files = write_scenario(&scenario, dir).map_err(|e| Error::refused(format!("writing {}", dir.display()), e))?;
    let count = |f: fn(&Frame) -> usize| scenario.frames.iter().map(f).sum::<usize>();
    let expectation = match config.driver.expectation() {
        dash2sim_sim::scenario::Expectation::Verifies => "its truth verifies".to_owned(),
        dash2sim_sim::scenario::Expectation::Fails(metric) => format!("its truth fails {metric}"),
    };
    println!(
        "scenario {seed} ({} profile, {} receiver, {} driver: {expectation}): {} frames, {} objects, {} 3D and {} 2D detections, {} GNSS fixes ({} in multipath), {} speed samples, {} VO session(s)",
        profile.name(),
        receiver.name(),
        config.driver.name(),
        scenario.frames.len(),
        scenario.frames.first().map_or(0, |f| f.objects.len()),
        count(|f| f.detections_3d.len()),
        count(|f| f.detections_2d.len()),
        scenario.gnss.len(),
        scenario.gnss.iter().filter(|g| g.multipath).count(),
        scenario.speed.len(),
        scenario.vo.reinits() + 1
    );
    for file in files {
        println!("  {}", file.display());
    }
    // What the commands that take this drive on need to agree with its truth.
    println!("ENU origin: --origin {} (for map build, record and import)", origin_option(scenario.config.origin));
    println!(
        "truth times: seconds from 2026-06-01T08:00:00Z, 10 Hz; a log's exports are in UTC, its clock within tens of ms: dash2sim traj ape {} EXPORT.tum --t-offset={} --max-diff 0.05",
        dir.join("ego.tum").display(),
        -START_UNIX_S
    );
    Ok(())
}

/// `dash2sim scenario eval`: drive `seed` through the 3D tracker, judged.
pub fn eval(seed: u64, duration_s: f64, profile: Profile, max_age: u32, as_json: bool) -> Result<()> {
    let scenario = generate(&config(seed, duration_s, profile, Receiver::Phone)?);
    let classes = tracker_classes();
    let report = evaluate_tracking::<64>(&scenario, Config3d { max_age, ..tracker_config(&classes) });
    let figures = [
        ("rmse_detections_m", report.rmse_detections),
        ("rmse_filtered_m", report.rmse_filtered),
        ("rmse_smoothed_m", report.rmse_smoothed),
        ("static_accuracy", report.static_accuracy()),
    ];
    if as_json {
        let mut out = json!({
            "seed": seed,
            "profile": profile.name(),
            "frames": report.frames,
            "objects": report.objects,
            "object_frames": report.object_frames,
            "detections": report.detections,
            "paired": report.paired,
            "rejected_detections": report.stats.rejected,
            "metrics": crate::render::json_of(&report.summary)?,
        });
        for (name, value) in figures {
            out[name] = json!(value);
        }
        println!("{out}");
        return Ok(());
    }
    println!(
        "scenario {seed} ({} profile): {} frames, {} objects in view, {} object-frames, {} detections",
        profile.name(),
        report.frames,
        report.objects,
        report.object_frames,
        report.detections
    );
    for name in ["mota", "motp", "idf1", "num_switches", "num_fragmentations", "num_false_positives", "num_misses"] {
        println!("{name:>20}  {}", report.metric(name));
    }
    for (name, value) in figures {
        println!("{name:>20}  {value:.4}");
    }
    println!("{:>20}  {} (object-frames with both a matched detection and a matched track)", "paired", report.paired);
    println!(
        "{:>20}  {} of {} (implausible: off the ground or of an unknown class)",
        "rejected", report.stats.rejected, report.detections
    );
    Ok(())
}

/// `dash2sim scenario corpus`: progress every 25 logs on stderr unless `--quiet`.
pub fn corpus(args: &CorpusArgs) -> Result<()> {
    let request = CorpusRequest {
        output: args.output.clone(),
        logs: args.logs,
        damaged_every: args.damaged_every,
        first_seed: args.first_seed,
        profile: args.profile,
    };
    let progress = |n: usize| {
        if !args.quiet && (n.is_multiple_of(25) || n == args.logs) {
            eprintln!("{n} of {} logs written", args.logs);
        }
    };
    let made = corpus::make_corpus(&request, &progress)?;
    println!(
        "{}: {} logs ({} damaged on purpose), listed in {}",
        args.output.display(),
        made.logs,
        made.damaged,
        made.listing.display()
    );
    Ok(())
}

/// `dash2sim scenario sweep`: a progress bar on stderr unless `--quiet`, the summary on
/// stdout.
pub fn sweep(args: &SweepArgs) -> Result<()> {
    let request = SweepRequest {
        seeds: args.seeds.clone(),
        driver: args.driver,
        profile: args.profile,
        receiver: args.receiver,
        anchors: args.anchors,
        oracle_latency: args.oracle_latency,
        relative_motion: args.relative_motion,
        doubt: dash2sim_verify::decide::DoubtSettings { decide_at: args.decide_at, object_sigma_m: args.object_sigma },
        duration: args.duration,
        jobs: args.jobs,
        output: args.output.clone(),
        keep: args.keep,
    };
    let bar = if args.quiet { ProgressBar::hidden() } else { ProgressBar::new(0) };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} drives ({elapsed}, about {eta} left)")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    // Drives end in any order on the workers: each call is one more.
    let progress = |_ended: usize, drives: usize| {
        bar.set_length(drives as u64);
        bar.inc(1);
    };
    let result = sweep::sweep(&request, &progress);
    bar.finish_and_clear();
    let (_, summary) = result?;
    if args.json {
        println!("{}", serde_json::to_string(&summary).map_err(Error::other)?);
    } else {
        print!("{}", summary.text());
        println!(
            "rows in {}, summary in {}",
            args.output.join("runs.csv").display(),
            args.output.join("summary.json").display()
        );
    }
    Ok(())
}
