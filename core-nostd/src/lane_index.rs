//! A fine index of a tile's lanes that are buffered centrelines (OpenStreetMap's), for the
//! drivable check.
//!
//! The tile's grid lists, per 25 m cell, every lane whose box reaches the cell: around a
//! footprint on central Helsinki some 10–30 lanes, each read (its box, then its centreline
//! in chunks) for the footprint's five points. This index says per small cell which lanes
//! may matter to a point of it — hold it, or be the drivable area nearest to it within the
//! search radius — and which of each one's segments may be its nearest there, so that a
//! point reads a few segments instead of every lane around it, with the same answers (the
//! segments left out cannot be nearest; those kept are read in driving order, so the same
//! one wins a tie).
//!
//! In the channel-sensitive mode a corner's nearest drivable lane may be one the cell does
//! not list (the nearest of all lanes is not on the channel): each cell states below what
//! distance its answers are exact for any set of lanes ([`LaneIndex::exact_below`]), and
//! the check falls back to the tile's grid for a pose beyond it.
//!
//! Built beside the tile where memory allows (the desktop; tens of MB for a city centre) and
//! lent to [`Checker::with_lane_index`](crate::drivable::Checker::with_lane_index) as plain
//! arrays: nothing here allocates, and a short or inconsistent array reads as empty cells,
//! never a panic.

use crate::fine_grid::FineGrid;

/// A lane that may matter to a point of a cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    /// The lane.
    pub lane: u32,
    /// Half its width, m: its area is the centreline buffered by this.
    pub half_width: f64,
    /// Its segments (a range of [`LaneIndex::segments`]) that may be nearest to a point of
    /// the cell, in driving order.
    pub segments: (u32, u32),
}

/// Where a cell's runs start, and below what its answers hold whatever the lanes allowed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellStart {
    /// The first of its runs; they end where the next cell's start.
    pub runs: u32,
    /// Every lane the cell does not list is farther than this outside the drivable area
    /// from each point of the cell, m: a distance found among its runs at or below it is
    /// the least of any set of lanes.
    pub exact_below: f32,
}

/// The index: a grid of small cells; per cell a range of `runs`, each a range of `segments`.
#[derive(Clone, Copy, Debug)]
pub struct LaneIndex<'a> {
    grid: FineGrid<'a>,
    /// One longer than the number of cells.
    starts: &'a [CellStart],
    /// By cell, each cell's by lane.
    runs: &'a [Run],
    /// Segments as stored in the tile (x, y of the start, x, y of the end).
    segments: &'a [[f32; 4]],
}

impl<'a> LaneIndex<'a> {
    /// An index over these arrays: the cells of `grid`, `starts` one longer than the number
    /// of cells.
    pub fn new(grid: FineGrid<'a>, starts: &'a [CellStart], runs: &'a [Run], segments: &'a [[f32; 4]]) -> Self {
        LaneIndex { grid, starts, runs, segments }
    }

    /// The cell holding (x, y); `None` outside the grid or where no lane is within the
    /// search radius.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<usize> {
        self.grid.cell_of(x, y)
    }

    /// The lanes that may matter to a point of cell `c`, by lane.
    pub fn runs(&self, c: usize) -> &'a [Run] {
        let range = || Some(self.starts.get(c)?.runs as usize..self.starts.get(c.checked_add(1)?)?.runs as usize);
        range().and_then(|r| self.runs.get(r)).unwrap_or(&[])
    }

    /// See [`CellStart::exact_below`] (−∞ for a cell that is not in the index).
    pub fn exact_below(&self, c: usize) -> f64 {
        self.starts.get(c).map_or(f64::NEG_INFINITY, |s| f64::from(s.exact_below))
    }

    /// A run's segments.
    pub fn segments(&self, run: &Run) -> &'a [[f32; 4]] {
        self.segments.get(run.segments.0 as usize..run.segments.1 as usize).unwrap_or(&[])
    }
}
