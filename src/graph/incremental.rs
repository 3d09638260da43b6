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
mod tests {
    //! Tests of the incremental graph: skipped updates, window updates against the batch
    //! optimum, rebuilds, unanchored components.

    use super::*;
    use crate::graph::file::BuildOptions;
    use crate::graph::synthetic::{self, SyntheticConfig};

    /// Pose 0 fixed and four unit steps along x (identity information), not yet solved.
    fn unit_chain(config: IncrementalConfig) -> IncrementalGraph {
        let mut g = PoseGraph::new();
        g.add_pose(0, Isometry3::identity()).unwrap();
        g.fix(0).unwrap();
        let mut inc = IncrementalGraph::new(g, config);
        let z = Isometry3::translation(1.0, 0.0, 0.0);
        for id in 1..5 {
            inc.add_odometry(id - 1, id, z, Matrix6::identity())
                .unwrap();
        }
        inc
    }

    /// A loop closure 0 → 4 of 3.5 m on [`unit_chain`]: the optimum puts pose 4 at 3.6 m.
    fn close_unit_chain(inc: &mut IncrementalGraph) {
        inc.graph_mut()
            .add_between(
                0,
                4,
                Isometry3::translation(3.5, 0.0, 0.0),
                Matrix6::identity(),
                RobustKernel::None,
            )
            .unwrap();
    }

    /// A synthetic graph of `poses` poses and `loop_closures` closures, and the pose graph
    /// of its first `keep` poses (the rest is appended by the test).
    fn truncated_synthetic(
        poses: usize,
        loop_closures: usize,
        keep: u64,
    ) -> (synthetic::SyntheticGraph, PoseGraph) {
        let synth = synthetic::generate(&SyntheticConfig {
            poses,
            loop_closures,
            ..SyntheticConfig::default()
        });
        let mut base = synth.file.clone();
        base.vertices.retain(|v| v.id < keep);
        base.edges.retain(|e| e.from < keep && e.to < keep);
        let graph = base.to_pose_graph(&BuildOptions::default()).unwrap();
        (synth, graph)
    }

    /// A copy of `inc`'s graph optimised to tight convergence, and its relative cost gap.
    fn batch_gap(inc: &IncrementalGraph) -> (PoseGraph, f64) {
        let mut full = inc.graph().clone();
        let batch = full
            .optimize(&SolverConfig {
                relative_tolerance: 1e-12,
                absolute_tolerance: 0.0,
                ..SolverConfig::default()
            })
            .unwrap();
        let gap = (inc.graph().cost() - batch.final_cost) / batch.final_cost;
        (full, gap)
    }

    /// Appends pose `to` by the synthetic graph's odometry edge `to − 1 → to`; returns the
    /// edge's information.
    fn append_synthetic_odometry(
        inc: &mut IncrementalGraph,
        synth: &synthetic::SyntheticGraph,
        to: u64,
    ) -> Matrix6<f64> {
        let e = synth.odometry()[(to - 1) as usize];
        inc.add_odometry(e.from, e.to, e.measured, e.information)
            .unwrap();
        e.information
    }

    #[test]
    fn odometry_appends_keep_the_optimum_without_solving() {
        let (_, graph) = truncated_synthetic(400, 30, 300);
        let mut inc = IncrementalGraph::new(graph, IncrementalConfig::default());
        assert!(inc.update().unwrap().optimized);
        let info = Matrix6::identity() * 100.0;
        let z = Isometry3::translation(1.0, 0.0, 0.0);
        for id in 300..310 {
            inc.add_odometry(id - 1, id, z, info).unwrap();
            let r = inc.update().unwrap();
            assert!(!r.optimized);
            assert_eq!(r.new_factors, 1);
        }
        // The skipped updates agree with a full optimisation.
        let cost = inc.update().unwrap().cost;
        let mut full = inc.into_graph();
        let report = full.optimize(&SolverConfig::default()).unwrap();
        assert!((report.initial_cost - cost).abs() <= 1e-9 * cost.max(1.0));
        assert!((report.final_cost - cost).abs() <= 1e-6 * cost.max(1.0));
    }

    /// Loop closures appended one by one to a 600-pose graph: the incremental updates land
    /// on the batch optimum of the same graph within the linearisation error.
    #[test]
    fn incremental_loop_closures_match_the_batch_optimum() {
        let (synth, graph) = truncated_synthetic(700, 40, 600);
        let mut inc = IncrementalGraph::new(graph, IncrementalConfig::default());
        assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
        let odometry = synth.odometry();
        let mut incremental = 0;
        for id in 600u64..615 {
            let e = odometry[(id - 1) as usize];
            inc.add_odometry(e.from, e.to, e.measured, e.information)
                .unwrap();
            let back = id - 45;
            let z = synth.truth[back as usize].inv_mul(&synth.truth[id as usize]);
            inc.graph_mut()
                .add_between(back, id, z, e.information, RobustKernel::None)
                .unwrap();
            let r = inc.update().unwrap();
            if r.method == UpdateMethod::Incremental {
                incremental += 1;
            }
            let (full, gap) = batch_gap(&inc);
            let cost = inc.graph().cost();
            assert!((-1e-9..1e-4).contains(&gap), "update {id}: gap {gap:e}");
            // The model's cost estimate is close to the true cost.
            assert!((r.cost - cost).abs() < 1e-3 * cost, "{} vs {cost}", r.cost);
            // Positions: the linearisation error of the old factors shows as a small
            // rotation of weakly constrained parts of the graph (centimetres at 100 m).
            for v in 0..=id {
                let p = inc.graph().pose(v).unwrap().translation.vector;
                let q = full.pose(v).unwrap().translation.vector;
                assert!((p - q).norm() < 0.15, "pose {v}: {}", (p - q).norm());
            }
        }
        assert!(incremental >= 4, "only {incremental} incremental updates");
    }

    /// With a tight relinearisation threshold a loop closure reaching past the window is
    /// absorbed by building the model again at the incremental estimate (no batch), and
    /// lands on the batch optimum.
    #[test]
    fn far_incremental_estimates_are_relinearised_without_a_batch() {
        let (synth, graph) = truncated_synthetic(400, 30, 300);
        let config = IncrementalConfig {
            relinearize_threshold: 0.02,
            window_variables: 20,
            window_iterations: 3,
            ..IncrementalConfig::default()
        };
        let mut inc = IncrementalGraph::new(graph, config);
        assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
        let info = append_synthetic_odometry(&mut inc, &synth, 300);
        let z = synth.truth[250].inv_mul(&synth.truth[300]);
        inc.graph_mut()
            .add_between(250, 300, z, info, RobustKernel::None)
            .unwrap();
        let r = inc.update().unwrap();
        assert_eq!(r.method, UpdateMethod::Relinearized, "{r:?}");
        let (_, gap) = batch_gap(&inc);
        assert!((-1e-9..1e-6).contains(&gap), "gap {gap:e}");
        // The next update starts from the new linearisation.
        append_synthetic_odometry(&mut inc, &synth, 301);
        assert_eq!(inc.update().unwrap().method, UpdateMethod::Skipped);
    }

    /// A tiny chain where the incremental update must equal the exact optimum: with linear
    /// (translation-only) factors the quadratic model is exact, whether the closure lies in
    /// the window or reaches into the settled part.
    #[test]
    fn incremental_update_is_exact_on_a_linear_problem() {
        for window in [1, 2, 100] {
            let mut inc = unit_chain(IncrementalConfig {
                relinearize_threshold: 1.0,
                window_variables: window,
                ..IncrementalConfig::default()
            });
            assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
            close_unit_chain(&mut inc);
            let r = inc.update().unwrap();
            assert_eq!(r.method, UpdateMethod::Incremental, "window {window}");
            let x4 = inc.graph().pose(4).unwrap().translation.x;
            assert!((x4 - 3.6).abs() < 1e-9, "window {window}: {x4}");
            let x2 = inc.graph().pose(2).unwrap().translation.x;
            assert!((x2 - 1.8).abs() < 1e-9, "window {window}: {x2}");
            assert!((r.cost - inc.graph().cost()).abs() < 1e-12);
        }
    }

    /// Loop closures reaching past a small window into the settled part, and a window that
    /// outgrows its limit: the updates stay incremental (the model is built again when the
    /// window is full) and on the batch optimum.
    #[test]
    fn closures_into_the_settled_part_and_a_full_window() {
        let (synth, graph) = truncated_synthetic(500, 30, 400);
        let config = IncrementalConfig {
            window_variables: 10,
            max_window_variables: 14,
            ..IncrementalConfig::default()
        };
        let mut inc = IncrementalGraph::new(graph, config);
        assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
        let mut methods = Vec::new();
        for id in 400u64..412 {
            let info = append_synthetic_odometry(&mut inc, &synth, id);
            let back = id - 30;
            let z = synth.truth[back as usize].inv_mul(&synth.truth[id as usize]);
            inc.graph_mut()
                .add_between(back, id, z, info, RobustKernel::None)
                .unwrap();
            let r = inc.update().unwrap();
            methods.push(r.method);
            let (_, gap) = batch_gap(&inc);
            assert!((-1e-9..1e-4).contains(&gap), "update {id}: gap {gap:e}");
            assert!((r.cost - inc.graph().cost()).abs() < 1e-3 * r.cost);
        }
        assert!(!methods.contains(&UpdateMethod::Batch), "{methods:?}");
        assert!(methods.contains(&UpdateMethod::Relinearized), "{methods:?}");
        assert!(methods.contains(&UpdateMethod::Incremental), "{methods:?}");
    }

    /// A second, unanchored chain (a session before its first relocalization) is held by
    /// its first pose as in the batch, so updates on the anchored chain stay incremental;
    /// the factor that joins the chains makes the holding be decided again.
    #[test]
    fn an_unanchored_component_is_held_like_the_batch_holds_it() {
        let (synth, mut graph) = truncated_synthetic(400, 30, 300);
        let step = Isometry3::translation(1.0, 0.0, 0.0);
        let info = Matrix6::identity() * 100.0;
        graph
            .add_pose(10_000, Isometry3::translation(0.0, 50.0, 0.0))
            .unwrap();
        for id in 10_001..10_005u64 {
            let initial = graph.pose(id - 1).unwrap() * step;
            graph.add_pose(id, initial).unwrap();
            graph
                .add_between(id - 1, id, step, info, RobustKernel::None)
                .unwrap();
        }
        let mut inc = IncrementalGraph::new(graph, IncrementalConfig::default());
        assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
        let mut methods = Vec::new();
        for id in 300u64..310 {
            let info = append_synthetic_odometry(&mut inc, &synth, id);
            let z = synth.truth[id as usize - 50].inv_mul(&synth.truth[id as usize]);
            inc.graph_mut()
                .add_between(id - 50, id, z, info, RobustKernel::None)
                .unwrap();
            methods.push(inc.update().unwrap().method);
            let (_, gap) = batch_gap(&inc);
            assert!((-1e-9..1e-4).contains(&gap), "update {id}: gap {gap:e}");
        }
        // The first closure corrects a metre of drift (a rebuild); none needs a batch.
        assert!(!methods.contains(&UpdateMethod::Batch), "{methods:?}");
        assert!(methods.contains(&UpdateMethod::Incremental), "{methods:?}");
        // Join the chains: the second one is now anchored through the first.
        let to_b = Isometry3::translation(0.0, 10.0, 0.0);
        inc.graph_mut()
            .add_between(309, 10_000, to_b, info, RobustKernel::None)
            .unwrap();
        let r = inc.update().unwrap();
        assert_ne!(r.method, UpdateMethod::Incremental, "{r:?}");
        let (full, gap) = batch_gap(&inc);
        assert!((-1e-9..1e-6).contains(&gap), "gap {gap:e}");
        let b0 = inc.graph().pose(10_000).unwrap().translation.vector;
        assert!((b0 - full.pose(10_000).unwrap().translation.vector).norm() < 1e-3);
    }

    #[test]
    fn a_loop_closure_triggers_a_full_solve() {
        let mut inc = unit_chain(IncrementalConfig {
            incremental: false,
            ..IncrementalConfig::default()
        });
        assert!(inc.update().unwrap().optimized);
        close_unit_chain(&mut inc);
        let r = inc.update().unwrap();
        assert!(r.optimized);
        let x4 = inc.graph().pose(4).unwrap().translation.x;
        // Four unit steps against one 3.5 closure, equal weights: x4 = 3.6.
        assert!((x4 - 3.6).abs() < 1e-9, "{x4}");
    }
}
