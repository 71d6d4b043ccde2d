//! Optimal assignment (linear sum assignment) without allocation.
//!
//! The shortest-augmenting-path algorithm of Crouse (2016), "On implementing 2D
//! rectangular assignment algorithms" — the one behind SciPy's `linear_sum_assignment`,
//! with the same tie-breaking, so evaluations that use SciPy (motmetrics) are reproduced
//! exactly. O(n²m) time for an n × m problem, O(n + m) memory in a [`Workspace`].
//!
//! [`Solver`] owns a fixed-capacity workspace for the device (`Solver<64>`: up to 64
//! rows and 64 columns); the std side can build a [`Workspace`] over its own buffers for
//! problems of any size. [`Solver::solve_sparse`] accepts forbidden pairs (gates, IoU
//! thresholds) the way motmetrics does: as the fewest possible forbidden edges, then the
//! least cost.

/// Why an assignment could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AssignError {
    /// More rows or columns than the workspace holds.
    TooLarge,
    /// A cost is NaN or infinite (use [`Solver::solve_sparse`] for forbidden pairs).
    NotFinite,
    /// The output slice is shorter than the number of rows.
    OutputTooShort,
}

impl core::fmt::Display for AssignError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            AssignError::TooLarge => write!(f, "assignment problem larger than the workspace"),
            AssignError::NotFinite => write!(f, "assignment cost is not finite"),
            AssignError::OutputTooShort => write!(f, "output shorter than the number of rows"),
        }
    }
}

impl core::error::Error for AssignError {}

/// Scratch space for one problem: borrowed slices, each at least as long as the larger of
/// rows and columns.
#[derive(Debug)]
pub struct Workspace<'a> {
    /// Dual variables of the rows.
    pub u: &'a mut [f64],
    /// Dual variables of the columns.
    pub v: &'a mut [f64],
    /// Shortest path costs to each column.
    pub shortest: &'a mut [f64],
    /// Predecessor row of each column on the path.
    pub path: &'a mut [usize],
    /// Column of each row (`usize::MAX` = none).
    pub col4row: &'a mut [usize],
    /// Row of each column (`usize::MAX` = none).
    pub row4col: &'a mut [usize],
    /// Rows visited in this search.
    pub seen_rows: &'a mut [bool],
    /// Columns visited in this search.
    pub seen_cols: &'a mut [bool],
    /// Columns not yet visited.
    pub remaining: &'a mut [usize],
}

const NONE: usize = usize::MAX;

impl Workspace<'_> {
    fn capacity(&self) -> usize {
        [
            self.u.len(),
            self.v.len(),
            self.shortest.len(),
            self.path.len(),
            self.col4row.len(),
            self.row4col.len(),
            self.seen_rows.len(),
            self.seen_cols.len(),
            self.remaining.len(),
        ]
        .into_iter()
        .min()
        .unwrap_or(0)
    }

    /// Solve a rows × cols problem with finite costs; `out[r]` receives the column of row
    /// `r` (every row when rows ≤ cols, else `None` for the rows left over). Returns the
    /// number of pairs.
    pub fn solve(
        &mut self,
        rows: usize,
        cols: usize,
        cost: impl Fn(usize, usize) -> f64,
        out: &mut [Option<usize>],
    ) -> Result<usize, AssignError> {
        if rows.max(cols) > self.capacity() {
            return Err(AssignError::TooLarge);
        }
        let out = out.get_mut(..rows).ok_or(AssignError::OutputTooShort)?;
        out.fill(None);
        if rows == 0 || cols == 0 {
            return Ok(0);
        }
        for r in 0..rows {
            for c in 0..cols {
                if !cost(r, c).is_finite() {
                    return Err(AssignError::NotFinite);
                }
            }
        }
        // The algorithm wants rows ≤ cols; transpose otherwise (as SciPy does).
        let transposed = rows > cols;
        let (nr, nc) = if transposed { (cols, rows) } else { (rows, cols) };
        let c = |i: usize, j: usize| if transposed { cost(j, i) } else { cost(i, j) };
        self.u[..nr].fill(0.0);
        self.v[..nc].fill(0.0);
        self.col4row[..nr].fill(NONE);
        self.row4col[..nc].fill(NONE);
        for row in 0..nr {
            let (sink, min_val) = self.augmenting_path(nc, row, &c);
            // Costs are finite, so every row finds a free column while rows ≤ cols.
            let Some(sink) = sink else { return Err(AssignError::NotFinite) };
            self.u[row] += min_val;
            for i in 0..nr {
                if self.seen_rows[i] && i != row {
                    self.u[i] += min_val - self.shortest[self.col4row[i]];
                }
            }
            for j in 0..nc {
                if self.seen_cols[j] {
                    self.v[j] -= min_val - self.shortest[j];
                }
            }
            let mut j = sink;
            loop {
                let i = self.path[j];
                self.row4col[j] = i;
                core::mem::swap(&mut self.col4row[i], &mut j);
                if i == row {
                    break;
                }
            }
        }
        if transposed {
            for (j, &i) in self.row4col[..nc].iter().enumerate() {
                if i != NONE {
                    out[j] = Some(i);
                }
            }
        } else {
            for (i, slot) in out.iter_mut().enumerate() {
                *slot = Some(self.col4row[i]);
            }
        }
        Ok(nr)
    }

    /// Dijkstra-like search from `row` for the cheapest free column (Crouse, Alg. 1).
    fn augmenting_path(&mut self, nc: usize, row: usize, cost: &impl Fn(usize, usize) -> f64) -> (Option<usize>, f64) {
        let mut min_val = 0.0;
        let mut remaining = nc;
        for (k, slot) in self.remaining[..nc].iter_mut().enumerate() {
            *slot = nc - k - 1;
        }
        self.seen_rows.fill(false);
        self.seen_cols[..nc].fill(false);
        self.shortest[..nc].fill(f64::INFINITY);
        let mut i = row;
        loop {
            let mut index = NONE;
            let mut lowest = f64::INFINITY;
            self.seen_rows[i] = true;
            for k in 0..remaining {
                let j = self.remaining[k];
                let r = min_val + cost(i, j) - self.u[i] - self.v[j];
                if r < self.shortest[j] {
                    self.path[j] = i;
                    self.shortest[j] = r;
                }
                if self.shortest[j] < lowest || (self.shortest[j] == lowest && self.row4col[j] == NONE) {
                    lowest = self.shortest[j];
                    index = k;
                }
            }
            min_val = lowest;
            if index == NONE || !min_val.is_finite() {
                return (None, min_val);
            }
            let j = self.remaining[index];
            self.seen_cols[j] = true;
            remaining -= 1;
            self.remaining[index] = self.remaining[remaining];
            if self.row4col[j] == NONE {
                return (Some(j), min_val);
            }
            i = self.row4col[j];
        }
    }

    /// Like [`Workspace::solve`], but `cost` may say `None` (forbidden). Forbidden pairs get
    /// a cost so large that a solution with fewer of them always wins (motmetrics'
    /// `add_expensive_edges`), and are removed from the result. Returns the pairs kept.
    pub fn solve_sparse(
        &mut self,
        rows: usize,
        cols: usize,
        cost: impl Fn(usize, usize) -> Option<f64>,
        out: &mut [Option<usize>],
    ) -> Result<usize, AssignError> {
        let mut largest: Option<f64> = None;
        for r in 0..rows {
            for c in 0..cols {
                if let Some(v) = cost(r, c) {
                    if !v.is_finite() {
                        return Err(AssignError::NotFinite);
                    }
                    largest = Some(largest.unwrap_or(0.0).max(v.abs()));
                }
            }
        }
        let Some(largest) = largest else {
            out.get_mut(..rows).ok_or(AssignError::OutputTooShort)?.fill(None);
            return Ok(0);
        };
        let c = largest + 1.0;
        let forbidden = 2.0 * rows.min(cols) as f64 * c + 1.0;
        self.solve(rows, cols, |r, col| cost(r, col).unwrap_or(forbidden), out)?;
        let mut kept = 0;
        for (r, slot) in out.iter_mut().take(rows).enumerate() {
            match *slot {
                Some(col) if cost(r, col).is_some() => kept += 1,
                _ => *slot = None,
            }
        }
        Ok(kept)
    }
}

/// A workspace for problems up to `N` × `N`, owned (about 50·N bytes).
#[derive(Clone, Debug)]
pub struct Solver<const N: usize> {
    u: [f64; N],
    v: [f64; N],
    shortest: [f64; N],
    path: [usize; N],
    col4row: [usize; N],
    row4col: [usize; N],
    seen_rows: [bool; N],
    seen_cols: [bool; N],
    remaining: [usize; N],
}

impl<const N: usize> Default for Solver<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Solver<N> {
    /// A solver with its workspace (const, so that a large one can live in a `static`).
    pub const fn new() -> Self {
        Solver {
            u: [0.0; N],
            v: [0.0; N],
            shortest: [0.0; N],
            path: [0; N],
            col4row: [0; N],
            row4col: [0; N],
            seen_rows: [false; N],
            seen_cols: [false; N],
            remaining: [0; N],
        }
    }
}

impl<const N: usize> Solver<N> {
    /// The workspace view.
    pub fn workspace(&mut self) -> Workspace<'_> {
        Workspace {
            u: &mut self.u,
            v: &mut self.v,
            shortest: &mut self.shortest,
            path: &mut self.path,
            col4row: &mut self.col4row,
            row4col: &mut self.row4col,
            seen_rows: &mut self.seen_rows,
            seen_cols: &mut self.seen_cols,
            remaining: &mut self.remaining,
        }
    }

    /// See [`Workspace::solve`].
    pub fn solve(
        &mut self,
        rows: usize,
        cols: usize,
        cost: impl Fn(usize, usize) -> f64,
        out: &mut [Option<usize>],
    ) -> Result<usize, AssignError> {
        self.workspace().solve(rows, cols, cost, out)
    }

    /// See [`Workspace::solve_sparse`].
    pub fn solve_sparse(
        &mut self,
        rows: usize,
        cols: usize,
        cost: impl Fn(usize, usize) -> Option<f64>,
        out: &mut [Option<usize>],
    ) -> Result<usize, AssignError> {
        self.workspace().solve_sparse(rows, cols, cost, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Minimum over all injective maps of the smaller side into the larger, by brute force.
    fn brute_force(rows: usize, cols: usize, cost: &[f64]) -> f64 {
        fn go(r: usize, rows: usize, cols: usize, used: &mut [bool; 8], cost: &[f64], transposed: bool) -> f64 {
            if r == rows {
                return 0.0;
            }
            let mut best = f64::INFINITY;
            for c in 0..cols {
                if !used[c] {
                    used[c] = true;
                    let v = if transposed { cost[c * rows + r] } else { cost[r * cols + c] };
                    best = best.min(v + go(r + 1, rows, cols, used, cost, transposed));
                    used[c] = false;
                }
            }
            best
        }
        let mut used = [false; 8];
        if rows <= cols {
            go(0, rows, cols, &mut used, cost, false)
        } else {
            go(0, cols, rows, &mut used, cost, true)
        }
    }

    proptest! {
        #[test]
        fn optimal_for_small_rectangular_problems(rows in 1usize..6, cols in 1usize..6, seed in proptest::collection::vec(0u32..1000, 36)) {
            let cost: heapless::Vec<f64, 36> = seed.iter().take(rows * cols).map(|&v| f64::from(v) / 10.0).collect();
            let mut solver = Solver::<8>::default();
            let mut out = [None; 8];
            let pairs = solver.solve(rows, cols, |r, c| cost[r * cols + c], &mut out).expect("solvable");
            prop_assert_eq!(pairs, rows.min(cols));
            let mut total = 0.0;
            let mut used = [false; 8];
            for (r, col) in out[..rows].iter().enumerate() {
                if let Some(col) = col {
                    prop_assert!(!used[*col], "column used twice");
                    used[*col] = true;
                    total += cost[r * cols + col];
                }
            }
            prop_assert!((total - brute_force(rows, cols, &cost)).abs() < 1e-9);
        }
    }

    #[test]
    fn forbidden_pairs_are_avoided_and_cardinality_comes_first() {
        let mut solver = Solver::<4>::default();
        let mut out = [None; 4];
        // Row 0 may only take column 0; row 1 prefers column 0 but can take column 1.
        let cost = [[Some(0.9), None], [Some(0.1), Some(0.8)]];
        let n = solver.solve_sparse(2, 2, |r, c| cost[r][c], &mut out).expect("solvable");
        assert_eq!((n, &out[..2]), (2, &[Some(0), Some(1)][..]));
        // Nothing allowed at all.
        let n = solver.solve_sparse(2, 3, |_, _| None, &mut out).expect("solvable");
        assert_eq!((n, &out[..2]), (0, &[None, None][..]));
        // A row with nothing allowed stays unassigned.
        let cost = [[None, None], [Some(0.5), Some(0.2)]];
        let n = solver.solve_sparse(2, 2, |r, c| cost[r][c], &mut out).expect("solvable");
        assert_eq!((n, &out[..2]), (1, &[None, Some(1)][..]));
    }

    #[test]
    fn tall_problems_are_transposed() {
        let mut solver = Solver::<4>::default();
        let mut out = [None; 4];
        let cost = [[5.0], [1.0], [3.0]];
        assert_eq!(solver.solve(3, 1, |r, c| cost[r][c], &mut out), Ok(1));
        assert_eq!(&out[..3], &[None, Some(0), None]);
    }

    #[test]
    fn errors_instead_of_panics() {
        let mut solver = Solver::<2>::default();
        let mut out = [None; 4];
        assert_eq!(solver.solve(3, 1, |_, _| 0.0, &mut out), Err(AssignError::TooLarge));
        assert_eq!(solver.solve(2, 2, |_, _| f64::NAN, &mut out), Err(AssignError::NotFinite));
        assert_eq!(solver.solve(2, 2, |_, _| 0.0, &mut out[..1]), Err(AssignError::OutputTooShort));
        assert_eq!(solver.solve_sparse(1, 1, |_, _| Some(f64::INFINITY), &mut out), Err(AssignError::NotFinite));
        assert_eq!(solver.solve(0, 2, |_, _| 0.0, &mut out), Ok(0));
    }
}
