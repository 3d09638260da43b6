//! Levenberg–Marquardt and Gauss–Newton on the Lie group, with graduated non-convexity.
//!
//! Each iteration linearises every factor at the current estimate, assembles the sparse
//! normal equations `(H + λD) δ = −g` into the structure analysed once by
//! [`NormalEquations`], refactors numerically, and retracts `X ← X · Exp(δ)` on every free
//! variable. The step is accepted if the cost does not increase (λ shrinks), otherwise λ
//! grows and the step is recomputed — GTSAM's policy, with its default parameters, so that
//! iteration counts compare. Robust kernels enter by iteratively reweighted least squares.

use super::components;
use super::factors::Factor;
use super::initialize;
use super::pose_graph::{PoseGraph, StructureCache};
use super::se3;
use super::structure::{NormalEquations, Precision};
use super::GraphError;
use nalgebra::{Isometry3, Vector6};
use std::time::Instant;

mod config;

pub use config::{
    Algorithm, Damping, GncConfig, Initialization, IterationLog, OptimizationReport, Profile,
    SolverConfig, Termination,
};

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
pub(crate) fn take_analysis(
    graph: &mut PoseGraph,
) -> Result<(StructureCache, Option<f64>), GraphError> {
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
    let mut run = LmRun {
        step: vec![0.0; system.dim()],
        candidate: graph.poses.clone(),
        graph,
        system,
        config,
        mu,
        state,
        lambda: config.lambda_initial,
        last_decrease: f64::INFINITY,
    };
    let mut chords_left = 0;
    // Absolute decrease of the previous accepted step (none yet).
    let mut previous_decrease = None;
    for _ in 0..config.max_iterations {
        // A chord step needs only the new gradient; the Hessian is assembled when a
        // factorisation follows.
        let chord_possible =
            chords_left > 0 && run.system.has_factor() && run.last_decrease < config.chord_regime;
        let cost = run.linearize(!chord_possible);
        if cost <= 0.0 {
            return Ok(Termination::ZeroCost);
        }
        let grad_max = run
            .system
            .gradient
            .iter()
            .fold(0.0f64, |m, g| m.max(g.abs()));
        if grad_max <= config.gradient_tolerance {
            return Ok(Termination::SmallGradient);
        }
        run.state.iterations += 1;
        let mut outcome = StepOutcome::Failed;
        if chord_possible {
            chords_left -= 1;
            outcome = run.chord_step(cost);
        }
        let chord = matches!(outcome, StepOutcome::Accepted { .. });
        if matches!(outcome, StepOutcome::Failed) {
            if chord_possible {
                // The chord step failed: assemble the Hessian at this estimate.
                run.linearize(true);
            }
            outcome = run.damped_step(cost);
            chords_left = config.chord_steps;
        }
        let (new_cost, stop_now, rejected, model) = match outcome {
            StepOutcome::Accepted {
                cost,
                stop,
                rejected,
                model,
            } => (cost, stop, rejected, model),
            StepOutcome::Stop(t) => return Ok(t),
            StepOutcome::Failed => return Ok(Termination::LambdaLimit),
        };
        let step_max = run.accept(cost, new_cost, rejected, chord);
        if let Some(t) = stop_now {
            return Ok(t);
        }
        let decreases = (cost - new_cost, previous_decrease);
        if let Some(t) = stop_after_step(cost, new_cost, decreases, step_max, &model, config) {
            return Ok(t);
        }
        previous_decrease = Some(cost - new_cost);
    }
    Ok(Termination::MaxIterations)
}

/// How an iteration's step attempt ended.
enum StepOutcome {
    /// A step lowered (or kept) the cost; `stop` is set when the test before it found the
    /// run converged (the step is taken anyway: it is already computed and lowers the cost).
    Accepted {
        cost: f64,
        stop: Option<Termination>,
        rejected: usize,
        model: StepModel,
    },
    /// No step was accepted, and the run ends.
    Stop(Termination),
    /// No step was accepted (a chord step that did not lower the cost).
    Failed,
}

/// The state of one Levenberg–Marquardt run.
struct LmRun<'a> {
    graph: &'a mut PoseGraph,
    system: &'a mut NormalEquations<6>,
    config: &'a SolverConfig,
    mu: f64,
    state: &'a mut RunState,
    step: Vec<f64>,
    candidate: Vec<Isometry3<f64>>,
    lambda: f64,
    /// Relative decrease of the last accepted step.
    last_decrease: f64,
}

impl LmRun<'_> {
    /// Cost at the estimate, with the normal equations (`full`) or the gradient alone.
    fn linearize(&mut self, full: bool) -> f64 {
        let t = Instant::now();
        let (factors, poses) = (&self.graph.factors, &self.graph.poses);
        let cost = if full {
            linearize(factors, poses, self.system, self.mu)
        } else {
            linearize_gradient(factors, poses, self.system, self.mu)
        };
        self.state.profile.linearize_ms += ms_since(t);
        cost
    }

    /// Cost at `estimate · Exp(step)` (into the candidate).
    fn try_current_step(&mut self) -> f64 {
        let t = Instant::now();
        let c = try_step(
            self.graph,
            self.system,
            &self.step,
            &mut self.candidate,
            self.mu,
        );
        self.state.profile.cost_ms += ms_since(t);
        c
    }

    /// A chord step: the last factor with the new gradient.
    fn chord_step(&mut self, cost: f64) -> StepOutcome {
        let t = Instant::now();
        let ok = self.system.solve(&mut self.step);
        self.state.profile.solve_ms += ms_since(t);
        if !ok {
            return StepOutcome::Failed;
        }
        let model = StepModel::of(self.system, &self.step);
        let stop = model
            .converged(cost, self.config)
            .then_some(Termination::SmallDecrement);
        let c = self.try_current_step();
        if c.is_finite() && c <= cost {
            return StepOutcome::Accepted {
                cost: c,
                stop,
                rejected: 0,
                model,
            };
        }
        stop.map_or(StepOutcome::Failed, StepOutcome::Stop)
    }

    /// Factorise `H + λD` and step, raising λ until the cost does not increase.
    fn damped_step(&mut self, cost: f64) -> StepOutcome {
        let gauss_newton = self.config.algorithm == Algorithm::GaussNewton;
        let mut rejected = 0;
        loop {
            let ok = self.factorize_and_solve(if gauss_newton { 0.0 } else { self.lambda });
            if !ok && gauss_newton {
                return StepOutcome::Stop(Termination::Singular);
            }
            let model = StepModel::of(self.system, &self.step);
            let stop = if ok {
                stop_before_step(&model, &self.step, cost, self.config)
            } else {
                None
            };
            if ok {
                let c = self.try_current_step();
                if gauss_newton || (c.is_finite() && c <= cost) {
                    self.state.factorizations += 1 + rejected;
                    return StepOutcome::Accepted {
                        cost: c,
                        stop,
                        rejected,
                        model,
                    };
                }
            }
            rejected += 1;
            if let Some(t) = stop {
                self.state.factorizations += rejected;
                return StepOutcome::Stop(t);
            }
            self.lambda *= self.config.lambda_factor;
            if self.lambda > self.config.lambda_max {
                self.state.factorizations += rejected;
                return StepOutcome::Stop(Termination::LambdaLimit);
            }
        }
    }

    /// Factorises `H + D(λ)` (in single precision while far from the optimum) and solves
    /// for the step; false when either fails.
    fn factorize_and_solve(&mut self, lam: f64) -> bool {
        let damping = self.config.damping;
        let t = Instant::now();
        let damp = |_, h: f64| match damping {
            Damping::Identity => lam,
            Damping::Diagonal => lam * h.clamp(1e-6, 1e32),
        };
        let single = self.last_decrease > self.config.single_precision_regime
            && self.system.single_precision_pays();
        let mut ok = single && self.system.factorize_damped_in(Precision::Single, damp);
        if ok {
            self.state.single_precision_factorizations += 1;
        } else {
            ok = self.system.factorize_damped(damp);
        }
        self.state.profile.factorize_ms += ms_since(t);
        let t = Instant::now();
        let near = self.last_decrease < self.config.chord_regime;
        let ok = ok && self.system.solve_refined(&mut self.step, near);
        self.state.profile.solve_ms += ms_since(t);
        ok
    }

    /// Moves the estimate to the candidate, logs the iteration and updates λ; returns the
    /// largest step entry.
    fn accept(&mut self, cost: f64, new_cost: f64, rejected: usize, chord: bool) -> f64 {
        let gauss_newton = self.config.algorithm == Algorithm::GaussNewton;
        std::mem::swap(&mut self.graph.poses, &mut self.candidate);
        let step_max = self.step.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        if self.config.log_iterations {
            self.state.log.push(IterationLog {
                iteration: self.state.iterations,
                cost_before: cost,
                cost_after: new_cost,
                lambda: if gauss_newton { 0.0 } else { self.lambda },
                step_max,
                rejected_steps: rejected,
                chord,
                mu: self.mu,
                time_ms: ms_since(self.state.start),
            });
        }
        if !chord {
            self.lambda = (self.lambda / self.config.lambda_factor).max(self.config.lambda_min);
        }
        self.last_decrease = (cost - new_cost) / cost;
        step_max
    }
}

/// What the quadratic model says about a step `δ` solving `(H + D) δ = −g`.
#[derive(Clone, Copy, Debug, Default)]
struct StepModel {
    /// `−gᵀδ = δᵀ(H + D)δ`.
    slope: f64,
    /// `δᵀDδ`, the damping's part of it.
    damping: f64,
}

impl StepModel {
    fn of(system: &NormalEquations<6>, step: &[f64]) -> Self {
        let slope = -system
            .gradient
            .iter()
            .zip(step)
            .map(|(g, d)| g * d)
            .sum::<f64>();
        Self {
            slope,
            damping: system.damping_form(step),
        }
    }

    /// Decrease predicted by the undamped model along `δ`:
    /// `−gᵀδ − ½δᵀHδ = ½(−gᵀδ + δᵀDδ)`; without damping, the Newton decrement `½gᵀH⁻¹g`.
    fn predicted(&self) -> f64 {
        0.5 * (self.slope + self.damping)
    }

    /// True when the damping made most of the step's model (`δᵀDδ > ½ δᵀ(H + D)δ`): the
    /// step was shortened by λ, so neither its size nor its decrease measures convergence.
    fn damping_dominated(&self) -> bool {
        self.damping > 0.5 * self.slope
    }

    /// The Newton-decrement test ([`SolverConfig::decrement_tolerance`]).
    fn converged(&self, cost: f64, config: &SolverConfig) -> bool {
        !self.damping_dominated()
            && self.predicted().is_finite()
            && self.predicted() <= config.decrement_tolerance * cost
    }
}

/// The stopping rule before a freshly factorised step is tried (the step is still taken if
/// it lowers the cost): the Newton decrement is below `decrement_tolerance` of the cost, or
/// the step (shrunk by a growing λ after rejections, which happens only where rounding keeps
/// the cost from decreasing) is below `step_tolerance`.
fn stop_before_step(
    model: &StepModel,
    step: &[f64],
    cost: f64,
    config: &SolverConfig,
) -> Option<Termination> {
    if model.converged(cost, config) {
        return Some(Termination::SmallDecrement);
    }
    let step_max = step.iter().fold(0.0f64, |m, s| m.max(s.abs()));
    (step_max <= config.step_tolerance).then_some(Termination::SmallStep)
}

/// Decrease still to come if the decreases keep shrinking by their last ratio
/// `ρ = d / d_prev`: `d ρ / (1 − ρ)`; `d` itself without a previous step, infinite when
/// they do not shrink.
fn extrapolated_decrease(decrease: f64, previous: Option<f64>) -> f64 {
    match previous {
        None => decrease,
        Some(p) if decrease < p => {
            let rho = decrease / p;
            decrease * rho / (1.0 - rho)
        }
        Some(_) => f64::INFINITY,
    }
}

/// The stopping rule after an accepted step from `cost` to `new_cost` (`decreases`: this
/// step's and the previous step's): zero cost, a small step, a small relative decrease
/// that the damping did not cause and after which little is left to come (a linearly
/// converging run, as on large-residual graphs, stops only once the extrapolated remainder
/// is below `extrapolated_tolerance`), or (if configured) a small absolute decrease.
fn stop_after_step(
    cost: f64,
    new_cost: f64,
    decreases: (f64, Option<f64>),
    step_max: f64,
    model: &StepModel,
    config: &SolverConfig,
) -> Option<Termination> {
    let (decrease, previous) = decreases;
    let small = decrease <= config.relative_tolerance * cost
        && extrapolated_decrease(decrease, previous) <= config.extrapolated_tolerance * cost;
    if new_cost <= 0.0 {
        Some(Termination::ZeroCost)
    } else if step_max <= config.step_tolerance {
        Some(Termination::SmallStep)
    } else if small && !model.damping_dominated() {
        Some(Termination::RelativeDecrease)
    } else if decrease <= config.absolute_tolerance {
        Some(Termination::AbsoluteDecrease)
    } else {
        None
    }
}
