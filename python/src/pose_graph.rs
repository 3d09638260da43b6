//! `segloc.optimize_pose_graph`: a g2o or TORO 3D file optimised.

use crate::convert::{config_from, json_to_py, stack_to};
use crate::error::to_py;
use nalgebra::Matrix4;
use numpy::{PyArray1, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use segloc::graph::file_solve::{optimize_file, FileSolve, FileSolveOptions};
use segloc::graph::{RobustKernel, SolverConfig};
use std::path::PathBuf;

/// Optimise a pose-graph file (g2o `VERTEX_SE3:QUAT`/`EDGE_SE3:QUAT` or TORO
/// `VERTEX3`/`EDGE3`) as `segloc graph optimize FILE` does: chordal start, Levenberg–
/// Marquardt, cost as GTSAM computes it, no robust kernel. `strict`:
/// refuse information matrices that are not positive definite instead of repairing them.
/// Keyword arguments override fields of the solver configuration (`segloc graph optimize
/// --print-config`). The GIL is released meanwhile. Raises `SegLocError` naming the file
/// and line on bad input.
#[pyfunction]
#[pyo3(signature = (path, strict=false, **solver))]
pub fn optimize_pose_graph(
    py: Python<'_>,
    path: PathBuf,
    strict: bool,
    solver: Option<&Bound<'_, PyDict>>,
) -> PyResult<PoseGraphResult> {
    let options = FileSolveOptions {
        strict,
        loop_closure_kernel: RobustKernel::None,
        solver: config_from::<SolverConfig>("solver configuration", solver)?,
    };
    py.detach(|| optimize_file(&path, &options))
        .map(|inner| PoseGraphResult { inner })
        .map_err(to_py)
}

/// An optimised pose graph: costs, iterations and the poses.
#[pyclass(module = "segloc", frozen)]
pub struct PoseGraphResult {
    inner: FileSolve,
}

#[pymethods]
impl PoseGraphResult {
    /// Cost ½ Σ rᵀΩr at the start (after the chordal initialisation when it ran).
    #[getter]
    fn initial_cost(&self) -> f64 {
        self.inner.report.initial_cost
    }

    /// Cost at the optimum.
    #[getter]
    fn final_cost(&self) -> f64 {
        self.inner.report.final_cost
    }

    /// Solver iterations.
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.report.iterations
    }

    /// Whether a convergence test was met.
    #[getter]
    fn converged(&self) -> bool {
        self.inner.report.converged
    }

    /// Optimised poses `world_from_rover`, (N, 4, 4), in id order (see `ids`).
    #[getter]
    fn poses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let poses: Vec<Matrix4<f64>> = self
            .inner
            .poses()
            .iter()
            .map(|(_, p)| p.to_homogeneous())
            .collect();
        stack_to(py, &poses)
    }

    /// Pose ids, (N,), ascending.
    #[getter]
    fn ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.inner.poses().iter().map(|(id, _)| *id).collect())
    }

    /// Warnings from reading the file (repaired information matrices, unknown tags).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.file.warnings.clone()
    }

    /// The solver's report as nested dicts (costs, iterations, factorisations, profile,
    /// termination, components, per-iteration log).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(
            py,
            &serde_json::to_value(&self.inner.report).map_err(to_py)?,
        )
    }

    fn __repr__(&self) -> String {
        let r = &self.inner.report;
        format!(
            "PoseGraphResult({} poses, cost {:.6e} -> {:.6e}, {} iterations)",
            r.poses, r.initial_cost, r.final_cost, r.iterations
        )
    }
}
