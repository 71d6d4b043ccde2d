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
//! Built beside the tile where memory allows (the desktop; 2 MB for a city centre) and
//! lent to [`Checker::with_lane_index`](crate::drivable::Checker::with_lane_index) as plain
//! arrays: nothing here allocates, and a short or inconsistent array reads as empty cells,
//! never a panic.

use crate::fine_grid::FineGrid;

/// A lane that may matter to a point of a cell, as the cell lists it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run<'a> {
    /// The lane.
    pub lane: u32,
    /// Half its width, m: its area is the centreline buffered by this.
    pub half_width: f64,
    /// Its segments that may be nearest to a point of the cell, in driving order: x, y of
    /// the start, x, y of the end, as stored in the tile (f32 bits).
    pub segments: &'a [[u32; 4]],
}

impl Run<'_> {
    /// The segments as the tile stores them.
    pub fn segments(&self) -> impl Iterator<Item = [f32; 4]> + '_ {
        self.segments.iter().map(|s| s.map(f32::from_bits))
    }

    /// The slot that heads a run of `lane`, `half_width`, with `segments` after it.
    pub fn head(lane: u32, half_width: f64, segments: u32) -> [u32; 4] {
        let bits = half_width.to_bits();
        [lane, segments, bits as u32, (bits >> 32) as u32]
    }
}

/// Where a cell's slots start, and below what its answers hold whatever the lanes allowed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellStart {
    /// Its first slot; they end where the next cell's start.
    pub slots: u32,
    /// Every lane the cell does not list is farther than this outside the drivable area
    /// from each point of the cell, m: a distance found among its runs at or below it is
    /// the least of any set of lanes.
    pub exact_below: f32,
}

/// The index: a grid of small cells; per cell a range of 16-byte slots holding its runs, each
/// a head ([`Run::head`]: the lane, how many segments follow, half its width) and its
/// segments. A cell's lanes and segments lie together, so that a point reads one or two
/// cache lines of the index beside its cell's start (in separate arrays each would cost a
/// cache miss).
#[derive(Clone, Copy, Debug)]
pub struct LaneIndex<'a> {
    grid: FineGrid<'a>,
    /// One longer than the number of cells.
    starts: &'a [CellStart],
    slots: &'a [[u32; 4]],
}

impl<'a> LaneIndex<'a> {
    /// An index over these arrays: the cells of `grid`, `starts` one longer than the number
    /// of cells.
    pub fn new(grid: FineGrid<'a>, starts: &'a [CellStart], slots: &'a [[u32; 4]]) -> Self {
        LaneIndex { grid, starts, slots }
    }

    /// The cell holding (x, y); `None` outside the grid or where no lane is within the
    /// search radius.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<usize> {
        self.grid.cell_of(x, y)
    }

    /// The lanes that may matter to a point of cell `c`, by lane (a run cut short by the end
    /// of the cell's slots ends the list).
    pub fn runs(&self, c: usize) -> impl Iterator<Item = Run<'a>> + 'a {
        let range = || Some(self.starts.get(c)?.slots as usize..self.starts.get(c.checked_add(1)?)?.slots as usize);
        let mut slots = range().and_then(|r| self.slots.get(r)).unwrap_or(&[]);
        core::iter::from_fn(move || {
            let ([lane, count, low, high], rest) = slots.split_first()?;
            let segments = rest.get(..*count as usize)?;
            slots = rest.get(*count as usize..).unwrap_or(&[]);
            let half_width = f64::from_bits(u64::from(*low) | u64::from(*high) << 32);
            Some(Run { lane: *lane, half_width, segments })
        })
    }

    /// See [`CellStart::exact_below`] (−∞ for a cell that is not in the index).
    pub fn exact_below(&self, c: usize) -> f64 {
        self.starts.get(c).map_or(f64::NEG_INFINITY, |s| f64::from(s.exact_below))
    }
}
