//! `dash2sim export`: the arguments, and what was written listed.

use std::path::PathBuf;

use clap::Args;
use dash2sim_export::{self as export, ExportRequest};
use dash2sim_linux::Result;

/// What to export (`dash2sim export`).
#[derive(Clone, Debug, Args)]
pub struct ExportArgs {
    /// The log.
    pub log: PathBuf,
    /// MCAP output (zstd chunks, Foxglove JSON schemas).
    #[arg(long)]
    pub mcap: Option<PathBuf>,
    /// TUM output: the ego poses.
    #[arg(long)]
    pub tum: Option<PathBuf>,
    /// GeoJSON output: ego and GNSS tracks, objects as points.
    #[arg(long)]
    pub geojson: Option<PathBuf>,
    /// Parquet output folder: one file per record kind (docs/parquet.md).
    #[arg(long)]
    pub parquet: Option<PathBuf>,
    /// The log's id in the Parquet files (default: the log file's name without extension).
    #[arg(long)]
    pub log_id: Option<String>,
    /// nuPlan output folder: `db/<log>.db` and `maps/` (needs --map).
    #[arg(long)]
    pub nuplan: Option<PathBuf>,
    /// CommonRoad scenario (2020a XML), the ego's solution trajectory beside it as
    /// `F.solution.xml` (needs --map; docs/commonroad.md).
    #[arg(long, value_name = "F.xml")]
    pub commonroad: Option<PathBuf>,
    /// ScenarioNet dataset folder: a scenario pickle per window (MetaDrive's
    /// `ScenarioDescription`), `dataset_summary.pkl` and `dataset_mapping.pkl` (needs --map;
    /// docs/scenarionet.md).
    #[arg(long, value_name = "DIR")]
    pub scenarionet: Option<PathBuf>,
    /// OpenSCENARIO folder: the map's roads as `road.xodr` (OpenDRIVE 1.7) and a scenario per
    /// window (`scenario.xosc`, OpenSCENARIO 1.0; needs --map; docs/openscenario.md).
    #[arg(long, value_name = "DIR")]
    pub openscenario: Option<PathBuf>,
    /// A map tile (`map build`) or an OpenStreetMap file (built into a tile around the
    /// log's origin): its lanes go into the MCAP as lines and are the nuPlan, CommonRoad,
    /// ScenarioNet and OpenDRIVE map.
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Length of a scenario, s: of a nuPlan scene (default 5; nuPlan drops the first two and
    /// the last of a log); with --commonroad, --scenarionet and --openscenario, one scenario
    /// per window of this length (`F-001.xml`, …; default: one for the whole log).
    #[arg(long)]
    pub scenario_seconds: Option<f64>,
    /// The map's name in nuPlan (default: `dash2sim-` and the map file's name).
    #[arg(long)]
    pub map_name: Option<String>,
}

/// `dash2sim export`: print what [`export::export`] wrote, a damaged log's warning on
/// stderr.
pub fn run(args: ExportArgs) -> Result<()> {
    let exported = export::export(&ExportRequest {
        log: args.log,
        mcap: args.mcap,
        tum: args.tum,
        geojson: args.geojson,
        parquet: args.parquet,
        log_id: args.log_id,
        nuplan: args.nuplan,
        commonroad: args.commonroad,
        scenarionet: args.scenarionet,
        openscenario: args.openscenario,
        map: args.map,
        scenario_seconds: args.scenario_seconds,
        map_name: args.map_name,
    })?;
    if let Some(warning) = &exported.warning {
        eprintln!("warning: {warning}");
    }
    for line in &exported.written {
        println!("{line}");
    }
    Ok(())
}
