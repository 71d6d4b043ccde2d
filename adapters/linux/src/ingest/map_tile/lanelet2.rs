//! Lanelet2 maps (OSM XML whose `type=lanelet` relations name a `left` and a `right` bound
//! way) → lanes whose area is the exact polygon between the bounds.
//!
//! Lanelet2 stores bounds as line strings that may point either way; the lanelet runs
//! along its bounds with the left bound on its left. Here the right bound is first turned
//! to run with the left one (the pairing of ends that is shorter), then both are turned if
//! the "left" bound lies on the right. The centreline is the mean of the two bounds sampled
//! at equal fractions of their lengths; the width is the mean distance between them.
//! Lanelets of subtypes cars may not use (crosswalk, walkway, bicycle_lane, stairs, …)
//! are skipped; `one_way=no` lanelets get a lane in each direction sharing one polygon.
//! Lanelet2 keeps speed limits in traffic rules, not the map: the limit is the German
//! rules' default for the lanelet's `location` (urban 50 km/h, nonurban 100 km/h), or
//! unknown.

use std::collections::HashMap;

use dash2sim_core::geo::{Geodetic, LocalFrame};

use super::{TileContent, TileLane};
use crate::ingest::osm::{MemberKind, OsmData, Relation};

/// Lanelet subtypes that carry motor vehicles (Lanelet2's `LaneletMapping.md`).
const VEHICLE_SUBTYPES: [&str; 5] = ["road", "highway", "play_street", "emergency_lane", "bus_lane"];
/// Road class code given to lanelet lanes (`docs/map-tile.md`).
pub const LANELET_CLASS: u8 = 11;
/// Points per sampled centreline.
const CENTRELINE_SAMPLES: usize = 16;

/// A lanelet's bounds as ENU polylines with their OSM end nodes.
struct Bounds {
    left: Vec<(f64, f64)>,
    right: Vec<(f64, f64)>,
    /// First and last node of the left and right bound, in driving order.
    ends: [i64; 4],
}

/// A bound way in ENU with its first and last node id.
type BoundLine = (Vec<(f64, f64)>, i64, i64);

fn length(line: &[(f64, f64)]) -> f64 {
    line.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).sum()
}

/// The point at fraction `f` of the polyline's length.
fn at_fraction(line: &[(f64, f64)], f: f64) -> (f64, f64) {
    let total = length(line);
    let mut left = f * total;
    for w in line.windows(2) {
        let seg = (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
        if left <= seg && seg > 0.0 {
            let t = left / seg;
            return (w[0].0 + t * (w[1].0 - w[0].0), w[0].1 + t * (w[1].1 - w[0].1));
        }
        left -= seg;
    }
    line.last().copied().unwrap_or((0.0, 0.0))
}

fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

fn bounds(
    relation: &Relation,
    ways: &HashMap<i64, &crate::ingest::osm::Way>,
    data: &OsmData,
    frame: &LocalFrame,
    warnings: &mut Vec<String>,
) -> Option<Bounds> {
    let bound = |role: &str| relation.members.iter().find(|m| m.kind == MemberKind::Way && m.role == role);
    let (Some(left), Some(right)) = (bound("left"), bound("right")) else {
        warnings.push(format!(
            "lanelet {}: needs a left and a right bound way (outside the extract?); skipped",
            relation.id
        ));
        return None;
    };
    let line = |id: i64| -> Option<BoundLine> {
        let way = ways.get(&id)?;
        let mut points = Vec::with_capacity(way.refs.len());
        for r in &way.refs {
            let &(lat, lon) = data.nodes.get(r)?;
            let p = frame.geodetic_to_enu(&Geodetic::new(lat, lon, 0.0).ok()?);
            points.push((p.x, p.y));
        }
        let (&first, &last) = (way.refs.first()?, way.refs.last()?);
        (points.len() >= 2).then_some((points, first, last))
    };
    let (Some((mut l, mut l0, mut l1)), Some((mut r, mut r0, mut r1))) = (line(left.id), line(right.id)) else {
        warnings
            .push(format!("lanelet {}: a bound way or node is missing (outside the extract?); skipped", relation.id));
        return None;
    };
    let (lf, ll, rf, rl) = (l[0], l[l.len() - 1], r[0], r[r.len() - 1]);
    if dist(lf, rl) + dist(ll, rf) < dist(lf, rf) + dist(ll, rl) {
        r.reverse();
        (r0, r1) = (r1, r0);
    }
    // The left bound must lie to the left of the direction of travel.
    let (a, b) = (at_fraction(&l, 0.5), at_fraction(&r, 0.5));
    let direction =
        (l[l.len() - 1].0 - l[0].0 + r[r.len() - 1].0 - r[0].0, l[l.len() - 1].1 - l[0].1 + r[r.len() - 1].1 - r[0].1);
    if direction.0 * (a.1 - b.1) - direction.1 * (a.0 - b.0) < 0.0 {
        l.reverse();
        r.reverse();
        (l0, l1, r0, r1) = (l1, l0, r1, r0);
    }
    Some(Bounds { left: l, right: r, ends: [l0, l1, r0, r1] })
}

/// Add the lanes of every vehicle lanelet in `data` to `content`; returns how many.
pub fn add_lanelets(
    data: &OsmData,
    frame: &LocalFrame,
    content: &mut TileContent,
    warnings: &mut Vec<String>,
) -> usize {
    let ways: HashMap<i64, &crate::ingest::osm::Way> = data.ways.iter().map(|w| (w.id, w)).collect();
    let first_lane = content.lanes.len();
    // Per lane: (start nodes, end nodes) of its bounds in its driving order, for successors.
    let mut ends: Vec<([i64; 2], [i64; 2])> = Vec::new();
    for relation in data.relations.iter().filter(|r| r.tag("type") == Some("lanelet")) {
        if !VEHICLE_SUBTYPES.contains(&relation.tag("subtype").unwrap_or("road")) {
            continue;
        }
        let Some(b) = bounds(relation, &ways, data, frame, warnings) else { continue };
        let samples: Vec<((f64, f64), (f64, f64))> = (0..CENTRELINE_SAMPLES)
            .map(|k| {
                let f = k as f64 / (CENTRELINE_SAMPLES - 1) as f64;
                (at_fraction(&b.left, f), at_fraction(&b.right, f))
            })
            .collect();
        let centre: Vec<(f64, f64)> = samples.iter().map(|(l, r)| ((l.0 + r.0) / 2.0, (l.1 + r.1) / 2.0)).collect();
        let width = samples.iter().map(|(l, r)| dist(*l, *r)).sum::<f64>() / samples.len() as f64;
        if length(&centre) < 0.01 || width < 0.01 {
            warnings.push(format!("lanelet {}: degenerate bounds; skipped", relation.id));
            continue;
        }
        let polygon = content.polygons.len();
        content.polygons.push(b.left.iter().chain(b.right.iter().rev()).copied().collect());
        let speed_limit = match relation.tag("location") {
            Some("urban") => Some(50.0 / 3.6),
            Some("nonurban") => Some(100.0 / 3.6),
            _ => None,
        };
        let lane = |points: Vec<(f64, f64)>| TileLane {
            points,
            width,
            speed_limit,
            class: LANELET_CLASS,
            neighbours: (None, None),
            successors: Vec::new(),
            area: Some(polygon),
        };
        let [l0, l1, r0, r1] = b.ends;
        content.lanes.push(lane(centre.clone()));
        ends.push(([l0, r0], [l1, r1]));
        if relation.tag("one_way") == Some("no") {
            content.lanes.push(lane(centre.into_iter().rev().collect()));
            ends.push(([r1, l1], [r0, l0]));
        }
    }
    // Successors share both end nodes; neighbours share a bound (the left of one is the
    // right of the other, in the same direction).
    let mut starting: HashMap<[i64; 2], Vec<u32>> = HashMap::new();
    for (k, (start, _)) in ends.iter().enumerate() {
        starting.entry(*start).or_default().push((first_lane + k) as u32);
    }
    for (k, (_, end)) in ends.iter().enumerate() {
        content.lanes[first_lane + k].successors = starting.get(end).cloned().unwrap_or_default();
    }
    let by_left: HashMap<[i64; 2], usize> = ends.iter().enumerate().map(|(k, (s, e))| ([s[0], e[0]], k)).collect();
    for (a, (start, end)) in ends.iter().enumerate() {
        if let Some(&b) = by_left.get(&[start[1], end[1]]).filter(|&&b| b != a) {
            content.lanes[first_lane + a].neighbours.1 = Some((first_lane + b) as u32);
            content.lanes[first_lane + b].neighbours.0 = Some((first_lane + a) as u32);
        }
    }
    ends.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three lanelets on an east-going road: A then B ahead of it, C to A's right. A's
    /// right bound is stored pointing west, C's bounds both point west (a reversed
    /// lanelet), B is two-way.
    const MAP: &str = r#"<?xml version="1.0"?>
<osm version="0.6">
  <node id="1" lat="0.0" lon="0.0"/><node id="2" lat="0.0" lon="0.0009"/><node id="3" lat="0.0" lon="0.0018"/>
  <node id="4" lat="-0.0000316533" lon="0.0"/><node id="5" lat="-0.0000316533" lon="0.0009"/><node id="6" lat="-0.0000316533" lon="0.0018"/>
  <node id="7" lat="-0.0000633066" lon="0.0"/><node id="8" lat="-0.0000633066" lon="0.0009"/>
  <way id="10"><nd ref="1"/><nd ref="2"/></way>
  <way id="11"><nd ref="5"/><nd ref="4"/></way>
  <way id="12"><nd ref="2"/><nd ref="3"/></way>
  <way id="13"><nd ref="5"/><nd ref="6"/></way>
  <way id="14"><nd ref="8"/><nd ref="7"/></way>
  <relation id="20"><member type="way" ref="10" role="left"/><member type="way" ref="11" role="right"/>
    <tag k="type" v="lanelet"/><tag k="subtype" v="road"/><tag k="location" v="urban"/></relation>
  <relation id="21"><member type="way" ref="12" role="left"/><member type="way" ref="13" role="right"/>
    <tag k="type" v="lanelet"/><tag k="one_way" v="no"/></relation>
  <relation id="22"><member type="way" ref="14" role="right"/><member type="way" ref="11" role="left"/>
    <tag k="type" v="lanelet"/><tag k="location" v="nonurban"/></relation>
  <relation id="23"><member type="way" ref="10" role="left"/><member type="way" ref="11" role="right"/>
    <tag k="type" v="lanelet"/><tag k="subtype" v="crosswalk"/></relation>
  <relation id="24"><member type="way" ref="10" role="left"/><tag k="type" v="lanelet"/></relation>
</osm>"#;

    #[test]
    fn lanelets_become_lanes_with_polygon_areas_successors_and_neighbours() {
        let data = crate::ingest::osm::parse_xml(MAP, "test.osm").expect("parses");
        let frame = LocalFrame::new(Geodetic::new(0.0, 0.0, 0.0).expect("origin"));
        let (mut content, mut warnings) = (TileContent::default(), Vec::new());
        assert_eq!(add_lanelets(&data, &frame, &mut content, &mut warnings), 4, "A, B both ways, C; not the crosswalk");
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].starts_with("lanelet 24: needs a left and a right bound"), "{warnings:?}");
        let [a, b, b_back, c] = &content.lanes[..] else { panic!("four lanes") };
        // Everything runs east except B's reverse; widths are the 3.5 m between bounds.
        for (lane, east) in [(a, true), (b, true), (b_back, false), (c, true)] {
            let (first, last) = (lane.points[0], lane.points[lane.points.len() - 1]);
            assert_eq!(last.0 > first.0, east, "{lane:?}");
            assert!((lane.width - 3.5).abs() < 0.01, "{}", lane.width);
            assert_eq!(lane.class, LANELET_CLASS);
        }
        assert!((a.points[0].1 - -1.75).abs() < 0.01 && (c.points[0].1 - -5.25).abs() < 0.01);
        assert_eq!((a.speed_limit, c.speed_limit, b.speed_limit), (Some(50.0 / 3.6), Some(100.0 / 3.6), None));
        assert_eq!(a.successors, vec![1], "A continues into B, not into B's reverse");
        assert_eq!(b_back.successors, Vec::<u32>::new(), "nothing was mapped west of A's start going west");
        assert_eq!((a.neighbours, c.neighbours), ((None, Some(3)), (Some(0), None)));
        assert_eq!((a.area, b.area, b_back.area, c.area), (Some(0), Some(1), Some(1), Some(2)));
        assert_eq!(content.polygons.len(), 3);
    }
}
