//! A map tile's lanes as a simulator draws them: cut at their junctions into pieces that
//! overlap no other lane ([`super::junctions`]), each with its left and right bounds, side by
//! side in roadblocks, joined through the junctions by connectors; and the tile's drivable
//! area. One geometry for every simulator export (nuPlan's map layers, CommonRoad's lanelets),
//! so that they and `verify` see the same roads.

use dash2sim_core::map::MapView;

use super::junctions::{layout, DisjointSets, LaneShape};
use super::projection::Projection;
use dash2sim_linux::geometry::{band, bezier, capsule, cut, heading_at, hull, is_simple, length, point_at, Line};
use dash2sim_linux::{Error, Result};

/// Points on a turn's curve.
const TURN_POINTS: usize = 12;

/// A stretch of one tile lane between junctions.
#[derive(Debug, Clone)]
pub struct Piece {
    /// The tile lane it is cut from.
    pub lane: usize,
    /// Centreline in driving order (projected metres).
    pub centre: Line,
    /// Left bound: the centreline offset by half the width (less the seam), one point per
    /// centreline point.
    pub left: Line,
    /// Right bound, likewise.
    pub right: Line,
    /// The polygon between the bounds.
    pub ring: Line,
    /// The lane's width, m (projected).
    pub width: f64,
    /// Its roadblock (index into [`Road::roadblocks`]): pieces side by side in one direction.
    pub roadblock: usize,
    /// Position in the roadblock counted from the leftmost lane (0).
    pub lane_index: i64,
    /// The piece side by side on the left in the same direction, if any.
    pub left_neighbour: Option<usize>,
    /// And on the right.
    pub right_neighbour: Option<usize>,
    /// Speed limit, m/s.
    pub speed_limit: Option<f64>,
}

/// A path through a junction from the end of one piece to the start of another: along the
/// lane where it goes on, a cubic curve between two lanes.
#[derive(Debug, Clone)]
pub struct Connector {
    /// The piece it leaves (index into [`Road::pieces`]).
    pub from: usize,
    /// The piece it enters.
    pub to: usize,
    /// Centreline.
    pub centre: Line,
    /// Left bound (the narrower lane's half width), one point per centreline point.
    pub left: Line,
    /// Right bound.
    pub right: Line,
    /// The polygon between the bounds; a turn tighter than half the width folds its band
    /// over on the inside, so then its convex hull (a polygon must be simple).
    pub ring: Line,
    /// Its width (the narrower lane's), m.
    pub width: f64,
    /// The speed limit of the lane it leaves, m/s.
    pub speed_limit: Option<f64>,
}

/// The tile's roads in a projected frame.
#[derive(Debug, Clone, Default)]
pub struct Road {
    /// Every piece, lane by lane in the tile's order, in driving order within a lane.
    pub pieces: Vec<Piece>,
    /// Every roadblock's outline: its leftmost piece's left bound and its rightmost piece's
    /// right bound (the convex hull of its pieces when a side is missing).
    pub roadblocks: Vec<Line>,
    /// Every connector through a junction.
    pub connectors: Vec<Connector>,
    /// The tile's drivable area as `verify` has it: one capsule per centreline segment (round
    /// caps and joins) of the lanes drawn from centrelines, and every tile polygon.
    pub drivable: Vec<Line>,
}

/// A roadblock's left bound this close (mean distance, m, both ways) to another's makes the
/// two the sides of a two-way road's centre line.
const CENTRE_LINE_M: f64 = 1.0;

impl Road {
    /// For each piece that is the leftmost of its roadblock, the leftmost piece of another
    /// roadblock whose left bound runs along its own: the lane across a two-way road's centre
    /// line, facing the other way (the tile does not record which lanes face each other; the
    /// geometry does).
    pub fn opposite_neighbours(&self) -> Vec<Option<usize>> {
        let leftmost: Vec<usize> =
            (0..self.pieces.len()).filter(|&i| self.pieces[i].left_neighbour.is_none()).collect();
        (0..self.pieces.len())
            .map(|i| {
                let piece = &self.pieces[i];
                if piece.left_neighbour.is_some() {
                    return None;
                }
                leftmost.iter().copied().find(|&j| {
                    let other = &self.pieces[j];
                    other.roadblock != piece.roadblock
                        && boxes_meet(&piece.left, &other.left, CENTRE_LINE_M)
                        && mean_distance(&piece.left, &other.left) < CENTRE_LINE_M
                        && mean_distance(&other.left, &piece.left) < CENTRE_LINE_M
                })
            })
            .collect()
    }
}

/// Whether the bounding boxes of `a` and `b`, grown by `margin`, overlap.
fn boxes_meet(a: &[(f64, f64)], b: &[(f64, f64)], margin: f64) -> bool {
    let bounds = |l: &[(f64, f64)]| {
        l.iter().fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |m, p| {
            [m[0].min(p.0), m[1].min(p.1), m[2].max(p.0), m[3].max(p.1)]
        })
    };
    let (p, q) = (bounds(a), bounds(b));
    p[0] - margin <= q[2] && q[0] - margin <= p[2] && p[1] - margin <= q[3] && q[1] - margin <= p[3]
}

/// Mean distance from the points of `a` to the nearest point of `b`.
fn mean_distance(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    let nearest = |p: &(f64, f64)| b.iter().map(|q| (p.0 - q.0).hypot(p.1 - q.1)).fold(f64::INFINITY, f64::min);
    a.iter().map(nearest).sum::<f64>() / a.len().max(1) as f64
}

/// The roads of `view` in `projection`'s frame, each piece's bounds drawn `seam` metres
/// inside its half width (nuPlan wants side-by-side lanes not to touch; CommonRoad wants
/// neighbours to share their bound: 0).
pub fn road(view: &MapView<'_>, projection: &Projection, seam: f64) -> Result<Road> {
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
    let scale = length(&project(vec![(0.0, 0.0), (1.0, 0.0)]));
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

    let mut road = Road::default();
    // Roadblock index by (group, piece index); piece index by (lane, piece index).
    let mut roadblock_of = std::collections::BTreeMap::new();
    let mut piece_at = std::collections::BTreeMap::new();
    // Per roadblock: its leftmost piece's left bound, its rightmost piece's right bound.
    let mut sides: Vec<(Option<Line>, Option<Line>, Vec<usize>)> = Vec::new();
    for (i, lane) in lanes.iter().enumerate() {
        for (k, &(from, to)) in cut_map.pieces[i].iter().enumerate() {
            let next = roadblock_of.len();
            let roadblock = *roadblock_of.entry((shapes[i].group, k)).or_insert(next);
            if roadblock == sides.len() {
                sides.push((None, None, Vec::new()));
            }
            let centre = cut(&centrelines[i], from, to);
            let (ring, left, right) = band(&centre, lane.width * scale / 2.0 - seam);
            let side = &mut sides[roadblock];
            side.2.push(road.pieces.len());
            if lane.left.is_none() {
                side.0 = Some(left.clone());
            }
            if lane.right.is_none() {
                side.1 = Some(right.clone());
            }
            piece_at.insert((i, k), road.pieces.len());
            road.pieces.push(Piece {
                lane: i,
                centre,
                left,
                right,
                ring,
                width: lane.width * scale,
                roadblock,
                lane_index: lane_index[i],
                left_neighbour: None,
                right_neighbour: None,
                speed_limit: lane.speed_limit,
            });
        }
    }
    // Neighbours: piece k of a lane lies beside piece k of its left and right lanes (lanes of
    // one roadblock are cut alike).
    for (&(i, k), &p) in &piece_at {
        let beside = |n: Option<u32>| n.and_then(|n| piece_at.get(&(n as usize, k)).copied());
        road.pieces[p].left_neighbour = beside(lanes[i].left);
        road.pieces[p].right_neighbour = beside(lanes[i].right);
    }
    road.roadblocks = sides
        .into_iter()
        .map(|(left, right, members)| match (left, right) {
            (Some(mut ring), Some(r)) => {
                ring.extend(r.iter().rev());
                ring
            }
            _ => hull(members.iter().flat_map(|&p| road.pieces[p].ring.clone()).collect()),
        })
        .collect();
    for join in &cut_map.joins {
        let ((i, k), (j, l)) = (join.from, join.to);
        let (Some(&from), Some(&to)) = (piece_at.get(&(i, k)), piece_at.get(&(j, l))) else { continue };
        let (end, start) = (cut_map.pieces[i][k].1, cut_map.pieces[j][l].0);
        let mut centre = if i == j {
            cut(&centrelines[i], end, start)
        } else {
            let (a, b) = (point_at(&centrelines[i], end), point_at(&centrelines[j], start));
            bezier(a, heading_at(&centrelines[i], end), b, heading_at(&centrelines[j], start), TURN_POINTS)
        };
        centre.dedup();
        if centre.len() < 2 || length(&centre) < 1e-3 {
            continue;
        }
        let width = lanes[i].width.min(lanes[j].width) * scale;
        let (ring, left, right) = band(&centre, width / 2.0);
        let ring = if is_simple(&ring) { ring } else { hull(ring) };
        road.connectors.push(Connector {
            from,
            to,
            centre,
            left,
            right,
            ring,
            width,
            speed_limit: lanes[i].speed_limit,
        });
    }
    for (i, lane) in lanes.iter().enumerate() {
        if lane.area.is_none() {
            road.drivable.extend(centrelines[i].windows(2).map(|w| capsule(w[0], w[1], lane.width * scale / 2.0)));
        }
    }
    for g in 0..view.header().polygons {
        if let Some(points) = view.polygon(g) {
            road.drivable.push(project(points.collect()));
        }
    }
    Ok(road)
}
