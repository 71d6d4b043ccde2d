//! A map tile's lanes as nuPlan's map layers (`docs/nuplan.md`): the same lanes `map build`
//! puts in the tile, so that `verify` and nuPlan see one geometry.
//!
//! * **Lanes**: each tile lane, its centreline trimmed by up to 2 m at an end that joins
//!   another lane, as `lanes_polygons` (the trimmed centreline offset by half the width on
//!   each side), its `baseline_paths` row and two `boundaries`.
//! * **Roadblocks** (`lane_groups_polygons`): lanes joined by left/right neighbours; their
//!   `lane_index` counts from the leftmost (0).
//! * **Lane connectors**: one per successor relation, the trimmed end of one lane and the
//!   trimmed start of the next; grouped by (roadblock, roadblock) into roadblock connectors.
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
use super::projection::Projection;

const ROADBLOCK_BASE: i64 = 1_000_000;
const CONNECTOR_BASE: i64 = 2_000_000;
const ROADBLOCK_CONNECTOR_BASE: i64 = 3_000_000;
const BOUNDARY_BASE: i64 = 4_000_000;
/// Length taken from each joined lane end for its connectors, m (at most a quarter of the
/// lane).
const TRIM_M: f64 = 2.0;
/// Points on a half circle of a capsule.
const CAP_POINTS: usize = 16;

/// What the log export needs to know about the map besides its layers.
#[derive(Debug, Clone)]
pub struct MapIds {
    /// Roadblock id of every tile lane.
    pub roadblock_of_lane: Vec<i64>,
    /// Roadblock connector id by (from roadblock, to roadblock).
    pub roadblock_connectors: BTreeMap<(i64, i64), i64>,
}

type Line = Vec<(f64, f64)>;

fn length(line: &[(f64, f64)]) -> f64 {
    line.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).sum()
}

/// The part of `line` between arc lengths `from` and `to`.
fn cut(line: &[(f64, f64)], from: f64, to: f64) -> Line {
    let mut out = Vec::new();
    let mut s = 0.0;
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        let l = (b.0 - a.0).hypot(b.1 - a.1);
        let at = |d: f64| {
            let f = if l > 0.0 { ((d - s) / l).clamp(0.0, 1.0) } else { 0.0 };
            (a.0 + (b.0 - a.0) * f, a.1 + (b.1 - a.1) * f)
        };
        if s + l >= from && s <= to {
            if out.is_empty() {
                out.push(at(from.max(s)));
            }
            out.push(at(to.min(s + l)));
        }
        s += l;
    }
    out.dedup();
    if out.len() == 1 {
        out.push(out[0]);
    }
    out
}

/// `line` moved sideways by `d` (left positive), each vertex along the mean of its
/// segments' normals scaled so that straight stretches keep their distance.
fn offset(line: &[(f64, f64)], d: f64) -> Line {
    let normal = |a: (f64, f64), b: (f64, f64)| {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let l = dx.hypot(dy).max(1e-9);
        (-dy / l, dx / l)
    };
    let n = line.len();
    (0..n)
        .map(|k| {
            let before = (k > 0).then(|| normal(line[k - 1], line[k]));
            let after = (k + 1 < n).then(|| normal(line[k], line[k + 1]));
            let (nx, ny) = match (before, after) {
                (Some(a), Some(b)) => {
                    let (x, y) = (a.0 + b.0, a.1 + b.1);
                    let l = x.hypot(y).max(1e-9);
                    // 1/cos of the half angle, limited at sharp turns.
                    let scale = (2.0 / (1.0 + a.0 * b.0 + a.1 * b.1).max(0.25)).sqrt();
                    (x / l * scale, y / l * scale)
                }
                (Some(a), None) | (None, Some(a)) => a,
                (None, None) => (0.0, 0.0),
            };
            (line[k].0 + nx * d, line[k].1 + ny * d)
        })
        .collect()
}

/// The polygon between a centreline's two offsets.
fn band(line: &[(f64, f64)], half_width: f64) -> (Line, Line, Line) {
    let left = offset(line, half_width);
    let right = offset(line, -half_width);
    let mut ring = left.clone();
    ring.extend(right.iter().rev());
    (ring, left, right)
}

/// A segment's capsule (round caps), as a polygon.
fn capsule(a: (f64, f64), b: (f64, f64), r: f64) -> Line {
    let heading = (b.1 - a.1).atan2(b.0 - a.0);
    let mut ring = Vec::with_capacity(2 * CAP_POINTS + 2);
    for (centre, start) in [(b, heading - std::f64::consts::FRAC_PI_2), (a, heading + std::f64::consts::FRAC_PI_2)] {
        for k in 0..=CAP_POINTS {
            let angle = start + std::f64::consts::PI * k as f64 / CAP_POINTS as f64;
            ring.push((centre.0 + r * angle.cos(), centre.1 + r * angle.sin()));
        }
    }
    ring
}

/// Convex hull (Andrew's monotone chain), counter-clockwise.
fn hull(mut points: Vec<(f64, f64)>) -> Line {
    points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0);
    let mut lower: Line = Vec::new();
    for &p in &points {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Line = Vec::new();
    for &p in points.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0.0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

/// The layers of `view` in `projection`'s frame, and the ids the log export needs.
pub fn layers(view: &MapView<'_>, projection: &Projection) -> Result<(Vec<Layer>, MapIds), String> {
    let lanes: Vec<_> = (0..view.len() as u32).filter_map(|i| view.lane(i)).collect();
    if lanes.is_empty() {
        return Err("the map has no lanes".to_owned());
    }
    // Project every centreline once (the tile's frame is the map's origin).
    let project = |pts: Vec<(f64, f64)>| -> Line {
        let enu: Vec<(f64, f64, f64)> = pts.iter().map(|&(x, y)| (x, y, 0.0)).collect();
        projection.project(&enu)
    };
    let centrelines: Vec<Line> = lanes.iter().map(|l| project(l.points().collect())).collect();
    let count = lanes.len();
    let mut predecessors = vec![0usize; count];
    for lane in &lanes {
        for s in lane.successors() {
            if let Some(p) = predecessors.get_mut(s as usize) {
                *p += 1;
            }
        }
    }
    // Roadblocks: connected by left/right neighbours.
    let mut group: Vec<usize> = (0..count).collect();
    fn root(group: &mut [usize], mut i: usize) -> usize {
        while group[i] != i {
            group[i] = group[group[i]];
            i = group[i];
        }
        i
    }
    for (i, lane) in lanes.iter().enumerate() {
        for n in [lane.left, lane.right].into_iter().flatten() {
            let (a, b) = (root(&mut group, i), root(&mut group, n as usize));
            if a != b && (n as usize) < count {
                group[a.max(b)] = a.min(b);
            }
        }
    }
    let mut roadblock_index = BTreeMap::new();
    let roadblock_of_lane: Vec<i64> = (0..count)
        .map(|i| {
            let r = root(&mut group, i);
            let next = roadblock_index.len() as i64;
            ROADBLOCK_BASE + 1 + *roadblock_index.entry(r).or_insert(next)
        })
        .collect();
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
    let trims: Vec<(f64, f64, f64)> = lanes
        .iter()
        .zip(&centrelines)
        .enumerate()
        .map(|(i, (lane, c))| {
            let l = length(c);
            let d = TRIM_M.min(0.25 * l);
            let start = if predecessors[i] > 0 { d } else { 0.0 };
            let end = if lane.successors().next().is_some() { d } else { 0.0 };
            (start, l - end, l)
        })
        .collect();

    let (mut lane_rows, mut baselines, mut boundaries) = (Vec::new(), Vec::new(), Vec::new());
    let mut roadblock_sides: BTreeMap<i64, (Option<Line>, Option<Line>)> = BTreeMap::new();
    let mut boundary_id = BOUNDARY_BASE;
    let mut add_boundary = |line: Line, boundaries: &mut Vec<(i64, Geometry, Vec<Value>)>| {
        boundary_id += 1;
        boundaries.push((boundary_id, Geometry::LineString(line), vec![]));
        boundary_id
    };
    for (i, lane) in lanes.iter().enumerate() {
        let (start, end, _) = trims[i];
        let centre = cut(&centrelines[i], start, end);
        let (ring, left, right) = band(&centre, lane.width / 2.0);
        let (left_id, right_id) =
            (add_boundary(left.clone(), &mut boundaries), add_boundary(right.clone(), &mut boundaries));
        let fid = i as i64 + 1;
        let speed = lane.speed_limit.map_or(Value::Null, Value::Real);
        lane_rows.push((
            fid,
            Geometry::Polygon(ring),
            vec![
                Value::Int(fid),
                Value::Int(roadblock_of_lane[i]),
                Value::Int(lane_index[i]),
                speed,
                Value::Int(left_id),
                Value::Int(right_id),
            ],
        ));
        baselines.push((fid, Geometry::LineString(centre), vec![Value::Int(fid), Value::Null]));
        let sides = roadblock_sides.entry(roadblock_of_lane[i]).or_default();
        if lane.left.is_none() {
            sides.0 = Some(left);
        }
        if lane.right.is_none() {
            sides.1 = Some(right);
        }
    }
    // Roadblocks: the leftmost lane's left side and the rightmost lane's right side.
    let mut roadblocks = Vec::new();
    for (&id, (left, right)) in &roadblock_sides {
        let members: Vec<usize> = (0..count).filter(|&i| roadblock_of_lane[i] == id).collect();
        let ring = match (left, right) {
            (Some(l), Some(r)) => {
                let mut ring = l.clone();
                ring.extend(r.iter().rev());
                ring
            }
            _ => hull(members.iter().flat_map(|&i| lane_rows[i].1.points().to_vec()).collect()),
        };
        roadblocks.push((id, Geometry::Polygon(ring), vec![]));
    }
    // Connectors.
    let (mut connectors, mut connector_polygons) = (Vec::new(), Vec::new());
    let mut roadblock_connectors: BTreeMap<(i64, i64), (i64, Line)> = BTreeMap::new();
    let mut connector_id = CONNECTOR_BASE;
    for (i, lane) in lanes.iter().enumerate() {
        for j in lane.successors() {
            let j = j as usize;
            let Some(next) = lanes.get(j) else { continue };
            let (_, end, total) = trims[i];
            let (start_next, _, _) = trims[j];
            let mut line = cut(&centrelines[i], end, total);
            line.extend(cut(&centrelines[j], 0.0, start_next).into_iter().skip(1));
            line.dedup();
            if line.len() < 2 || length(&line) < 1e-3 {
                continue;
            }
            connector_id += 1;
            let width = lane.width.min(next.width);
            let (ring, left, right) = band(&line, width / 2.0);
            let (left_id, right_id) = (add_boundary(left, &mut boundaries), add_boundary(right, &mut boundaries));
            let key = (roadblock_of_lane[i], roadblock_of_lane[j]);
            let next_id = ROADBLOCK_CONNECTOR_BASE + 1 + roadblock_connectors.len() as i64;
            let entry = roadblock_connectors.entry(key).or_insert((next_id, Vec::new()));
            entry.1.extend(ring.iter().copied());
            let speed = lane.speed_limit.map_or(Value::Null, Value::Real);
            connectors.push((
                connector_id,
                Geometry::LineString(line.clone()),
                vec![
                    Value::Int(i as i64 + 1),
                    Value::Int(j as i64 + 1),
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
                Geometry::Polygon(capsule(w[0], w[1], lane.width / 2.0)),
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
    let ids = MapIds {
        roadblock_of_lane,
        roadblock_connectors: roadblock_connectors.iter().map(|(k, (id, _))| (*k, *id)).collect(),
    };
    Ok((layers, ids))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cutting_offsetting_and_capsules() {
        let line = vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)];
        assert_eq!(cut(&line, 2.0, 12.0), vec![(2.0, 0.0), (10.0, 0.0), (10.0, 2.0)]);
        // A right-angle corner offset by 1 to the left: the corner point moves to (9, 1).
        let left = offset(&line, 1.0);
        assert!((left[1].0 - 9.0).abs() < 1e-12 && (left[1].1 - 1.0).abs() < 1e-12, "{left:?}");
        let c = capsule((0.0, 0.0), (4.0, 0.0), 1.0);
        assert!(c.iter().all(|p| {
            let d = if p.0 < 0.0 {
                p.0.hypot(p.1)
            } else if p.0 > 4.0 {
                (p.0 - 4.0).hypot(p.1)
            } else {
                p.1.abs()
            };
            (d - 1.0).abs() < 1e-12
        }));
        assert_eq!(hull(vec![(0.0, 0.0), (1.0, 0.0), (0.5, 0.2), (1.0, 1.0), (0.0, 1.0)]).len(), 4);
    }
}
