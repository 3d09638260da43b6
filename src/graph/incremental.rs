//! Incremental use: add poses and factors as the rover drives and re-optimise warm-started.
//!
//! [`IncrementalGraph`] wraps a [`PoseGraph`]. New poses start at the composition of the
//! previous estimate with the odometry. An update first checks whether the factors added
//! since the last converged optimisation pull on the estimate at all: a new pose tied by
//! one odometry factor and initialised by it has a zero residual, so the old optimum extended
//! by that pose *is* the new optimum (the old factors' gradient was zero and the new one
//! adds none) and nothing needs solving. Otherwise — a loop closure, a relocalization, a
//! second constraint on a new pose — the whole graph is re-optimised from the warm start.

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
        }
    }
}

/// What one [`IncrementalGraph::update`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IncrementalReport {
    /// True when the graph was re-optimised; false when the new factors left the optimum
    /// unchanged.
    pub optimized: bool,
    /// Factors added since the previous update.
    pub new_factors: usize,
    /// Cost after the update.
    pub cost: f64,
    /// Wall time of the update.
    pub time_ms: f64,
    /// The optimisation report when the graph was re-optimised.
    pub report: Option<OptimizationReport>,
}

/// A pose graph grown online and re-optimised after each batch of additions.
#[derive(Debug, Default)]
pub struct IncrementalGraph {
    graph: PoseGraph,
    config: IncrementalConfig,
    /// Factors `[0, settled)` were part of the last converged optimisation.
    settled: usize,
    /// Cost of the settled factors at the current estimate.
    settled_cost: f64,
    converged: bool,
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
                    new_factors,
                    cost: self.settled_cost,
                    time_ms: start.elapsed().as_secs_f64() * 1e3,
                    report: None,
                });
            }
        }
        let report = self.graph.optimize(&self.config.solver)?;
        self.converged = report.converged;
        self.settled = self.graph.num_factors();
        self.settled_cost = report.final_cost;
        Ok(IncrementalReport {
            optimized: true,
            new_factors,
            cost: report.final_cost,
            time_ms: start.elapsed().as_secs_f64() * 1e3,
            report: Some(report),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::file::BuildOptions;
    use crate::graph::synthetic::{self, SyntheticConfig};

    #[test]
    fn odometry_appends_keep_the_optimum_without_solving() {
        let synth = synthetic::generate(&SyntheticConfig {
            poses: 400,
            loop_closures: 30,
            ..SyntheticConfig::default()
        });
        let mut base = synth.file.clone();
        base.vertices.retain(|v| v.id < 300);
        base.edges.retain(|e| e.from < 300 && e.to < 300);
        let graph = base.to_pose_graph(&BuildOptions::default()).unwrap();
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

    #[test]
    fn a_loop_closure_triggers_a_full_solve() {
        let mut g = PoseGraph::new();
        g.add_pose(0, Isometry3::identity()).unwrap();
        g.fix(0).unwrap();
        let mut inc = IncrementalGraph::new(g, IncrementalConfig::default());
        let info = Matrix6::identity();
        let z = Isometry3::translation(1.0, 0.0, 0.0);
        for id in 1..5 {
            inc.add_odometry(id - 1, id, z, info).unwrap();
        }
        assert!(inc.update().unwrap().optimized);
        inc.graph_mut()
            .add_between(
                0,
                4,
                Isometry3::translation(3.5, 0.0, 0.0),
                info,
                RobustKernel::None,
            )
            .unwrap();
        let r = inc.update().unwrap();
        assert!(r.optimized);
        let x4 = inc.graph().pose(4).unwrap().translation.x;
        // Four unit steps against one 3.5 closure, equal weights: x4 = 3.6.
        assert!((x4 - 3.6).abs() < 1e-9, "{x4}");
    }
}
