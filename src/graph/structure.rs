//! Sparse structure of the normal equations, analysed once and reused across iterations.
//!
//! The Gauss–Newton Hessian `H = Σ Jᵀ W J` of a pose graph has one dense 6×6 block per free
//! variable and one per pair of free variables sharing a factor. Its upper triangle is stored
//! in compressed sparse columns; every factor knows in advance where its blocks land, so
//! assembling an iteration's system is a scatter without searching. The fill-reducing
//! ordering is approximate minimum degree computed on the *block* graph (36× smaller than the
//! scalar one) and expanded to scalars, and the symbolic Cholesky factorisation is computed
//! once; each iteration only refactors numerically.

use super::factors::Factor;
use super::GraphError;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use nalgebra::{Matrix6, Vector6};

/// Marker for a variable that is held (not part of the linear system).
const HELD: usize = usize::MAX;

/// Where one factor's blocks live in the value array.
#[derive(Clone, Copy, Debug)]
struct FactorSlots {
    /// Block column of the first variable, or `HELD`.
    block_a: usize,
    /// Block column of the second variable, or `HELD` (also for unary factors).
    block_b: usize,
    /// Position of the off-diagonal block's rows within its column (block rank × 6).
    off_rank: usize,
}

/// Sparse normal equations with a reusable symbolic Cholesky factorisation.
pub(crate) struct NormalEquations {
    /// Block column → variable index.
    pub var_of: Vec<usize>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Number of strictly-upper blocks in each block column.
    off_count: Vec<usize>,
    slots: Vec<FactorSlots>,
    /// Undamped Hessian values (upper triangle).
    pub hessian: Vec<f64>,
    /// Damped copy handed to the factorisation.
    damped: Vec<f64>,
    /// Positions of the scalar diagonal entries.
    diag_pos: Vec<usize>,
    /// Gradient `Σ Jᵀ W r`.
    pub gradient: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    workspace: MemBuffer,
}

impl NormalEquations {
    /// Analyses the structure for the given factors with the given held variables.
    pub fn analyse(held: &[bool], factors: &[Factor]) -> Result<Self, GraphError> {
        let n_vars = held.len();
        let mut block_of = vec![HELD; n_vars];
        let mut var_of = Vec::new();
        for (v, &h) in held.iter().enumerate() {
            if !h {
                block_of[v] = var_of.len();
                var_of.push(v);
            }
        }
        let nb = var_of.len();
        // Strictly-upper block rows of each block column.
        let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); nb];
        for f in factors {
            if f.is_unary() {
                continue;
            }
            let [a, b] = f.vars();
            let (ba, bb) = (block_of[a], block_of[b]);
            if ba != HELD && bb != HELD && ba != bb {
                let (r, c) = if ba < bb { (ba, bb) } else { (bb, ba) };
                rows_of[c].push(r);
            }
        }
        for rows in &mut rows_of {
            rows.sort_unstable();
            rows.dedup();
        }
        let off_count: Vec<usize> = rows_of.iter().map(Vec::len).collect();

        // Scalar upper CSC.
        let n = 6 * nb;
        let nnz: usize = off_count.iter().map(|m| 36 * m + 21).sum();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::with_capacity(nnz);
        let mut diag_pos = Vec::with_capacity(n);
        col_ptr.push(0);
        for (c, rows) in rows_of.iter().enumerate() {
            for k in 0..6 {
                for &r in rows {
                    row_idx.extend((0..6).map(|i| 6 * r + i));
                }
                row_idx.extend((0..=k).map(|i| 6 * c + i));
                diag_pos.push(row_idx.len() - 1);
                col_ptr.push(row_idx.len());
            }
        }

        let slots = factors
            .iter()
            .map(|f| {
                let [a, b] = f.vars();
                let block_a = block_of[a];
                let block_b = if f.is_unary() { HELD } else { block_of[b] };
                let mut off_rank = 0;
                if block_a != HELD && block_b != HELD && block_a != block_b {
                    let (r, c) = if block_a < block_b {
                        (block_a, block_b)
                    } else {
                        (block_b, block_a)
                    };
                    // The row was inserted above, so the search succeeds.
                    off_rank = 6 * rows_of[c].binary_search(&r).unwrap_or(0);
                }
                FactorSlots {
                    block_a,
                    block_b,
                    off_rank,
                }
            })
            .collect();

        let symbolic = symbolic_factorisation(nb, &rows_of, &col_ptr, &row_idx)?;
        let par = Par::Seq;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        let workspace = MemBuffer::try_new(req)
            .map_err(|_| GraphError::LinearAlgebra("out of memory".into()))?;
        let l_values = vec![0.0; symbolic.len_val()];
        Ok(Self {
            var_of,
            hessian: vec![0.0; row_idx.len()],
            damped: vec![0.0; row_idx.len()],
            col_ptr,
            row_idx,
            off_count,
            slots,
            diag_pos,
            gradient: vec![0.0; n],
            symbolic,
            l_values,
            workspace,
        })
    }

    /// Dimension of the linear system (6 × free variables).
    pub fn dim(&self) -> usize {
        self.gradient.len()
    }

    /// Clears the Hessian and gradient before assembly.
    pub fn clear(&mut self) {
        self.hessian.fill(0.0);
        self.gradient.fill(0.0);
    }

    /// Adds one factor's weighted contribution: `W = w Ω`, blocks `JᵀWJ` and gradient `JᵀWr`.
    pub fn add_factor(
        &mut self,
        factor_index: usize,
        jac_a: &Matrix6<f64>,
        jac_b: &Matrix6<f64>,
        weighted_info: &Matrix6<f64>,
        residual: &Vector6<f64>,
    ) {
        let s = self.slots[factor_index];
        let wr = weighted_info * residual;
        let a_free = s.block_a != HELD;
        let b_free = s.block_b != HELD;
        let jta_w = if a_free {
            Some(jac_a.transpose() * weighted_info)
        } else {
            None
        };
        let jtb_w = if b_free {
            Some(jac_b.transpose() * weighted_info)
        } else {
            None
        };
        if let Some(ref jta_w) = jta_w {
            let haa = jta_w * jac_a;
            self.add_diag_block(s.block_a, &haa);
            let g = jac_a.transpose() * wr;
            self.add_gradient(s.block_a, &g);
        }
        if let Some(ref jtb_w) = jtb_w {
            let hbb = jtb_w * jac_b;
            self.add_diag_block(s.block_b, &hbb);
            let g = jac_b.transpose() * wr;
            self.add_gradient(s.block_b, &g);
        }
        if let (Some(jta_w), true) = (jta_w, b_free) {
            if s.block_a != s.block_b {
                let hab = jta_w * jac_b;
                if s.block_a < s.block_b {
                    self.add_off_block(s.block_b, s.off_rank, &hab, false);
                } else {
                    self.add_off_block(s.block_a, s.off_rank, &hab, true);
                }
            } else {
                // Both ends on one variable: H += JaᵀWJb + JbᵀWJa.
                let hab = jta_w * jac_b;
                let sym = hab + hab.transpose();
                self.add_diag_block(s.block_a, &sym);
            }
        }
    }

    fn add_gradient(&mut self, block: usize, g: &Vector6<f64>) {
        let base = 6 * block;
        for i in 0..6 {
            self.gradient[base + i] += g[i];
        }
    }

    fn add_diag_block(&mut self, block: usize, h: &Matrix6<f64>) {
        let m6 = 6 * self.off_count[block];
        for k in 0..6 {
            let start = self.col_ptr[6 * block + k] + m6;
            for i in 0..=k {
                self.hessian[start + i] += h[(i, k)];
            }
        }
    }

    /// Adds block `h` (rows of the lower-numbered block, columns of `col_block`), or its
    /// transpose when `transpose` is set.
    fn add_off_block(&mut self, col_block: usize, rank6: usize, h: &Matrix6<f64>, transpose: bool) {
        for k in 0..6 {
            let start = self.col_ptr[6 * col_block + k] + rank6;
            let dst = &mut self.hessian[start..start + 6];
            if transpose {
                for (i, d) in dst.iter_mut().enumerate() {
                    *d += h[(k, i)];
                }
            } else {
                for (i, d) in dst.iter_mut().enumerate() {
                    *d += h[(i, k)];
                }
            }
        }
    }

    /// Factorises `H + diag(damping)` and solves `(H + D) δ = −g` into `step`.
    ///
    /// Returns `Ok(false)` when the damped matrix is not numerically positive definite.
    pub fn solve_damped(
        &mut self,
        damping: impl Fn(usize, f64) -> f64,
        step: &mut [f64],
    ) -> Result<bool, GraphError> {
        self.damped.copy_from_slice(&self.hessian);
        for (i, &p) in self.diag_pos.iter().enumerate() {
            self.damped[p] += damping(i, self.hessian[p]);
        }
        let n = self.dim();
        // The CSC arrays were built consistently above; `new_checked` re-verifies them.
        let symbolic =
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let matrix = SparseColMatRef::new(symbolic, &self.damped);
        let par = Par::Seq;
        let stack = MemStack::new(&mut self.workspace);
        let result = self.symbolic.factorize_numeric_llt::<f64>(
            &mut self.l_values,
            matrix,
            Side::Upper,
            Default::default(),
            par,
            stack,
            Default::default(),
        );
        if result.is_err() {
            // The only failure is a non-positive pivot: not positive definite.
            return Ok(false);
        }
        for (s, g) in step.iter_mut().zip(&self.gradient) {
            *s = -g;
        }
        let llt = LltRef::<'_, usize, f64>::new(&self.symbolic, &self.l_values);
        let rhs = MatMut::from_column_major_slice_mut(step, n, 1);
        llt.solve_in_place_with_conj(Conj::No, rhs, par, MemStack::new(&mut self.workspace));
        Ok(step.iter().all(|v| v.is_finite()))
    }

    /// Number of non-zeros of the Cholesky factor (a measure of fill).
    pub fn factor_nnz(&self) -> usize {
        self.l_values.len()
    }
}

/// Symbolic Cholesky factorisation with an AMD ordering computed on the block graph.
fn symbolic_factorisation(
    nb: usize,
    rows_of: &[Vec<usize>],
    col_ptr: &[usize],
    row_idx: &[usize],
) -> Result<SymbolicCholesky<usize>, GraphError> {
    let n = 6 * nb;
    // Block-level upper pattern (diagonal included).
    let mut b_col_ptr = Vec::with_capacity(nb + 1);
    let mut b_row_idx = Vec::with_capacity(rows_of.iter().map(Vec::len).sum::<usize>() + nb);
    b_col_ptr.push(0);
    for (c, rows) in rows_of.iter().enumerate() {
        b_row_idx.extend_from_slice(rows);
        b_row_idx.push(c);
        b_col_ptr.push(b_row_idx.len());
    }
    let block_pattern = SymbolicSparseColMatRef::new_checked(nb, nb, &b_col_ptr, None, &b_row_idx);
    let mut b_fwd = vec![0usize; nb];
    let mut b_inv = vec![0usize; nb];
    let lin_err = |e: faer::sparse::FaerError| GraphError::LinearAlgebra(format!("{e:?}"));
    if nb > 0 {
        let mut mem = MemBuffer::try_new(amd::order_scratch::<usize>(nb, b_row_idx.len()))
            .map_err(|_| GraphError::LinearAlgebra("out of memory".into()))?;
        amd::order(
            &mut b_fwd,
            &mut b_inv,
            block_pattern,
            amd::Control::default(),
            MemStack::new(&mut mem),
        )
        .map_err(lin_err)?;
    }
    let mut fwd = vec![0usize; n];
    let mut inv = vec![0usize; n];
    for b in 0..nb {
        for k in 0..6 {
            fwd[6 * b + k] = 6 * b_fwd[b] + k;
            inv[6 * b + k] = 6 * b_inv[b] + k;
        }
    }
    let perm = PermRef::new_checked(&fwd, &inv, n);
    let pattern = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);

    factorize_symbolic_cholesky(
        pattern,
        Side::Upper,
        SymmetricOrdering::Custom(perm),
        CholeskySymbolicParams::default(),
    )
    .map_err(lin_err)
}
