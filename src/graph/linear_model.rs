//! Incremental re-optimisation on a fixed linearisation of the settled part of the graph,
//! with a window of recent variables that is always solved exactly (iSAM's idea, with the
//! recent part of the graph relinearised on every update as a fixed-lag smoother does).
//!
//! At a build, the variables split into *settled* ones (all but the last
//! `window` free variables, in insertion order) and the *window*. Factors among settled
//! variables only are *frozen*: they are linearised once at the build's estimate `x₀` and
//! represented by their quadratic model `q(δ) = g₀ᵀδ + ½ δᵀH₀δ` (`H₀` factored once, as iSAM
//! keeps old rows of its square-root factor). Every other factor — those touching the
//! window, and every factor added since — is *live*: evaluated exactly on every update.
//!
//! An update minimises `q` plus the live factors. Minimising `q` over the settled variables
//! that no live factor touches leaves, on the touched *boundary* `T`, the marginal
//! `½ (δ_T − δ*_T)ᵀ S (δ_T − δ*_T)` with `S = ((H₀⁻¹)_TT)⁻¹` and `δ* = −H₀⁻¹ g₀`. `(H₀⁻¹)_TT`
//! comes from forward solves `L₀⁻¹ E_v` along each boundary variable's elimination path
//! (`factor_paths`), computed once per boundary variable and kept until the next build.
//! Gauss–Newton on the window and the boundary (a sparse problem, see `window_solve`) gives
//! their estimates; one backward solve, `δ = H₀⁻¹(P_T μ − g₀) = δ* + L₀⁻ᵀ Σ_v (L₀⁻¹E_v) μ_v`
//! with `μ = S(δ_T − δ*_T)`, moves every other settled variable to the minimiser of the
//! model given `δ_T`. The result differs from the full nonlinear optimum only through the
//! linearisation of the frozen factors, so the caller builds again when a settled variable
//! moves more than a threshold from `x₀` (iSAM2's relinearisation threshold), or the
//! window or boundary grows large.

use super::components;
use super::factor_paths::{FactorPaths, PathColumns};
use super::factors::Factor;
use super::pose_graph::PoseGraph;
use super::se3;
use super::solver::linearize;
use super::structure::NormalEquations;
use super::window_solve::{BoundaryPrior, WindowProblem};
use nalgebra::{DMatrix, Isometry3, Vector6};

/// What an incremental update did.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ModelUpdate {
    /// Cost of the model: frozen factors to second order around `x₀`, live factors exact.
    pub cost: f64,
    /// Largest entry of the step of a settled variable from its linearisation point.
    pub old_step_max: f64,
    /// Variables solved exactly: the window and the boundary.
    pub active: usize,
}

/// Limits of one update.
#[derive(Clone, Copy, Debug)]
pub(crate) struct UpdateLimits {
    /// Boundary variables (settled variables touched by live factors) at most; the
    /// boundary's marginal is dense.
    pub max_boundary: usize,
    /// Window variables at most (the window grows with every appended pose).
    pub max_window: usize,
    /// Gauss–Newton iterations on the window at most.
    pub iterations: usize,
}

/// The frozen factors linearised and factored at `x₀`.
struct Frozen {
    /// Normal equations of the frozen factors over the free settled variables, factored.
    system: NormalEquations<6>,
    /// Block column of each variable in `system` (`None` for window and fixed variables).
    block_of: Vec<Option<usize>>,
    /// Gradient at `x₀`.
    g0: Vec<f64>,
    /// Gauss–Newton step of the model, `−H₀⁻¹ g₀`.
    delta_star: Vec<f64>,
    /// Cost of the frozen factors at `x₀`.
    cost0: f64,
    /// Elimination tree of the factor, for solves with sparse right-hand sides.
    paths: FactorPaths,
}

impl Frozen {
    fn build(held: &[bool], factors: &[Factor], x0: &[Isometry3<f64>]) -> Option<Self> {
        let mut system = NormalEquations::<6>::analyse(held, factors).ok()?;
        let cost0 = linearize(factors, x0, &mut system, 0.0);
        if !system.factorize_damped(|_, _| 0.0) {
            return None;
        }
        let mut delta_star = vec![0.0; system.dim()];
        if !system.solve(&mut delta_star) {
            return None;
        }
        let paths = FactorPaths::new(system.supernodal_factor()?);
        Some(Self {
            block_of: system.block_of(x0.len()),
            g0: system.gradient.clone(),
            system,
            delta_star,
            cost0,
            paths,
        })
    }
}

/// The linearisation of the settled part and what updates have computed from it.
pub(crate) struct LinearModel {
    /// Estimates at the linearisation point.
    x0: Vec<Isometry3<f64>>,
    /// Fixed flags at the build; a change needs a new build.
    fixed: Vec<bool>,
    /// Held variables at the build: the fixed ones and the first variable of every
    /// component without an anchor, which the batch holds too.
    held: Vec<bool>,
    /// Factors at the build.
    num_factors: usize,
    /// Settled variables (their factors among themselves are frozen).
    settled: Vec<bool>,
    /// Factors of the build that are live (touch a window variable).
    live: Vec<usize>,
    /// The frozen part; `None` when no free variable is settled.
    frozen: Option<Frozen>,
    /// Boundary: settled free variables touched by live factors.
    touched: Vec<usize>,
    /// `L₀⁻¹ E_v` for each boundary variable, on its elimination path; `(H₀⁻¹)_uv` is the
    /// product of two of them.
    columns: Vec<PathColumns>,
    /// `(H₀⁻¹)_TT` over the boundary, grown as variables join it.
    covariance_tt: DMatrix<f64>,
    /// The frozen factors' marginal on the boundary, recomputed when the boundary grows.
    prior: BoundaryPrior,
}

impl LinearModel {
    /// Linearises the frozen factors of `graph` at its current estimate, leaving live the
    /// window chosen by [`choose_split`] (and settled variables without frozen factors).
    /// Returns `None` when that is not possible (a GNC kernel, a settled part without an
    /// anchor, a singular system).
    pub fn build(graph: &PoseGraph, window: usize, max_window: usize) -> Option<Self> {
        if graph.factors.iter().any(|f| f.kernel().is_gnc()) {
            return None;
        }
        let n = graph.poses.len();
        let fixed = graph.fixed_flags();
        let (_, held) = components::analyse(graph.keys(), fixed, &graph.factors);
        let split = choose_split(graph, &held, window, max_window);
        let is_frozen = |f: &Factor| {
            let [a, b] = f.vars();
            a < split && (f.is_unary() || b < split)
        };
        let mut settled = vec![false; n];
        let (mut frozen_factors, mut live) = (Vec::new(), Vec::new());
        for (i, f) in graph.factors.iter().enumerate() {
            if is_frozen(f) {
                let [a, b] = f.vars();
                settled[a] = true;
                settled[b] = settled[b] || !f.is_unary();
                frozen_factors.push(f.clone());
            } else {
                live.push(i);
            }
        }
        let not_frozen: Vec<bool> = (0..n).map(|v| held[v] || !settled[v]).collect();
        let frozen = if not_frozen.iter().all(|&h| h) {
            None
        } else {
            Some(Frozen::build(&not_frozen, &frozen_factors, &graph.poses)?)
        };
        Some(Self {
            x0: graph.poses.clone(),
            fixed: fixed.to_vec(),
            held,
            num_factors: graph.factors.len(),
            settled,
            live,
            frozen,
            touched: Vec::new(),
            columns: Vec::new(),
            covariance_tt: DMatrix::zeros(0, 0),
            prior: BoundaryPrior::default(),
        })
    }

    /// Brings the estimates of `graph` to the optimum of the model with the factors added
    /// since the build. Returns `None` when the model cannot handle the change (fixed flags
    /// changed, a GNC kernel, a limit exceeded, a failed solve); the estimates are then
    /// unchanged.
    pub fn update(&mut self, graph: &mut PoseGraph, limits: UpdateLimits) -> Option<ModelUpdate> {
        let n_old = self.x0.len();
        if graph.poses.len() < n_old
            || graph.factors.len() < self.num_factors
            || graph.fixed_flags()[..n_old] != self.fixed[..]
        {
            return None;
        }
        // A new factor on a variable the build held to anchor its component may anchor the
        // component otherwise: the holding must be decided again.
        let auto_held = |v: usize| v < n_old && self.held[v] && !self.fixed[v];
        if graph.factors[self.num_factors..].iter().any(|f| {
            let [a, b] = f.vars();
            f.kernel().is_gnc() || auto_held(a) || (!f.is_unary() && auto_held(b))
        }) {
            return None;
        }
        let live: Vec<usize> = (self.live.iter().copied())
            .chain(self.num_factors..graph.factors.len())
            .collect();
        let fixed = graph.fixed_flags();
        let window: Vec<usize> = (0..graph.poses.len())
            .filter(|&v| match v < n_old {
                true => !self.held[v] && !self.settled[v],
                false => !fixed[v],
            })
            .collect();
        if window.len() > limits.max_window {
            return None;
        }
        let fresh = self.fresh_boundary(&graph.factors, &live);
        if self.touched.len() + fresh.len() > limits.max_boundary {
            return None;
        }
        if !fresh.is_empty() {
            self.add_columns(&fresh)?;
        }
        let prior = &self.prior;
        let mut problem = WindowProblem::new(graph, &live, &window, prior)?;
        let mut poses = graph.poses.clone();
        let live_cost = problem.solve(&graph.factors, &mut poses, limits.iterations)?;
        let active = window.len() + self.touched.len();
        let (old_step_max, q) = match &self.frozen {
            Some(frozen) => settle(frozen, &self.x0, &self.columns, prior, &mut poses)?,
            None => (0.0, 0.0),
        };
        let cost0 = self.frozen.as_ref().map_or(0.0, |f| f.cost0);
        graph.poses = poses;
        Some(ModelUpdate {
            cost: cost0 + q + live_cost,
            old_step_max,
            active,
        })
    }

    /// Settled free variables touched by live factors that are not on the boundary yet.
    fn fresh_boundary(&self, factors: &[Factor], live: &[usize]) -> Vec<usize> {
        let Some(frozen) = &self.frozen else {
            return Vec::new();
        };
        let mut fresh = Vec::new();
        for &i in live {
            let f = &factors[i];
            let [a, b] = f.vars();
            let vars: &[usize] = if f.is_unary() { &[a] } else { &[a, b] };
            for &v in vars {
                let on_boundary = frozen.block_of.get(v).is_some_and(Option::is_some);
                if on_boundary && !self.touched.contains(&v) && !fresh.contains(&v) {
                    fresh.push(v);
                }
            }
        }
        fresh
    }

    /// Forward-solves `L₀⁻¹ E_v` of new boundary variables (six columns each) along their
    /// elimination paths, extends `(H₀⁻¹)_TT` by their rows and columns and computes the
    /// boundary's marginal again.
    fn add_columns(&mut self, fresh: &[usize]) -> Option<()> {
        let frozen = self.frozen.as_ref()?;
        let llt = frozen.system.supernodal_factor()?;
        // All blocks first, so that a failure leaves the model as it was.
        let blocks: Vec<usize> = fresh
            .iter()
            .map(|&v| frozen.block_of[v])
            .collect::<Option<_>>()?;
        let old = self.touched.len();
        for (&v, &b) in fresh.iter().zip(&blocks) {
            self.columns.push(frozen.paths.forward_unit(llt, 6 * b, 6));
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
        self.prior = self.boundary_prior()?;
        Some(())
    }

    /// The frozen factors' marginal on the boundary: `S = ((H₀⁻¹)_TT)⁻¹` around `x₀ ⊞ δ*`.
    fn boundary_prior(&self) -> Option<BoundaryPrior> {
        let frozen = self.frozen.as_ref()?;
        let information = self.covariance_tt.clone().cholesky()?.inverse();
        let target = self
            .touched
            .iter()
            .map(|&v| {
                let b = frozen.block_of[v]?;
                let d = Vector6::from_column_slice(&frozen.delta_star[6 * b..6 * b + 6]);
                Some((v, self.x0[v], d))
            })
            .collect::<Option<_>>()?;
        Some(BoundaryPrior {
            information,
            target,
        })
    }
}

/// Where the window of a build starts: at least the last `window` free variables, extended
/// back (by as many as leave `window` appends of room before `max_window`) where that
/// removes boundary variables — settled variables sharing a factor with the window — each
/// worth [`BOUNDARY_WEIGHT`] window variables. A stretch of trajectory dense with loop
/// closures then lies wholly in the window instead of straddling the split, where every
/// closure across it would add a variable to the dense boundary and pull settled variables
/// away from their linearisation point.
fn choose_split(graph: &PoseGraph, held: &[bool], window: usize, max_window: usize) -> usize {
    let longest = window.max(max_window.saturating_sub(window));
    let mut candidates = Vec::new();
    let mut free = 0;
    for s in (0..graph.poses.len()).rev() {
        if held[s] {
            continue;
        }
        free += 1;
        if free > longest {
            break;
        }
        if free >= window {
            candidates.push(s);
        }
    }
    let Some(&earliest) = candidates.last() else {
        return 0;
    };
    // Binary factors reaching from a free variable before a candidate split to one after.
    let spans: Vec<(usize, usize)> = graph
        .factors
        .iter()
        .filter(|f| !f.is_unary())
        .map(|f| {
            let [a, b] = f.vars();
            (a.min(b), a.max(b))
        })
        .filter(|&(a, b)| b >= earliest && a < b && !held[a])
        .collect();
    let mut best = (usize::MAX, 0);
    let mut boundary = Vec::new();
    for (extra, &s) in candidates.iter().enumerate() {
        boundary.clear();
        boundary.extend(
            spans
                .iter()
                .filter(|&&(a, b)| a < s && s <= b)
                .map(|&(a, _)| a),
        );
        boundary.sort_unstable();
        boundary.dedup();
        let score = extra + BOUNDARY_WEIGHT * boundary.len();
        if score < best.0 {
            best = (score, s);
        }
    }
    best.1
}

/// Window variables a boundary variable is worth when a build chooses its split: its
/// marginal adds a dense block to every update, and settled variables tied to the window by
/// loop closures are the ones that move.
const BOUNDARY_WEIGHT: usize = 25;

/// Moves every settled variable off the boundary to the model's minimiser given the
/// boundary's estimate in `poses`: `δ = δ* + L₀⁻ᵀ Σ_v (L₀⁻¹E_v) μ_v`, `μ = S(δ_T − δ*_T)`.
/// Returns the largest step entry of a settled variable from `x₀`, and the model's value
/// `q(δ) = ½ g₀ᵀδ + ½ δ_Tᵀ μ` there.
fn settle(
    frozen: &Frozen,
    x0: &[Isometry3<f64>],
    columns: &[PathColumns],
    prior: &BoundaryPrior,
    poses: &mut [Isometry3<f64>],
) -> Option<(f64, f64)> {
    let e = prior.residual(poses);
    let mu = &prior.information * &e;
    let mut delta = vec![0.0; frozen.system.dim()];
    for (i, column) in columns.iter().enumerate() {
        column.scatter_add(&mu.as_slice()[6 * i..6 * i + 6], &mut delta);
    }
    if !frozen.system.backward_solve(&mut delta) {
        return None;
    }
    for (d, star) in delta.iter_mut().zip(&frozen.delta_star) {
        *d += star;
    }
    let mut old_step_max: f64 = 0.0;
    for (v, blk) in frozen.block_of.iter().enumerate() {
        let Some(b) = *blk else { continue };
        let d = Vector6::from_column_slice(&delta[6 * b..6 * b + 6]);
        old_step_max = old_step_max.max(d.amax());
        if !prior.contains(v) {
            poses[v] = se3::retract(&x0[v], &d);
        }
    }
    let delta_t: f64 = prior
        .target
        .iter()
        .enumerate()
        .map(|(i, (v, x0_v, _))| {
            let d = se3::log(&(x0_v.inverse() * poses[*v]));
            d.dot(&mu.fixed_rows::<6>(6 * i))
        })
        .sum();
    let g0_delta: f64 = frozen.g0.iter().zip(&delta).map(|(g, d)| g * d).sum();
    Some((old_step_max, 0.5 * g0_delta + 0.5 * delta_t))
}
