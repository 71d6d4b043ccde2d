//! A fine index of a tile's drivable polygons (Lanelet2 lanes), for the drivable check.
//!
//! The tile's grid lists, per 25 m cell, every lane or polygon whose box reaches the cell:
//! around a footprint that is some 19 small polygons, each then walked whole for each
//! corner. This index says per small cell which polygons may hold a point of it (and
//! whether one holds all of it), which of each one's edges may be nearest to a point of it
//! inside, and which edges of all may be nearest to a point of it outside them all. A
//! corner then reads a few edges instead of every polygon around it, with the same answer
//! (edges that cannot be nearest are left out; those that can are read in the same order).
//!
//! It is built beside the tile where memory allows (the desktop's `verify`; several MB for
//! the Lanelet2 example, so not on the microcontroller) and lent to
//! [`Checker::with_index`](crate::drivable::Checker::with_index) as plain arrays: nothing
//! here allocates, and a short or inconsistent array reads as empty cells, never a panic.

/// Set in an area's key when its polygon holds the whole cell (with a margin): points of the
/// cell need no parity test.
pub const WHOLE_BIT: u32 = 0x4000_0000;

/// The index: a grid of cells of `cell` metres from `min`; per cell a range of `areas` and
/// a range of `edges`.
#[derive(Clone, Copy, Debug)]
pub struct PolygonIndex<'a> {
    min: (f64, f64),
    cell: f64,
    cols: u32,
    rows: u32,
    /// Per cell `c`, its areas from `area_starts[c]` to `area_starts[c + 1]`.
    area_starts: &'a [u32],
    /// Grid key (with [`WHOLE_BIT`]), polygon, and the range of `depth_edges` that may be
    /// nearest to a point of the cell inside it; by key.
    areas: &'a [[u32; 4]],
    /// Per cell `c`, its edges from `edge_starts[c]` to `edge_starts[c + 1]`.
    edge_starts: &'a [u32],
    /// Edges as stored in the tile (x, y of the start, x, y of the end), by key and then in
    /// ring order.
    edges: &'a [[f32; 4]],
    /// The areas' edges, likewise.
    depth_edges: &'a [[f32; 4]],
}

impl<'a> PolygonIndex<'a> {
    /// An index over these arrays: `[cols, rows]` cells of `cell` metres from `min`,
    /// `[area_starts, edge_starts]` each one longer than the number of cells.
    pub fn new(
        min: (f64, f64),
        cell: f64,
        [cols, rows]: [u32; 2],
        [area_starts, edge_starts]: [&'a [u32]; 2],
        areas: &'a [[u32; 4]],
        edges: &'a [[f32; 4]],
        depth_edges: &'a [[f32; 4]],
    ) -> Self {
        PolygonIndex { min, cell, cols, rows, area_starts, areas, edge_starts, edges, depth_edges }
    }

    /// The cell holding (x, y); `None` outside the grid, where nothing is within the search
    /// radius.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<usize> {
        let (col, row) = ((x - self.min.0) / self.cell, (y - self.min.1) / self.cell);
        // Written so that NaN fails too.
        if !(col >= 0.0 && row >= 0.0 && col < f64::from(self.cols) && row < f64::from(self.rows)) {
            return None;
        }
        (row as usize).checked_mul(self.cols as usize)?.checked_add(col as usize)
    }

    /// The polygons that may hold a point of cell `c`: grid key (with [`WHOLE_BIT`]),
    /// polygon, and the range of their edges for [`PolygonIndex::depth_edges`].
    pub fn areas(&self, c: usize) -> &'a [[u32; 4]] {
        range(self.area_starts, c).and_then(|r| self.areas.get(r)).unwrap_or(&[])
    }

    /// The edges of all polygons that may be nearest to a point of cell `c` outside them
    /// all, within the search radius.
    pub fn edges(&self, c: usize) -> &'a [[f32; 4]] {
        range(self.edge_starts, c).and_then(|r| self.edges.get(r)).unwrap_or(&[])
    }

    /// An area's edges that may be nearest to a point of its cell inside it.
    pub fn depth_edges(&self, start: u32, end: u32) -> &'a [[f32; 4]] {
        self.depth_edges.get(start as usize..end as usize).unwrap_or(&[])
    }
}

fn range(starts: &[u32], c: usize) -> Option<core::ops::Range<usize>> {
    Some(*starts.get(c)? as usize..*starts.get(c.checked_add(1)?)? as usize)
}
