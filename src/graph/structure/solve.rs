//! Solves with the numeric factor: full solves (single-precision ones refined in double
//! precision) and the backward half alone for right-hand sides built along elimination
//! paths.

use super::{NormalEquations, Precision};
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
        let Some(precision) = self.factored else {
            return false;
        };
        for (s, g) in step.iter_mut().zip(&self.gradient) {
            *s = -g;
        }
        let n = self.dim();
        match precision {
            Precision::Double => {
                let llt = LltRef::<'_, usize, f64>::new(&self.symbolic, &self.l_values);
                let rhs = MatMut::from_column_major_slice_mut(step, n, 1);
                llt.solve_in_place_with_conj(
                    Conj::No,
                    rhs,
                    Par::Seq,
                    MemStack::new(&mut self.workspace),
                );
            }
            Precision::Single => {
                let mut x = std::mem::take(&mut self.scratch_f32);
                x.clear();
                x.extend(step.iter().map(|&v| v as f32));
                self.solve_f32(&mut x);
                for (s, &v) in step.iter_mut().zip(&x) {
                    *s = f64::from(v);
                }
                if !refine {
                    self.scratch_f32 = x;
                    return step.iter().all(|v| v.is_finite());
                }
                // One refinement: r = −g − A x in double precision, then x += A⁻¹ r.
                let mut residual: Vec<f64> = self.gradient.iter().map(|g| -g).collect();
                self.sub_damped_times(step, &mut residual);
                x.clear();
                x.extend(residual.iter().map(|&v| v as f32));
                self.solve_f32(&mut x);
                for (s, &v) in step.iter_mut().zip(&x) {
                    *s += f64::from(v);
                }
                self.scratch_f32 = x;
            }
        }
        step.iter().all(|v| v.is_finite())
    }

    /// Solves with the single-precision factor in place.
    fn solve_f32(&mut self, x: &mut [f32]) {
        let n = self.dim();
        let llt = LltRef::<'_, usize, f32>::new(&self.symbolic, &self.l_values_f32);
        let rhs = MatMut::from_column_major_slice_mut(x, n, 1);
        llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut self.workspace));
    }

    /// `out −= (H + D) x`, with the symmetric damped matrix stored as its lower triangle.
    fn sub_damped_times(&self, x: &[f64], out: &mut [f64]) {
        for (c, &xc) in x.iter().enumerate() {
            let range = self.col_ptr[c]..self.col_ptr[c + 1];
            let mut acc = 0.0;
            for (&r, &v) in self.row_idx[range.clone()].iter().zip(&self.damped[range]) {
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
