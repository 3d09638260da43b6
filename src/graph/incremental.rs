//! Incremental use: add poses and factors as the rover drives and re-optimise warm-started.
//!
//! [`IncrementalGraph`] wraps a [`PoseGraph`]. New poses start at the composition of the
//! previous estimate with the odometry. An update first checks whether the factors added
//! since the last converged optimisation pull on the estimate at all: a new pose tied by
//! one odometry factor and initialised by it has a zero residual, so the old optimum extended
//! by that pose *is* the new optimum (the old factors' gradient was zero and the new one
//! adds none) and nothing needs solving. Otherwise — a loop closure, a relocalization, a
//! second constraint on a new pose — the estimate moves to the optimum of the graph with the
//! factors among settled variables kept linearised at the last linearisation point and the
//! factors of a window of recent variables evaluated exactly (see `linear_model`): a sparse
//! problem over the window and the settled variables it touches, forward solves along those
//! variables' elimination paths and one backward solve, a few milliseconds on a 5,000-pose
//! graph. When that moves a settled variable more than `relinearize_threshold` from its
//! linearisation point, or the window or its boundary grows past its limit, the model is
//! built again at the new estimate (the last `window_variables` free variables live) and the
//! update repeated on it (while the settled variables still move that far); that model
//! serves the next updates. A batch re-optimisation of the whole graph (warm started) runs
//! when there is no model yet, or when a rebuilt model's update does not lower the cost.

use super::linear_model::{LinearModel, ModelUpdate, UpdateLimits};
use super::robust::RobustKernel;
use super::solver::{OptimizationReport, SolverConfig};
use super::{GraphError, PoseGraph};
use nalgebra::{Isometry3, Matrix6};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Parameters of incremental re-optimisation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct IncrementalConfig {
    /// Solver parameters for each full re-optimisation.
    pub solver: SolverConfig,
    /// New factors whose gradient entries (`Jᵀ W r`) are all at most this leave the
    /// optimum unchanged, so the update skips solving.
    pub skip_gradient_tolerance: f64,
    /// Update on the last batch linearisation instead of re-optimising the whole graph.
    pub incremental: bool,
    /// Free variables (the most recent, in insertion order) whose factors are evaluated
    /// exactly on every update, at least; the factors among the others are kept linearised.
    /// A build extends the window back (leaving room for this many appends) to where the
    /// fewest of its factors reach into the settled part.
    pub window_variables: usize,
    /// Gauss–Newton iterations on the window per update at most. One, as iSAM2 takes one
    /// step per update: the next update continues from where this one stopped, and the
    /// window's step is already nearly exact when the new factors are consistent with it.
    pub window_iterations: usize,
    /// Build the model again once the window, grown by appended poses, holds more free
    /// variables than this.
    pub max_window_variables: usize,
    /// Build the model again once more settled variables than this are touched by factors
    /// of the window: their marginal is a dense matrix.
    pub max_boundary_variables: usize,
    /// Build the model again once a settled variable's step from its linearisation point
    /// exceeds this in any tangent entry (radians or metres; iSAM2's default is 0.1).
    pub relinearize_threshold: f64,
}

/// How an update brought the estimate to the optimum.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UpdateMethod {
    /// The new factors leave the optimum unchanged; nothing was solved.
    Skipped,
    /// Window solved exactly on the last model, the settled variables moved on its
    /// linearisation.
    Incremental,
    /// Model built again at the incremental estimate (no full re-optimisation) and the
    /// update repeated on it, when settled variables had moved more than
    /// `relinearize_threshold` from the last linearisation point or the window or its
    /// boundary had outgrown its limit.
    Relinearized,
    /// Whole graph re-optimised.
    Batch,
}

impl Default for IncrementalConfig {
    fn default() -> Self {
        Self {
            solver: SolverConfig {
                max_iterations: 10,
                log_iterations: false,
                ..SolverConfig::default()
            },
            skip_gradient_tolerance: 1e-9,
            incremental: true,
            window_variables: 100,
            max_window_variables: 500,
            window_iterations: 1,
            max_boundary_variables: 40,
            relinearize_threshold: 0.1,
        }
    }
}

/// What one [`IncrementalGraph::update`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IncrementalReport {
    /// True when the graph was re-optimised; false when the new factors left the optimum
    /// unchanged.
    pub optimized: bool,
    /// How the update was done.
    pub method: UpdateMethod,
    /// Variables solved exactly in the last model update (window and boundary; 0 when none
    /// was made).
    pub active_variables: usize,
    /// Largest step entry of a settled variable from its linearisation point in the last
    /// model update (0 when none was made).
    pub old_step_max: f64,
    /// Factors added since the previous update.
    pub new_factors: usize,
    /// Cost after the update; after an incremental update, the cost with the old factors
    /// to second order around their linearisation point.
    pub cost: f64,
    /// Wall time of the update.
    pub time_ms: f64,
    /// The optimisation report when the graph was re-optimised.
    pub report: Option<OptimizationReport>,
}

/// A pose graph grown online and re-optimised after each batch of additions.
#[derive(Default)]
pub struct IncrementalGraph {
    graph: PoseGraph,
    config: IncrementalConfig,
    /// Factors `[0, settled)` were part of the last converged optimisation.
    settled: usize,
    /// Cost of the settled factors at the current estimate.
    settled_cost: f64,
    converged: bool,
    /// Linearisation of the settled variables, when incremental updates are on.
    model: Option<LinearModel>,
}

impl std::fmt::Debug for IncrementalGraph {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IncrementalGraph")
            .field("graph", &self.graph)
            .field("settled", &self.settled)
            .field("converged", &self.converged)
            .field("linearised", &self.model.is_some())
            .finish()
    }
}

impl IncrementalGraph {
    /// Wraps an existing graph; its estimates are the warm start, and the first update
    /// optimises it fully.
    pub fn new(graph: PoseGraph, config: IncrementalConfig) -> Self {
        Self {
            graph,
            config,
            settled: 0,
            settled_cost: 0.0,
            converged: false,
            model: None,
        }
    }

    /// The underlying graph.
    pub fn graph(&self) -> &PoseGraph {
        &self.graph
    }

    /// Mutable access to the underlying graph, e.g. to add relocalization factors. Changing
    /// existing estimates or kernels through it requires [`IncrementalGraph::invalidate`].
    pub fn graph_mut(&mut self) -> &mut PoseGraph {
        &mut self.graph
    }

    /// Forces the next update to re-optimise the whole graph.
    pub fn invalidate(&mut self) {
        self.converged = false;
        self.model = None;
    }

    /// Gives the graph back.
    pub fn into_graph(self) -> PoseGraph {
        self.graph
    }

    /// Adds pose `new_id` reached from pose `from` by the odometry `from_T_new`, initialised
    /// at `X_from · from_T_new`, and the between factor. Returns the factor index.
    pub fn add_odometry(
        &mut self,
        from: u64,
        new_id: u64,
        from_t_new: Isometry3<f64>,
        information: Matrix6<f64>,
    ) -> Result<usize, GraphError> {
        let base = self
            .graph
            .pose(from)
            .ok_or(GraphError::UnknownVariable(from.into()))?;
        self.graph.add_pose(new_id, base * from_t_new)?;
        self.graph
            .add_between(from, new_id, from_t_new, information, RobustKernel::None)
    }

    /// Brings the estimate to the optimum of all factors added so far.
    pub fn update(&mut self) -> Result<IncrementalReport, GraphError> {
        let start = Instant::now();
        let factors = self.graph.factors();
        let new_factors = factors.len().saturating_sub(self.settled);
        let mut attempt = None;
        if self.converged && self.settled <= factors.len() {
            let poses = &self.graph.poses;
            let mut new_cost = 0.0;
            let mut pulls = false;
            for f in &factors[self.settled..] {
                let lin = f.linearize(poses);
                let s = f.mahalanobis2(&lin.residual);
                new_cost += f.cost(poses, 0.0);
                let wr = f.information() * lin.residual * f.kernel().weight(s, 0.0);
                let ga = lin.jac_a.transpose() * wr;
                let gb = lin.jac_b.transpose() * wr;
                if ga.amax().max(gb.amax()) > self.config.skip_gradient_tolerance {
                    pulls = true;
                    break;
                }
            }
            if !pulls {
                self.settled = factors.len();
                self.settled_cost += new_cost;
                return Ok(IncrementalReport {
                    optimized: false,
                    method: UpdateMethod::Skipped,
                    active_variables: 0,
                    old_step_max: 0.0,
                    new_factors,
                    cost: self.settled_cost,
                    time_ms: start.elapsed().as_secs_f64() * 1e3,
                    report: None,
                });
            }
            let limits = self.limits();
            if let (true, Some(model)) = (self.config.incremental, self.model.as_mut()) {
                attempt = model.update(&mut self.graph, limits);
                if let Some(u) = attempt {
                    if u.old_step_max <= self.config.relinearize_threshold {
                        self.settled = self.graph.num_factors();
                        self.settled_cost = u.cost;
                        return Ok(IncrementalReport {
                            optimized: true,
                            method: UpdateMethod::Incremental,
                            active_variables: u.active,
                            old_step_max: u.old_step_max,
                            new_factors,
                            cost: u.cost,
                            time_ms: start.elapsed().as_secs_f64() * 1e3,
                            report: None,
                        });
                    }
                }
            }
        }
        let old_step_max = attempt.map_or(0.0, |u| u.old_step_max);
        if self.model.is_some() && self.config.incremental {
            // Settled variables moved too far from the linearisation point, or the window
            // outgrew its limits: build the model again at the current estimate.
            if let Some(u) = self.relinearize() {
                self.settled = self.graph.num_factors();
                self.settled_cost = u.cost;
                return Ok(IncrementalReport {
                    optimized: true,
                    method: UpdateMethod::Relinearized,
                    active_variables: u.active,
                    old_step_max,
                    new_factors,
                    cost: u.cost,
                    time_ms: start.elapsed().as_secs_f64() * 1e3,
                    report: None,
                });
            }
        }
        self.model = None;
        let report = self.graph.optimize(&self.config.solver)?;
        self.converged = report.converged;
        self.settled = self.graph.num_factors();
        self.settled_cost = report.final_cost;
        if self.config.incremental && report.converged {
            self.model = LinearModel::build(
                &self.graph,
                self.config.window_variables,
                self.config.max_window_variables,
            );
        }
        Ok(IncrementalReport {
            optimized: true,
            method: UpdateMethod::Batch,
            active_variables: attempt.map_or(0, |u| u.active),
            old_step_max,
            new_factors,
            cost: report.final_cost,
            time_ms: start.elapsed().as_secs_f64() * 1e3,
            report: Some(report),
        })
    }
}

impl IncrementalGraph {
    fn limits(&self) -> UpdateLimits {
        UpdateLimits {
            max_boundary: self.config.max_boundary_variables,
            max_window: self.config.max_window_variables,
            iterations: self.config.window_iterations,
        }
    }

    /// Builds the model again at the current estimate and updates on it, repeating while the
    /// update moves a settled variable more than the relinearisation threshold (at most
    /// [`RELINEARIZE_STEPS`] builds). Returns the update with the graph's true cost, or
    /// `None` (no model, estimates unchanged) when a build or update fails or the cost does
    /// not go down.
    fn relinearize(&mut self) -> Option<ModelUpdate> {
        self.model = None;
        let start = self.graph.poses.clone();
        let cost_start = self.graph.cost();
        let limits = self.limits();
        for _ in 0..RELINEARIZE_STEPS {
            let built = LinearModel::build(
                &self.graph,
                self.config.window_variables,
                self.config.max_window_variables,
            );
            let Some(mut model) = built else { break };
            let Some(mut u) = model.update(&mut self.graph, limits) else {
                break;
            };
            u.cost = self.graph.cost();
            if !(u.cost.is_finite() && u.cost <= cost_start * (1.0 + COST_RISE_TOLERANCE)) {
                break;
            }
            if u.old_step_max <= self.config.relinearize_threshold {
                self.model = Some(model);
                return Some(u);
            }
        }
        self.graph.poses = start;
        None
    }
}

/// Model builds a relinearisation may take before it leaves the work to a batch.
const RELINEARIZE_STEPS: usize = 3;

/// Relative rise of the cost a rebuild may bring: near the optimum, settled poses slide
/// along nearly flat directions of the cost, and a rise of round-off size is no failure.
const COST_RISE_TOLERANCE: f64 = 1e-6;

#[cfg(test)]
#[path = "incremental_tests.rs"]
mod tests;
