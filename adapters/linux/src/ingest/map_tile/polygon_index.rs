//! Build the fine [`PolygonIndex`] of a tile whose lanes are polygons (Lanelet2), in memory,
//! for the drivable check on the desktop (`verify`, `map check`).
//!
//! Per cell of [`CELL`] metres it lists the polygons that may hold a point of the cell
//! (marked when one holds all of it), each with its edges that may be nearest to a point
//! of the cell inside it, and the edges of all polygons that may be nearest to a point of
//! the cell outside them all (within the search radius). An edge may be nearest to some
//! point of the cell when its least distance to the cell is at most the least, over edges,
//! of the greatest distance from the cell (plus a centimetre for f32 rounding).

use dash2sim_core::drivable::{Checker, SEARCH_RADIUS};
use dash2sim_core::map::{edges_parity, segment_distance, LaneArea, MapView, POLYGON_BIT};
use dash2sim_core::obb::Footprint;
use dash2sim_core::polygon_index::{Area, PolygonIndex, BLOCK};

/// Cell size, m: a corner then reads about 11 edges for its distance to the drivable area
/// (the 25 m cells of the tile's grid list every polygon around a footprint, ~36 edges per
/// corner on the Lanelet2 example).
pub const CELL: f64 = 2.0;

/// At most this many cells (32 MiB of cell ranges); a larger map gets coarser cells.
const MAX_CELLS: f64 = 4_194_304.0;

/// Margin on every "cannot be nearest / cannot be crossed" test, m: far more than the f32
/// rounding of map coordinates.
const SLACK: f64 = 0.01;

/// Edges and polygon boxes are bucketed by this size (m) to find those near a cell.
const BUCKET: f64 = 16.0;

/// The arrays of an index, owned; [`IndexArrays::view`] lends them to the check.
#[derive(Clone, Debug)]
pub struct IndexArrays {
    min: (f64, f64),
    cell: f64,
    cols: u32,
    rows: u32,
    starts: Vec<[u32; 2]>,
    blocks: Vec<u64>,
    areas: Vec<Area>,
    edges: Vec<[f32; 4]>,
    area_edges: Vec<[f32; 4]>,
}

impl IndexArrays {
    /// The index over these arrays.
    pub fn view(&self) -> PolygonIndex<'_> {
        PolygonIndex::new(
            self.min,
            self.cell,
            [self.cols, self.rows],
            &self.starts,
            &self.blocks,
            &self.areas,
            [&self.edges, &self.area_edges],
        )
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        8 * (self.starts.len() + self.blocks.len())
            + size_of::<Area>() * self.areas.len()
            + 16 * (self.edges.len() + self.area_edges.len())
    }
}

/// A checker for `map` that reads `index` (built for `map`) where there is one.
pub fn checker<'a>(map: MapView<'a>, footprint: Footprint, index: Option<&'a IndexArrays>) -> Checker<'a> {
    match index {
        Some(index) => Checker::new(map, footprint).with_index(index.view()),
        None => Checker::new(map, footprint),
    }
}

type Point = (f64, f64);

/// A drivable polygon: its grid key, polygon index, ring (and its edges as stored) and box.
struct Ring {
    key: u32,
    polygon: u32,
    points: Vec<Point>,
    stored: Vec<[f32; 4]>,
    lo: Point,
    hi: Point,
}

impl Ring {
    /// Edge `j`: from point j − 1 to point j (the order the check walks them in).
    fn edge(&self, j: usize) -> (Point, Point) {
        let n = self.points.len();
        (self.points[(j + n - 1) % n], self.points[j])
    }

    /// Whether the polygon holds `p`, by the test the check makes.
    fn holds(&self, p: Point) -> bool {
        edges_parity(&self.stored, p, false)
    }
}

/// A cell: its lower-left and upper-right corners.
#[derive(Clone, Copy)]
struct Cell {
    lo: Point,
    hi: Point,
}

impl Cell {
    fn corners(&self) -> [Point; 4] {
        [self.lo, (self.hi.0, self.lo.1), self.hi, (self.lo.0, self.hi.1)]
    }

    fn holds(&self, p: Point) -> bool {
        p.0 >= self.lo.0 && p.0 <= self.hi.0 && p.1 >= self.lo.1 && p.1 <= self.hi.1
    }

    /// The least distance from the cell to the segment a–b.
    fn least_distance(&self, a: Point, b: Point) -> f64 {
        let c = self.corners();
        if self.holds(a) || self.holds(b) || (0..4).any(|k| segments_cross(a, b, c[k], c[(k + 1) % 4])) {
            return 0.0;
        }
        let to_cell = |p: Point| {
            (self.lo.0 - p.0).max(p.0 - self.hi.0).max(0.0).hypot((self.lo.1 - p.1).max(p.1 - self.hi.1).max(0.0))
        };
        c.iter().map(|&c| segment_distance(c, a, b)).fold(to_cell(a).min(to_cell(b)), f64::min)
    }

    /// The greatest distance from a point of the cell to the segment a–b (at a corner: the
    /// distance to a segment is convex).
    fn greatest_distance(&self, a: Point, b: Point) -> f64 {
        self.corners().iter().map(|&c| segment_distance(c, a, b)).fold(0.0, f64::max)
    }
}

fn segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool {
    let cross = |o: Point, p: Point, q: Point| (p.0 - o.0) * (q.1 - o.1) - (p.1 - o.1) * (q.0 - o.0);
    ((cross(c, d, a) > 0.0) != (cross(c, d, b) > 0.0)) && ((cross(a, b, c) > 0.0) != (cross(a, b, d) > 0.0))
}

fn stored(a: Point, b: Point) -> [f32; 4] {
    // The ring's points are the tile's f32 coordinates widened: narrowing is exact.
    [a.0 as f32, a.1 as f32, b.0 as f32, b.1 as f32]
}

/// Fixed-size buckets over the grid's area, each listing what reaches into it.
struct Buckets<T> {
    min: Point,
    cols: usize,
    rows: usize,
    lists: Vec<Vec<T>>,
}

impl<T: Copy> Buckets<T> {
    fn new(min: Point, size: Point) -> Self {
        let (cols, rows) = ((size.0 / BUCKET).ceil() as usize + 1, (size.1 / BUCKET).ceil() as usize + 1);
        Buckets { min, cols, rows, lists: vec![Vec::new(); cols * rows] }
    }

    fn span(&self, lo: Point, hi: Point) -> impl Iterator<Item = usize> + '_ {
        let at = |v: f64, min: f64, n: usize| (((v - min) / BUCKET).floor().max(0.0) as usize).min(n - 1);
        let (c0, c1) = (at(lo.0, self.min.0, self.cols), at(hi.0, self.min.0, self.cols));
        let (r0, r1) = (at(lo.1, self.min.1, self.rows), at(hi.1, self.min.1, self.rows));
        (r0..=r1).flat_map(move |r| (c0..=c1).map(move |c| r * self.cols + c))
    }

    fn insert(&mut self, lo: Point, hi: Point, value: T) {
        let span: Vec<usize> = self.span(lo, hi).collect();
        for b in span {
            self.lists[b].push(value);
        }
    }

    /// Everything in the buckets the box lo–hi touches (with repeats).
    fn near(&self, lo: Point, hi: Point) -> impl Iterator<Item = T> + '_ {
        self.span(lo, hi).flat_map(move |b| self.lists[b].iter().copied())
    }
}

/// The index of `map`'s drivable polygons; `None` when the map has a lane that is not a
/// polygon (OpenStreetMap tiles: their lanes are buffered centrelines) or no polygon.
pub fn build(map: &MapView<'_>) -> Option<IndexArrays> {
    let mut rings = Vec::new();
    let ring = |key: u32, polygon: u32| -> Option<Ring> {
        let points: Vec<Point> = map.polygon(polygon)?.collect();
        let lo = points.iter().fold((f64::INFINITY, f64::INFINITY), |l, p| (l.0.min(p.0), l.1.min(p.1)));
        let hi = points.iter().fold((f64::NEG_INFINITY, f64::NEG_INFINITY), |h, p| (h.0.max(p.0), h.1.max(p.1)));
        let stored =
            (0..points.len()).map(|j| stored(points[(j + points.len() - 1) % points.len()], points[j])).collect();
        Some(Ring { key, polygon, points, stored, lo, hi })
    };
    for i in 0..map.header().lanes {
        match map.lane_area(i)? {
            LaneArea::Polygon(p) => rings.push(ring(i, p)?),
            LaneArea::Buffered(_) => return None,
        }
    }
    for p in 0..map.header().polygons {
        rings.push(ring(p | POLYGON_BIT, p)?);
    }
    let lo = rings.iter().map(|r| r.lo).reduce(|l, p| (l.0.min(p.0), l.1.min(p.1)))?;
    let hi = rings.iter().map(|r| r.hi).fold(lo, |h, p| (h.0.max(p.0), h.1.max(p.1)));
    let reach = SEARCH_RADIUS + SLACK;
    let min = (lo.0 - reach, lo.1 - reach);
    let size = (hi.0 + reach - min.0, hi.1 + reach - min.1);
    let cell = CELL.max((size.0 * size.1 / MAX_CELLS).sqrt());
    let (cols, rows) = ((size.0 / cell).ceil() as u32 + 1, (size.1 / cell).ceil() as u32 + 1);

    let extent = (f64::from(cols) * cell, f64::from(rows) * cell);
    let mut edge_buckets = Buckets::new(min, extent);
    let mut ring_buckets = Buckets::new(min, extent);
    for (r, ring) in rings.iter().enumerate() {
        ring_buckets.insert((ring.lo.0 - SLACK, ring.lo.1 - SLACK), (ring.hi.0 + SLACK, ring.hi.1 + SLACK), r);
        for j in 0..ring.points.len() {
            let (a, b) = ring.edge(j);
            edge_buckets.insert((a.0.min(b.0), a.1.min(b.1)), (a.0.max(b.0), a.1.max(b.1)), (r, j));
        }
    }

    let mut out = IndexArrays {
        min,
        cell,
        cols,
        rows,
        starts: vec![[0, 0]],
        blocks: vec![0; (cols.div_ceil(BLOCK) * rows.div_ceil(BLOCK)).div_ceil(64) as usize],
        areas: Vec::new(),
        edges: Vec::new(),
        area_edges: Vec::new(),
    };
    // Edges within reach of the cell: ring, edge, least distance to the cell.
    let mut near: Vec<(usize, usize, f64)> = Vec::new();
    let mut held_rings: Vec<usize> = Vec::new();
    for row in 0..rows {
        for col in 0..cols {
            let lo = (min.0 + f64::from(col) * cell, min.1 + f64::from(row) * cell);
            let c = Cell { lo, hi: (lo.0 + cell, lo.1 + cell) };
            near.clear();
            for (r, j) in edge_buckets.near((c.lo.0 - reach, c.lo.1 - reach), (c.hi.0 + reach, c.hi.1 + reach)) {
                near.push((r, j, 0.0));
            }
            near.sort_unstable_by_key(|&(r, j, _)| (r, j));
            near.dedup_by_key(|&mut (r, j, _)| (r, j));
            let mut bound = f64::INFINITY;
            near.retain_mut(|(r, j, least)| {
                let (a, b) = rings[*r].edge(*j);
                *least = c.least_distance(a, b);
                if *least <= reach {
                    bound = bound.min(c.greatest_distance(a, b));
                }
                *least <= reach
            });
            let limit = bound.min(SEARCH_RADIUS) + SLACK;
            out.edges.extend(near.iter().filter(|e| e.2 <= limit).map(|&(r, j, _)| rings[r].stored[j]));

            held_rings.clear();
            held_rings.extend(ring_buckets.near(c.lo, c.hi));
            held_rings.sort_unstable();
            held_rings.dedup();
            for &r in &held_rings {
                let ring = &rings[r];
                if ring.lo.0 > c.hi.0 + SLACK
                    || ring.hi.0 < c.lo.0 - SLACK
                    || ring.lo.1 > c.hi.1 + SLACK
                    || ring.hi.1 < c.lo.1 - SLACK
                {
                    continue;
                }
                let crossed = near.iter().any(|e| e.0 == r && e.2 <= SLACK);
                let held = c.corners().map(|p| ring.holds(p));
                if !crossed && held.iter().all(|&h| !h) {
                    // No edge comes into the cell and its corners are outside: it misses the cell.
                    continue;
                }
                let whole = !crossed && held.iter().all(|&h| h);
                // The edges that decide its parity for a point of the cell: those that may
                // cross the row within reach of the cell's right. An edge wholly above or
                // below the row, or wholly left of the cell, crosses no point's ray; one
                // wholly across the row and wholly to the right crosses every point's.
                // (A polygon holding the whole cell needs none.)
                let (mut parity, start) = (false, out.area_edges.len() as u32);
                for j in 0..if whole { 0 } else { ring.points.len() } {
                    let (a, b) = ring.edge(j);
                    let (below, above) = (a.1.min(b.1), a.1.max(b.1));
                    if above < c.lo.1 - SLACK || below > c.hi.1 + SLACK || a.0.max(b.0) < c.lo.0 - SLACK {
                        continue;
                    }
                    if below < c.lo.1 - SLACK && above > c.hi.1 + SLACK && a.0.min(b.0) > c.hi.0 + SLACK {
                        parity = !parity;
                    } else {
                        out.area_edges.push(ring.stored[j]);
                    }
                }
                let crossing = (start, out.area_edges.len() as u32);
                // Its edges that may be nearest to a point of the cell (its depth).
                let bound = (0..ring.points.len()).map(|j| {
                    let (a, b) = ring.edge(j);
                    c.greatest_distance(a, b)
                });
                let bound = bound.fold(f64::INFINITY, f64::min) + SLACK;
                let start = out.area_edges.len() as u32;
                out.area_edges.extend((0..ring.points.len()).filter_map(|j| {
                    let (a, b) = ring.edge(j);
                    (c.least_distance(a, b) <= bound).then_some(ring.stored[j])
                }));
                let nearest = (start, out.area_edges.len() as u32);
                out.areas.push(Area { key: ring.key, polygon: ring.polygon, whole, parity, crossing, nearest });
            }
            let start = out.starts[out.starts.len() - 1];
            out.starts.push([out.areas.len() as u32, out.edges.len() as u32]);
            if start != out.starts[out.starts.len() - 1] {
                let block = (row / BLOCK * cols.div_ceil(BLOCK) + col / BLOCK) as usize;
                out.blocks[block / 64] |= 1 << (block % 64);
            }
        }
    }
    Some(out)
}
