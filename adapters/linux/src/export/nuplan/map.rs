//! A map tile's lanes as nuPlan's map layers (`docs/nuplan.md`): the same lanes `map build`
//! puts in the tile, so that `verify` and nuPlan see one geometry.
//!
//! * **Lanes**: each tile lane cut at its junctions ([`super::junctions`]) into pieces that
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
use super::junctions::{layout, DisjointSets, LaneShape};
use super::projection::Projection;
use crate::geometry::{band, bezier, capsule, contains, cut, heading_at, hull, is_simple, length, point_at, Line};
use crate::{Error, Result};

const ROADBLOCK_BASE: i64 = 1_000_000;
const CONNECTOR_BASE: i64 = 2_000_000;
const ROADBLOCK_CONNECTOR_BASE: i64 = 3_000_000;
const BOUNDARY_BASE: i64 = 4_000_000;
/// Lanes are drawn this much narrower on each side, m, so that side-by-side lanes never
/// share a sliver (rounding of f32 points and of the projection) in which nuPlan would find
/// two lanes under a point.
const SEAM_M: f64 = 0.001;
/// Points on a turn's curve.
const TURN_POINTS: usize = 12;

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

/// A roadblock's outer sides (its leftmost lane's left, its rightmost lane's right) and its
/// lane rows.
#[derive(Default)]
struct RoadblockSides(Option<Line>, Option<Line>, Vec<usize>);

/// The layers of `view` in `projection`'s frame, and the ids the log export needs.
pub fn layers(view: &MapView<'_>, projection: &Projection) -> Result<(Vec<Layer>, MapIds)> {
    let lanes: Vec<_> = (0..view.len() as u32).filter_map(|i| view.lane(i)).collect();
    if lanes.is_empty() {
        return Err(Error::invalid("the map has no lanes"));
    }
    // Project every centreline once (the tile's frame is the map's origin).
    let project = |pts: Vec<(f64, f64)>| -> Line {
        let enu: Vec<(f64, f64, f64)> = pts.iter().map(|&(x, y)| (x, y, 0.0)).collect();
        projection.project(&enu)
    };
    let centrelines: Vec<Line> = lanes.iter().map(|l| project(l.points().collect())).collect();
    // Widths in projected metres: UTM shrinks distances by up to 0.04 %, which would make
    // the bands of side-by-side lanes overlap by a millimetre and more.
    let scale = {
        let unit = project(vec![(0.0, 0.0), (1.0, 0.0)]);
        length(&unit)
    };
    let count = lanes.len();
    let mut has_predecessor = vec![false; count];
    for lane in &lanes {
        for s in lane.successors() {
            if let Some(p) = has_predecessor.get_mut(s as usize) {
                *p = true;
            }
        }
    }
    // Roadblocks: lanes connected by left/right neighbours.
    let mut groups = DisjointSets::new(count);
    for (i, lane) in lanes.iter().enumerate() {
        for n in [lane.left, lane.right].into_iter().flatten().filter(|&n| (n as usize) < count) {
            groups.join(i, n as usize);
        }
    }
    let lane_index: Vec<i64> = lanes
        .iter()
        .map(|l| {
            let (mut k, mut at) = (0, l.left);
            while let Some(i) = at {
                k += 1;
                at = lanes.get(i as usize).and_then(|n| n.left);
                if k > 64 {
                    break;
                }
            }
            k
        })
        .collect();
    let shapes: Vec<LaneShape> = lanes
        .iter()
        .enumerate()
        .map(|(i, lane)| LaneShape {
            centre: centrelines[i].clone(),
            width: lane.width * scale,
            successors: lane.successors().map(|s| s as usize).filter(|&s| s < count).collect(),
            has_predecessor: has_predecessor[i],
            group: groups.root(i),
            carve: lane.area.is_none(),
        })
        .collect();
    let cut_map = layout(&shapes);

    let (mut lane_rows, mut baselines, mut boundaries): (Vec<Row>, Vec<Row>, Vec<Row>) = Default::default();
    let mut boundary_id = BOUNDARY_BASE;
    let mut add_boundary = |line: Line, boundaries: &mut Vec<Row>| {
        boundary_id += 1;
        boundaries.push((boundary_id, Geometry::LineString(line), vec![]));
        boundary_id
    };
    // Roadblock ids by (group, piece index); lane fids and roadblocks by (lane, piece).
    let mut roadblock_ids: BTreeMap<(usize, usize), i64> = BTreeMap::new();
    let mut piece_ids: BTreeMap<(usize, usize), (i64, i64)> = BTreeMap::new();
    let mut roadblock_sides: BTreeMap<i64, RoadblockSides> = BTreeMap::new();
    for (i, lane) in lanes.iter().enumerate() {
        for (k, &(from, to)) in cut_map.pieces[i].iter().enumerate() {
            let next = ROADBLOCK_BASE + 1 + roadblock_ids.len() as i64;
            let roadblock = *roadblock_ids.entry((shapes[i].group, k)).or_insert(next);
            let centre = cut(&centrelines[i], from, to);
            let (ring, left, right) = band(&centre, lane.width * scale / 2.0 - SEAM_M);
            let (left_id, right_id) =
                (add_boundary(left.clone(), &mut boundaries), add_boundary(right.clone(), &mut boundaries));
            let fid = lane_rows.len() as i64 + 1;
            piece_ids.insert((i, k), (fid, roadblock));
            let speed = lane.speed_limit.map_or(Value::Null, Value::Real);
            let sides = roadblock_sides.entry(roadblock).or_default();
            sides.2.push(lane_rows.len());
            lane_rows.push((
                fid,
                Geometry::Polygon(ring),
                vec![
                    Value::Int(fid),
                    Value::Int(roadblock),
                    Value::Int(lane_index[i]),
                    speed,
                    Value::Int(left_id),
                    Value::Int(right_id),
                ],
            ));
            baselines.push((fid, Geometry::LineString(centre), vec![Value::Int(fid), Value::Null]));
            if lane.left.is_none() {
                sides.0 = Some(left);
            }
            if lane.right.is_none() {
                sides.1 = Some(right);
            }
        }
    }
    // Roadblocks: the leftmost lane's left side and the rightmost lane's right side.
    let mut roadblocks = Vec::new();
    for (&id, RoadblockSides(left, right, members)) in &roadblock_sides {
        let ring = match (left, right) {
            (Some(l), Some(r)) => {
                let mut ring = l.clone();
                ring.extend(r.iter().rev());
                ring
            }
            _ => hull(members.iter().flat_map(|&r| lane_rows[r].1.points().to_vec()).collect()),
        };
        roadblocks.push((id, Geometry::Polygon(ring), vec![]));
    }
    // Connectors.
    let (mut connectors, mut connector_polygons) = (Vec::new(), Vec::new());
    let mut roadblock_connectors: BTreeMap<(i64, i64), (i64, Line)> = BTreeMap::new();
    let mut connector_id = CONNECTOR_BASE;
    for join in &cut_map.joins {
        let ((i, k), (j, l)) = (join.from, join.to);
        let (Some(&(from_fid, from_block)), Some(&(to_fid, to_block))) =
            (piece_ids.get(&(i, k)), piece_ids.get(&(j, l)))
        else {
            continue;
        };
        let (end, start) = (cut_map.pieces[i][k].1, cut_map.pieces[j][l].0);
        let mut line = if i == j {
            cut(&centrelines[i], end, start)
        } else {
            let (a, b) = (point_at(&centrelines[i], end), point_at(&centrelines[j], start));
            bezier(a, heading_at(&centrelines[i], end), b, heading_at(&centrelines[j], start), TURN_POINTS)
        };
        line.dedup();
        if line.len() < 2 || length(&line) < 1e-3 {
            continue;
        }
        connector_id += 1;
        let width = lanes[i].width.min(lanes[j].width) * scale;
        let (ring, left, right) = band(&line, width / 2.0);
        // A turn tighter than half the lane's width folds its band over on the inside: its
        // hull stands for it (a polygon must be simple).
        let ring = if is_simple(&ring) { ring } else { hull(ring) };
        let (left_id, right_id) = (add_boundary(left, &mut boundaries), add_boundary(right, &mut boundaries));
        let key = (from_block, to_block);
        let next_id = ROADBLOCK_CONNECTOR_BASE + 1 + roadblock_connectors.len() as i64;
        let entry = roadblock_connectors.entry(key).or_insert((next_id, Vec::new()));
        entry.1.extend(ring.iter().copied());
        let speed = lanes[i].speed_limit.map_or(Value::Null, Value::Real);
        connectors.push((
            connector_id,
            Geometry::LineString(line.clone()),
            vec![
                Value::Int(from_fid),
                Value::Int(to_fid),
                Value::Int(key.0),
                Value::Int(key.1),
                Value::Int(entry.0),
                Value::Null,
                speed,
                Value::Text(String::new()),
            ],
        ));
        connector_polygons.push((
            connector_id,
            Geometry::Polygon(ring),
            vec![Value::Int(connector_id), Value::Int(left_id), Value::Int(right_id)],
        ));
        baselines.push((0, Geometry::LineString(line), vec![Value::Null, Value::Int(connector_id)]));
    }
    let roadblock_connector_rows = roadblock_connectors
        .iter()
        .map(|(&(from, to), (id, points))| {
            (*id, Geometry::Polygon(hull(points.clone())), vec![Value::Int(from), Value::Int(to), Value::Null])
        })
        .collect();
    // The tile's drivable area: one capsule per centreline segment, and its polygons.
    let mut drivable = Vec::new();
    for (i, lane) in lanes.iter().enumerate() {
        if lane.area.is_some() {
            continue;
        }
        for w in centrelines[i].windows(2) {
            drivable.push((
                drivable.len() as i64 + 1,
                Geometry::Polygon(capsule(w[0], w[1], lane.width * scale / 2.0)),
                vec![],
            ));
        }
    }
    for g in 0..view.header().polygons {
        if let Some(points) = view.polygon(g) {
            drivable.push((drivable.len() as i64 + 1, Geometry::Polygon(project(points.collect())), vec![]));
        }
    }
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
