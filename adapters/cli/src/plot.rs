//! `dash2sim plot`: the arguments, and what was drawn summarised.

use std::path::PathBuf;

use dash2sim_linux::Result;
use dash2sim_verify::plot::{self, PlotRequest};

/// `dash2sim plot` arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct PlotArgs {
    /// The log (the device's, or a finished one).
    pub log: PathBuf,
    /// A map tile (`map build`): its lanes under the drive, in grey.
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// The finished log of the same drive (`finish`), drawn in blue over the online one.
    #[arg(long)]
    pub finished: Option<PathBuf>,
    /// The picture: `.svg` or `.png`.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `dash2sim plot`.
pub fn run(args: PlotArgs) -> Result<()> {
    let request = PlotRequest { log: args.log, map: args.map, finished: args.finished, output: args.output };
    let drawn = plot::plot(&request)?;
    let classes: Vec<String> = drawn.tracks.iter().map(|(c, n)| format!("{n} {c}")).collect();
    println!(
        "{}: {} lanes, {} online and {} finished ego poses, {} GNSS fixes, tracks: {}; {} of {} windows verified",
        request.output.display(),
        drawn.lanes,
        drawn.poses.0,
        drawn.poses.1,
        drawn.poses.2,
        if classes.is_empty() { "none".to_owned() } else { classes.join(", ") },
        drawn.windows.1,
        drawn.windows.0
    );
    Ok(())
}
