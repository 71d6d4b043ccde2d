//! `dash2sim export LOG [--mcap F] [--tum F] [--geojson F] [--parquet DIR] [--nuplan DIR]
//! [--commonroad F.xml] [--scenarionet DIR] [--openscenario DIR] [--map MAP|OSM]`: one log into
//! every format asked for — Foxglove (MCAP), evo (TUM), QGIS (GeoJSON), DuckDB/pandas/Spark
//! (Parquet), nuPlan, CommonRoad, ScenarioNet, OpenSCENARIO with OpenDRIVE. Each exporter is a
//! module (`mcap`, `tum`, `geojson`, `parquet`, `nuplan`, `commonroad`, `scenarionet`,
//! `openscenario` and `opendrive`, on the shared `road` and `ticks`; the log's views they read
//! are the host library's `log::views`); this module only reads the request and calls them.
//!
//! The crate `dash2sim-export` (issue #56: the exports out of the host library).
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod commonroad;
pub mod geojson;
pub mod junctions;
#[cfg(feature = "mcap")]
pub mod mcap;
#[cfg(feature = "nuplan")]
pub mod nuplan;
pub mod opendrive;
pub mod openscenario;
#[cfg(feature = "parquet")]
pub mod parquet;
mod partial;
pub mod pickle;
pub mod plan_view;
pub mod projection;
mod request;
pub mod road;
pub mod scenarionet;
pub mod ticks;
pub mod tum;

pub use request::ScenarioRequest;

use std::path::{Path, PathBuf};

use dash2sim_linux::log::views::ego_poses;
use dash2sim_linux::log::{frame, read, LogContents};
use dash2sim_linux::{Error, Field, Result};

/// What to export (`dash2sim export`).
#[derive(Clone, Debug)]
pub struct ExportRequest {
    /// The log.
    pub log: PathBuf,
    /// MCAP output (zstd chunks, Foxglove JSON schemas).
    pub mcap: Option<PathBuf>,
    /// TUM output: the ego poses.
    pub tum: Option<PathBuf>,
    /// GeoJSON output: ego and GNSS tracks, objects as points.
    pub geojson: Option<PathBuf>,
    /// Parquet output folder: one file per record kind (docs/parquet.md).
    pub parquet: Option<PathBuf>,
    /// The log's id in the Parquet files (default: the log file's name without extension).
    pub log_id: Option<String>,
    /// nuPlan output folder: `db/<log>.db` and `maps/` (needs --map).
    pub nuplan: Option<PathBuf>,
    /// CommonRoad scenario file (`F.xml`, its solution `F.solution.xml`; needs --map).
    pub commonroad: Option<PathBuf>,
    /// ScenarioNet dataset folder (scenario pickles and the dataset's summary and mapping;
    /// needs --map).
    pub scenarionet: Option<PathBuf>,
    /// OpenSCENARIO output folder: `road.xodr` (OpenDRIVE) and a `.xosc` per window (needs
    /// --map).
    pub openscenario: Option<PathBuf>,
    /// A map tile (`map build`) or an OpenStreetMap file (built into a tile around the
    /// log's origin): its lanes go into the MCAP as lines and are the nuPlan map.
    pub map: Option<PathBuf>,
    /// Length of a scenario, s: a nuPlan scene ([`DEFAULT_SCENARIO_SECONDS`] when not
    /// given; nuPlan drops the first two and the last of a log), one CommonRoad file or
    /// ScenarioNet or OpenSCENARIO scenario per window (not given: one for the whole log).
    pub scenario_seconds: Option<f64>,
    /// The map's name in nuPlan (default: `dash2sim-` and the map file's name).
    pub map_name: Option<String>,
}

/// The length of a nuPlan scene when none is named, s.
pub const DEFAULT_SCENARIO_SECONDS: f64 = 5.0;

/// A map tile from `path`: a tile as it is, an OpenStreetMap file (XML or PBF) built into
/// one around `origin` (its own centre when `None`).
pub fn map_tile(path: &Path, origin: Option<dash2sim_core::geo::Geodetic>) -> Result<Vec<u8>> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    if bytes.starts_with(b"D2SMAP") {
        return Ok(bytes);
    }
    let osm = dash2sim_linux::ingest::osm::read(path).map_err(|e| Error::file(path, e))?;
    Ok(dash2sim_linux::ingest::map_tile::encode(
        &dash2sim_linux::ingest::map_tile::from_osm(&osm, origin, &mut Vec::new()),
        dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M,
    ))
}

/// `text` as an XML attribute's value or element's text (the XML exports' escaping).
fn xml_escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn write(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| Error::file(path, e))
}

/// What [`export`] wrote: one line per output, and a warning when the log was damaged.
#[derive(Debug, Default)]
pub struct Exported {
    /// What was skipped while reading the log, if anything.
    pub warning: Option<String>,
    /// One line per output written: its path and what it holds.
    pub written: Vec<String>,
}

/// Export a log as `request` says (the command line and the Python package's `export`).
pub fn export(request: &ExportRequest) -> Result<Exported> {
    if request.mcap.is_none()
        && request.tum.is_none()
        && request.geojson.is_none()
        && request.parquet.is_none()
        && request.nuplan.is_none()
        && request.commonroad.is_none()
        && request.scenarionet.is_none()
        && request.openscenario.is_none()
    {
        return Err(Error::request(
            Field::Formats,
            "nothing to export: ask for MCAP, TUM, GeoJSON, Parquet, nuPlan, CommonRoad, ScenarioNet and/or OpenSCENARIO",
        ));
    }
    let log = read(&request.log).map_err(Error::other)?;
    let mut exported = Exported::default();
    if log.stats.damaged > 0 {
        exported.warning = Some(format!(
            "{}: {} damaged stretches ({} bytes) skipped; exporting the {} intact records",
            request.log.display(),
            log.stats.damaged,
            log.stats.damaged_bytes,
            log.records.len()
        ));
    }
    if let Some(path) = &request.tum {
        let n = ego_poses(&log).count();
        if n == 0 {
            return Err(Error::file(
                &request.log,
                "no ego poses to write as TUM (a log of GNSS and speed only has none; its GeoJSON and MCAP exports carry its fixes)",
            ));
        }
        write(path, &tum::tum(&log))?;
        exported.written.push(format!("{}: {n} ego poses", path.display()));
    }
    if let Some(path) = &request.geojson {
        let g = geojson::geojson(&log)?;
        write(path, &g.to_string())?;
        exported.written.push(format!("{}: {} features", path.display(), g["features"].as_array().map_or(0, Vec::len)));
    }
    if let Some(dir) = &request.parquet {
        exported.written.push(parquet(&log, request, dir)?);
    }
    let origin = log.header.as_ref().and_then(frame).map(|f| f.origin());
    let map = request.map.as_deref().map(|p| map_tile(p, origin)).transpose()?;
    if let Some(dir) = &request.nuplan {
        let (Some(tile), Some(map_path)) = (&map, &request.map) else {
            return Err(Error::request(Field::Map, "the nuPlan export needs one (a tile or an OpenStreetMap file)"));
        };
        exported.written.push(nuplan(&log, request, tile, map_path, dir)?);
    }
    if let Some(path) = &request.commonroad {
        let Some(tile) = &map else {
            return Err(Error::request(
                Field::Map,
                "the CommonRoad export needs one (a tile or an OpenStreetMap file)",
            ));
        };
        exported.written.extend(commonroad(&log, request, tile, path)?);
    }
    if let Some(dir) = &request.scenarionet {
        let Some(tile) = &map else {
            return Err(Error::request(
                Field::Map,
                "the ScenarioNet export needs one (a tile or an OpenStreetMap file)",
            ));
        };
        exported.written.push(scenarionet(&log, request, tile, dir)?);
    }
    if let Some(dir) = &request.openscenario {
        let Some(tile) = &map else {
            return Err(Error::request(
                Field::Map,
                "the OpenSCENARIO export needs one (a tile or an OpenStreetMap file)",
            ));
        };
        exported.written.extend(openscenario(&log, request, tile, dir)?);
    }
    if let Some(path) = &request.mcap {
        exported.written.push(mcap(&log, map.as_deref(), path)?);
    }
    Ok(exported)
}

/// The MCAP file written: how many messages on which topics.
#[cfg(feature = "mcap")]
fn mcap(log: &LogContents, map: Option<&[u8]>, path: &Path) -> Result<String> {
    let view = map.map(dash2sim_core::map::MapView::parse).transpose().map_err(|e| Error::refused("map", e))?;
    let counts = mcap::write(log, view.as_ref(), path, None)?;
    let total: u64 = counts.values().sum();
    let detail: Vec<String> = counts.iter().map(|(topic, n)| format!("{n} {topic}")).collect();
    Ok(format!("{}: {total} messages ({})", path.display(), detail.join(", ")))
}

#[cfg(not(feature = "mcap"))]
fn mcap(_: &LogContents, _: Option<&[u8]>, _: &Path) -> Result<String> {
    Err(Error::FeatureMissing {
        field: Field::Mcap,
        krate: env!("CARGO_PKG_NAME"),
        part: "MCAP export",
        feature: "mcap",
    })
}

/// The Parquet folder written: what it holds.
#[cfg(feature = "parquet")]
fn parquet(log: &LogContents, request: &ExportRequest, dir: &Path) -> Result<String> {
    let stem = request.log.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let id = request.log_id.clone().unwrap_or(stem);
    let rows = parquet::write(log, &id, dir)?;
    let each: Vec<String> = rows.iter().map(|(name, n)| format!("{n} {name}")).collect();
    Ok(format!("{}: {} (log id {id:?})", dir.display(), each.join(", ")))
}

#[cfg(not(feature = "parquet"))]
fn parquet(_: &LogContents, _: &ExportRequest, _: &Path) -> Result<String> {
    Err(Error::FeatureMissing {
        field: Field::Parquet,
        krate: env!("CARGO_PKG_NAME"),
        part: "Parquet export",
        feature: "parquet",
    })
}

/// The nuPlan log database and map written: what they hold.
#[cfg(feature = "nuplan")]
fn nuplan(log: &LogContents, request: &ExportRequest, tile: &[u8], map_path: &Path, dir: &Path) -> Result<String> {
    let stem = map_path.file_stem().and_then(|s| s.to_str()).unwrap_or("map");
    let name = request.map_name.clone().unwrap_or_else(|| nuplan::map_name(stem));
    let log_name = request.log.display().to_string();
    let started = std::time::Instant::now();
    let out = nuplan::export(&nuplan::NuplanRequest {
        log,
        log_name: &log_name,
        tile,
        map_name: &name,
        out: dir,
        scene_s: request.scenario_seconds.unwrap_or(DEFAULT_SCENARIO_SECONDS),
    })?;
    let layers: Vec<String> = out.layers.iter().filter(|l| l.1 > 0).map(|(n, c)| format!("{c} {n}")).collect();
    Ok(format!(
        "{}: {} ego states at 20 Hz, {} scenes (EPSG:{}); map {} `{name}`: {} ({:.2} s)",
        out.db.display(),
        out.ego_states,
        out.scenes,
        out.epsg,
        out.gpkg.display(),
        layers.join(", "),
        started.elapsed().as_secs_f64()
    ))
}

/// The CommonRoad scenarios written: one line each.
fn commonroad(log: &LogContents, request: &ExportRequest, tile: &[u8], path: &Path) -> Result<Vec<String>> {
    let log_name = request.log.display().to_string();
    let started = std::time::Instant::now();
    let out = commonroad::export(&ScenarioRequest {
        log,
        log_name: &log_name,
        tile,
        out: path,
        window_s: request.scenario_seconds,
    })?;
    let seconds = started.elapsed().as_secs_f64();
    Ok(out
        .scenarios
        .iter()
        .map(|s| {
            format!(
                "{}: CommonRoad {} — {} lanelets (EPSG:{} less the map origin), {} steps of {} s, {} dynamic and {} static obstacles; the ego's trajectory in {} ({seconds:.2} s)",
                s.path.display(),
                s.id,
                out.lanelets,
                out.epsg,
                s.steps,
                commonroad::TIME_STEP_S,
                s.dynamic,
                s.r#static,
                s.solution.display()
            )
        })
        .collect())
}

/// The ScenarioNet dataset written: what it holds.
fn scenarionet(log: &LogContents, request: &ExportRequest, tile: &[u8], dir: &Path) -> Result<String> {
    let log_name = request.log.display().to_string();
    let started = std::time::Instant::now();
    let out = scenarionet::export(&ScenarioRequest {
        log,
        log_name: &log_name,
        tile,
        out: dir,
        window_s: request.scenario_seconds,
    })?;
    let steps: usize = out.scenarios.iter().map(|s| s.steps).sum();
    let tracks: usize = out.scenarios.iter().map(|s| s.tracks).sum();
    Ok(format!(
        "{}: ScenarioNet, {} scenarios ({steps} steps of {} s, {tracks} tracks with the ego's), {} map features each (EPSG:{} less the map origin); {} and {} ({:.2} s)",
        dir.display(),
        out.scenarios.len(),
        scenarionet::TIME_STEP_S,
        out.map_features,
        out.epsg,
        out.summary.display(),
        out.mapping.display(),
        started.elapsed().as_secs_f64()
    ))
}

/// The OpenSCENARIO folder written: the road, then one line per scenario.
fn openscenario(log: &LogContents, request: &ExportRequest, tile: &[u8], dir: &Path) -> Result<Vec<String>> {
    let log_name = request.log.display().to_string();
    let started = std::time::Instant::now();
    let road_name =
        request.map.as_deref().and_then(Path::file_name).map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let out = openscenario::export(
        &ScenarioRequest { log, log_name: &log_name, tile, out: dir, window_s: request.scenario_seconds },
        &road_name,
    )?;
    let seconds = started.elapsed().as_secs_f64();
    let mut lines = vec![opendrive_line(&out.road, &out.opendrive)];
    lines.extend(out.scenarios.iter().map(|s| {
        format!(
            "{}: OpenSCENARIO 1.0 — {} entities ({} following their trajectories, the ego's {} steps of {} s) on {} ({seconds:.2} s)",
            s.path.display(),
            s.entities,
            s.moving,
            s.steps,
            openscenario::TIME_STEP_S,
            openscenario::ROAD_FILE
        )
    }));
    Ok(lines)
}

/// What an OpenDRIVE file written holds, on one line.
pub fn opendrive_line(path: &Path, d: &opendrive::OpenDrive) -> String {
    format!(
        "{}: OpenDRIVE 1.7 — {} roads ({} lanes), {} junctions ({} connecting roads), EPSG:{} less ({:.3}, {:.3}); lane centres within {:.3} m of the tile's, connecting roads within {:.3} m of their curves",
        path.display(),
        d.roads,
        d.lanes,
        d.junctions,
        d.connecting_roads,
        d.epsg,
        d.offset.0,
        d.offset.1,
        d.worst_centre_m,
        d.worst_connector_m
    )
}

#[cfg(not(feature = "nuplan"))]
fn nuplan(_: &LogContents, _: &ExportRequest, _: &[u8], _: &Path, _: &Path) -> Result<String> {
    Err(Error::FeatureMissing {
        field: Field::Nuplan,
        krate: env!("CARGO_PKG_NAME"),
        part: "nuPlan export",
        feature: "nuplan",
    })
}
