//! Parameters and reports of the nonlinear solver: what to run ([`SolverConfig`], with
//! GTSAM's defaults) and what it did ([`OptimizationReport`]).

use crate::graph::components::ComponentInfo;
use crate::graph::GraphError;
use serde::{Deserialize, Serialize};

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
/// [`RobustKernel::Gnc`]: crate::graph::robust::RobustKernel::Gnc
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
    /// Stop when an accepted step decreased the cost by at most this fraction of it
    /// (GTSAM's `relativeErrorTol`), unless the damping made most of the step's model
    /// decrease (a step shortened by a large λ says nothing about convergence; λ shrinks
    /// after it and the next step tells).
    pub relative_tolerance: f64,
    /// ... and only once the decrease still to come, extrapolated geometrically from the
    /// last two decreases (`d ρ / (1 − ρ)`, `ρ = d / d_prev`), is at most this fraction of the
    /// cost. Near an optimum Gauss–Newton converges quadratically on small-residual graphs
    /// (ρ tiny: no extra iteration) but only linearly on large-residual ones, where a
    /// decrease of 1e-5 can leave more than 1e-6 of the cost to go.
    pub extrapolated_tolerance: f64,
    /// Stop when an accepted step decreased the cost by at most this amount. Depends on the
    /// cost's scale (a graph whose optimum cost is below 1 would stop far from it with
    /// GTSAM's 1e-5), so it is off (0) by default: `relative_tolerance` and
    /// `decrement_tolerance` make the stopping rule scale-free.
    pub absolute_tolerance: f64,
    /// Stop before a step when the decrease predicted by the Gauss–Newton model,
    /// `½ gᵀH⁻¹g` (the gradient's squared norm in the inverse Hessian's metric, the
    /// Newton decrement), is at most this fraction of the cost: near a local optimum the
    /// cost is then within about this fraction of it. Scale-free, and it ends runs whose
    /// last steps can no longer lower the cost in floating point.
    pub decrement_tolerance: f64,
    /// Stop before iterating when the largest gradient entry is at most this (absolute;
    /// 0 = off).
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
    /// the optimum reached is the same. `inf` turns single precision off; it is not used
    /// either for factors under 100,000 non-zeros, which stay in the cache (it gains nothing
    /// there and its solves cost two).
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
            extrapolated_tolerance: 1e-7,
            absolute_tolerance: 0.0,
            decrement_tolerance: 1e-10,
            gradient_tolerance: 0.0,
            step_tolerance: 1e-12,
            lambda_initial: 1e-5,
            lambda_factor: 10.0,
            lambda_max: 1e5,
            lambda_min: 0.0,
            damping: Damping::Identity,
            initialization: Initialization::None,
            chord_steps: 1,
            chord_regime: 1e-2,
            single_precision_regime: 1e-2,
            gnc: GncConfig::default(),
            log_iterations: true,
        }
    }
}

impl SolverConfig {
    /// Checks that every parameter is in its range.
    pub(crate) fn validate(&self) -> Result<(), GraphError> {
        let bad = |what: &str| Err(GraphError::InvalidConfig(what.to_string()));
        let nonneg = |v: f64| v.is_finite() && v >= 0.0;
        if !nonneg(self.relative_tolerance)
            || !nonneg(self.absolute_tolerance)
            || !nonneg(self.decrement_tolerance)
            || !nonneg(self.extrapolated_tolerance)
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
    /// The Newton decrement was below `decrement_tolerance` times the cost (converged).
    SmallDecrement,
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
                | Termination::SmallDecrement
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
