//! A map tile's lanes as nuPlan's map layers (`docs/nuplan.md`): the same lanes `map build`
//! puts in the tile, so that `verify` and nuPlan see one geometry — the pieces, roadblocks,
//! connectors and drivable area of [`crate::road`], as nuPlan's tables.
//!
//! * **Lanes**: each tile lane cut at its junctions ([`crate::junctions`]) into pieces that
//!   overlap no other lane; each piece as `lanes_polygons` (its centreline offset by half
//!   the width, in projected metres and less a 1 mm seam, on each side), its
//!   `baseline_paths` row and two `boundaries`.
//! * **Roadblocks** (`lane_groups_polygons`): pieces side by side, of lanes joined by
//!   left/right neighbours; their `lane_index` counts from the leftmost (0).
//! * **Lane connectors**: one per join through a junction — along the centreline where a
//!   lane goes on, a cubic curve between two lanes; grouped by (roadblock, roadblock) into
//!   roadblock connectors.
//! * **Drivable area**: the roadblocks as `road_segments`, and — so that nuPlan's drivable
//!   area equals the tile's (round caps and joins) — every centreline segment's capsule and
//!   every tile polygon as `generic_drivable_areas`.
//!
//! Ids never collide across kinds (PDM-Closed keys lanes and connectors in one dictionary):
//! lanes 1…, roadblocks 1 000 001…, connectors 2 000 001…, roadblock connectors
//! 3 000 001…, boundaries 4 000 001….

use std::collections::BTreeMap;

use dash2sim_core::map::MapView;

use super::gpkg::{Geometry, Layer, Value};
use crate::projection::Projection;
use crate::road::road;
use dash2sim_linux::geometry::{contains, hull, Line};
use dash2sim_linux::Result;

const ROADBLOCK_BASE: i64 = 1_000_000;
const CONNECTOR_BASE: i64 = 2_000_000;
const ROADBLOCK_CONNECTOR_BASE: i64 = 3_000_000;
const BOUNDARY_BASE: i64 = 4_000_000;
/// Lanes are drawn this much narrower on each side, m, so that side-by-side lanes never
/// share a sliver (rounding of f32 points and of the projection) in which nuPlan would find
/// two lanes under a point.
const SEAM_M: f64 = 0.001;

/// What the log export needs to know about the map besides its layers.
#[derive(Debug, Clone, Default)]
pub struct MapIds {
    /// Every roadblock: id, bounding box (x0, y0, x1, y1) and polygon.
    pub roadblocks: Vec<(i64, [f64; 4], Line)>,
    /// Roadblock connector id by (from roadblock, to roadblock).
    pub roadblock_connectors: BTreeMap<(i64, i64), i64>,
}

impl MapIds {
    /// The roadblock under `p` (projected), if any.
    pub fn roadblock_at(&self, p: (f64, f64)) -> Option<i64> {
        self.roadblocks
            .iter()
            .find(|(_, b, ring)| p.0 >= b[0] && p.1 >= b[1] && p.0 <= b[2] && p.1 <= b[3] && contains(ring, p))
            .map(|(id, _, _)| *id)
    }
}

type Row = (i64, Geometry, Vec<Value>);

/// The layers of `view` in `projection`'s frame, and the ids the log export needs.
pub fn layers(view: &MapView<'_>, projection: &Projection) -> Result<(Vec<Layer>, MapIds)> {
    let road = road(view, projection, SEAM_M)?;
    let (mut lane_rows, mut baselines, mut boundaries): (Vec<Row>, Vec<Row>, Vec<Row>) = Default::default();
    let add_boundary = |line: &Line, boundaries: &mut Vec<Row>| {
        let id = BOUNDARY_BASE + 1 + boundaries.len() as i64;
        boundaries.push((id, Geometry::LineString(line.clone()), vec![]));
        id
    };
    let roadblock_id = |index: usize| ROADBLOCK_BASE + 1 + index as i64;
    // Lane fids (1…) and roadblock ids, by piece.
    let mut piece_ids = Vec::with_capacity(road.pieces.len());
    for piece in &road.pieces {
        let (left_id, right_id) =
            (add_boundary(&piece.left, &mut boundaries), add_boundary(&piece.right, &mut boundaries));
        let fid = lane_rows.len() as i64 + 1;
        let roadblock = roadblock_id(piece.roadblock);
        piece_ids.push((fid, roadblock));
        lane_rows.push((
            fid,
            Geometry::Polygon(piece.ring.clone()),
            vec![
                Value::Int(fid),
                Value::Int(roadblock),
                Value::Int(piece.lane_index),
                piece.speed_limit.map_or(Value::Null, Value::Real),
                Value::Int(left_id),
                Value::Int(right_id),
            ],
        ));
        baselines.push((fid, Geometry::LineString(piece.centre.clone()), vec![Value::Int(fid), Value::Null]));
    }
    let roadblocks: Vec<Row> = road
        .roadblocks
        .iter()
        .enumerate()
        .map(|(k, ring)| (roadblock_id(k), Geometry::Polygon(ring.clone()), vec![]))
        .collect();
    // Connectors, grouped by (roadblock, roadblock) into roadblock connectors.
    let (mut connectors, mut connector_polygons) = (Vec::new(), Vec::new());
    let mut roadblock_connectors: BTreeMap<(i64, i64), (i64, Line)> = BTreeMap::new();
    for (k, c) in road.connectors.iter().enumerate() {
        let connector_id = CONNECTOR_BASE + 1 + k as i64;
        let ((from_fid, from_block), (to_fid, to_block)) = (piece_ids[c.from], piece_ids[c.to]);
        let (left_id, right_id) = (add_boundary(&c.left, &mut boundaries), add_boundary(&c.right, &mut boundaries));
        let key = (from_block, to_block);
        let next_id = ROADBLOCK_CONNECTOR_BASE + 1 + roadblock_connectors.len() as i64;
        let entry = roadblock_connectors.entry(key).or_insert((next_id, Vec::new()));
        entry.1.extend(c.ring.iter().copied());
        connectors.push((
            connector_id,
            Geometry::LineString(c.centre.clone()),
            vec![
                Value::Int(from_fid),
                Value::Int(to_fid),
                Value::Int(key.0),
                Value::Int(key.1),
                Value::Int(entry.0),
                Value::Null,
                c.speed_limit.map_or(Value::Null, Value::Real),
                Value::Text(String::new()),
            ],
        ));
        connector_polygons.push((
            connector_id,
            Geometry::Polygon(c.ring.clone()),
            vec![Value::Int(connector_id), Value::Int(left_id), Value::Int(right_id)],
        ));
        baselines.push((0, Geometry::LineString(c.centre.clone()), vec![Value::Null, Value::Int(connector_id)]));
    }
    let roadblock_connector_rows = roadblock_connectors
        .iter()
        .map(|(&(from, to), (id, points))| {
            (*id, Geometry::Polygon(hull(points.clone())), vec![Value::Int(from), Value::Int(to), Value::Null])
        })
        .collect();
    let drivable: Vec<Row> = road
        .drivable
        .iter()
        .enumerate()
        .map(|(k, ring)| (k as i64 + 1, Geometry::Polygon(ring.clone()), vec![]))
        .collect();
    // Baseline path fids in order.
    for (k, b) in baselines.iter_mut().enumerate() {
        b.0 = k as i64 + 1;
    }
    let ids = MapIds {
        roadblocks: roadblocks
            .iter()
            .map(|(id, ring, _)| {
                let points = ring.points();
                let bounds =
                    points.iter().fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, p| {
                        [b[0].min(p.0), b[1].min(p.1), b[2].max(p.0), b[3].max(p.1)]
                    });
                (*id, bounds, points.to_vec())
            })
            .collect(),
        roadblock_connectors: roadblock_connectors.iter().map(|(k, (id, _))| (*k, *id)).collect(),
    };
    let empty = |name: &'static str| Layer { name, geometry_type: "POLYGON", columns: vec![], features: vec![] };
    let layers = vec![
        Layer {
            name: "lanes_polygons",
            geometry_type: "POLYGON",
            columns: vec![
                ("lane_fid", "INTEGER"),
                ("lane_group_fid", "INTEGER"),
                ("lane_index", "INTEGER"),
                ("speed_limit_mps", "REAL"),
                ("left_boundary_fid", "INTEGER"),
                ("right_boundary_fid", "INTEGER"),
            ],
            features: lane_rows,
        },
        Layer { name: "lane_groups_polygons", geometry_type: "POLYGON", columns: vec![], features: roadblocks.clone() },
        Layer {
            name: "lane_connectors",
            geometry_type: "LINESTRING",
            columns: vec![
                ("exit_lane_fid", "INTEGER"),
                ("entry_lane_fid", "INTEGER"),
                ("exit_lane_group_fid", "INTEGER"),
                ("entry_lane_group_fid", "INTEGER"),
                ("lane_group_connector_fid", "INTEGER"),
                ("intersection_fid", "INTEGER"),
                ("speed_limit_mps", "REAL"),
                ("traffic_light_stop_line_fids", "TEXT"),
            ],
            features: connectors,
        },
        Layer {
            name: "lane_group_connectors",
            geometry_type: "POLYGON",
            columns: vec![
                ("from_lane_group_fid", "INTEGER"),
                ("to_lane_group_fid", "INTEGER"),
                ("intersection_fid", "INTEGER"),
            ],
            features: roadblock_connector_rows,
        },
        Layer {
            name: "baseline_paths",
            geometry_type: "LINESTRING",
            columns: vec![("lane_fid", "REAL"), ("lane_connector_fid", "REAL")],
            features: baselines,
        },
        Layer {
            name: "gen_lane_connectors_scaled_width_polygons",
            geometry_type: "POLYGON",
            columns: vec![
                ("lane_connector_fid", "INTEGER"),
                ("left_boundary_fid", "INTEGER"),
                ("right_boundary_fid", "INTEGER"),
            ],
            features: connector_polygons,
        },
        Layer { name: "boundaries", geometry_type: "LINESTRING", columns: vec![], features: boundaries },
        Layer { name: "road_segments", geometry_type: "POLYGON", columns: vec![], features: roadblocks },
        Layer { name: "generic_drivable_areas", geometry_type: "POLYGON", columns: vec![], features: drivable },
        empty("intersections"),
        empty("carpark_areas"),
        empty("crosswalks"),
        empty("walkways"),
        empty("stop_polygons"),
    ];
    Ok((layers, ids))
}
