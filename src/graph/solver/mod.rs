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
