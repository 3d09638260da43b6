//! Sparse structure of the normal equations, analysed once and reused across iterations.
//!
//! The Gauss–Newton Hessian `H = Σ Jᵀ W J` of a pose graph has one dense B×B block per free
//! variable (B = 6 for poses) and one per pair of free variables sharing a factor. Its upper
//! triangle is stored in compressed sparse columns; every factor knows in advance where its
//! blocks land, so assembling an iteration's system is a scatter without searching. The
//! fill-reducing ordering is computed on the block graph ([`super::ordering`]) and the
//! symbolic Cholesky factorisation once; each iteration only refactors numerically.

use super::factors::Factor;
use super::ordering;
use super::GraphError;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Par, Side};
use nalgebra::{SMatrix, SVector};

mod solve;

/// Marker for a variable that is held (not part of the linear system).
const HELD: usize = usize::MAX;

/// Right-hand sides solved together at most ([`NormalEquations::solve_columns`]): the three
/// rows of the rotations, or the three coordinates, of the chordal initialisation.
pub(crate) const MAX_COLUMNS: usize = 3;

/// Non-zeros of the factor below which single precision is not used
/// ([`NormalEquations::single_precision_pays`]): such a factor (under 800 kB in double
/// precision) stays in the cache, so halving its bytes gains nothing, while every
/// single-precision solve is refined by a second one (see `docs/design/posegraph-fixed-costs.md`).
const SINGLE_PRECISION_MIN_NNZ: usize = 100_000;

/// Where one factor's blocks live in the value array.
#[derive(Clone, Copy, Debug)]
struct FactorSlots {
    /// Block column of the first variable, or `HELD`.
    block_a: usize,
    /// Block column of the second variable, or `HELD` (also for unary factors).
    block_b: usize,
    /// Offset of the off-diagonal block's rows among the strictly-lower blocks of its
    /// column (block rank × B).
    off_rank: usize,
}

/// One factor's contribution to the normal equations.
pub(crate) struct FactorBlocks<const B: usize> {
    /// `J_aᵀ W J_a`.
    pub haa: SMatrix<f64, B, B>,
    /// `J_aᵀ W J_b`.
    pub hab: SMatrix<f64, B, B>,
    /// `J_bᵀ W J_b`.
    pub hbb: SMatrix<f64, B, B>,
    /// `J_aᵀ W r`.
    pub ga: SVector<f64, B>,
    /// `J_bᵀ W r`.
    pub gb: SVector<f64, B>,
}

/// Floating-point precision of a numeric factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Precision {
    /// `f32` factor, solves refined in `f64`.
    Single,
    /// `f64` factor.
    Double,
}

/// Sparse normal equations with B×B blocks and a reusable symbolic Cholesky factorisation.
pub(crate) struct NormalEquations<const B: usize> {
    /// Block column → variable index (block columns are in elimination order).
    pub var_of: Vec<usize>,
    /// Elimination order as indices into the free variables in insertion order.
    pub order: Vec<usize>,
    /// Lower-triangle pattern (scalar CSC), checked once when analysed.
    pattern: SymbolicSparseColMat<usize>,
    slots: Vec<FactorSlots>,
    /// Undamped Hessian values (upper triangle).
    hessian: Vec<f64>,
    /// Damped copy handed to the factorisation.
    damped: Vec<f64>,
    /// Its single-precision copy, for single-precision factorisations.
    damped_f32: Vec<f32>,
    /// Right-hand side scratch of single-precision solves.
    scratch_f32: Vec<f32>,
    /// Positions of the scalar diagonal entries.
    diag_pos: Vec<usize>,
    /// Gradient `Σ Jᵀ W r`.
    pub gradient: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    /// Single-precision factor values (allocated on first use).
    l_values_f32: Vec<f32>,
    /// Which factor is valid, if any.
    factored: Option<Precision>,
    workspace: MemBuffer,
}

impl<const B: usize> NormalEquations<B> {
    /// Analyses the structure for the given factors with the given held variables.
    pub fn analyse(held: &[bool], factors: &[Factor]) -> Result<Self, GraphError> {
        Self::analyse_with_order(held, factors, None)
    }

    /// Like [`NormalEquations::analyse`], with the elimination order of the free variables
    /// (indices into the free variables in insertion order) given, e.g. to share the ordering
    /// of another system with the same graph; `None` computes it by AMD.
    pub fn analyse_with_order(
        held: &[bool],
        factors: &[Factor],
        order: Option<&[usize]>,
    ) -> Result<Self, GraphError> {
        let (free_of, free) = free_variables(held);
        let nb = free.len();
        let pairs: Vec<(usize, usize)> = factors
            .iter()
            .filter(|f| !f.is_unary())
            .filter_map(|f| {
                let [a, b] = f.vars();
                let (fa, fb) = (free_of[a], free_of[b]);
                (fa != HELD && fb != HELD && fa != fb).then_some((fa, fb))
            })
            .collect();
        let order = match order {
            Some(o) if o.len() == nb => o.to_vec(),
            _ => amd_order(nb, &pairs)?,
        };
        // Block columns follow the elimination order, so faer needs no permutation.
        let mut position = vec![0usize; nb];
        for (k, &fi) in order.iter().enumerate() {
            position[fi] = k;
        }
        let var_of: Vec<usize> = order.iter().map(|&fi| free[fi]).collect();
        let block_of: Vec<usize> = free_of
            .iter()
            .map(|&fi| if fi == HELD { HELD } else { position[fi] })
            .collect();
        let rows_of = lower_block_rows(nb, &pairs, &position);
        let (col_ptr, row_idx, diag_pos) = lower_pattern::<B>(&rows_of);
        let slots = factor_slots::<B>(factors, &block_of, &rows_of);
        let n = B * nb;
        let (symbolic, workspace) = symbolic_analysis::<B>(n, &rows_of)?;
        let l_values = vec![0.0; symbolic.len_val()];
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        Ok(Self {
            var_of,
            order,
            hessian: vec![0.0; pattern.compute_nnz()],
            damped: vec![0.0; pattern.compute_nnz()],
            damped_f32: Vec::new(),
            scratch_f32: Vec::new(),
            pattern,
            slots,
            diag_pos,
            gradient: vec![0.0; n],
            symbolic,
            l_values,
            l_values_f32: Vec::new(),
            factored: None,
            workspace,
        })
    }

    /// Dimension of the linear system (B × free variables).
    pub fn dim(&self) -> usize {
        self.gradient.len()
    }

    /// Clears the Hessian and gradient before assembly.
    pub fn clear(&mut self) {
        self.hessian.fill(0.0);
        self.gradient.fill(0.0);
    }

    /// Clears only the gradient (for a new right-hand side on the same Hessian).
    pub fn clear_gradient(&mut self) {
        self.gradient.fill(0.0);
    }

    /// Adds one factor's weighted contribution: blocks `JᵀWJ` and gradient `JᵀWr`.
    /// `jac_b` is ignored for unary factors.
    pub fn add_factor(
        &mut self,
        factor_index: usize,
        jac_a: &SMatrix<f64, B, B>,
        jac_b: &SMatrix<f64, B, B>,
        weight: &SMatrix<f64, B, B>,
        residual: &SVector<f64, B>,
    ) {
        self.add_factor_gradient(factor_index, jac_a, jac_b, weight, residual);
        let s = self.slots[factor_index];
        let b_free = s.block_b != HELD;
        let jta_w = (s.block_a != HELD).then(|| jac_a.transpose() * weight);
        if let Some(ref jta_w) = jta_w {
            self.add_diag_block(s.block_a, &(jta_w * jac_a));
        }
        if b_free {
            let jtb_w = jac_b.transpose() * weight;
            self.add_diag_block(s.block_b, &(jtb_w * jac_b));
        }
        if let (Some(jta_w), true) = (jta_w, b_free) {
            self.add_cross_block(&s, &(jta_w * jac_b));
        }
    }

    /// Adds precomputed blocks of one factor: `H_aa`, `H_ab` (rows of the first variable),
    /// `H_bb` and the gradients `g_a`, `g_b`. The second-variable terms are ignored for unary
    /// factors; the blocks of held variables are skipped.
    pub fn add_blocks(&mut self, factor_index: usize, blocks: &FactorBlocks<B>) {
        let s = self.slots[factor_index];
        let a_free = s.block_a != HELD;
        let b_free = s.block_b != HELD;
        if a_free {
            self.add_diag_block(s.block_a, &blocks.haa);
            self.add_gradient(s.block_a, &blocks.ga);
        }
        if b_free {
            self.add_diag_block(s.block_b, &blocks.hbb);
            self.add_gradient(s.block_b, &blocks.gb);
        }
        if a_free && b_free {
            self.add_cross_block(&s, &blocks.hab);
        }
    }

    /// Adds only the gradient `JᵀWr` of one factor.
    pub fn add_factor_gradient(
        &mut self,
        factor_index: usize,
        jac_a: &SMatrix<f64, B, B>,
        jac_b: &SMatrix<f64, B, B>,
        weight: &SMatrix<f64, B, B>,
        residual: &SVector<f64, B>,
    ) {
        let wr = weight * residual;
        let (ga, gb) = (jac_a.transpose() * wr, jac_b.transpose() * wr);
        self.add_gradient_blocks(factor_index, &ga, &gb);
    }

    /// Adds precomputed gradient blocks `g_a`, `g_b` of one factor (`g_b` is ignored for
    /// unary factors; held variables are skipped).
    pub fn add_gradient_blocks(
        &mut self,
        factor_index: usize,
        ga: &SVector<f64, B>,
        gb: &SVector<f64, B>,
    ) {
        let s = self.slots[factor_index];
        if s.block_a != HELD {
            self.add_gradient(s.block_a, ga);
        }
        if s.block_b != HELD {
            self.add_gradient(s.block_b, gb);
        }
    }

    fn add_gradient(&mut self, block: usize, g: &SVector<f64, B>) {
        let dst = &mut self.gradient[B * block..B * block + B];
        for (d, v) in dst.iter_mut().zip(g.iter()) {
            *d += v;
        }
    }

    fn add_diag_block(&mut self, block: usize, h: &SMatrix<f64, B, B>) {
        for k in 0..B {
            let start = self.pattern.col_ptr()[B * block + k];
            for (d, i) in self.hessian[start..start + B - k].iter_mut().zip(k..B) {
                *d += h[(i, k)];
            }
        }
    }

    /// Adds `H_ab` (rows of the factor's first variable, columns of its second) where it
    /// lands in the lower triangle.
    fn add_cross_block(&mut self, s: &FactorSlots, hab: &SMatrix<f64, B, B>) {
        if s.block_a == s.block_b {
            // Both ends on one variable: H += JaᵀWJb + JbᵀWJa.
            self.add_diag_block(s.block_a, &(hab + hab.transpose()));
            return;
        }
        // The stored block has the later variable's rows and the earlier one's columns.
        let (col, transpose) = if s.block_a > s.block_b {
            (s.block_b, false)
        } else {
            (s.block_a, true)
        };
        for k in 0..B {
            let start = self.pattern.col_ptr()[B * col + k] + (B - k) + s.off_rank;
            let dst = &mut self.hessian[start..start + B];
            for (i, d) in dst.iter_mut().enumerate() {
                *d += if transpose { hab[(k, i)] } else { hab[(i, k)] };
            }
        }
    }

    /// Factorises `H + diag(damping(i, H_ii))` in double precision, keeping the factor for
    /// [`NormalEquations::solve`].
    ///
    /// Returns `false` when the damped matrix is not numerically positive definite.
    pub fn factorize_damped(&mut self, damping: impl Fn(usize, f64) -> f64) -> bool {
        self.factorize_damped_in(Precision::Double, damping)
    }

    /// Like [`NormalEquations::factorize_damped`], in the given precision. A single-precision
    /// factor halves the floating-point work and memory traffic of the factorisation; its
    /// solves are refined once against the double-precision matrix (see
    /// [`NormalEquations::solve`]).
    pub fn factorize_damped_in(
        &mut self,
        precision: Precision,
        damping: impl Fn(usize, f64) -> f64,
    ) -> bool {
        self.damped.copy_from_slice(&self.hessian);
        for (i, &p) in self.diag_pos.iter().enumerate() {
            self.damped[p] += damping(i, self.hessian[p]);
        }
        let symbolic = self.pattern.as_ref();
        let stack = MemStack::new(&mut self.workspace);
        let ok = match precision {
            Precision::Double => {
                let matrix = SparseColMatRef::new(symbolic, &self.damped[..]);
                factorize_llt(&self.symbolic, &mut self.l_values, matrix, stack)
            }
            Precision::Single => {
                self.damped_f32.clear();
                self.damped_f32
                    .extend(self.damped.iter().map(|&v| v as f32));
                self.l_values_f32.resize(self.symbolic.len_val(), 0.0);
                let matrix = SparseColMatRef::new(symbolic, &self.damped_f32[..]);
                factorize_llt(&self.symbolic, &mut self.l_values_f32, matrix, stack)
            }
        };
        self.factored = ok.then_some(precision);
        ok
    }

    /// `xᵀ D x` for the damping `D` of the last factorisation (the part it added to the
    /// Hessian's diagonal).
    pub fn damping_form(&self, x: &[f64]) -> f64 {
        self.diag_pos
            .iter()
            .zip(x)
            .map(|(&p, &v)| (self.damped[p] - self.hessian[p]) * v * v)
            .sum()
    }

    /// Block column of each variable (`None` for held variables), indexed by variable.
    pub fn block_of(&self, num_vars: usize) -> Vec<Option<usize>> {
        let mut out = vec![None; num_vars];
        for (b, &v) in self.var_of.iter().enumerate() {
            if v < num_vars {
                out[v] = Some(b);
            }
        }
        out
    }

    /// True when a valid numeric factor is available.
    pub fn has_factor(&self) -> bool {
        self.factored.is_some()
    }

    /// Number of non-zeros of the Cholesky factor (a measure of fill).
    pub fn factor_nnz(&self) -> usize {
        self.l_values.len()
    }

    /// True when a single-precision factorisation is worth its refined solves: the factor
    /// has at least [`SINGLE_PRECISION_MIN_NNZ`] non-zeros.
    pub fn single_precision_pays(&self) -> bool {
        self.factor_nnz() >= SINGLE_PRECISION_MIN_NNZ
    }
}

/// Each variable's index among the free ones (`HELD` for held ones), and the free
/// variables in insertion order.
fn free_variables(held: &[bool]) -> (Vec<usize>, Vec<usize>) {
    let mut free_of = vec![HELD; held.len()];
    let mut free = Vec::new();
    for (v, &h) in held.iter().enumerate() {
        if !h {
            free_of[v] = free.len();
            free.push(v);
        }
    }
    (free_of, free)
}

/// The block AMD elimination order of `nb` free variables linked by `pairs`.
fn amd_order(nb: usize, pairs: &[(usize, usize)]) -> Result<Vec<usize>, GraphError> {
    let mut upper: Vec<Vec<usize>> = vec![Vec::new(); nb];
    for &(fa, fb) in pairs {
        upper[fa.max(fb)].push(fa.min(fb));
    }
    for rows in &mut upper {
        rows.sort_unstable();
        rows.dedup();
    }
    ordering::block_amd(&upper)
}

/// The strictly-lower block rows of each block column (sorted, unique).
fn lower_block_rows(nb: usize, pairs: &[(usize, usize)], position: &[usize]) -> Vec<Vec<usize>> {
    let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); nb];
    for &(fa, fb) in pairs {
        let (pa, pb) = (position[fa], position[fb]);
        rows_of[pa.min(pb)].push(pa.max(pb));
    }
    for rows in &mut rows_of {
        rows.sort_unstable();
        rows.dedup();
    }
    rows_of
}

/// The scalar lower CSC pattern `(col_ptr, row_idx, diag_pos)`: in scalar column k of
/// block column c, the diagonal block's rows k..B, then the rows of the strictly-lower
/// blocks (B each).
fn lower_pattern<const B: usize>(rows_of: &[Vec<usize>]) -> (Vec<usize>, Vec<usize>, Vec<usize>) {
    let n = B * rows_of.len();
    let nnz: usize = rows_of
        .iter()
        .map(|m| B * B * m.len() + B * (B + 1) / 2)
        .sum();
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::with_capacity(nnz);
    let mut diag_pos = Vec::with_capacity(n);
    col_ptr.push(0);
    for (c, rows) in rows_of.iter().enumerate() {
        for k in 0..B {
            diag_pos.push(row_idx.len());
            row_idx.extend((k..B).map(|i| B * c + i));
            for &r in rows {
                row_idx.extend((0..B).map(|i| B * r + i));
            }
            col_ptr.push(row_idx.len());
        }
    }
    (col_ptr, row_idx, diag_pos)
}

/// Where each factor's blocks land in the pattern.
fn factor_slots<const B: usize>(
    factors: &[Factor],
    block_of: &[usize],
    rows_of: &[Vec<usize>],
) -> Vec<FactorSlots> {
    factors
        .iter()
        .map(|f| {
            let [a, b] = f.vars();
            let block_a = block_of[a];
            let block_b = if f.is_unary() { HELD } else { block_of[b] };
            let mut off_rank = 0;
            if block_a != HELD && block_b != HELD && block_a != block_b {
                let (c, r) = (block_a.min(block_b), block_a.max(block_b));
                // The row was inserted by `lower_block_rows`, so the search succeeds.
                off_rank = B * rows_of[c].binary_search(&r).unwrap_or(0);
            }
            FactorSlots {
                block_a,
                block_b,
                off_rank,
            }
        })
        .collect()
}

/// faer's symbolic Cholesky of the pattern, and a workspace for every numeric step.
///
/// faer's symbolic analysis without a permutation reads the upper triangle, while its
/// supernodal numeric factorisation consumes the lower one as is: analyse the transposed
/// pattern once, hand over the lower values every iteration.
fn symbolic_analysis<const B: usize>(
    n: usize,
    rows_of: &[Vec<usize>],
) -> Result<(SymbolicCholesky<usize>, MemBuffer), GraphError> {
    let (up_ptr, up_idx) = upper_pattern::<B>(rows_of);
    let upper = SymbolicSparseColMatRef::new_checked(n, n, &up_ptr, None, &up_idx);
    let params = CholeskySymbolicParams {
        // faer picks the simplicial (column by column) factorisation for long chains
        // with little fill, which measured 2× slower than the supernodal one on a
        // 5,000-pose graph; the 6×6 blocks make supernodes worthwhile everywhere. The
        // 3×3- and 1×1-block systems of the chordal start keep faer's own choice, which
        // measured faster there (sphere2500's scalar Laplacian: 2.1 instead of 2.4–6.6 ms;
        // the 27-pose grid's initialisation: 0.075 instead of 0.098 ms).
        supernodal_flop_ratio_threshold: if B >= 6 {
            SupernodalThreshold::FORCE_SUPERNODAL
        } else {
            SupernodalThreshold::AUTO
        },
        ..Default::default()
    };
    let symbolic =
        factorize_symbolic_cholesky(upper, Side::Lower, SymmetricOrdering::Identity, params)
            .map_err(|e| GraphError::LinearAlgebra(format!("{e:?}")))?;
    let par = Par::Seq;
    let req = StackReq::any_of(&[
        symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        symbolic.factorize_numeric_llt_scratch::<f32>(par, Default::default()),
        symbolic.solve_in_place_scratch::<f64>(MAX_COLUMNS, par),
        symbolic.solve_in_place_scratch::<f32>(MAX_COLUMNS, par),
    ]);
    let workspace =
        MemBuffer::try_new(req).map_err(|_| GraphError::LinearAlgebra("out of memory".into()))?;
    Ok((symbolic, workspace))
}

/// Numeric supernodal `L Lᵀ` of the lower triangle `matrix` into `l_values`; `false` when a
/// pivot is not positive (the matrix is not numerically positive definite).
fn factorize_llt<T: faer::traits::ComplexField>(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &mut [T],
    matrix: SparseColMatRef<'_, usize, T>,
    stack: &mut MemStack,
) -> bool {
    symbolic
        .factorize_numeric_llt::<T>(
            l_values,
            matrix,
            Side::Lower,
            Default::default(),
            Par::Seq,
            stack,
            Default::default(),
        )
        .is_ok()
}

/// The scalar upper CSC pattern `(col_ptr, row_idx)` of the same matrix as
/// [`lower_pattern`] (its transpose), built from the block rows directly: in scalar column
/// k of block column c, the rows of every earlier block linked to c (B each), then the
/// diagonal block's rows 0..=k.
fn upper_pattern<const B: usize>(rows_of: &[Vec<usize>]) -> (Vec<usize>, Vec<usize>) {
    let nb = rows_of.len();
    let mut above_of: Vec<Vec<usize>> = vec![Vec::new(); nb];
    for (r, rows) in rows_of.iter().enumerate() {
        for &c in rows {
            // r grows, so every list stays sorted.
            above_of[c].push(r);
        }
    }
    let nnz: usize = above_of
        .iter()
        .map(|m| B * B * m.len() + B * (B + 1) / 2)
        .sum();
    let mut col_ptr = Vec::with_capacity(B * nb + 1);
    let mut row_idx = Vec::with_capacity(nnz);
    col_ptr.push(0);
    for (c, above) in above_of.iter().enumerate() {
        for k in 0..B {
            for &r in above {
                row_idx.extend(B * r..B * r + B);
            }
            row_idx.extend(B * c..=B * c + k);
            col_ptr.push(row_idx.len());
        }
    }
    (col_ptr, row_idx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upper_pattern_is_the_transpose_of_the_lower_one() {
        // Block columns in elimination order; strictly-lower block rows of each.
        let rows_of = vec![vec![2, 3], vec![2], vec![3], vec![]];
        let (l_ptr, l_idx, _) = lower_pattern::<3>(&rows_of);
        let (u_ptr, u_idx) = upper_pattern::<3>(&rows_of);
        let n = 12;
        let mut entries_l = Vec::new();
        for c in 0..n {
            for &r in &l_idx[l_ptr[c]..l_ptr[c + 1]] {
                entries_l.push((r, c));
            }
        }
        let mut entries_u = Vec::new();
        for c in 0..n {
            let rows = &u_idx[u_ptr[c]..u_ptr[c + 1]];
            assert!(rows.windows(2).all(|w| w[0] < w[1]), "rows sorted");
            entries_u.extend(rows.iter().map(|&r| (c, r)));
        }
        entries_l.sort_unstable();
        entries_u.sort_unstable();
        assert_eq!(entries_l, entries_u);
    }
}
