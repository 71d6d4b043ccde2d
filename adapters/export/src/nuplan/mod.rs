//! `dash2sim export LOG --nuplan DIR --map MAP|OSM`: a 4D log and its roads as a nuPlan
//! log database and map (`docs/nuplan.md`), for nuPlan's simulator and metrics.
//!
//! `DIR/db/<log>.db` is the log database ([`logdb`]); `DIR/maps/nuplan-maps-v1.0.json` and
//! `DIR/maps/<map name>/<version>/map.gpkg` the map ([`map`], written by [`gpkg`]) in the UTM
//! zone of the map's origin ([`super::projection`]). Everything is written under temporary names
//! and renamed at the end: a refused input leaves nothing behind.

pub mod gpkg;
pub mod logdb;
pub mod map;

use std::path::{Path, PathBuf};

use serde_json::json;

use super::partial::Cleanup;
use super::ticks::{on_map, OnMap};
use dash2sim_linux::log::LogContents;
use dash2sim_linux::{Error, Field, Result};
use gpkg::GeoPackage;

/// The map version directory nuPlan's map reader expects.
pub const MAP_VERSION: &str = "9.17.1964";
/// nuPlan drops the first two scenes and the last one.
pub const MIN_SCENES: usize = 5;

/// What `export --nuplan` was asked.
#[derive(Clone, Debug)]
pub struct NuplanRequest<'a> {
    /// The log, read.
    pub log: &'a LogContents,
    /// Its name, for the database's file name and messages.
    pub log_name: &'a str,
    /// The map tile's bytes.
    pub tile: &'a [u8],
    /// The map's name in nuPlan (its `location` and `map_version`).
    pub map_name: &'a str,
    /// Output folder.
    pub out: &'a Path,
    /// Length of a scene, s.
    pub scene_s: f64,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct NuplanExport {
    /// The log database.
    pub db: PathBuf,
    /// The GeoPackage.
    pub gpkg: PathBuf,
    /// Ego states written (20 Hz).
    pub ego_states: usize,
    /// Scenes.
    pub scenes: usize,
    /// Map layers and their feature counts.
    pub layers: Vec<(&'static str, usize)>,
    /// EPSG code of the projected frame.
    pub epsg: i32,
}

/// Export. Errors name what is missing; nothing is left behind on an error.
pub fn export(request: &NuplanRequest<'_>) -> Result<NuplanExport> {
    if !(request.scene_s.is_finite() && request.scene_s >= 1.0) {
        return Err(Error::request(Field::ScenarioSeconds, format!("{} s must be at least 1 s", request.scene_s)));
    }
    let OnMap { view, map_projection, log_projection, ticks, .. } =
        on_map(request.log, request.log_name, request.tile, logdb::RATE_HZ)?;
    let duration = ticks.len().saturating_sub(1) as f64 / logdb::RATE_HZ;
    let scenes = logdb::scene_count(ticks.len(), request.scene_s);
    if scenes < MIN_SCENES {
        return Err(Error::request(
            Field::ScenarioSeconds,
            format!(
                "{}: {duration:.1} s of ego poses make {scenes} scenes of {} s; nuPlan needs at least {MIN_SCENES} (it \
                 drops the first two and the last): a longer log or shorter scenes",
                request.log_name, request.scene_s
            ),
        ));
    }
    let (layers, ids) = map::layers(&view, &map_projection)?;

    let db_dir = request.out.join("db");
    let map_dir = request.out.join("maps").join(request.map_name).join(MAP_VERSION);
    for d in [&db_dir, &map_dir] {
        std::fs::create_dir_all(d).map_err(|e| Error::file(d, e))?;
    }
    let stem = Path::new(request.log_name).file_stem().and_then(|s| s.to_str()).unwrap_or("log");
    let start = ticks.first().map_or(0, |t| t.t_us);
    let db_path = db_dir.join(format!("{}_dash2sim_{stem}.db", date_name(start)));
    let gpkg_path = map_dir.join("map.gpkg");
    let json_path = request.out.join("maps").join("nuplan-maps-v1.0.json");
    let partial = |p: &Path| p.with_extension("partial");
    let mut cleanup = Cleanup(vec![partial(&db_path), partial(&gpkg_path), partial(&json_path)]);
    for p in &cleanup.0 {
        let _ = std::fs::remove_file(p);
    }
    let mut package =
        GeoPackage::create(&partial(&gpkg_path), map_projection.epsg(), &map_projection.name(), &map_projection.wkt())?;
    let mut counts = Vec::new();
    for layer in &layers {
        package.write_layer(layer)?;
        counts.push((layer.name, layer.features.len()));
    }
    package.write_attributes(
        "meta",
        &[("projectedCoordSystem", &format!("epsg:{}", map_projection.epsg())), ("geographicCoordSystem", "epsg:4326")],
    )?;
    drop(package);
    let written = logdb::write(
        &partial(&db_path),
        request.log,
        &ticks,
        request.map_name,
        &ids,
        &log_projection,
        request.scene_s,
    )?;
    let maps_json = json!({request.map_name: {"version": MAP_VERSION, "layers": {}}});
    std::fs::write(partial(&json_path), format!("{maps_json:#}")).map_err(|e| Error::file(&json_path, e))?;
    for (from, to) in
        [(partial(&gpkg_path), &gpkg_path), (partial(&db_path), &db_path), (partial(&json_path), &json_path)]
    {
        std::fs::rename(&from, to).map_err(|e| Error::file(to, e))?;
    }
    cleanup.0.clear();
    Ok(NuplanExport {
        db: db_path,
        gpkg: gpkg_path,
        ego_states: ticks.len(),
        scenes: written,
        layers: counts,
        epsg: map_projection.epsg(),
    })
}

/// nuPlan's log names start with the date and time: `YYYY.MM.DD.HH.MM.SS` (the UTC of
/// `dash2sim_linux::utc::iso8601`, re-punctuated).
fn date_name(t_us: i64) -> String {
    dash2sim_linux::utc::iso8601(t_us).chars().take(19).map(|c| if c.is_ascii_digit() { c } else { '.' }).collect()
}

/// The nuPlan map name for a map file's stem: `dash2sim-`, then the stem in lower case with
/// `-` for anything but letters and digits.
pub fn map_name(stem: &str) -> String {
    let clean: String =
        stem.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect();
    format!("dash2sim-{}", clean.trim_matches('-'))
}

#[cfg(test)]
mod tests {
    #[test]
    fn log_names_carry_the_utc_date() {
        // 2026-06-01T08:00:00Z (the scenario clock's zero).
        assert_eq!(super::date_name(1_780_300_800_000_000), "2026.06.01.08.00.00");
        assert_eq!(super::date_name(0), "1970.01.01.00.00.00");
    }
}
