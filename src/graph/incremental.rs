//! Incremental use: add poses and factors as the rover drives and re-optimise warm-started.
//!
//! [`IncrementalGraph`] wraps a [`PoseGraph`]. New poses start at the composition of the
//! previous estimate with the odometry, so the graph stays close to its optimum and a
//! re-optimisation needs few iterations. While no variable or factor is added, the symbolic
//! analysis of the normal equations is reused.

use super::robust::RobustKernel;
use super::solver::{OptimizationReport, SolverConfig};
use super::{GraphError, PoseGraph};
use nalgebra::{Isometry3, Matrix6};
use serde::{Deserialize, Serialize};

/// Parameters of incremental re-optimisation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct IncrementalConfig {
    /// Solver parameters for each update.
    pub solver: SolverConfig,
}

impl Default for IncrementalConfig {
    fn default() -> Self {
        Self {
            solver: SolverConfig {
                max_iterations: 10,
                log_iterations: false,
                ..SolverConfig::default()
            },
        }
    }
}

/// A pose graph grown online and re-optimised after each batch of additions.
#[derive(Debug, Default)]
pub struct IncrementalGraph {
    graph: PoseGraph,
    config: IncrementalConfig,
}

impl IncrementalGraph {
    /// Wraps an existing graph (its estimates are the warm start).
    pub fn new(graph: PoseGraph, config: IncrementalConfig) -> Self {
        Self { graph, config }
    }

    /// The underlying graph.
    pub fn graph(&self) -> &PoseGraph {
        &self.graph
    }

    /// Mutable access to the underlying graph, e.g. to add relocalization factors.
    pub fn graph_mut(&mut self) -> &mut PoseGraph {
        &mut self.graph
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

    /// Re-optimises from the current estimates.
    pub fn update(&mut self) -> Result<OptimizationReport, GraphError> {
        self.graph.optimize(&self.config.solver)
    }
}
