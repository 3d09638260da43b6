//! Gauss–Newton on the live part of an incremental update: the window of recent variables
//! and the settled boundary variables that live factors touch (see `linear_model`).
//!
//! The live factors are evaluated exactly. The frozen factors enter through their marginal
//! on the boundary, a dense quadratic prior `½ (δ_T − δ*_T)ᵀ S (δ_T − δ*_T)` with
//! `δ_v = Log(x₀_v⁻¹ X_v)`. The normal equations are sparse (the window is a stretch of
//! trajectory with its loop closures) except for the boundary's dense block, so they use the
//! same block-sparse structure and Cholesky as the batch solver: the prior's couplings enter
//! the structure as pattern-only factors, one per boundary variable and one per boundary
//! pair, whose blocks are written directly.

use super::factors::{Factor, FactorKind};
use super::pose_graph::PoseGraph;
use super::se3;
use super::structure::{FactorBlocks, NormalEquations};
use crate::graph::robust::RobustKernel;
use nalgebra::{DMatrix, DVector, Isometry3, Matrix6, Vector6};

/// Halvings of a step that does not lower the cost before the iteration gives up.
const BACKTRACKS: usize = 3;

/// A step with an entry beyond this (metres or radians) is far outside the linearisation
/// it came from — a first relocalization moving a whole session, two chains joined — and
/// the solve iterates on past its iteration budget, up to [`MAX_ITERATIONS`].
const LARGE_STEP: f64 = 1.0;

/// Gauss–Newton iterations at most, large steps included.
const MAX_ITERATIONS: usize = 10;

/// The frozen factors' marginal on the boundary variables.
#[derive(Clone, Debug)]
pub(crate) struct BoundaryPrior {
    /// `S = ((H₀⁻¹)_TT)⁻¹`, 6 rows and columns per boundary variable.
    pub information: DMatrix<f64>,
    /// Per boundary variable: its index, `x₀_v` and `δ*_v`.
    pub target: Vec<(usize, Isometry3<f64>, Vector6<f64>)>,
}

impl Default for BoundaryPrior {
    fn default() -> Self {
        Self {
            information: DMatrix::zeros(0, 0),
            target: Vec::new(),
        }
    }
}

impl BoundaryPrior {
    /// True when `v` is a boundary variable.
    pub fn contains(&self, v: usize) -> bool {
        self.target.iter().any(|(u, _, _)| *u == v)
    }

    /// `δ_T − δ*_T` at `poses`.
    pub fn residual(&self, poses: &[Isometry3<f64>]) -> DVector<f64> {
        let mut e = DVector::zeros(6 * self.target.len());
        for (i, (v, x0_v, star)) in self.target.iter().enumerate() {
            let d = se3::log(&(x0_v.inverse() * poses[*v]));
            e.fixed_rows_mut::<6>(6 * i).copy_from(&(d - star));
        }
        e
    }

    /// `½ eᵀ S e` at `poses`.
    fn cost(&self, poses: &[Isometry3<f64>]) -> f64 {
        let e = self.residual(poses);
        0.5 * e.dot(&(&self.information * &e))
    }
}

/// The sparse normal equations of one update's live problem.
pub(crate) struct WindowProblem<'a> {
    /// Live factors (indices into the graph's factors); entry `i` is pattern factor `i`.
    live: &'a [usize],
    prior: &'a BoundaryPrior,
    system: NormalEquations<6>,
    /// Variables of the problem, by block column.
    vars: Vec<usize>,
}

impl<'a> WindowProblem<'a> {
    /// Analyses the structure of the live factors over `window` and the boundary. `None`
    /// when the structure cannot be analysed.
    pub fn new(
        graph: &PoseGraph,
        live: &'a [usize],
        window: &[usize],
        prior: &'a BoundaryPrior,
    ) -> Option<Self> {
        let keys = graph.keys();
        let mut pattern: Vec<Factor> = live.iter().map(|&i| graph.factors[i].clone()).collect();
        let identity = Isometry3::identity();
        let unit = Matrix6::identity();
        let boundary: Vec<usize> = prior.target.iter().map(|(v, _, _)| *v).collect();
        for &v in &boundary {
            let kind = FactorKind::Prior { var: keys[v] };
            pattern.push(Factor::new(kind, [v, v], true, identity, unit, RobustKernel::None).ok()?);
        }
        for (j, &b) in boundary.iter().enumerate() {
            for &a in &boundary[..j] {
                let kind = FactorKind::Between {
                    from: keys[a],
                    to: keys[b],
                };
                pattern.push(
                    Factor::new(kind, [a, b], false, identity, unit, RobustKernel::None).ok()?,
                );
            }
        }
        let mut held = vec![true; graph.poses.len()];
        for &v in window.iter().chain(&boundary) {
            held[v] = false;
        }
        let system = NormalEquations::<6>::analyse(&held, &pattern).ok()?;
        let vars = system.var_of.clone();
        Some(Self {
            live,
            prior,
            system,
            vars,
        })
    }

    /// Cost of the live factors at `poses`.
    fn live_cost(&self, factors: &[Factor], poses: &[Isometry3<f64>]) -> f64 {
        self.live.iter().map(|&i| factors[i].cost(poses, 0.0)).sum()
    }

    /// Assembles the normal equations at `poses`; returns the live factors' cost and the
    /// prior's there.
    fn assemble(&mut self, factors: &[Factor], poses: &[Isometry3<f64>]) -> (f64, f64) {
        self.system.clear();
        let mut live_cost = 0.0;
        for (k, &i) in self.live.iter().enumerate() {
            let (c, blocks) = factors[i].normal_blocks(poses, 0.0);
            live_cost += c;
            self.system.add_blocks(k, &blocks);
        }
        let t = self.prior.target.len();
        if t == 0 {
            return (live_cost, 0.0);
        }
        let e = self.prior.residual(poses);
        let se = &self.prior.information * &e;
        let prior_cost = 0.5 * e.dot(&se);
        let jac: Vec<Matrix6<f64>> = self
            .prior
            .target
            .iter()
            .map(|(v, x0_v, _)| {
                se3::right_jacobian_inverse(&se3::log(&(x0_v.inverse() * poses[*v])))
            })
            .collect();
        let s = |i: usize, j: usize| -> Matrix6<f64> {
            self.prior
                .information
                .fixed_view::<6, 6>(6 * i, 6 * j)
                .into_owned()
        };
        let zero = Matrix6::zeros();
        let base = self.live.len();
        let mut blocks = Vec::with_capacity(t * (t + 1) / 2);
        for (i, j_i) in jac.iter().enumerate() {
            blocks.push(FactorBlocks {
                haa: j_i.transpose() * s(i, i) * j_i,
                hab: zero,
                hbb: zero,
                ga: j_i.transpose() * se.fixed_rows::<6>(6 * i),
                gb: Vector6::zeros(),
            });
        }
        for j in 0..t {
            for i in 0..j {
                blocks.push(FactorBlocks {
                    haa: zero,
                    hab: jac[i].transpose() * s(i, j) * jac[j],
                    hbb: zero,
                    ga: Vector6::zeros(),
                    gb: Vector6::zeros(),
                });
            }
        }
        for (k, b) in blocks.iter().enumerate() {
            self.system.add_blocks(base + k, b);
        }
        (live_cost, prior_cost)
    }

    /// Gauss–Newton from `poses` (only the problem's variables change): `iterations` steps
    /// at most, and more while the last was larger than [`LARGE_STEP`], each shortened until
    /// it lowers the cost. Returns the live
    /// factors' cost at the result; `None` when the system is singular or not even a
    /// shortened first step lowers the cost.
    pub fn solve(
        &mut self,
        factors: &[Factor],
        poses: &mut [Isometry3<f64>],
        iterations: usize,
    ) -> Option<f64> {
        if self.system.dim() == 0 {
            return Some(self.live_cost(factors, poses));
        }
        let mut step = vec![0.0; self.system.dim()];
        let mut live_cost = 0.0;
        for iteration in 0..MAX_ITERATIONS {
            let (live, prior) = self.assemble(factors, poses);
            live_cost = live;
            let cost = live + prior;
            if !self.system.factorize_damped(|_, _| 0.0) || !self.system.solve(&mut step) {
                return None;
            }
            let saved: Vec<Isometry3<f64>> = self.vars.iter().map(|&v| poses[v]).collect();
            let mut scale = 1.0;
            let mut accepted = None;
            for _ in 0..=BACKTRACKS {
                for (b, &v) in self.vars.iter().enumerate() {
                    let d = Vector6::from_column_slice(&step[6 * b..6 * b + 6]) * scale;
                    poses[v] = se3::retract(&saved[b], &d);
                }
                let live = self.live_cost(factors, poses);
                let new_cost = live + self.prior.cost(poses);
                if new_cost.is_finite() && new_cost <= cost {
                    accepted = Some((live, new_cost));
                    break;
                }
                scale *= 0.5;
            }
            let Some((live, new_cost)) = accepted else {
                for (b, &v) in self.vars.iter().enumerate() {
                    poses[v] = saved[b];
                }
                return (iteration > 0).then_some(live_cost);
            };
            live_cost = live;
            let step_max = step.iter().fold(0.0f64, |m, s| m.max(s.abs())) * scale;
            let converged = step_max < 1e-9 || cost - new_cost <= 1e-12 * new_cost.max(1e-300);
            if converged || (iteration + 1 >= iterations && step_max <= LARGE_STEP) {
                break;
            }
        }
        Some(live_cost)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::SolverConfig;

    /// Pose 0 fixed, four unit steps along x and a 3.5 m closure 0 → 4 (identity
    /// information): with every free pose in the window and no boundary, the window solve is
    /// the full optimisation.
    #[test]
    fn window_without_boundary_reaches_the_full_optimum() {
        let mut graph = PoseGraph::new();
        graph.add_pose(0, Isometry3::identity()).unwrap();
        graph.fix(0).unwrap();
        let step = Isometry3::translation(1.0, 0.0, 0.0);
        for id in 1..5u64 {
            let initial = graph.pose(id - 1).unwrap() * step;
            graph.add_pose(id, initial).unwrap();
            graph
                .add_between(id - 1, id, step, Matrix6::identity(), RobustKernel::None)
                .unwrap();
        }
        let closure = Isometry3::translation(3.5, 0.0, 0.0);
        graph
            .add_between(0, 4, closure, Matrix6::identity(), RobustKernel::None)
            .unwrap();
        let live: Vec<usize> = (0..graph.factors.len()).collect();
        let window: Vec<usize> = (1..5).collect();
        let prior = BoundaryPrior::default();
        let mut problem = WindowProblem::new(&graph, &live, &window, &prior).unwrap();
        let mut poses = graph.poses.clone();
        problem.solve(&graph.factors, &mut poses, 10).unwrap();
        let mut full = graph.clone();
        full.optimize(&SolverConfig::default()).unwrap();
        for (p, q) in poses.iter().zip(&full.poses) {
            assert!((p.translation.vector - q.translation.vector).norm() < 1e-9);
        }
        assert!((poses[4].translation.x - 3.6).abs() < 1e-9);
    }

    #[test]
    fn the_boundary_prior_vanishes_at_its_target() {
        let x0 = Isometry3::translation(1.0, 2.0, 3.0);
        let star = Vector6::new(0.01, -0.02, 0.03, 0.1, 0.0, -0.1);
        let prior = BoundaryPrior {
            information: DMatrix::identity(6, 6),
            target: vec![(1, x0, star)],
        };
        let poses = [Isometry3::identity(), se3::retract(&x0, &star)];
        assert!(prior.residual(&poses).amax() < 1e-12);
        assert!(prior.cost(&poses) < 1e-20);
        assert!(prior.contains(1) && !prior.contains(0));
    }
}
