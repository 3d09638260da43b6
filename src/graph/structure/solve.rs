//! Solves with the numeric factor: full solves (single-precision ones refined in double
//! precision), for one or a few right-hand sides, and the backward half alone for
//! right-hand sides built along elimination paths.

use super::{NormalEquations, Precision, MAX_COLUMNS};
use crate::graph::factor_paths;
use faer::dyn_stack::MemStack;
use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use faer::sparse::linalg::cholesky::{LltRef, SymbolicCholeskyRaw};
use faer::{Conj, MatMut, Par};

impl<const B: usize> NormalEquations<B> {
    /// Solves `(H + D) δ = −g` with the last factor and the current gradient.
    ///
    /// With a single-precision factor the solution gets one step of iterative refinement:
    /// the residual `−g − (H + D) δ` is formed in double precision and solved for a
    /// correction, which brings the step to near double-precision accuracy on well-scaled
    /// systems.
    ///
    /// Returns `false` if there is no valid factor or the step is not finite.
    pub fn solve(&mut self, step: &mut [f64]) -> bool {
        self.solve_refined(step, true)
    }

    /// Like [`NormalEquations::solve`], refining a single-precision solve only if `refine`:
    /// far from an optimum an unrefined step (relative error about `κ · 10⁻⁷`) is as good.
    pub fn solve_refined(&mut self, step: &mut [f64], refine: bool) -> bool {
        for (s, g) in step.iter_mut().zip(&self.gradient) {
            *s = -g;
        }
        self.solve_columns(step, 1, refine)
    }

    /// Solves `(H + D) X = R` in place for `columns` (at most [`MAX_COLUMNS`]) right-hand
    /// sides stored one after the other in `x` (`dim × columns`, column-major), in one pass
    /// over the factor; single-precision solves are refined if `refine`, as in
    /// [`NormalEquations::solve`]. Returns `false` without a valid factor, for a wrong
    /// shape or for a non-finite result.
    pub fn solve_columns(&mut self, x: &mut [f64], columns: usize, refine: bool) -> bool {
        let n = self.dim();
        let Some(precision) = self.factored else {
            return false;
        };
        if columns == 0 || columns > MAX_COLUMNS || x.len() != n * columns {
            return false;
        }
        match precision {
            Precision::Double => {
                let llt = LltRef::<'_, usize, f64>::new(&self.symbolic, &self.l_values);
                let rhs = MatMut::from_column_major_slice_mut(x, n, columns);
                let stack = MemStack::new(&mut self.workspace);
                llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, stack);
            }
            Precision::Single => {
                let b = refine.then(|| x.to_vec());
                self.solve_f32_in_place(x, columns);
                if let Some(mut residual) = b {
                    // One refinement: r = b − A x in double precision, then x += A⁻¹ r.
                    for (c, r) in residual.chunks_exact_mut(n).enumerate() {
                        self.sub_damped_times(&x[c * n..(c + 1) * n], r);
                    }
                    self.solve_f32_in_place(&mut residual, columns);
                    for (s, r) in x.iter_mut().zip(&residual) {
                        *s += r;
                    }
                }
            }
        }
        x.iter().all(|v| v.is_finite())
    }

    /// Solves in place with the single-precision factor (`x` rounded to `f32` first).
    fn solve_f32_in_place(&mut self, x: &mut [f64], columns: usize) {
        let n = self.dim();
        let mut y = std::mem::take(&mut self.scratch_f32);
        y.clear();
        y.extend(x.iter().map(|&v| v as f32));
        let llt = LltRef::<'_, usize, f32>::new(&self.symbolic, &self.l_values_f32);
        let rhs = MatMut::from_column_major_slice_mut(&mut y, n, columns);
        llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut self.workspace));
        for (s, &v) in x.iter_mut().zip(&y) {
            *s = f64::from(v);
        }
        self.scratch_f32 = y;
    }

    /// `out −= (H + D) x`, with the symmetric damped matrix stored as its lower triangle.
    fn sub_damped_times(&self, x: &[f64], out: &mut [f64]) {
        let (col_ptr, row_idx) = (self.pattern.col_ptr(), self.pattern.row_idx());
        for (c, &xc) in x.iter().enumerate() {
            let range = col_ptr[c]..col_ptr[c + 1];
            let mut acc = 0.0;
            for (&r, &v) in row_idx[range.clone()].iter().zip(&self.damped[range]) {
                out[r] -= v * xc;
                if r != c {
                    acc += v * x[r];
                }
            }
            out[c] -= acc;
        }
    }

    /// The double-precision supernodal factor, when one is valid.
    pub fn supernodal_factor(&self) -> Option<SupernodalLltRef<'_, usize, f64>> {
        if self.factored != Some(Precision::Double) {
            return None;
        }
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(symbolic) => {
                Some(SupernodalLltRef::new(symbolic, &self.l_values))
            }
            SymbolicCholeskyRaw::Simplicial(_) => None,
        }
    }

    /// Solves `Lᵀ x = z` in place with the double-precision factor (the backward half of a
    /// solve). Returns `false` without a valid supernodal factor or for a non-finite result.
    pub fn backward_solve(&self, z: &mut [f64]) -> bool {
        match self.supernodal_factor() {
            Some(llt) => factor_paths::backward_solve(llt, z),
            None => false,
        }
    }
}
