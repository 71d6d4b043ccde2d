//! The fine index the desktop's drivable check reads beside a tile, whichever its lanes
//! need: Lanelet2's polygons ([`super::polygon_index`], the channel-insensitive mode) or
//! OpenStreetMap's buffered centrelines ([`super::lane_index`], both modes). Same answers as
//! the tile's grid alone, faster (docs/verify.md, docs/benchmarks.md).

use dash2sim_core::drivable::Checker;
use dash2sim_core::map::MapView;
use dash2sim_core::obb::Footprint;

use super::lane_index::{self, LaneArrays};
use super::polygon_index::{self, IndexArrays};

/// A tile's fine index.
#[derive(Clone, Debug)]
pub enum FineIndex {
    /// Of a tile whose lanes are polygons.
    Polygons(IndexArrays),
    /// Of a tile whose lanes are buffered centrelines.
    Lanes(LaneArrays),
}

impl FineIndex {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        match self {
            FineIndex::Polygons(p) => p.bytes(),
            FineIndex::Lanes(l) => l.bytes(),
        }
    }
}

/// The index of `map`, if it has lanes (or polygons) of one kind.
pub fn build(map: &MapView<'_>) -> Option<FineIndex> {
    match polygon_index::build(map) {
        Some(p) => Some(FineIndex::Polygons(p)),
        None => lane_index::build(map).map(FineIndex::Lanes),
    }
}

/// The index of `map` where it pays for `checks` footprint checks: a map of polygons always
/// (the grid alone is several times slower there); a map of buffered lanes when the checks
/// number four (`CHECKS_PER_CELL`) for each of the index's cells, so that a 40 s drive on its own
/// road is checked through the grid, and ten thousand footprints on a city through the index.
pub fn for_checks(map: &MapView<'_>, checks: usize) -> Option<FineIndex> {
    match polygon_index::build(map) {
        Some(p) => Some(FineIndex::Polygons(p)),
        None if checks >= CHECKS_PER_CELL * lane_index::cells(map) => lane_index::build(map).map(FineIndex::Lanes),
        None => None,
    }
}

/// Checks a cell of the lane index must serve to pay for its build: on central Helsinki the
/// build takes ~1.5 µs a cell (29 000 cells in ~45 ms) and a check through the index saves
/// ~0.35 µs (1.1 → 0.77 µs).
const CHECKS_PER_CELL: usize = 4;

/// A checker for `map` that reads `index` (built for `map`) where there is one.
pub fn checker<'a>(map: MapView<'a>, footprint: Footprint, index: Option<&'a FineIndex>) -> Checker<'a> {
    let plain = Checker::new(map, footprint);
    match index {
        Some(FineIndex::Polygons(p)) => plain.with_index(p.view()),
        Some(FineIndex::Lanes(l)) => plain.with_lane_index(l.view()),
        None => plain,
    }
}
