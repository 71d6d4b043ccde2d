//! A fine index of a tile's drivable polygons (Lanelet2 lanes), for the drivable check.
//!
//! The tile's grid lists, per 25 m cell, every lane or polygon whose box reaches the cell:
//! around a footprint that is some 19 small polygons, each then walked whole for each
//! corner. This index says per small cell which polygons may hold a point of it (and
//! whether one holds all of it, or else which of its edges decide it), which of each one's
//! edges may be nearest to a point of it, and which edges of all may be nearest to a point of
//! it outside them all. A
//! corner then reads a few edges instead of every polygon around it, with the same answer
//! (edges that cannot be nearest are left out; those that can are read in the same order).
//!
//! It is built beside the tile where memory allows (the desktop's `verify`; several MB for
//! the Lanelet2 example, so not on the microcontroller) and lent to
//! [`Checker::with_index`](crate::drivable::Checker::with_index) as plain arrays: nothing
//! here allocates, and a short or inconsistent array reads as empty cells, never a panic.

use crate::fine_grid::FineGrid;

/// A polygon that may hold points of a cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Area {
    /// The grid key of its item (a lane, or a free-standing polygon).
    pub key: u32,
    /// The polygon.
    pub polygon: u32,
    /// It holds the whole cell, with a margin: its points need no parity test.
    pub whole: bool,
    /// The even-odd parity a point of the cell has from the edges that cross the cell's row
    /// wholly and lie wholly to its right (every such point's ray crosses them).
    pub parity: bool,
    /// Its edges (a range of [`PolygonIndex::area_edges`]) that may cross the ray from a
    /// point of the cell towards +x: the rest cannot, or are counted in `parity`.
    pub crossing: (u32, u32),
    /// Its edges that may be nearest to a point of the cell.
    pub nearest: (u32, u32),
}

/// The index: a grid of small cells; per cell a range of `areas` and a range of `edges`.
#[derive(Clone, Copy, Debug)]
pub struct PolygonIndex<'a> {
    grid: FineGrid<'a>,
    /// Per cell `c`, where its areas and its edges start; they end where those of `c + 1`
    /// start (one array: a cell's lookup touches one cache line, not two).
    starts: &'a [[u32; 2]],
    /// By key.
    areas: &'a [Area],
    /// Edges as stored in the tile (x, y of the start, x, y of the end), by key and then in
    /// ring order.
    edges: &'a [[f32; 4]],
    /// The areas' edges, likewise.
    area_edges: &'a [[f32; 4]],
}

impl<'a> PolygonIndex<'a> {
    /// An index over these arrays: the cells of `grid`, `starts` (where each cell's areas
    /// and edges start) one longer than the number of cells; `[edges, area_edges]`.
    pub fn new(
        grid: FineGrid<'a>,
        starts: &'a [[u32; 2]],
        areas: &'a [Area],
        [edges, area_edges]: [&'a [[f32; 4]]; 2],
    ) -> Self {
        PolygonIndex { grid, starts, areas, edges, area_edges }
    }

    /// The cell holding (x, y); `None` outside the grid or where nothing is within the
    /// search radius.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<usize> {
        self.grid.cell_of(x, y)
    }

    /// The polygons that may hold a point of cell `c`, by key.
    pub fn areas(&self, c: usize) -> &'a [Area] {
        self.range(c, 0).and_then(|r| self.areas.get(r)).unwrap_or(&[])
    }

    /// The edges of all polygons that may be nearest to a point of cell `c` outside them
    /// all, within the search radius.
    pub fn edges(&self, c: usize) -> &'a [[f32; 4]] {
        self.range(c, 1).and_then(|r| self.edges.get(r)).unwrap_or(&[])
    }

    /// Cell `c`'s areas (`which` 0) or edges (1).
    fn range(&self, c: usize, which: usize) -> Option<core::ops::Range<usize>> {
        let (start, end) = (self.starts.get(c)?, self.starts.get(c.checked_add(1)?)?);
        Some(*start.get(which)? as usize..*end.get(which)? as usize)
    }

    /// An area's edges: `(start, end)` of [`Area::crossing`] or [`Area::nearest`].
    pub fn area_edges(&self, (start, end): (u32, u32)) -> &'a [[f32; 4]] {
        self.area_edges.get(start as usize..end as usize).unwrap_or(&[])
    }
}
