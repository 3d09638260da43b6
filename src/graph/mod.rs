//! SE(3) pose graph: rover poses, map-frame variables and landmark points tied by
//! odometry, loop-closure, prior, relocalization and point-observation factors, optimised by Levenberg–Marquardt (or Gauss–Newton) on
//! the Lie group with a sparse Cholesky factorisation from `faer`.
//!
//! # Conventions
//!
//! * A pose variable is `world_from_rover` (maps rover-body points into the graph's world);
//!   a frame variable is `world_from_prior` for one prior map or session.
//! * Tangent vectors and information matrices are ordered **(rotation, translation)**, as in
//!   GTSAM. Perturbations act on the right: `X ← X · Exp(δ)`.
//! * The cost is `½ Σ ρ(rᵀ Ω r)` with `r = Log(Zᵢⱼ⁻¹ · Xᵢ⁻¹ · Xⱼ)` for a between factor, so
//!   costs compare number for number with GTSAM's `NonlinearFactorGraph::error`.
//!
//! # Pieces
//!
//! * [`PoseGraph`]: variables ([`VarKey`]), factors ([`Factor`]), `optimize`.
//! * `solver`: Levenberg–Marquardt / Gauss–Newton ([`SolverConfig`], [`OptimizationReport`]),
//!   chord steps near convergence, graduated non-convexity ([`RobustKernel::Gnc`]).
//! * `structure` + `ordering`: the sparse normal equations, laid out once in AMD order with a
//!   symbolic Cholesky that is reused until the graph's structure changes.
//! * `initialize`: chordal initialisation ([`Initialization::Chordal`]).
//! * [`IncrementalGraph`]: online use, skipping solves that cannot change the optimum,
//!   solving a window of recent poses exactly (`window_solve`) and keeping the settled part
//!   on its last linearisation (`linear_model`) between rebuilds.
//! * [`stereo`]: the rectified stereo camera of the stereo projection factor
//!   ([`PoseGraph::add_stereo_observation`]); [`stereo_file`]: GTSAM's stereo VO example.
//! * [`file`](mod@file), [`g2o`], [`toro`]: g2o 3D and TORO 3D files; [`synthetic`] and [`metrics`]
//!   for tests and benchmarks.
//!
//! # Example
//!
//! ```
//! use nalgebra::{Isometry3, Matrix6, Vector3};
//! use segloc::graph::{PoseGraph, RobustKernel, SolverConfig};
//!
//! let step = Isometry3::translation(1.0, 0.0, 0.0);
//! let mut graph = PoseGraph::new();
//! graph.add_pose(0, Isometry3::identity())?;
//! graph.add_pose(1, Isometry3::translation(0.8, 0.1, 0.0))?;
//! graph.add_pose(2, Isometry3::translation(2.3, -0.2, 0.0))?;
//! graph.fix(0)?;
//! let info = Matrix6::identity();
//! graph.add_between(0, 1, step, info, RobustKernel::None)?;
//! graph.add_between(1, 2, step, info, RobustKernel::None)?;
//! let report = graph.optimize(&SolverConfig::default())?;
//! assert!(report.final_cost < 1e-12);
//! let p2 = graph.pose(2).unwrap();
//! assert!((p2.translation.vector - Vector3::new(2.0, 0.0, 0.0)).norm() < 1e-9);
//! # Ok::<(), segloc::graph::GraphError>(())
//! ```

mod bundle;
mod components;
mod error;
mod factor_paths;
mod factors;
pub mod file;
pub mod file_solve;
pub mod g2o;
pub mod gravity;
mod incremental;
pub mod information;
mod initialize;
mod linear_model;
pub mod metrics;
mod ordering;
mod pose_graph;
pub mod robust;
pub mod se3;
mod solver;
#[cfg(test)]
mod solver_tests;
pub mod stereo;
pub mod stereo_file;
mod structure;
pub mod synthetic;
pub mod toro;
mod window_solve;

pub use components::{Anchor, ComponentInfo};
pub use error::GraphError;
pub use factors::{Factor, FactorKind};
pub use gravity::gravity_information;
pub use incremental::{IncrementalConfig, IncrementalGraph, IncrementalReport, UpdateMethod};
pub use pose_graph::PoseGraph;
pub use robust::RobustKernel;
pub use solver::{
    Algorithm, Damping, GncConfig, Initialization, IterationLog, OptimizationReport, Profile,
    SolverConfig, Termination,
};
pub use stereo::StereoCalibration;

use serde::{Deserialize, Serialize};
use std::fmt;

/// Key of a graph variable: a rover pose or a prior-map/session frame, each with its own ids.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(tag = "type", content = "id", rename_all = "snake_case")]
pub enum VarKey {
    /// Rover pose `world_from_rover` with the given id.
    Pose(u64),
    /// Prior map or session frame `world_from_prior` with the given id.
    Frame(u64),
    /// A landmark's position `p_world` (the translation of its stored isometry; the
    /// rotation means nothing and stays at the identity), with its own ids.
    Point(u64),
}

impl fmt::Display for VarKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            VarKey::Pose(id) => write!(f, "pose {id}"),
            VarKey::Frame(id) => write!(f, "frame {id}"),
            VarKey::Point(id) => write!(f, "point {id}"),
        }
    }
}

/// A bare id is a pose id.
impl From<u64> for VarKey {
    fn from(id: u64) -> Self {
        VarKey::Pose(id)
    }
}
