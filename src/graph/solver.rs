//! Levenberg–Marquardt and Gauss–Newton on the Lie group, with graduated non-convexity.
//!
//! Each iteration linearises every factor at the current estimate, assembles the sparse
//! normal equations `(H + λD) δ = −g` into the structure analysed once by
//! [`NormalEquations`], refactors numerically, and retracts `X ← X · Exp(δ)` on every free
//! variable. The step is accepted if the cost does not increase (λ shrinks), otherwise λ
//! grows and the step is recomputed — GTSAM's policy, with its default parameters, so that
//! iteration counts compare. Robust kernels enter by iteratively reweighted least squares.

use super::components::{self, ComponentInfo};
use super::factors::Factor;
use super::initialize;
use super::pose_graph::{PoseGraph, StructureCache};
use super::se3;
use super::structure::{NormalEquations, Precision};
use super::GraphError;
use nalgebra::{Isometry3, Vector6};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Which nonlinear least-squares method to run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Algorithm {
    /// Levenberg–Marquardt with a trust-region style damping update.
    #[default]
    LevenbergMarquardt,
    /// Plain Gauss–Newton: every step is taken undamped.
    GaussNewton,
}

/// How the Levenberg–Marquardt damping is added to the Hessian diagonal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Damping {
    /// `H + λ I` (GTSAM's default).
    #[default]
    Identity,
    /// `H + λ diag(H)` (Marquardt's scaling, clamped to [1e-6, 1e32]).
    Diagonal,
}

/// How the estimates are initialised before iterating.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Initialization {
    /// Start from the current estimates (warm start).
    #[default]
    None,
    /// Replace them by the chordal relaxation (rotations, then translations) first; see
    /// the `initialize` module. Ignores robust kernels, so wrong loop closures distort it.
    Chordal,
}

/// Graduated non-convexity schedule for factors with [`RobustKernel::Gnc`].
///
/// [`RobustKernel::Gnc`]: super::RobustKernel::Gnc
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GncConfig {
    /// Divisor of the control parameter μ between stages (> 1).
    pub mu_step: f64,
    /// Iterations per intermediate stage; the last stage (μ = 1) runs to convergence. One
    /// step per μ, as in Yang et al. (2020), alternates weights and estimate; on sphere2500
    /// with 10% wrong loop closures it reached the oracle's solution (wrong closures
    /// removed) on 20 of 20 seeds, where two steps per μ settled on a worse local minimum of
    /// the truncated cost on one (see BENCHMARKS.md).
    pub stage_iterations: usize,
    /// Starting μ; `None` picks `2 max(s) / c²` over the GNC factors at the initial estimate.
    pub initial_mu: Option<f64>,
}

impl Default for GncConfig {
    fn default() -> Self {
        Self {
            mu_step: 2.0,
            stage_iterations: 1,
            initial_mu: None,
        }
    }
}

/// Parameters of the nonlinear solver. Defaults follow GTSAM's `LevenbergMarquardtParams`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SolverConfig {
    /// Levenberg–Marquardt or Gauss–Newton.
    pub algorithm: Algorithm,
    /// Maximum number of linearisations.
    pub max_iterations: usize,
    /// Stop when the cost decreases by less than this fraction in one iteration.
    pub relative_tolerance: f64,
    /// Stop when the cost decreases by less than this amount in one iteration.
    pub absolute_tolerance: f64,
    /// Stop before iterating when the largest gradient entry is at most this.
    pub gradient_tolerance: f64,
    /// Stop when the largest step entry is at most this.
    pub step_tolerance: f64,
    /// Initial damping λ.
    pub lambda_initial: f64,
    /// Factor by which λ shrinks after a successful step and grows after a failed one.
    pub lambda_factor: f64,
    /// Give up when λ exceeds this.
    pub lambda_max: f64,
    /// Smallest λ.
    pub lambda_min: f64,
    /// How λ enters the normal equations.
    pub damping: Damping,
    /// Initialisation before iterating (the initial cost is reported before it).
    pub initialization: Initialization,
    /// Chord steps tried after each factorisation once the cost decreases by less than 0.1 %
    /// per step: steps that reuse the last factor with the new gradient instead of
    /// refactoring (0 = classic Levenberg–Marquardt).
    pub chord_steps: usize,
    /// Chord steps are only tried once the last step decreased the cost by less than this
    /// fraction: far from the optimum the Hessian changes too much between iterations for
    /// the old factor to give a useful step, and a failed try costs a solve and a cost
    /// evaluation.
    pub chord_regime: f64,
    /// Factorise in single precision while the last step decreased the cost by more than
    /// this fraction (the first factorisation of a run counts as far from the optimum);
    /// closer to the optimum, in double precision. A single-precision factor costs about a
    /// quarter less time (half the floating-point work and memory traffic). Once the cost
    /// decreases by less than `chord_regime` per step, solves with such a factor are refined
    /// once against the double-precision matrix, which makes the step nearly as accurate;
    /// a factorisation that fails is redone in double precision.
    /// Costs, gradients and the convergence test stay in double precision throughout, so
    /// the optimum reached is the same. `inf` turns single precision off.
    pub single_precision_regime: f64,
    /// Graduated non-convexity schedule (used only when a factor has a GNC kernel).
    pub gnc: GncConfig,
    /// Keep a per-iteration log in the report.
    pub log_iterations: bool,
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            algorithm: Algorithm::LevenbergMarquardt,
            max_iterations: 100,
            relative_tolerance: 1e-5,
            absolute_tolerance: 1e-5,
            gradient_tolerance: 0.0,
            step_tolerance: 1e-12,
            lambda_initial: 1e-5,
            lambda_factor: 10.0,
            lambda_max: 1e5,
            lambda_min: 0.0,
            damping: Damping::Identity,
            initialization: Initialization::None,
            chord_steps: 1,
            chord_regime: 1e-3,
            single_precision_regime: 1e-2,
            gnc: GncConfig::default(),
            log_iterations: true,
        }
    }
}

impl SolverConfig {
    fn validate(&self) -> Result<(), GraphError> {
        let bad = |what: &str| Err(GraphError::InvalidConfig(what.to_string()));
        let nonneg = |v: f64| v.is_finite() && v >= 0.0;
        if !nonneg(self.relative_tolerance)
            || !nonneg(self.absolute_tolerance)
            || !nonneg(self.gradient_tolerance)
            || !nonneg(self.step_tolerance)
            || !nonneg(self.chord_regime)
            || self.single_precision_regime.is_nan()
            || self.single_precision_regime < 0.0
        {
            return bad("tolerances and chord_regime must be finite and non-negative");
        }
        if !(self.lambda_initial.is_finite() && self.lambda_initial > 0.0) {
            return bad("lambda_initial must be positive");
        }
        if !(self.lambda_factor.is_finite() && self.lambda_factor > 1.0) {
            return bad("lambda_factor must be greater than 1");
        }
        if !(self.lambda_max >= self.lambda_initial && nonneg(self.lambda_min)) {
            return bad("need 0 <= lambda_min and lambda_initial <= lambda_max");
        }
        if !(self.gnc.mu_step.is_finite() && self.gnc.mu_step > 1.0) {
            return bad("gnc.mu_step must be greater than 1");
        }
        if let Some(mu) = self.gnc.initial_mu {
            if !(mu.is_finite() && mu >= 1.0) {
                return bad("gnc.initial_mu must be at least 1");
            }
        }
        Ok(())
    }
}

/// Why the solver stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The cost decreased by less than `relative_tolerance` (converged).
    RelativeDecrease,
    /// The cost decreased by less than `absolute_tolerance` (converged).
    AbsoluteDecrease,
    /// The step was below `step_tolerance` (converged).
    SmallStep,
    /// The gradient was below `gradient_tolerance` (converged).
    SmallGradient,
    /// The cost reached zero (converged).
    ZeroCost,
    /// Every variable is held; nothing to optimise.
    NoFreeVariables,
    /// `max_iterations` reached before convergence.
    MaxIterations,
    /// λ exceeded `lambda_max` without finding a decreasing step.
    LambdaLimit,
    /// Gauss–Newton met a singular system.
    Singular,
}

impl Termination {
    /// True when the stop criterion means convergence.
    pub fn converged(self) -> bool {
        matches!(
            self,
            Termination::RelativeDecrease
                | Termination::AbsoluteDecrease
                | Termination::SmallStep
                | Termination::SmallGradient
                | Termination::ZeroCost
                | Termination::NoFreeVariables
        )
    }
}

/// One accepted (or final, failed) iteration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IterationLog {
    /// 1-based iteration number.
    pub iteration: usize,
    /// Cost (with the stage's μ) before the step.
    pub cost_before: f64,
    /// Cost after the step.
    pub cost_after: f64,
    /// Damping used for the accepted step.
    pub lambda: f64,
    /// Largest entry of the step.
    pub step_max: f64,
    /// Steps rejected before this one was accepted.
    pub rejected_steps: usize,
    /// True when the step reused the previous factor (chord step).
    pub chord: bool,
    /// GNC control parameter μ of the stage (0 in the final stage).
    pub mu: f64,
    /// Wall time since the start of the optimisation.
    pub time_ms: f64,
}

/// What an optimisation did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptimizationReport {
    /// Number of pose variables.
    pub poses: usize,
    /// Number of variables (poses and frames).
    pub variables: usize,
    /// Number of factors.
    pub factors: usize,
    /// Cost `½ Σ ρ(rᵀΩr)` at the initial estimate.
    pub initial_cost: f64,
    /// Cost at the final estimate.
    pub final_cost: f64,
    /// Number of iterations (linearisations followed by a step).
    pub iterations: usize,
    /// Number of numeric factorisations (including those of rejected steps).
    pub factorizations: usize,
    /// How many of them were in single precision (see
    /// [`SolverConfig::single_precision_regime`]).
    pub single_precision_factorizations: usize,
    /// Wall time of the optimisation including analysis.
    pub time_ms: f64,
    /// True if a previous symbolic analysis was reused.
    pub analysis_reused: bool,
    /// Whether a convergence criterion was met.
    pub converged: bool,
    /// Why the solver stopped.
    pub termination: Termination,
    /// Connected components and their gauge anchors.
    pub components: Vec<ComponentInfo>,
    /// Non-zeros of the Cholesky factor.
    pub factor_nnz: usize,
    /// Number of GNC stages run (0 without GNC).
    pub gnc_stages: usize,
    /// Where the time went.
    pub profile: Profile,
    /// Per-iteration log (empty when `log_iterations` is off).
    pub log: Vec<IterationLog>,
}

/// Time spent in each phase of an optimisation.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    /// Ordering and symbolic factorisation.
    pub analysis_ms: f64,
    /// Chordal initialisation.
    pub initialize_ms: f64,
    /// Linearising factors and assembling the normal equations.
    pub linearize_ms: f64,
    /// Numeric factorisations.
    pub factorize_ms: f64,
    /// Triangular solves.
    pub solve_ms: f64,
    /// Retraction and cost evaluation of candidate steps.
    pub cost_ms: f64,
}

/// Runs the configured solver on `graph`, updating its estimates.
pub(crate) fn optimize(
    graph: &mut PoseGraph,
    config: &SolverConfig,
) -> Result<OptimizationReport, GraphError> {
    config.validate()?;
    let start = Instant::now();
    let mut state = RunState {
        start,
        log: Vec::new(),
        iterations: 0,
        factorizations: 0,
        single_precision_factorizations: 0,
        profile: Profile::default(),
    };
    let (mut cache, analysis_ms) = take_analysis(graph)?;
    let analysis_reused = analysis_ms.is_none();
    state.profile.analysis_ms = analysis_ms.unwrap_or(0.0);
    let initial_cost = graph.cost();
    if config.initialization == Initialization::Chordal {
        let t = Instant::now();
        initialize::chordal_initialize(
            &mut graph.poses,
            &graph.factors,
            &cache.held,
            Some(&cache.system.order),
        )?;
        state.profile.initialize_ms = ms_since(t);
    }
    let result = run(graph, &mut cache.system, config, &mut state);
    let components = cache.components.clone();
    let factor_nnz = cache.system.factor_nnz();
    graph.cache = Some(cache);
    let (termination, gnc_stages) = result?;
    Ok(OptimizationReport {
        poses: graph.num_poses(),
        variables: graph.num_variables(),
        factors: graph.num_factors(),
        initial_cost,
        final_cost: graph.cost(),
        iterations: state.iterations,
        factorizations: state.factorizations,
        single_precision_factorizations: state.single_precision_factorizations,
        time_ms: ms_since(start),
        analysis_reused,
        converged: termination.converged(),
        termination,
        components,
        factor_nnz,
        gnc_stages,
        profile: state.profile,
        log: state.log,
    })
}

/// Takes the structure analysis out of `graph`: the cached one if it is for the current
/// structure, else a new one (components, gauge, ordering, symbolic factorisation) with the
/// time it took.
fn take_analysis(graph: &mut PoseGraph) -> Result<(StructureCache, Option<f64>), GraphError> {
    let version = graph.structure_version;
    if let Some(cache) = graph.cache.take().filter(|c| c.version == version) {
        return Ok((cache, None));
    }
    let t = Instant::now();
    let (components, held) = components::analyse(graph.keys(), graph.fixed_flags(), &graph.factors);
    let system = NormalEquations::<6>::analyse(&held, &graph.factors)?;
    let cache = StructureCache {
        version,
        components,
        held,
        system,
    };
    Ok((cache, Some(ms_since(t))))
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Bookkeeping shared by the stages of one optimisation.
struct RunState {
    start: Instant,
    log: Vec<IterationLog>,
    /// Iterations so far.
    iterations: usize,
    /// Numeric factorisations so far.
    factorizations: usize,
    /// Of which in single precision.
    single_precision_factorizations: usize,
    profile: Profile,
}

/// Termination and number of GNC stages.
type RunResult = (Termination, usize);

/// GNC stages (if any) followed by the final solve.
fn run(
    graph: &mut PoseGraph,
    system: &mut NormalEquations<6>,
    config: &SolverConfig,
    state: &mut RunState,
) -> Result<RunResult, GraphError> {
    if system.dim() == 0 {
        return Ok((Termination::NoFreeVariables, 0));
    }
    let mut stages = 0;
    if graph.factors.iter().any(|f| f.kernel().is_gnc()) {
        let mut mu = match config.gnc.initial_mu {
            Some(mu) => mu,
            None => initial_mu(&graph.factors, &graph.poses),
        };
        let mut stage = config.clone();
        stage.max_iterations = config.gnc.stage_iterations;
        loop {
            levenberg_marquardt(graph, system, &stage, mu, state)?;
            stages += 1;
            if mu <= 1.0 {
                break;
            }
            mu = (mu / config.gnc.mu_step).max(1.0);
        }
        stages += 1;
    }
    // μ = 0 is the final truncated quadratic of GNC factors (ignored by other kernels).
    let termination = levenberg_marquardt(graph, system, config, 0.0, state)?;
    Ok((termination, stages))
}

/// GNC starting point `2 max(s) / c²` (Yang et al., 2020), at least 1.
fn initial_mu(factors: &[Factor], poses: &[Isometry3<f64>]) -> f64 {
    let mut mu: f64 = 1.0;
    for f in factors {
        if let (true, Some(c)) = (f.kernel().is_gnc(), f.kernel().scale()) {
            let s = f.mahalanobis2(&f.residual(poses));
            mu = mu.max(2.0 * s / (c * c));
        }
    }
    mu
}

/// Assembles the normal equations at `poses`; returns the cost (with μ).
pub(crate) fn linearize(
    factors: &[Factor],
    poses: &[Isometry3<f64>],
    system: &mut NormalEquations<6>,
    mu: f64,
) -> f64 {
    system.clear();
    let mut cost = 0.0;
    for (i, f) in factors.iter().enumerate() {
        let (c, blocks) = f.normal_blocks(poses, mu);
        cost += c;
        system.add_blocks(i, &blocks);
    }
    cost
}

/// Assembles only the gradient at `poses` (the Hessian keeps its last values); returns the
/// cost (with μ).
fn linearize_gradient(
    factors: &[Factor],
    poses: &[Isometry3<f64>],
    system: &mut NormalEquations<6>,
    mu: f64,
) -> f64 {
    system.clear_gradient();
    let mut cost = 0.0;
    for (i, f) in factors.iter().enumerate() {
        let (c, ga, gb) = f.gradient_blocks(poses, mu);
        cost += c;
        system.add_gradient_blocks(i, &ga, &gb);
    }
    cost
}

fn total_cost(factors: &[Factor], poses: &[Isometry3<f64>], mu: f64) -> f64 {
    factors.iter().fold(0.0, |acc, f| acc + f.cost(poses, mu))
}

/// Retracts every free variable by its block of `step` into `candidate`; returns the cost.
fn try_step(
    graph: &PoseGraph,
    system: &NormalEquations<6>,
    step: &[f64],
    candidate: &mut [Isometry3<f64>],
    mu: f64,
) -> f64 {
    candidate.copy_from_slice(&graph.poses);
    for (b, &v) in system.var_of.iter().enumerate() {
        let d = Vector6::from_column_slice(&step[6 * b..6 * b + 6]);
        candidate[v] = se3::retract(&graph.poses[v], &d);
    }
    total_cost(&graph.factors, candidate, mu)
}

/// One Levenberg–Marquardt (or Gauss–Newton) run at fixed μ; returns why it stopped.
///
/// With `chord_steps`, an iteration first tries the step computed from the previous
/// iteration's factor and the new gradient (a simplified Newton, or chord, step); only if it
/// fails to decrease the cost is the Hessian refactored. Near the optimum the chord step is
/// almost as good as a full one and costs a triangular solve instead of a factorisation.
fn levenberg_marquardt(
    graph: &mut PoseGraph,
    system: &mut NormalEquations<6>,
    config: &SolverConfig,
    mu: f64,
    state: &mut RunState,
) -> Result<Termination, GraphError> {
    let gauss_newton = config.algorithm == Algorithm::GaussNewton;
    let mut lambda = config.lambda_initial;
    let mut step = vec![0.0; system.dim()];
    let mut candidate = graph.poses.clone();
    let mut chords_left = 0;
    let mut last_decrease = f64::INFINITY;
    for _ in 0..config.max_iterations {
        // A chord step needs only the new gradient; the Hessian is assembled when a
        // factorisation follows.
        let chord_possible =
            chords_left > 0 && system.has_factor() && last_decrease < config.chord_regime;
        let t = Instant::now();
        let cost = if chord_possible {
            linearize_gradient(&graph.factors, &graph.poses, system, mu)
        } else {
            linearize(&graph.factors, &graph.poses, system, mu)
        };
        state.profile.linearize_ms += ms_since(t);
        if cost <= 0.0 {
            return Ok(Termination::ZeroCost);
        }
        let grad_max = system.gradient.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        if grad_max <= config.gradient_tolerance {
            return Ok(Termination::SmallGradient);
        }
        state.iterations += 1;
        let mut rejected = 0;
        let mut chord = false;
        let mut new_cost = f64::NAN;
        if chord_possible {
            chords_left -= 1;
            let t = Instant::now();
            let ok = system.solve(&mut step);
            state.profile.solve_ms += ms_since(t);
            if ok {
                let t = Instant::now();
                let c = try_step(graph, system, &step, &mut candidate, mu);
                state.profile.cost_ms += ms_since(t);
                if c.is_finite() && c <= cost {
                    chord = true;
                    new_cost = c;
                }
            }
        }
        if !chord {
            if chord_possible {
                // The chord step failed: assemble the Hessian at this estimate.
                let t = Instant::now();
                linearize(&graph.factors, &graph.poses, system, mu);
                state.profile.linearize_ms += ms_since(t);
            }
            new_cost = loop {
                let lam = if gauss_newton { 0.0 } else { lambda };
                let damping = config.damping;
                let t = Instant::now();
                let damp = |_, h: f64| match damping {
                    Damping::Identity => lam,
                    Damping::Diagonal => lam * h.clamp(1e-6, 1e32),
                };
                let single = last_decrease > config.single_precision_regime;
                let mut ok = single && system.factorize_damped_in(Precision::Single, damp);
                if ok {
                    state.single_precision_factorizations += 1;
                } else {
                    ok = system.factorize_damped(damp);
                }
                state.profile.factorize_ms += ms_since(t);
                let t = Instant::now();
                let near = last_decrease < config.chord_regime;
                let ok = ok && system.solve_refined(&mut step, near);
                state.profile.solve_ms += ms_since(t);
                if !ok && gauss_newton {
                    return Ok(Termination::Singular);
                }
                if ok {
                    let t = Instant::now();
                    let c = try_step(graph, system, &step, &mut candidate, mu);
                    state.profile.cost_ms += ms_since(t);
                    if gauss_newton || (c.is_finite() && c <= cost) {
                        break c;
                    }
                }
                rejected += 1;
                lambda *= config.lambda_factor;
                if lambda > config.lambda_max {
                    return Ok(Termination::LambdaLimit);
                }
            };
            state.factorizations += 1 + rejected;
            chords_left = config.chord_steps;
        }
        std::mem::swap(&mut graph.poses, &mut candidate);
        let step_max = step.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        if config.log_iterations {
            state.log.push(IterationLog {
                iteration: state.iterations,
                cost_before: cost,
                cost_after: new_cost,
                lambda: if gauss_newton { 0.0 } else { lambda },
                step_max,
                rejected_steps: rejected,
                chord,
                mu,
                time_ms: ms_since(state.start),
            });
        }
        if !chord {
            lambda = (lambda / config.lambda_factor).max(config.lambda_min);
        }
        let decrease = cost - new_cost;
        last_decrease = decrease / cost;
        if new_cost <= 0.0 {
            return Ok(Termination::ZeroCost);
        }
        if step_max <= config.step_tolerance {
            return Ok(Termination::SmallStep);
        }
        if decrease <= config.relative_tolerance * cost {
            return Ok(Termination::RelativeDecrease);
        }
        if decrease <= config.absolute_tolerance {
            return Ok(Termination::AbsoluteDecrease);
        }
    }
    Ok(Termination::MaxIterations)
}
