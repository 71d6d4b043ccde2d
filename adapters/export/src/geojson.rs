//! GeoJSON (QGIS, geojson.io): a log's ego trajectory and GNSS fixes as lines, its objects
//! as points.

use dash2sim_core::binlog::Record;
use dash2sim_core::nalgebra::Vector3;
use dash2sim_linux::log::views::{ego_enu, ego_poses, last_tracks};
use dash2sim_linux::log::{frame, seconds, LogContents};
use dash2sim_linux::{Error, Result};
use serde_json::{json, Value};

/// GeoJSON: the ego trajectory and the GNSS fixes as LineStrings, every 3D track's last
/// position as a Point with its properties.
pub fn geojson(log: &LogContents) -> Result<Value> {
    let header = log.header.ok_or_else(|| Error::invalid("the log's header is damaged: no geodetic origin"))?;
    let frame = frame(&header).ok_or_else(|| Error::invalid("the log's origin is not a valid position"))?;
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
                "class": dash2sim_core::class::name_of(t.class),
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
