//! What building the fine indexes of a tile shares ([`super::polygon_index`],
//! [`super::lane_index`]): the grid of small cells around the map and its blocks' bits,
//! a cell's least and greatest distance to a segment, and buckets to find what is near a
//! cell.

use dash2sim_core::fine_grid::{FineGrid, BLOCK};
use dash2sim_core::map::segment_distance;

/// Cell size, m: a corner then reads a few segments or edges for its distance to the
/// drivable area (the 25 m cells of the tile's grid list every lane or polygon around a
/// footprint: ~36 edges per corner on the Lanelet2 example).
pub const CELL: f64 = 2.0;

/// At most this many cells (32 MiB of cell ranges); a larger map gets coarser cells.
const MAX_CELLS: f64 = 4_194_304.0;

/// Margin on every "cannot be nearest / cannot be crossed" test, m: far more than the f32
/// rounding of map coordinates.
pub(super) const SLACK: f64 = 0.01;

/// Segments and boxes are bucketed by this size (m) to find those near a cell.
const BUCKET: f64 = 16.0;

pub(super) type Point = (f64, f64);

/// The cells over a map's box grown by `reach`, and which blocks of them list anything.
#[derive(Clone, Debug)]
pub(super) struct Layout {
    pub(super) min: Point,
    pub(super) cell: f64,
    pub(super) cols: u32,
    pub(super) rows: u32,
    pub(super) blocks: Vec<u64>,
}

impl Layout {
    /// [`CELL`] metres a cell, coarser where the map is large; over `lo`–`hi` grown by `reach`.
    pub(super) fn around(lo: Point, hi: Point, reach: f64, cell: f64) -> Layout {
        let min = (lo.0 - reach, lo.1 - reach);
        let size = (hi.0 + reach - min.0, hi.1 + reach - min.1);
        let cell = cell.max((size.0 * size.1 / MAX_CELLS).sqrt());
        let (cols, rows) = ((size.0 / cell).ceil() as u32 + 1, (size.1 / cell).ceil() as u32 + 1);
        let blocks = vec![0; (cols.div_ceil(BLOCK) * rows.div_ceil(BLOCK)).div_ceil(64) as usize];
        Layout { min, cell, cols, rows, blocks }
    }

    /// Its area, m.
    pub(super) fn extent(&self) -> Point {
        (f64::from(self.cols) * self.cell, f64::from(self.rows) * self.cell)
    }

    /// Every cell, row by row: its row, column and corners (the layout stays free to be
    /// marked meanwhile).
    pub(super) fn cells(&self) -> impl Iterator<Item = (u32, u32, Cell)> + use<> {
        let (min, cell, cols) = (self.min, self.cell, self.cols);
        (0..self.rows).flat_map(move |row| {
            (0..cols).map(move |col| {
                let lo = (min.0 + f64::from(col) * cell, min.1 + f64::from(row) * cell);
                (row, col, Cell { lo, hi: (lo.0 + cell, lo.1 + cell) })
            })
        })
    }

    /// Mark the block of the cell at `row`, `col` as listing something.
    pub(super) fn mark(&mut self, row: u32, col: u32) {
        let block = (row / BLOCK * self.cols.div_ceil(BLOCK) + col / BLOCK) as usize;
        self.blocks[block / 64] |= 1 << (block % 64);
    }

    /// The grid the check reads.
    pub(super) fn view(&self) -> FineGrid<'_> {
        FineGrid::new(self.min, self.cell, [self.cols, self.rows], &self.blocks)
    }
}

/// A cell: its lower-left and upper-right corners.
#[derive(Clone, Copy)]
pub(super) struct Cell {
    pub(super) lo: Point,
    pub(super) hi: Point,
}

impl Cell {
    pub(super) fn corners(&self) -> [Point; 4] {
        [self.lo, (self.hi.0, self.lo.1), self.hi, (self.lo.0, self.hi.1)]
    }

    fn holds(&self, p: Point) -> bool {
        p.0 >= self.lo.0 && p.0 <= self.hi.0 && p.1 >= self.lo.1 && p.1 <= self.hi.1
    }

    /// The least distance from the cell to the segment a–b.
    pub(super) fn least_distance(&self, a: Point, b: Point) -> f64 {
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
    pub(super) fn greatest_distance(&self, a: Point, b: Point) -> f64 {
        self.corners().iter().map(|&c| segment_distance(c, a, b)).fold(0.0, f64::max)
    }
}

fn segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool {
    let cross = |o: Point, p: Point, q: Point| (p.0 - o.0) * (q.1 - o.1) - (p.1 - o.1) * (q.0 - o.0);
    ((cross(c, d, a) > 0.0) != (cross(c, d, b) > 0.0)) && ((cross(a, b, c) > 0.0) != (cross(a, b, d) > 0.0))
}

pub(super) fn stored(a: Point, b: Point) -> [f32; 4] {
    // The points are the tile's f32 coordinates widened: narrowing is exact.
    [a.0 as f32, a.1 as f32, b.0 as f32, b.1 as f32]
}

/// Fixed-size buckets over the grid's area, each listing what reaches into it.
pub(super) struct Buckets<T> {
    min: Point,
    cols: usize,
    rows: usize,
    lists: Vec<Vec<T>>,
}

impl<T: Copy> Buckets<T> {
    pub(super) fn new(min: Point, size: Point) -> Self {
        let (cols, rows) = ((size.0 / BUCKET).ceil() as usize + 1, (size.1 / BUCKET).ceil() as usize + 1);
        Buckets { min, cols, rows, lists: vec![Vec::new(); cols * rows] }
    }

    fn span(&self, lo: Point, hi: Point) -> impl Iterator<Item = usize> + '_ {
        let at = |v: f64, min: f64, n: usize| (((v - min) / BUCKET).floor().max(0.0) as usize).min(n - 1);
        let (c0, c1) = (at(lo.0, self.min.0, self.cols), at(hi.0, self.min.0, self.cols));
        let (r0, r1) = (at(lo.1, self.min.1, self.rows), at(hi.1, self.min.1, self.rows));
        (r0..=r1).flat_map(move |r| (c0..=c1).map(move |c| r * self.cols + c))
    }

    pub(super) fn insert(&mut self, lo: Point, hi: Point, value: T) {
        let span: Vec<usize> = self.span(lo, hi).collect();
        for b in span {
            self.lists[b].push(value);
        }
    }

    /// Everything in the buckets the box lo–hi touches (with repeats).
    pub(super) fn near(&self, lo: Point, hi: Point) -> impl Iterator<Item = T> + '_ {
        self.span(lo, hi).flat_map(move |b| self.lists[b].iter().copied())
    }
}
