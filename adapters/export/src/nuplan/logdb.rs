//! A 4D log as a nuPlan log database (SQLite, the devkit's schema as its queries read it;
//! `docs/nuplan.md`): the ego at exactly 20 Hz (`lidar_pc` is the clock), body-frame
//! velocities and accelerations, 3D tracks as `track` + `lidar_box` with nuPlan
//! categories, scenes in time order with the route's roadblocks ahead and a goal.

use std::collections::BTreeMap;
use std::path::Path;

use rusqlite::{params, Connection};

use super::map::MapIds;
use crate::projection::Projection;
use crate::ticks::{agents_at_ticks, EgoTick};
use dash2sim_core::class::name_of as class_name;
use dash2sim_linux::log::LogContents;
use dash2sim_linux::{Error, Result};

/// nuPlan's clock, Hz (the devkit hard-codes 0.05 s).
pub const RATE_HZ: f64 = 20.0;
/// nuPlan's categories, in the order of their rows.
const CATEGORIES: [&str; 7] =
    ["vehicle", "bicycle", "pedestrian", "traffic_cone", "barrier", "czone_sign", "generic_object"];

/// The nuPlan category of a dash2sim class.
pub fn category(class: &str) -> &'static str {
    match class {
        "car" | "truck" | "bus" | "motorcycle" => "vehicle",
        "bicycle" => "bicycle",
        "pedestrian" => "pedestrian",
        "cone" => "traffic_cone",
        "drum" | "barricade" | "barrier" => "barrier",
        "sign" | "arrow_board" => "czone_sign",
        _ => "generic_object",
    }
}

/// Scenes of `scene_s` in `ticks` ticks: whole scenes, the last one taking the rest.
pub fn scene_count(ticks: usize, scene_s: f64) -> usize {
    (ticks / ((scene_s * RATE_HZ).round() as usize).max(1)).max(1)
}

/// An 8-byte token: the kind in the high byte, a counter below.
fn token(kind: u8, index: usize) -> Vec<u8> {
    ((u64::from(kind) << 56) | index as u64).to_be_bytes().to_vec()
}

/// The roadblocks (and roadblock connectors between them) the ego's rear axle is on, in
/// order, from tick `from` on: nuPlan's own polygons, so that its route and the ego agree.
fn route(ticks: &[EgoTick], from: usize, ids: &MapIds) -> Vec<i64> {
    let mut out: Vec<i64> = Vec::new();
    for tick in &ticks[from..] {
        let Some(roadblock) = ids.roadblock_at((tick.x, tick.y)) else { continue };
        if let Some(&previous) = out.last() {
            if previous == roadblock {
                continue;
            }
            if let Some(&connector) = ids.roadblock_connectors.get(&(previous, roadblock)) {
                out.push(connector);
            }
        }
        out.push(roadblock);
    }
    out
}

/// Write the log database at `path` (which must not exist).
#[allow(clippy::too_many_arguments)]
pub fn write(
    path: &Path,
    log: &LogContents,
    ticks: &[EgoTick],
    map_name: &str,
    ids: &MapIds,
    log_projection: &Projection,
    scene_s: f64,
) -> Result<usize> {
    let err = |e: rusqlite::Error| Error::file(path, e);
    let mut db = Connection::open(path).map_err(err)?;
    db.execute_batch(SCHEMA).map_err(err)?;
    let tx = db.transaction().map_err(err)?;
    let log_token = token(1, 0);
    let lidar_token = token(2, 0);
    let start = ticks.first().map_or(0, |t| t.t_us);
    tx.execute(
        "INSERT INTO log VALUES (?1, 'dash2sim', ?2, ?3, ?4, ?5, ?5)",
        params![log_token, format!("{}", start / 1_000_000), start, "dash2sim", map_name],
    )
    .map_err(err)?;
    tx.execute(
        "INSERT INTO lidar VALUES (?1, ?2, 'MergedPointCloud', 'none', NULL, NULL)",
        params![lidar_token, log_token],
    )
    .map_err(err)?;
    for (k, name) in CATEGORIES.iter().enumerate() {
        tx.execute("INSERT INTO category VALUES (?1, ?2, ?2)", params![token(3, k), name]).map_err(err)?;
    }
    let per_scene = ((scene_s * RATE_HZ).round() as usize).max(1);
    let scenes = scene_count(ticks.len(), scene_s);
    for (i, t) in ticks.iter().enumerate() {
        let (qw, qz) = ((t.heading / 2.0).cos(), (t.heading / 2.0).sin());
        tx.execute(
            "INSERT INTO ego_pose VALUES (?1, ?2, ?3, ?4, ?5, ?6, 0, 0, ?7, ?8, ?9, 0, ?10, ?11, 0, 0, 0, ?12, ?13, ?14)",
            params![
                token(4, i),
                t.t_us,
                t.x,
                t.y,
                t.z,
                qw,
                qz,
                t.velocity.0,
                t.velocity.1,
                t.acceleration.0,
                t.acceleration.1,
                t.yaw_rate,
                log_projection.epsg(),
                log_token
            ],
        )
        .map_err(err)?;
        let next = (i + 1 < ticks.len()).then(|| token(5, i + 1));
        let previous = i.checked_sub(1).map(|p| token(5, p));
        tx.execute(
            "INSERT INTO lidar_pc VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
            params![
                token(5, i),
                next,
                previous,
                token(4, i),
                lidar_token,
                token(6, (i / per_scene).min(scenes - 1)),
                format!("MergedPointCloud/{i:06}.pcd"),
                t.t_us
            ],
        )
        .map_err(err)?;
    }
    for s in 0..scenes {
        let first = s * per_scene;
        // The goal: the ego's pose at the end of the drive, the route: roadblocks ahead.
        let goal = ticks.len() - 1;
        let roadblocks: Vec<String> = route(ticks, first, ids).iter().map(i64::to_string).collect();
        tx.execute(
            "INSERT INTO scene VALUES (?1, ?2, ?3, ?4, ?5)",
            params![token(6, s), log_token, format!("scene-{s:04}"), token(4, goal), roadblocks.join(" ")],
        )
        .map_err(err)?;
    }
    // Tracks and their boxes, chained per track.
    let boxes = agents_at_ticks(log, ticks, log_projection);
    let mut by_track: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    for (k, b) in boxes.iter().enumerate() {
        by_track.entry(b.track.id).or_default().push(k);
    }
    for (n, members) in by_track.values().enumerate() {
        let Some(&first) = members.first() else { continue };
        let t = &boxes[first].track;
        let category = CATEGORIES.iter().position(|c| *c == category(class_name(t.class))).unwrap_or(6);
        tx.execute(
            "INSERT INTO track VALUES (?1, ?2, ?3, ?4, ?5)",
            params![token(7, n), token(3, category), t.w_mm as f64 * 1e-3, t.l_mm as f64 * 1e-3, t.h_mm as f64 * 1e-3],
        )
        .map_err(err)?;
        for (m, &k) in members.iter().enumerate() {
            let b = &boxes[k];
            tx.execute(
                "INSERT INTO lidar_box VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, 0, ?14, 1.0)",
                params![
                    token(8, k),
                    token(5, b.tick),
                    token(7, n),
                    members.get(m + 1).map(|&j| token(8, j)),
                    m.checked_sub(1).map(|p| token(8, members[p])),
                    b.x,
                    b.y,
                    b.z,
                    b.track.w_mm as f64 * 1e-3,
                    b.track.l_mm as f64 * 1e-3,
                    b.track.h_mm as f64 * 1e-3,
                    b.velocity.0,
                    b.velocity.1,
                    b.heading
                ],
            )
            .map_err(err)?;
        }
    }
    tx.commit().map_err(err)?;
    Ok(scenes)
}

const SCHEMA: &str = "
CREATE TABLE log (token BLOB NOT NULL, vehicle_name VARCHAR(64), date VARCHAR(64), timestamp INTEGER,
  logfile VARCHAR(64), location VARCHAR(64), map_version VARCHAR(64), PRIMARY KEY (token));
CREATE TABLE lidar (token BLOB NOT NULL, log_token BLOB NOT NULL, channel VARCHAR(64), model VARCHAR(64),
  translation BLOB, rotation BLOB, PRIMARY KEY (token));
CREATE TABLE ego_pose (token BLOB NOT NULL, timestamp INTEGER, x FLOAT, y FLOAT, z FLOAT, qw FLOAT, qx FLOAT, qy FLOAT,
  qz FLOAT, vx FLOAT, vy FLOAT, vz FLOAT, acceleration_x FLOAT, acceleration_y FLOAT, acceleration_z FLOAT,
  angular_rate_x FLOAT, angular_rate_y FLOAT, angular_rate_z FLOAT, epsg INTEGER, log_token BLOB NOT NULL,
  PRIMARY KEY (token));
CREATE TABLE scene (token BLOB NOT NULL, log_token BLOB NOT NULL, name TEXT, goal_ego_pose_token BLOB,
  roadblock_ids TEXT, PRIMARY KEY (token));
CREATE TABLE lidar_pc (token BLOB NOT NULL, next_token BLOB, prev_token BLOB, ego_pose_token BLOB NOT NULL,
  lidar_token BLOB NOT NULL, scene_token BLOB, filename VARCHAR(128), timestamp INTEGER, PRIMARY KEY (token));
CREATE TABLE category (token BLOB NOT NULL, name VARCHAR(64), description TEXT, PRIMARY KEY (token));
CREATE TABLE track (token BLOB NOT NULL, category_token BLOB NOT NULL, width FLOAT, length FLOAT, height FLOAT,
  PRIMARY KEY (token));
CREATE TABLE lidar_box (token BLOB NOT NULL, lidar_pc_token BLOB NOT NULL, track_token BLOB NOT NULL, next_token BLOB,
  prev_token BLOB, x FLOAT, y FLOAT, z FLOAT, width FLOAT, length FLOAT, height FLOAT, vx FLOAT, vy FLOAT, vz FLOAT,
  yaw FLOAT, confidence FLOAT, PRIMARY KEY (token));
CREATE TABLE traffic_light_status (token BLOB NOT NULL, lidar_pc_token BLOB NOT NULL, lane_connector_id INTEGER,
  status VARCHAR(8), PRIMARY KEY (token));
CREATE TABLE scenario_tag (token BLOB NOT NULL, lidar_pc_token BLOB NOT NULL, type TEXT, agent_track_token BLOB,
  PRIMARY KEY (token));
CREATE INDEX lidar_pc_timestamp ON lidar_pc (timestamp);
CREATE INDEX lidar_box_pc ON lidar_box (lidar_pc_token);
";
