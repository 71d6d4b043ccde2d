//! `dash2sim demo`: the whole product on a generated work-zone drive, by its own path
//! ([`dash2sim_sim::demo`]: generate, record live over shared memory, finish, verify, judge
//! against the truth, export, plot), or on the real recordings of a data folder
//! ([`dash2sim_sim::demo::data`]). This module parses the arguments, draws the progress and
//! renders the typed report, human or `--json`.

mod progress;
mod summary;

use std::path::PathBuf;
use std::process::Command;

use dash2sim_linux::{Error, Result};
use dash2sim_sim::demo::{self, data, DemoRequest, Recording};
use dash2sim_sim::fidelity::drive::Anchors;
use dash2sim_sim::scenario::profile::Profile;
use dash2sim_sim::scenario::publish::PublishRequest;
use dash2sim_sim::scenario::Driver;
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
    if let Some(dir) = &args.data {
        let dir = dir.clone().unwrap_or_else(dash2sim_sim::datasets::default_dir);
        let report = data::run(&dir, &args.output, &progress)?;
        if args.json {
            println!("{}", demo::summary_json(&report)?);
        } else {
            summary::print_data(&report);
        }
        let failed = report.failures();
        return if failed.is_empty() { Ok(()) } else { Err(Error::invalid(failed.join("; "))) };
    }
    let request = DemoRequest {
        output: args.output.clone(),
        seed: args.seed,
        duration_s: args.duration,
        driver: args.driver,
        profile: args.profile,
        anchors: args.anchors,
        recording: if args.offline { Recording::Offline } else { Recording::Live { camera } },
    };
    let report = demo::run(&request, &progress)?;
    if args.json {
        println!("{}", demo::summary_json(&report)?);
    } else {
        summary::print(&report);
    }
    Ok(())
}

/// The camera process: this executable's `scenario publish`.
fn camera(request: &PublishRequest) -> std::io::Result<Command> {
    let mut command = Command::new(std::env::current_exe()?);
    command.args(["scenario", "publish"]).args(dash2sim_args::publish::arguments(request));
    Ok(command)
}
