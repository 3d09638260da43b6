//! Triangular solves with the supernodal Cholesky factor for sparse right-hand sides.
//!
//! With `H = L Lᵀ`, the forward solve `y = L⁻¹ e` of a right-hand side that is non-zero only
//! in the columns of one variable touches only the supernodes on the path from that
//! variable's supernode to the root of the supernodal elimination tree (every row below a
//! supernode's diagonal block belongs to one of its ancestors). On a long pose chain that
//! path is a small part of the factor, so `L⁻¹ E_v` costs far less than a full solve, and
//! entries of `H⁻¹` follow from products of such paths: `(H⁻¹)_uv = (L⁻¹E_u)ᵀ (L⁻¹E_v)`.
//! This is what lets an incremental update (`linear_model`) avoid full solves for the
//! marginals of the variables it touches.

use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use nalgebra::DMatrix;

/// `L⁻¹ E` for a right-hand side `E` of `k` unit columns, stored on its elimination path.
#[derive(Clone, Debug)]
pub(crate) struct PathColumns {
    /// Supernodes of the path, increasing (leaf to root).
    path: Vec<usize>,
    /// First column of each path supernode.
    starts: Vec<usize>,
    /// Number of columns of each path supernode.
    sizes: Vec<usize>,
    /// Start of each path supernode's rows in `values`.
    offsets: Vec<usize>,
    /// For each path supernode, its rows of the solution (`size × k`, column-major).
    values: Vec<f64>,
    /// Number of right-hand sides.
    k: usize,
}

impl PathColumns {
    /// Index of row `r` of path supernode `i` in column `c`.
    fn at(&self, i: usize, r: usize, c: usize) -> usize {
        self.offsets[i] + c * self.sizes[i] + r
    }

    /// `selfᵀ other` (`k × k'`): an entry block of `H⁻¹` when both are `L⁻¹ E`.
    pub fn gram(&self, other: &PathColumns) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(self.k, other.k);
        // Both paths end at the root, so they meet and then coincide.
        let (mut i, mut j) = (0, 0);
        while i < self.path.len() && j < other.path.len() {
            match self.path[i].cmp(&other.path[j]) {
                std::cmp::Ordering::Less => i += 1,
                std::cmp::Ordering::Greater => j += 1,
                std::cmp::Ordering::Equal => {
                    for a in 0..self.k {
                        for b in 0..other.k {
                            let x = &self.values[self.at(i, 0, a)..][..self.sizes[i]];
                            let y = &other.values[other.at(j, 0, b)..][..other.sizes[j]];
                            out[(a, b)] += x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
                        }
                    }
                    i += 1;
                    j += 1;
                }
            }
        }
        out
    }

    /// `z += self · coeffs` (`coeffs` of length `k`) into a dense vector.
    pub fn scatter_add(&self, coeffs: &[f64], z: &mut [f64]) {
        for i in 0..self.path.len() {
            for (c, &w) in coeffs.iter().enumerate().take(self.k) {
                let x = &self.values[self.at(i, 0, c)..][..self.sizes[i]];
                for (dst, v) in z[self.starts[i]..].iter_mut().zip(x) {
                    *dst += w * v;
                }
            }
        }
    }
}

/// The supernode of every column and the parent of every supernode of a factor.
pub(crate) struct FactorPaths {
    supernode_of: Vec<usize>,
    parent: Vec<Option<usize>>,
}

impl FactorPaths {
    /// Reads the supernodal elimination tree of a factor.
    pub fn new(llt: SupernodalLltRef<'_, usize, f64>) -> Self {
        let symbolic = llt.symbolic();
        let mut supernode_of = vec![0; symbolic.nrows()];
        for s in 0..symbolic.n_supernodes() {
            let (start, end) = (symbolic.supernode_begin()[s], symbolic.supernode_end()[s]);
            supernode_of[start..end].fill(s);
        }
        let parent = (0..symbolic.n_supernodes())
            .map(|s| {
                let pattern = symbolic.supernode(s).pattern();
                pattern.first().map(|&row| supernode_of[row])
            })
            .collect();
        Self {
            supernode_of,
            parent,
        }
    }

    /// `L⁻¹ E` for the unit columns `first..first + k` of the factor's dimension.
    pub fn forward_unit(
        &self,
        llt: SupernodalLltRef<'_, usize, f64>,
        first: usize,
        k: usize,
    ) -> PathColumns {
        let symbolic = llt.symbolic();
        let mut path = Vec::new();
        let mut node = Some(self.supernode_of[first]);
        while let Some(s) = node {
            path.push(s);
            node = self.parent[s];
        }
        let starts: Vec<usize> = path
            .iter()
            .map(|&s| symbolic.supernode_begin()[s])
            .collect();
        let sizes: Vec<usize> = path
            .iter()
            .zip(&starts)
            .map(|(&s, &start)| symbolic.supernode_end()[s] - start)
            .collect();
        let mut offsets = Vec::with_capacity(path.len());
        let mut total = 0;
        for &size in &sizes {
            offsets.push(total);
            total += size * k;
        }
        let mut y = PathColumns {
            path,
            starts,
            sizes,
            offsets,
            values: vec![0.0; total],
            k,
        };
        // The unit columns lie in the first path supernodes (a variable's columns are a
        // chain in the elimination tree).
        for c in 0..k {
            let col = first + c;
            if let Ok(i) = y.path.binary_search(&self.supernode_of[col]) {
                let at = y.at(i, col - y.starts[i], c);
                y.values[at] = 1.0;
            }
        }
        for i in 0..y.path.len() {
            let sn = llt.supernode(y.path[i]);
            let l = sn.val();
            let size = y.sizes[i];
            // x_top ← L_top⁻¹ x_top (lower triangular, small).
            for c in 0..k {
                let base = y.at(i, 0, c);
                let x = &mut y.values[base..base + size];
                for j in 0..size {
                    let xj = x[j] / l[(j, j)];
                    x[j] = xj;
                    if xj != 0.0 {
                        for (r, xr) in x.iter_mut().enumerate().skip(j + 1) {
                            *xr -= l[(r, j)] * xj;
                        }
                    }
                }
            }
            // Rows below the diagonal block: x[row] −= L_bot x_top; all lie on the path.
            for (p, &row) in sn.pattern().iter().enumerate() {
                let Ok(t) = y.path.binary_search(&self.supernode_of[row]) else {
                    continue;
                };
                for c in 0..k {
                    let base = y.at(i, 0, c);
                    let acc: f64 = (0..size)
                        .map(|j| l[(size + p, j)] * y.values[base + j])
                        .sum();
                    let at = y.at(t, row - y.starts[t], c);
                    y.values[at] -= acc;
                }
            }
        }
        y
    }
}

/// Solves `Lᵀ x = z` in place, supernode by supernode from the root. On the factor of a pose
/// chain, thousands of supernodes of a few columns each, a plain loop over each supernode's
/// columns measured several times faster than faer's general supernodal solve, whose cost
/// per supernode dominates there. Returns `false` for a non-finite result.
pub(crate) fn backward_solve(llt: SupernodalLltRef<'_, usize, f64>, z: &mut [f64]) -> bool {
    let symbolic = llt.symbolic();
    if z.len() != symbolic.nrows() {
        return false;
    }
    for s in (0..symbolic.n_supernodes()).rev() {
        let sn = llt.supernode(s);
        let l = sn.val();
        let start = symbolic.supernode_begin()[s];
        let size = symbolic.supernode_end()[s] - start;
        let pattern = sn.pattern();
        // Rows below the diagonal block belong to ancestors, solved already.
        for j in 0..size {
            let Some(col) = l.col(j).try_as_col_major() else {
                return false;
            };
            let below: f64 = col.as_slice()[size..]
                .iter()
                .zip(pattern)
                .map(|(v, &r)| v * z[r])
                .sum();
            z[start + j] -= below;
        }
        for j in (0..size).rev() {
            let Some(col) = l.col(j).try_as_col_major() else {
                return false;
            };
            let col = col.as_slice();
            let above: f64 = col[j + 1..size]
                .iter()
                .zip(&z[start + j + 1..start + size])
                .map(|(v, x)| v * x)
                .sum();
            z[start + j] = (z[start + j] - above) / col[j];
        }
    }
    z.iter().all(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use crate::graph::components;
    use crate::graph::file::BuildOptions;
    use crate::graph::solver::linearize;
    use crate::graph::structure::NormalEquations;
    use crate::graph::synthetic::{self, SyntheticConfig};

    use super::*;

    /// `H⁻¹ e_j` by a full solve (the solver negates the gradient).
    fn full_column(system: &mut NormalEquations<6>, j: usize) -> Vec<f64> {
        system.gradient.fill(0.0);
        system.gradient[j] = -1.0;
        let mut x = vec![0.0; system.dim()];
        assert!(system.solve(&mut x));
        x
    }

    #[test]
    fn path_solves_agree_with_full_solves() {
        let synth = synthetic::generate(&SyntheticConfig {
            poses: 120,
            loop_closures: 15,
            ..SyntheticConfig::default()
        });
        let graph = synth.file.to_pose_graph(&BuildOptions::default()).unwrap();
        let (_, held) = components::analyse(graph.keys(), graph.fixed_flags(), &graph.factors);
        let mut system = NormalEquations::<6>::analyse(&held, &graph.factors).unwrap();
        linearize(&graph.factors, &graph.poses, &mut system, 0.0);
        assert!(system.factorize_damped(|_, _| 0.0));
        let llt = system.supernodal_factor().unwrap();
        let paths = FactorPaths::new(llt);
        let (u, v) = (7, 95);
        let yu = paths.forward_unit(llt, 6 * u, 6);
        let yv = paths.forward_unit(llt, 6 * v, 6);
        let block = yu.gram(&yv);
        let diag = yu.gram(&yu);
        let n = system.dim();
        // H⁻¹ (P_u a + P_v b) through the paths and a backward solve, and by full solves.
        let (a, b) = (
            [0.3, -1.0, 0.5, 2.0, 0.1, -0.7],
            [1.1, 0.2, -0.4, 0.0, 0.9, 0.6],
        );
        let mut z = vec![0.0; n];
        yu.scatter_add(&a, &mut z);
        yv.scatter_add(&b, &mut z);
        assert!(system.backward_solve(&mut z));
        let mut expected = vec![0.0; n];
        for c in 0..6 {
            let cu = full_column(&mut system, 6 * u + c);
            let cv = full_column(&mut system, 6 * v + c);
            for r in 0..6 {
                let scale = cu[6 * u + r].abs().max(1e-12);
                assert!((block[(r, c)] - cv[6 * u + r]).abs() < 1e-9 * scale.max(1.0));
                assert!((diag[(r, c)] - cu[6 * u + r]).abs() < 1e-9 * scale.max(1.0));
            }
            for i in 0..n {
                expected[i] += a[c] * cu[i] + b[c] * cv[i];
            }
        }
        let worst = z
            .iter()
            .zip(&expected)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{worst}");
    }
}
