//! The batch problem's normal equations: whitened residual rows accumulated blockwise —
//! block-tridiagonal in the keyframes (7×7 blocks) plus the dense columns of the globals —
//! and solved by faer's sparse Cholesky, linear in the drive's length.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};

use dash2sim_core::nalgebra::Vector3;

use super::{SolveError, BLOCK, FIRST_LAMBDA, GLOBALS, ROTATION_STEP_INFORMATION};

/// One scalar residual, whitened: value and its Jacobian's non-zeros.
#[derive(Clone, Copy)]
pub(super) struct Row {
    pub(super) value: f64,
    pub(super) index: [usize; 16],
    pub(super) coeff: [f64; 16],
    pub(super) len: usize,
}

impl Row {
    pub(super) fn new(value: f64) -> Self {
        Row { value, index: [0; 16], coeff: [0.0; 16], len: 0 }
    }
    pub(super) fn with(mut self, index: usize, coeff: f64) -> Self {
        self.put(index, coeff);
        self
    }

    /// Adds a non-zero in place (a loop that rebuilt the row with `with` copied its 272
    /// bytes at every column: half of a sweep's time went to those copies, `perf`).
    pub(super) fn put(&mut self, index: usize, coeff: f64) {
        if coeff != 0.0 && self.len < 16 {
            self.index[self.len] = index;
            self.coeff[self.len] = coeff;
            self.len += 1;
        }
    }
}

/// The normal equations `H δ = −g`, stored by block: diagonal blocks, the blocks coupling
/// keyframe k and k + 1, each block's coupling with the globals, and the globals'.
pub(super) struct Normal {
    pub(super) blocks: usize,
    pub(super) diagonal: Vec<[[f64; BLOCK]; BLOCK]>,
    pub(super) next: Vec<[[f64; BLOCK]; BLOCK]>,
    pub(super) global: Vec<[[f64; GLOBALS]; BLOCK]>,
    pub(super) globals: [[f64; GLOBALS]; GLOBALS],
    pub(super) g: Vec<f64>,
    /// Σ w·e² over the rows (the a-posteriori variance factor's numerator).
    pub(super) chi2: f64,
    /// The cost the solve minimises: ½e² of every plain row, and what the assembly adds for
    /// each robust measurement (its kernel's cost, not ½w·e²: the steps are judged by the
    /// cost whose minimum the weights lead to, or the solve stops short of it).
    pub(super) cost: f64,
    pub(super) rows: usize,
}

impl Normal {
    pub(super) fn new(blocks: usize) -> Self {
        Normal {
            blocks,
            diagonal: vec![[[0.0; BLOCK]; BLOCK]; blocks],
            next: vec![[[0.0; BLOCK]; BLOCK]; blocks],
            global: vec![[[0.0; GLOBALS]; BLOCK]; blocks],
            globals: [[0.0; GLOBALS]; GLOBALS],
            g: vec![0.0; blocks * BLOCK + GLOBALS],
            chi2: 0.0,
            cost: 0.0,
            rows: 0,
        }
    }

    pub(super) fn size(&self) -> usize {
        self.blocks * BLOCK + GLOBALS
    }

    /// H[i][j] += v for i ≤ j (the upper triangle).
    pub(super) fn add(&mut self, i: usize, j: usize, v: f64) {
        let (i, j) = if i <= j { (i, j) } else { (j, i) };
        let first_global = self.blocks * BLOCK;
        match (i < first_global, j < first_global) {
            (true, true) => {
                let (bi, bj) = (i / BLOCK, j / BLOCK);
                if bi == bj {
                    self.diagonal[bi][i % BLOCK][j % BLOCK] += v;
                } else if bj == bi + 1 {
                    self.next[bi][i % BLOCK][j % BLOCK] += v;
                }
                // No residual couples keyframes further apart (see `place`).
            }
            (true, false) => self.global[i / BLOCK][i % BLOCK][j - first_global] += v,
            _ => self.globals[i - first_global][j - first_global] += v,
        }
    }

    pub(super) fn push(&mut self, row: &Row, weight: f64) {
        if weight <= 0.0 || !row.value.is_finite() {
            return;
        }
        self.chi2 += weight * row.value * row.value;
        self.rows += 1;
        for a in 0..row.len {
            self.g[row.index[a]] += weight * row.coeff[a] * row.value;
            for b in 0..row.len {
                if row.index[a] <= row.index[b] {
                    self.add(row.index[a], row.index[b], weight * row.coeff[a] * row.coeff[b]);
                }
            }
        }
    }

    /// A row without a robust kernel: its ½e² is part of the cost.
    pub(super) fn plain(&mut self, row: &Row) {
        if row.value.is_finite() {
            self.cost += 0.5 * row.value * row.value;
        }
        self.push(row, 1.0);
    }

    /// The three rows of a 3-vector residual without a robust kernel ([`Normal::push3`]).
    pub(super) fn plain3(&mut self, r: &Vector3<f64>, sigma: &Vector3<f64>, jac: &[(usize, &[Vector3<f64>])]) {
        let e = r.component_div(sigma);
        if e.iter().all(|x| x.is_finite()) {
            self.cost += 0.5 * e.norm_squared();
        }
        self.push3(r, sigma, jac, 1.0);
    }

    /// The three rows of a 3-vector residual `r / σ` with Jacobian blocks `(first
    /// unknown, 3×m matrix)`.
    pub(super) fn push3(
        &mut self,
        r: &Vector3<f64>,
        sigma: &Vector3<f64>,
        jac: &[(usize, &[Vector3<f64>])],
        weight: f64,
    ) {
        for axis in 0..3 {
            let mut row = Row::new(r[axis] / sigma[axis]);
            for (first, columns) in jac {
                for (c, column) in columns.iter().enumerate() {
                    row.put(first + c, column[axis] / sigma[axis]);
                }
            }
            self.push(&row, weight);
        }
    }

    /// The upper triangle as a sparse matrix, the diagonal scaled by `1 + lambda`, plus
    /// `rotation_information` on every rotation increment's (and a tiny absolute term on
    /// the others', so that an unobserved unknown does not make it singular).
    pub(super) fn matrix(
        &self,
        lambda: f64,
        rotation_information: f64,
    ) -> Result<SparseColMat<usize, f64>, SolveError> {
        let mut triplets = Vec::with_capacity(self.blocks * (BLOCK * BLOCK * 2 + BLOCK * GLOBALS) + 4);
        let first_global = self.blocks * BLOCK;
        for b in 0..self.blocks {
            for i in 0..BLOCK {
                for j in i..BLOCK {
                    let v = self.diagonal[b][i][j] * if i == j { 1.0 + lambda } else { 1.0 }
                        + match (i == j, i >= 4) {
                            (true, true) => rotation_information,
                            (true, false) => 1e-9,
                            _ => 0.0,
                        };
                    triplets.push(Triplet::new(b * BLOCK + i, b * BLOCK + j, v));
                }
                if b + 1 < self.blocks {
                    for j in 0..BLOCK {
                        let v = self.next[b][i][j];
                        if v != 0.0 {
                            triplets.push(Triplet::new(b * BLOCK + i, (b + 1) * BLOCK + j, v));
                        }
                    }
                }
                for j in 0..GLOBALS {
                    let v = self.global[b][i][j];
                    if v != 0.0 {
                        triplets.push(Triplet::new(b * BLOCK + i, first_global + j, v));
                    }
                }
            }
        }
        for i in 0..GLOBALS {
            for j in i..GLOBALS {
                let v = self.globals[i][j] * if i == j { 1.0 + lambda } else { 1.0 } + if i == j { 1e-9 } else { 0.0 };
                triplets.push(Triplet::new(first_global + i, first_global + j, v));
            }
        }
        SparseColMat::try_new_from_triplets(self.size(), self.size(), &triplets).map_err(|_| SolveError::Singular)
    }
}

/// The sparse Cholesky factorisation of the normal matrices of one solve, its symbolic part
/// (the fill-reducing ordering and the elimination tree, a quarter of a solve's time when
/// redone at every iteration) kept while the matrices' pattern stays the same. The pattern
/// is compared whole, so a factor is the one `sp_cholesky` would give, bit for bit.
#[derive(Default)]
pub(super) struct Factoriser {
    symbolic: Option<(Vec<usize>, Vec<usize>, SymbolicLlt<usize>)>,
}

impl Factoriser {
    /// The factor of `matrix` (upper triangle stored).
    pub(super) fn factor(&mut self, matrix: &SparseColMat<usize, f64>) -> Result<Llt<usize, f64>, SolveError> {
        let pattern = matrix.symbolic();
        let same = self.symbolic.as_ref().is_some_and(|(columns, rows, _)| {
            columns.as_slice() == pattern.col_ptr() && rows.as_slice() == pattern.row_idx()
        });
        if !same {
            let symbolic = SymbolicLlt::try_new(pattern, Side::Upper).map_err(|_| SolveError::Singular)?;
            self.symbolic = Some((pattern.col_ptr().to_vec(), pattern.row_idx().to_vec(), symbolic));
        }
        let Some((_, _, symbolic)) = &self.symbolic else { return Err(SolveError::Singular) };
        Llt::try_new_with_symbolic(symbolic.clone(), matrix.as_ref(), Side::Upper).map_err(|_| SolveError::Singular)
    }
}

/// One damped Gauss–Newton step: `(H + λ·diag H + D_rot) δ = −g`, `D_rot` the rotation
/// increments' damping in proportion to λ ([`ROTATION_STEP_INFORMATION`]).
pub(super) fn solve_normal(normal: &Normal, lambda: f64, factoriser: &mut Factoriser) -> Result<Vec<f64>, SolveError> {
    let rotation_information = ROTATION_STEP_INFORMATION * lambda / FIRST_LAMBDA;
    let llt = factoriser.factor(&normal.matrix(lambda, rotation_information)?)?;
    let rhs = Mat::from_fn(normal.size(), 1, |i, _| -normal.g[i]);
    let delta = llt.solve(&rhs);
    let delta: Vec<f64> = (0..normal.size()).map(|i| delta[(i, 0)]).collect();
    if delta.iter().any(|v| !v.is_finite()) {
        return Err(SolveError::Singular);
    }
    Ok(delta)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small problem: two keyframes, a prior on every unknown, and optionally a row coupling
    /// the two keyframes (which changes the matrix's pattern).
    fn normal(coupled: bool) -> Normal {
        let mut n = Normal::new(2);
        for i in 0..n.size() {
            n.plain(&Row::new(0.1 * i as f64 + 0.3).with(i, 1.0 + 0.01 * i as f64));
        }
        if coupled {
            n.plain(&Row::new(0.7).with(2, 1.5).with(BLOCK + 2, -1.5));
        }
        n
    }

    fn solve_with(llt: &Llt<usize, f64>, n: &Normal) -> Vec<f64> {
        let rhs = Mat::from_fn(n.size(), 1, |i, _| -n.g[i]);
        let x = llt.solve(&rhs);
        (0..n.size()).map(|i| x[(i, 0)]).collect()
    }

    #[test]
    fn the_kept_symbolic_factor_gives_sp_choleskys_solution_and_follows_a_new_pattern() {
        let mut factoriser = Factoriser::default();
        for (coupled, lambda) in [(false, 1e-4), (false, 1e-2), (true, 1e-2), (true, 1.0), (false, 0.0)] {
            let n = normal(coupled);
            let matrix = n.matrix(lambda, 1.0).expect("matrix");
            let fresh = matrix.sp_cholesky(Side::Upper).expect("factor");
            let kept = factoriser.factor(&matrix).expect("factor");
            // Bit for bit: the symbolic part is the one this pattern gives, kept or not.
            assert_eq!(solve_with(&kept, &n), solve_with(&fresh, &n), "coupled {coupled}, λ {lambda}");
            let (columns, rows, _) = factoriser.symbolic.as_ref().expect("kept");
            assert_eq!(columns.as_slice(), matrix.symbolic().col_ptr());
            assert_eq!(rows.as_slice(), matrix.symbolic().row_idx());
        }
    }
}
