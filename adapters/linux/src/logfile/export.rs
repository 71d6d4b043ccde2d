//! `dash2sim export LOG [--mcap F] [--tum F] [--geojson F] [--parquet DIR] [--nuplan DIR]
//! [--map MAP|OSM]`: a log into the formats people already use — Foxglove (MCAP), evo
//! (TUM), QGIS (GeoJSON), DuckDB/pandas/Spark (Parquet, `super::parquet_export`), nuPlan
//! (`crate::nuplan`).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use dash2sim_core::binlog::{EgoPose, Record, Track3d};
use dash2sim_core::nalgebra::Vector3;
use serde_json::{json, Value};

use super::import::CLASSES;
use super::{frame, read, seconds, LogContents};

/// What to export (`dash2sim export`).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ExportRequest {
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
    /// A map tile (`map build`) or an OpenStreetMap file (built into a tile around the
    /// log's origin): its lanes go into the MCAP as lines and are the nuPlan map.
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Length of a nuPlan scene, s (nuPlan drops the first two and the last of a log).
    #[arg(long, default_value_t = 5.0)]
    pub scenario_seconds: f64,
    /// The map's name in nuPlan (default: `dash2sim-` and the map file's name).
    #[arg(long)]
    pub map_name: Option<String>,
}

/// A map tile from `path`: a tile as it is, an OpenStreetMap file (XML or PBF) built into
/// one around the log's origin.
fn map_tile(path: &Path, log: &LogContents) -> Result<Vec<u8>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if bytes.starts_with(b"D2SMAP") {
        return Ok(bytes);
    }
    let origin = log.header.as_ref().and_then(frame).map(|f| f.origin());
    let osm = crate::osm::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(crate::map_tile::encode(
        &crate::map_tile::from_osm(&osm, origin, &mut Vec::new()),
        crate::map_tile::DEFAULT_CELL_M,
    ))
}

/// A nuPlan map name from a file name: lower case, `-` for anything but letters and digits.
/// The nuPlan map name for a map file's stem.
pub fn map_name(stem: &str) -> String {
    let clean: String =
        stem.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect();
    format!("dash2sim-{}", clean.trim_matches('-'))
}

/// The ego poses of a log.
pub fn ego_poses(log: &LogContents) -> impl Iterator<Item = &EgoPose> {
    log.records.iter().filter_map(|r| match r {
        Record::EgoPose(p) => Some(p),
        _ => None,
    })
}

/// ENU position (m) and heading (rad) of an ego pose.
pub fn ego_enu(p: &EgoPose) -> (Vector3<f64>, f64) {
    (Vector3::new(p.x_mm as f64, p.y_mm as f64, p.z_mm as f64) * 1e-3, p.yaw_e4 as f64 * 1e-4)
}

/// The ego trajectory as TUM text (`t x y z qx qy qz qw`, heading about z).
pub fn tum(log: &LogContents) -> String {
    let mut out = String::from("# dash2sim export: ego (rear axle) in the log's ENU frame\n");
    for p in ego_poses(log) {
        let (v, yaw) = ego_enu(p);
        let (s, c) = (yaw / 2.0).sin_cos();
        let _ = writeln!(out, "{:.6} {:.3} {:.3} {:.3} 0 0 {s:.9} {c:.9}", seconds(p.t_us), v.x, v.y, v.z);
    }
    out
}

/// Class name of a `Track3d` class code.
pub fn class_name(code: i64) -> &'static str {
    usize::try_from(code).ok().and_then(|i| CLASSES.get(i)).copied().unwrap_or("other")
}

/// Every 3D track with its time, in log order.
pub fn tracks(log: &LogContents) -> impl Iterator<Item = (i64, &Track3d)> {
    log.records
        .iter()
        .filter_map(|r| match r {
            Record::Tracks3d(b) => Some(b),
            _ => None,
        })
        .flat_map(|b| b.tracks.iter().map(move |t| (b.t_us, t)))
}

/// The last state of every 3D track, by id, with its time.
pub fn last_tracks(log: &LogContents) -> BTreeMap<i64, (i64, &Track3d)> {
    tracks(log).map(|(t, track)| (track.id, (t, track))).collect()
}

/// GeoJSON: the ego trajectory and the GNSS fixes as LineStrings, every 3D track's last
/// position as a Point with its properties.
pub fn geojson(log: &LogContents) -> Result<Value, String> {
    let header = log.header.ok_or("the log's header is damaged: no geodetic origin")?;
    let frame = frame(&header).ok_or("the log's origin is not a valid position")?;
    let to_lonlat = |x: f64, y: f64, z: f64| -> Option<[f64; 2]> {
        frame.enu_to_geodetic(&Vector3::new(x, y, z)).ok().map(|g| [g.lon_deg, g.lat_deg])
    };
    let mut features = Vec::new();
    let ego: Vec<(i64, [f64; 2])> = ego_poses(log)
        .filter_map(|p| {
            let (v, _) = ego_enu(p);
            Some((p.t_us, to_lonlat(v.x, v.y, v.z)?))
        })
        .collect();
    if let (Some(first), Some(last)) = (ego.first(), ego.last()) {
        features.push(json!({
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": ego.iter().map(|(_, c)| c).collect::<Vec<_>>()},
            "properties": {"name": "ego", "poses": ego.len(), "t_start": seconds(first.0), "t_end": seconds(last.0)},
        }));
    }
    let gnss: Vec<[f64; 2]> = log
        .records
        .iter()
        .filter_map(|r| match r {
            Record::GnssFix(f) => Some([f.lon_e7 as f64 * 1e-7, f.lat_e7 as f64 * 1e-7]),
            _ => None,
        })
        .collect();
    if gnss.len() >= 2 {
        features.push(json!({
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": gnss},
            "properties": {"name": "gnss", "fixes": gnss.len()},
        }));
    }
    for (id, (t_us, t)) in last_tracks(log) {
        let Some(c) = to_lonlat(t.x_mm as f64 * 1e-3, t.y_mm as f64 * 1e-3, t.z_mm as f64 * 1e-3) else { continue };
        features.push(json!({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": c},
            "properties": {
                "id": id,
                "class": class_name(t.class),
                "static": t.is_static != 0,
                "t": seconds(t_us),
                "length_m": t.l_mm as f64 * 1e-3,
                "width_m": t.w_mm as f64 * 1e-3,
                "height_m": t.h_mm as f64 * 1e-3,
                "heading_rad": t.yaw_e4 as f64 * 1e-4,
            },
        }));
    }
    Ok(json!({"type": "FeatureCollection", "features": features}))
}

fn write(path: &Path, text: &str) -> Result<(), String> {
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// What [`export`] wrote: one line per output, and a warning when the log was damaged.
#[derive(Debug, Default)]
pub struct Exported {
    /// What was skipped while reading the log, if anything.
    pub warning: Option<String>,
    /// One line per output written: its path and what it holds.
    pub written: Vec<String>,
}

/// `dash2sim export`: print what [`export`] wrote.
pub fn run(request: &ExportRequest) -> Result<(), String> {
    let exported = export(request)?;
    if let Some(warning) = &exported.warning {
        eprintln!("warning: {warning}");
    }
    for line in &exported.written {
        println!("{line}");
    }
    Ok(())
}

/// Export a log as `request` says (the command line and the Python package's `export`).
pub fn export(request: &ExportRequest) -> Result<Exported, String> {
    if request.mcap.is_none()
        && request.tum.is_none()
        && request.geojson.is_none()
        && request.parquet.is_none()
        && request.nuplan.is_none()
    {
        return Err("nothing to export: give --mcap, --tum, --geojson, --parquet and/or --nuplan".to_owned());
    }
    let log = read(&request.log).map_err(|e| e.to_string())?;
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
            return Err(format!("{}: no ego poses to write as TUM", request.log.display()));
        }
        write(path, &tum(&log))?;
        exported.written.push(format!("{}: {n} ego poses", path.display()));
    }
    if let Some(path) = &request.geojson {
        let g = geojson(&log)?;
        write(path, &g.to_string())?;
        exported.written.push(format!("{}: {} features", path.display(), g["features"].as_array().map_or(0, Vec::len)));
    }
    if let Some(dir) = &request.parquet {
        let stem = request.log.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let id = request.log_id.clone().unwrap_or(stem);
        let rows = super::parquet_export::write(&log, &id, dir)?;
        let each: Vec<String> = rows.iter().map(|(name, n)| format!("{n} {name}")).collect();
        exported.written.push(format!("{}: {} (log id {id:?})", dir.display(), each.join(", ")));
    }
    let map = request.map.as_deref().map(|p| map_tile(p, &log)).transpose()?;
    if let Some(dir) = &request.nuplan {
        let (Some(tile), Some(map_path)) = (&map, &request.map) else {
            return Err("--nuplan needs --map (a tile or an OpenStreetMap file)".to_owned());
        };
        let stem = map_path.file_stem().and_then(|s| s.to_str()).unwrap_or("map");
        let name = request.map_name.clone().unwrap_or_else(|| map_name(stem));
        let log_name = request.log.display().to_string();
        let started = std::time::Instant::now();
        let out = crate::nuplan::export(&crate::nuplan::NuplanRequest {
            log: &log,
            log_name: &log_name,
            tile,
            map_name: &name,
            out: dir,
            scene_s: request.scenario_seconds,
        })?;
        let layers: Vec<String> = out.layers.iter().filter(|l| l.1 > 0).map(|(n, c)| format!("{c} {n}")).collect();
        exported.written.push(format!(
            "{}: {} ego states at 20 Hz, {} scenes (EPSG:{}); map {} `{name}`: {} ({:.2} s)",
            out.db.display(),
            out.ego_states,
            out.scenes,
            out.epsg,
            out.gpkg.display(),
            layers.join(", "),
            started.elapsed().as_secs_f64()
        ));
    }
    if let Some(path) = &request.mcap {
        let view =
            map.as_deref().map(dash2sim_core::map::MapView::parse).transpose().map_err(|e| format!("--map: {e}"))?;
        let counts = super::mcap_export::write(&log, view.as_ref(), path, None)?;
        let total: u64 = counts.values().sum();
        let detail: Vec<String> = counts.iter().map(|(topic, n)| format!("{n} {topic}")).collect();
        exported.written.push(format!("{}: {total} messages ({})", path.display(), detail.join(", ")));
    }
    Ok(exported)
}
