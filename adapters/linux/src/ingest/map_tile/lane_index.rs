//! Build the fine [`LaneIndex`] of a tile whose lanes are buffered centrelines
//! (OpenStreetMap's), in memory, for the drivable check on the desktop (`verify`,
//! `map check`).
//!
//! Per cell of 8 m (`LANE_CELL`) it lists, by lane, the lanes that may
//! matter to a point of the cell, each with its segments that may be nearest there. For a
//! point p of the cell and a lane whose nearest segment to p is s, the cell's least distance
//! to s is at most |p s|, which is at most U, the least over the lane's segments of their
//! greatest distance from the cell: s passes that test. It is kept when it may also hold p
//! (least distance ≤ half the width) or give p's distance outside the drivable area within
//! the search radius (least distance − half width ≤ T, where T is the least over lanes of
//! U − half width, capped at the search radius: every point of the cell is within T of
//! some lane). A lane none of whose segments is kept is farther than T outside from every
//! point of the cell, which is the cell's [`CellStart::exact_below`]. Every test has a
//! centimetre of slack for f32 rounding.

use dash2sim_core::drivable::SEARCH_RADIUS;
use dash2sim_core::lane_index::{CellStart, LaneIndex, Run};
use dash2sim_core::map::{LaneArea, MapView};

use super::fine_grid::{stored, Buckets, Layout, Point, SLACK};

/// Cell size, m. Finer cells list fewer segments per point but make a larger index, whose
/// reads then miss the cache: on central Helsinki 2 m cells (13 MB) took 0.52–1.16 µs a
/// pose from run to run, 6 m 0.68–0.87 µs, 8 m (2.1 MB) 0.77–0.78 µs (docs/benchmarks.md).
const LANE_CELL: f64 = 8.0;

/// The arrays of an index, owned; [`LaneArrays::view`] lends them to the check.
#[derive(Clone, Debug)]
pub struct LaneArrays {
    layout: Layout,
    starts: Vec<CellStart>,
    slots: Vec<[u32; 4]>,
}

impl LaneArrays {
    /// The index over these arrays.
    pub fn view(&self) -> LaneIndex<'_> {
        LaneIndex::new(self.layout.view(), &self.starts, &self.slots)
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        size_of::<CellStart>() * self.starts.len() + 8 * self.layout.blocks.len() + 16 * self.slots.len()
    }
}

/// A lane's centreline: its points, its segments as stored and half its width.
struct Centre {
    half_width: f64,
    points: Vec<Point>,
    stored: Vec<[f32; 4]>,
}

/// A segment near a cell: its lane, its place in the lane, and the cell's least and
/// greatest distance to it.
#[derive(Clone, Copy)]
struct Near {
    lane: usize,
    segment: usize,
    least: f64,
    greatest: f64,
}

/// How many cells [`build`] would lay over `map` (0 for a map without lanes).
pub fn cells(map: &MapView<'_>) -> usize {
    let Some((lo, hi, widest)) = extent(map) else { return 0 };
    let layout = Layout::around(lo, hi, SEARCH_RADIUS + widest + SLACK, LANE_CELL);
    layout.cols as usize * layout.rows as usize
}

/// The box of `map`'s lane points and its widest lane's half width.
fn extent(map: &MapView<'_>) -> Option<(Point, Point, f64)> {
    let lanes = (0..map.header().lanes).filter_map(|i| map.lane(i));
    let mut widest = 0.0f64;
    let mut bounds: Option<(Point, Point)> = None;
    for lane in lanes {
        widest = widest.max(lane.width / 2.0);
        for p in lane.points() {
            let (lo, hi) = bounds.unwrap_or((p, p));
            bounds = Some(((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1))));
        }
    }
    bounds.map(|(lo, hi)| (lo, hi, widest))
}

/// The index of `map`'s buffered lanes; `None` when the map has a lane that is a polygon or
/// a free-standing polygon (Lanelet2 tiles: [`super::polygon_index`]) or no lane.
pub fn build(map: &MapView<'_>) -> Option<LaneArrays> {
    if map.header().polygons > 0 {
        return None;
    }
    let mut lanes = Vec::new();
    for i in 0..map.header().lanes {
        let LaneArea::Buffered(centreline) = map.lane_area(i)? else { return None };
        let points: Vec<Point> = centreline.points().collect();
        let stored = points.windows(2).map(|w| stored(w[0], w[1])).collect();
        lanes.push(Centre { half_width: centreline.width / 2.0, points, stored });
    }
    let (lo, hi, widest) = extent(map)?;
    // Beyond this from a cell a segment can neither hold nor be within the search radius of
    // a point of it.
    let reach = SEARCH_RADIUS + widest + SLACK;
    let mut out =
        LaneArrays { layout: Layout::around(lo, hi, reach, LANE_CELL), starts: Vec::new(), slots: Vec::new() };
    let mut buckets = Buckets::new(out.layout.min, out.layout.extent());
    for (l, lane) in lanes.iter().enumerate() {
        for (j, w) in lane.points.windows(2).enumerate() {
            buckets.insert((w[0].0.min(w[1].0), w[0].1.min(w[1].1)), (w[0].0.max(w[1].0), w[0].1.max(w[1].1)), (l, j));
        }
    }

    let mut near: Vec<Near> = Vec::new();
    for (row, col, c) in out.layout.cells() {
        near.clear();
        near.extend(
            buckets
                .near((c.lo.0 - reach, c.lo.1 - reach), (c.hi.0 + reach, c.hi.1 + reach))
                .map(|(lane, segment)| Near { lane, segment, least: 0.0, greatest: 0.0 }),
        );
        near.sort_unstable_by_key(|n| (n.lane, n.segment));
        near.dedup_by_key(|n| (n.lane, n.segment));
        near.retain_mut(|n| {
            let lane = &lanes[n.lane];
            let (a, b) = (lane.points[n.segment], lane.points[n.segment + 1]);
            n.least = c.least_distance(a, b);
            if n.least - lane.half_width > SEARCH_RADIUS + SLACK {
                return false;
            }
            n.greatest = c.greatest_distance(a, b);
            true
        });
        // Per lane (the near segments are grouped by lane), the least greatest distance; and
        // over lanes, the least of those outside the area: T.
        let groups: Vec<&[Near]> = near.chunk_by(|a, b| a.lane == b.lane).collect();
        let bound = |group: &[Near]| group.iter().map(|n| n.greatest).fold(f64::INFINITY, f64::min);
        let outside = groups.iter().map(|g| bound(g) - lanes[g[0].lane].half_width).fold(f64::INFINITY, f64::min);
        let exact_below = outside.min(SEARCH_RADIUS) + SLACK;
        let first = out.slots.len();
        out.starts.push(CellStart { slots: first as u32, exact_below: rounded_down(exact_below) });
        for group in groups {
            let lane = &lanes[group[0].lane];
            let own = bound(group) + SLACK;
            let head = out.slots.len();
            out.slots.push([0; 4]);
            out.slots.extend(
                group
                    .iter()
                    .filter(|n| {
                        n.least <= own
                            && (n.least <= lane.half_width + SLACK || n.least - lane.half_width <= exact_below)
                    })
                    .map(|n| lane.stored[n.segment].map(f32::to_bits)),
            );
            let count = out.slots.len() - head - 1;
            if count == 0 {
                out.slots.pop();
            } else {
                out.slots[head] = Run::head(group[0].lane as u32, lane.half_width, count as u32);
            }
        }
        if out.slots.len() > first {
            out.layout.mark(row, col);
        }
    }
    out.starts.push(CellStart { slots: out.slots.len() as u32, exact_below: f32::NEG_INFINITY });
    Some(out)
}

/// The f32 at or below `v` nearest to it (a bound that must not grow by rounding).
fn rounded_down(v: f64) -> f32 {
    let r = v as f32;
    if f64::from(r) > v {
        r.next_down()
    } else {
        r
    }
}
