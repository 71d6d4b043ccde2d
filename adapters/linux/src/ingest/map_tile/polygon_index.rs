//! Build the fine [`PolygonIndex`] of a tile whose lanes are polygons (Lanelet2), in memory,
//! for the drivable check on the desktop (`verify`, `map check`).
//!
//! Per cell of 2 m (`fine_grid::CELL`) it lists the polygons that may hold a point of the cell
//! (marked when one holds all of it), each with its edges that may be nearest to a point
//! of the cell inside it, and the edges of all polygons that may be nearest to a point of
//! the cell outside them all (within the search radius). An edge may be nearest to some
//! point of the cell when its least distance to the cell is at most the least, over edges,
//! of the greatest distance from the cell (plus a centimetre for f32 rounding).

use dash2sim_core::drivable::SEARCH_RADIUS;
use dash2sim_core::map::{edges_parity, LaneArea, MapView, POLYGON_BIT};
use dash2sim_core::polygon_index::{Area, PolygonIndex};

use super::fine_grid::{stored, Buckets, Layout, Point, CELL, SLACK};

/// The arrays of an index, owned; [`IndexArrays::view`] lends them to the check.
#[derive(Clone, Debug)]
pub struct IndexArrays {
    layout: Layout,
    starts: Vec<[u32; 2]>,
    areas: Vec<Area>,
    edges: Vec<[f32; 4]>,
    area_edges: Vec<[f32; 4]>,
}

impl IndexArrays {
    /// The index over these arrays.
    pub fn view(&self) -> PolygonIndex<'_> {
        PolygonIndex::new(self.layout.view(), &self.starts, &self.areas, [&self.edges, &self.area_edges])
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        8 * (self.starts.len() + self.layout.blocks.len())
            + size_of::<Area>() * self.areas.len()
            + 16 * (self.edges.len() + self.area_edges.len())
    }
}

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
    let mut out = IndexArrays {
        layout: Layout::around(lo, hi, reach, CELL),
        starts: vec![[0, 0]],
        areas: Vec::new(),
        edges: Vec::new(),
        area_edges: Vec::new(),
    };
    let mut edge_buckets = Buckets::new(out.layout.min, out.layout.extent());
    let mut ring_buckets = Buckets::new(out.layout.min, out.layout.extent());
    for (r, ring) in rings.iter().enumerate() {
        ring_buckets.insert((ring.lo.0 - SLACK, ring.lo.1 - SLACK), (ring.hi.0 + SLACK, ring.hi.1 + SLACK), r);
        for j in 0..ring.points.len() {
            let (a, b) = ring.edge(j);
            edge_buckets.insert((a.0.min(b.0), a.1.min(b.1)), (a.0.max(b.0), a.1.max(b.1)), (r, j));
        }
    }

    // Edges within reach of the cell: ring, edge, least distance to the cell.
    let mut near: Vec<(usize, usize, f64)> = Vec::new();
    let mut held_rings: Vec<usize> = Vec::new();
    for (row, col, c) in out.layout.cells() {
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
            out.layout.mark(row, col);
        }
    }
    Some(out)
}
