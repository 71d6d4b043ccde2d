//! A camera process for tests, demos and load runs: publishes a generated work-zone drive
//! over the shared-memory bridge at its real frame rate (or `--speedup` times faster) and
//! prints `N frames published` (with `--json`, what it published per kind: the load runs'
//! accounting) (`dash2sim_sim::scenario::publish` is the code; `dash2sim
//! scenario publish` runs the same).
//!
//! `cargo run --release -p dash2sim-examples --bin camera_sim -- --seconds 10`
//!
//! A 10-minute load run at 30 fps with 64 objects a frame (see docs/benchmarks.md):
//! `camera_sim --fps 30 --objects 64 --seconds 50 --laps 12 --nmea-out gnss.fifo --can-out can.fifo`

use std::process::ExitCode;

use clap::Parser;
use dash2sim_args::PublishArgs;
use dash2sim_sim::scenario::publish;

/// Publish a generated work-zone drive as a camera process would.
#[derive(Debug, Parser)]
#[command(name = "camera_sim", version, about)]
struct Args {
    #[command(flatten)]
    publish: PublishArgs,
}

fn main() -> ExitCode {
    let args = Args::parse().publish;
    match publish::run(&(&args).into()) {
        Ok(published) => {
            println!("{}", args.render(&published));
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("camera_sim: {}", dash2sim_args::errors::message(&e));
            ExitCode::FAILURE
        }
    }
}
