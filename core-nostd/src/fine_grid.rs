//! The grid of small cells the fine indexes of a map share ([`crate::polygon_index`],
//! [`crate::lane_index`]): cells of a few metres from a corner, and one bit per block of
//! [`BLOCK`] × [`BLOCK`] cells saying whether any of them lists anything — a few KB that stay
//! in cache, so that a point far from everything costs no read of the larger arrays.

/// Cells per side of a block.
pub const BLOCK: u32 = 8;

/// Cells of `cell` metres from `min`, `cols` × `rows` of them, and the blocks' bits (row by
/// row, `cols.div_ceil(BLOCK)` blocks to a row).
#[derive(Clone, Copy, Debug)]
pub struct FineGrid<'a> {
    min: (f64, f64),
    cell: f64,
    cols: u32,
    rows: u32,
    blocks: &'a [u64],
}

impl<'a> FineGrid<'a> {
    /// A grid of `[cols, rows]` cells of `cell` metres from `min`; `blocks` the bits of the
    /// blocks whose cells list anything.
    pub fn new(min: (f64, f64), cell: f64, [cols, rows]: [u32; 2], blocks: &'a [u64]) -> Self {
        FineGrid { min, cell, cols, rows, blocks }
    }

    /// The cell holding (x, y); `None` outside the grid or in a block whose cells list
    /// nothing.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<usize> {
        let (col, row) = ((x - self.min.0) / self.cell, (y - self.min.1) / self.cell);
        // Written so that NaN fails too.
        if !(col >= 0.0 && row >= 0.0 && col < f64::from(self.cols) && row < f64::from(self.rows)) {
            return None;
        }
        let (col, row) = (col as u32, row as u32);
        let block = (row / BLOCK) as usize * self.cols.div_ceil(BLOCK) as usize + (col / BLOCK) as usize;
        if self.blocks.get(block / 64).is_none_or(|bits| bits & 1 << (block % 64) == 0) {
            return None;
        }
        (row as usize).checked_mul(self.cols as usize)?.checked_add(col as usize)
    }
}
