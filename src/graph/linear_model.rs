//! Incremental re-optimisation on a fixed batch linearisation, in the spirit of iSAM.
//!
//! After a batch optimisation the factors are linearised once more at the optimum `x₀` and
//! the undamped normal equations `H₀ δ = −g₀` are factored. Until the next batch, the old
//! factors are represented by that quadratic model `q(δ) = g₀ᵀδ + ½ δᵀH₀δ` (as iSAM keeps old
//! rows of its square-root factor at their linearisation point), and only the factors added
//! since then are evaluated exactly.
//!
//! An update solves a small dense problem over the *active* variables: the old variables
//! `T` touched by the new factors and the variables added since the batch. Minimising `q`
//! over every other old variable leaves the marginal `½ (δ_T − δ*_T)ᵀ S (δ_T − δ*_T)` with
//! `S = ((H₀⁻¹)_TT)⁻¹` and `δ* = −H₀⁻¹ g₀`. `(H₀⁻¹)_TT` comes from forward solves `L₀⁻¹
//! E_v` along each touched variable's elimination path (`factor_paths`), a small part of
//! the factor, computed once per touched variable and kept until the next batch.
//! Gauss–Newton on the small problem (new factors relinearised every iteration) gives `δ_T`
//! and the new poses; one backward solve, `δ = H₀⁻¹(P_T μ − g₀) = δ* + L₀⁻ᵀ Σ_v (L₀⁻¹E_v)
//! μ_v` with `μ = S(δ_T − δ*_T)`, moves every old variable to the minimiser of the model
//! given `δ_T`. The result is the exact optimum of the model; it differs from the full
//! nonlinear optimum only through the linearisation of the old factors, so the caller runs
//! a batch again when the steps of old variables grow beyond a threshold (iSAM2's
//! relinearisation threshold) or the active set gets large.

use super::factor_paths::{FactorPaths, PathColumns};
use super::factors::Factor;
use super::pose_graph::{PoseGraph, StructureCache};
use super::se3;
use super::solver::linearize;
use nalgebra::{DMatrix, DVector, Isometry3, Matrix6, Vector6};
use std::ops::AddAssign;

/// Gauss–Newton iterations on the small problem at most.
const MAX_ITERATIONS: usize = 6;

/// What an incremental update did.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ModelUpdate {
    /// Cost of the model: old factors to second order around `x₀`, new factors exact.
    pub cost: f64,
    /// Largest entry of the step of an old variable from its linearisation point.
    pub old_step_max: f64,
    /// Active variables of the small problem.
    pub active: usize,
}

/// The batch linearisation and what updates have computed from it.
pub(crate) struct LinearModel {
    /// Estimates at the linearisation point.
    x0: Vec<Isometry3<f64>>,
    /// Fixed flags at the batch; a change needs a new batch.
    fixed: Vec<bool>,
    /// Factors in the batch.
    num_factors: usize,
    /// The structure analysis, with the normal equations factored at `x₀`.
    structure: StructureCache,
    /// Block column of each batch variable (`None` when held).
    block_of: Vec<Option<usize>>,
    /// Gradient at `x₀`.
    g0: Vec<f64>,
    /// Gauss–Newton step of the model, `−H₀⁻¹ g₀`.
    delta_star: Vec<f64>,
    /// Cost at `x₀`.
    cost0: f64,
    /// Elimination tree of the factor, for solves with sparse right-hand sides.
    paths: FactorPaths,
    /// Old free variables touched by factors added since the batch.
    touched: Vec<usize>,
    /// `L₀⁻¹ E_v` for each touched variable, on its elimination path; `(H₀⁻¹)_uv` is the
    /// product of two of them.
    columns: Vec<PathColumns>,
    /// `(H₀⁻¹)_TT` over the touched variables, grown as variables are touched.
    covariance_tt: DMatrix<f64>,
}

impl LinearModel {
    /// Linearises `graph` at its current estimate with the structure its last optimisation
    /// analysed. Returns `None` when that is not possible (no current analysis, a GNC kernel,
    /// a singular system).
    pub fn build(graph: &mut PoseGraph) -> Option<Self> {
        if graph.factors.iter().any(|f| f.kernel().is_gnc()) {
            return None;
        }
        let mut structure = graph.cache.take()?;
        if structure.version != graph.structure_version {
            return None;
        }
        let system = &mut structure.system;
        if system.dim() == 0 {
            return None;
        }
        let cost0 = linearize(&graph.factors, &graph.poses, system, 0.0);
        if !system.factorize_damped(|_, _| 0.0) {
            return None;
        }
        let mut delta_star = vec![0.0; system.dim()];
        if !system.solve(&mut delta_star) {
            return None;
        }
        let block_of = system.block_of(graph.poses.len());
        let paths = FactorPaths::new(system.supernodal_factor()?);
        Some(Self {
            x0: graph.poses.clone(),
            fixed: graph.fixed_flags().to_vec(),
            num_factors: graph.factors.len(),
            g0: structure.system.gradient.clone(),
            structure,
            block_of,
            delta_star,
            cost0,
            paths,
            touched: Vec::new(),
            columns: Vec::new(),
            covariance_tt: DMatrix::zeros(0, 0),
        })
    }

    /// The model's minimiser `x₀ ⊞ δ*`: one Gauss–Newton step of the whole graph from the
    /// linearisation point.
    pub fn gauss_newton_poses(&self) -> Vec<Isometry3<f64>> {
        let mut poses = self.x0.clone();
        for (v, blk) in self.block_of.iter().enumerate() {
            if let Some(b) = *blk {
                let d = Vector6::from_column_slice(&self.delta_star[6 * b..6 * b + 6]);
                poses[v] = se3::retract(&self.x0[v], &d);
            }
        }
        poses
    }

    /// Gives back the structure analysis (its numeric factor is this model's), to analyse
    /// nothing again when the graph is relinearised with the same structure.
    pub fn into_structure(self) -> StructureCache {
        self.structure
    }

    /// Largest entry of the Gauss–Newton step `δ*` of the model.
    pub fn gauss_newton_step_max(&self) -> f64 {
        self.delta_star.iter().fold(0.0, |m, d| m.max(d.abs()))
    }

    /// Brings the estimates of `graph` to the optimum of the model with the factors added
    /// since the batch. Returns `None` when the model cannot handle the change (fixed flags
    /// changed, a GNC kernel, more than `max_active` active variables, a failed solve); the
    /// estimates are then unchanged.
    pub fn update(&mut self, graph: &mut PoseGraph, max_active: usize) -> Option<ModelUpdate> {
        let n_old = self.x0.len();
        if graph.poses.len() < n_old
            || graph.factors.len() < self.num_factors
            || graph.fixed_flags()[..n_old] != self.fixed[..]
        {
            return None;
        }
        let new_factors = &graph.factors[self.num_factors..];
        if new_factors.iter().any(|f| f.kernel().is_gnc()) {
            return None;
        }
        let fixed = graph.fixed_flags();
        let new_vars: Vec<usize> = (n_old..graph.poses.len()).filter(|&v| !fixed[v]).collect();
        // Old free variables the new factors touch.
        let mut fresh = Vec::new();
        for f in new_factors {
            let [a, b] = f.vars();
            let vars: &[usize] = if f.is_unary() { &[a] } else { &[a, b] };
            for &v in vars {
                if v < n_old
                    && self.block_of[v].is_some()
                    && !self.touched.contains(&v)
                    && !fresh.contains(&v)
                {
                    fresh.push(v);
                }
            }
        }
        if self.touched.len() + fresh.len() + new_vars.len() > max_active {
            return None;
        }
        if !fresh.is_empty() {
            self.add_columns(&fresh)?;
        }
        let t = self.touched.len();
        let mut slot = vec![usize::MAX; graph.poses.len()];
        for (i, &v) in self.touched.iter().chain(&new_vars).enumerate() {
            slot[v] = i;
        }
        let active = t + new_vars.len();
        let s = self.marginal_information()?;
        let target: Vec<Vector6<f64>> = self
            .touched
            .iter()
            .map(|&v| self.block_vector(&self.delta_star, v))
            .collect();

        let mut poses = graph.poses.clone();
        let mut cost = self.small_cost(&poses, new_factors, &s, &target);
        for _ in 0..MAX_ITERATIONS {
            let (h, g) = self.small_system(&poses, new_factors, &s, &target, &slot, active);
            let step = h.cholesky()?.solve(&(-g));
            if !step.iter().all(|v| v.is_finite()) {
                return None;
            }
            let mut candidate = poses.clone();
            for (v, &k) in slot.iter().enumerate() {
                if k != usize::MAX {
                    let d = Vector6::from_column_slice(&step.as_slice()[6 * k..6 * k + 6]);
                    candidate[v] = se3::retract(&poses[v], &d);
                }
            }
            let new_cost = self.small_cost(&candidate, new_factors, &s, &target);
            if !(new_cost.is_finite() && new_cost <= cost) {
                break;
            }
            let step_max = step.amax();
            let decrease = cost - new_cost;
            poses = candidate;
            cost = new_cost;
            if step_max < 1e-9 || decrease <= 1e-12 * cost.max(1e-300) {
                break;
            }
        }

        // Every old variable to the model's minimiser given δ_T:
        // δ = H₀⁻¹(P_T μ − g₀) = δ* + L₀⁻ᵀ Σ_v (L₀⁻¹E_v) μ_v.
        let (e, _) = self.prior_residual(&poses, &target);
        let mu = &s * &e;
        let mut rhs = vec![0.0; self.structure.system.dim()];
        for (i, column) in self.columns.iter().enumerate() {
            column.scatter_add(&mu.as_slice()[6 * i..6 * i + 6], &mut rhs);
        }
        if !self.structure.system.backward_solve(&mut rhs) {
            return None;
        }
        for (d, star) in rhs.iter_mut().zip(&self.delta_star) {
            *d += star;
        }
        let mut old_step_max: f64 = 0.0;
        for (v, blk) in self.block_of.iter().enumerate() {
            let Some(b) = *blk else { continue };
            let d = Vector6::from_column_slice(&rhs[6 * b..6 * b + 6]);
            old_step_max = old_step_max.max(d.amax());
            if slot[v] == usize::MAX {
                poses[v] = se3::retract(&self.x0[v], &d);
            }
        }
        // q(δ) = ½ g₀ᵀδ + ½ δ_Tᵀ μ at the model's minimiser.
        let delta_t: Vec<f64> = self
            .touched
            .iter()
            .flat_map(|&v| se3::log(&(self.x0[v].inverse() * poses[v])).data.0[0])
            .collect();
        let q = 0.5 * self.g0.iter().zip(&rhs).map(|(g, d)| g * d).sum::<f64>()
            + 0.5
                * delta_t
                    .iter()
                    .zip(mu.iter())
                    .map(|(d, m)| d * m)
                    .sum::<f64>();
        let new_cost: f64 = new_factors.iter().map(|f| f.cost(&poses, 0.0)).sum();
        graph.poses = poses;
        Some(ModelUpdate {
            cost: self.cost0 + q + new_cost,
            old_step_max,
            active,
        })
    }

    /// Forward-solves `L₀⁻¹ E_v` of newly touched variables (six columns each) along their
    /// elimination paths, and extends `(H₀⁻¹)_TT` by their rows and columns.
    fn add_columns(&mut self, fresh: &[usize]) -> Option<()> {
        let llt = self.structure.system.supernodal_factor()?;
        // All blocks first, so that a failure leaves the model as it was.
        let blocks: Vec<usize> = fresh
            .iter()
            .map(|&v| self.block_of[v])
            .collect::<Option<_>>()?;
        let old = self.touched.len();
        for (&v, &b) in fresh.iter().zip(&blocks) {
            self.columns.push(self.paths.forward_unit(llt, 6 * b, 6));
            self.touched.push(v);
        }
        let t = self.touched.len();
        let mut m = self.covariance_tt.clone().resize(6 * t, 6 * t, 0.0);
        for j in old..t {
            for i in 0..=j {
                let block = self.columns[i].gram(&self.columns[j]);
                m.view_mut((6 * i, 6 * j), (6, 6)).copy_from(&block);
                m.view_mut((6 * j, 6 * i), (6, 6))
                    .copy_from(&block.transpose());
            }
        }
        self.covariance_tt = m;
        Some(())
    }

    /// `S = ((H₀⁻¹)_TT)⁻¹`.
    fn marginal_information(&self) -> Option<DMatrix<f64>> {
        Some(self.covariance_tt.clone().cholesky()?.inverse())
    }

    fn block_vector(&self, x: &[f64], v: usize) -> Vector6<f64> {
        match self.block_of[v] {
            Some(b) => Vector6::from_column_slice(&x[6 * b..6 * b + 6]),
            None => Vector6::zeros(),
        }
    }

    /// `δ_T − δ*_T` and the blocks `J_r⁻¹(δ_v)` of its Jacobian.
    fn prior_residual(
        &self,
        poses: &[Isometry3<f64>],
        target: &[Vector6<f64>],
    ) -> (DVector<f64>, Vec<Matrix6<f64>>) {
        let t = self.touched.len();
        let mut e = DVector::zeros(6 * t);
        let mut jac = Vec::with_capacity(t);
        for (i, &v) in self.touched.iter().enumerate() {
            let d = se3::log(&(self.x0[v].inverse() * poses[v]));
            e.rows_mut(6 * i, 6).copy_from(&(d - target[i]));
            jac.push(se3::right_jacobian_inverse(&d));
        }
        (e, jac)
    }

    fn small_cost(
        &self,
        poses: &[Isometry3<f64>],
        new_factors: &[Factor],
        s: &DMatrix<f64>,
        target: &[Vector6<f64>],
    ) -> f64 {
        let (e, _) = self.prior_residual(poses, target);
        let prior = 0.5 * e.dot(&(s * &e));
        prior + new_factors.iter().map(|f| f.cost(poses, 0.0)).sum::<f64>()
    }

    /// Normal equations of the small problem over the active variables.
    fn small_system(
        &self,
        poses: &[Isometry3<f64>],
        new_factors: &[Factor],
        s: &DMatrix<f64>,
        target: &[Vector6<f64>],
        slot: &[usize],
        active: usize,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let d = 6 * active;
        let mut h = DMatrix::zeros(d, d);
        let mut g = DVector::zeros(d);
        let t = self.touched.len();
        let (e, jac) = self.prior_residual(poses, target);
        let se = s * &e;
        for i in 0..t {
            let gi = jac[i].transpose() * se.fixed_rows::<6>(6 * i);
            g.fixed_rows_mut::<6>(6 * i).add_assign(&gi);
            for j in 0..t {
                let sij: Matrix6<f64> = s.fixed_view::<6, 6>(6 * i, 6 * j).into_owned();
                let block = jac[i].transpose() * sij * jac[j];
                h.fixed_view_mut::<6, 6>(6 * i, 6 * j).add_assign(&block);
            }
        }
        for f in new_factors {
            let (_, blocks) = f.normal_blocks(poses, 0.0);
            let [a, b] = f.vars();
            let sa = slot[a];
            let sb = if f.is_unary() { usize::MAX } else { slot[b] };
            if sa != usize::MAX {
                h.fixed_view_mut::<6, 6>(6 * sa, 6 * sa)
                    .add_assign(&blocks.haa);
                g.fixed_rows_mut::<6>(6 * sa).add_assign(&blocks.ga);
            }
            if sb != usize::MAX {
                h.fixed_view_mut::<6, 6>(6 * sb, 6 * sb)
                    .add_assign(&blocks.hbb);
                g.fixed_rows_mut::<6>(6 * sb).add_assign(&blocks.gb);
            }
            if sa != usize::MAX && sb != usize::MAX {
                h.fixed_view_mut::<6, 6>(6 * sa, 6 * sb)
                    .add_assign(&blocks.hab);
                h.fixed_view_mut::<6, 6>(6 * sb, 6 * sa)
                    .add_assign(&blocks.hab.transpose());
            }
        }
        (h, g)
    }
}
