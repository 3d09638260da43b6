//! `segloc.Relocalizer`: a prior map prepared once, relocalized against many times.

use crate::config::RelocalizeConfig;
use crate::convert::{isometry_to, json_to_py, matrix6_to};
use crate::error::to_py;
use crate::object_map::ObjectMap;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::prelude::*;
use segloc::relocalize::Relocalization;

/// A prior map prepared once for relocalization; `relocalize(query)` finds
/// `prior_from_query` for each query map, or refuses with the reason.
///
/// `Relocalizer(prior, config=None)`: `config` is a `RelocalizeConfig` (default: the
/// library's defaults, as the CLI without `--config`). Raises `SegLocError` when the prior
/// map is invalid or too small.
#[pyclass(module = "segloc", frozen)]
pub struct Relocalizer {
    inner: segloc::relocalize::Relocalizer,
}

#[pymethods]
impl Relocalizer {
    #[new]
    #[pyo3(signature = (prior, config=None))]
    fn new(py: Python<'_>, prior: &ObjectMap, config: Option<&RelocalizeConfig>) -> PyResult<Self> {
        let config = config.cloned().unwrap_or_default().inner;
        let prior = prior.inner.clone();
        py.detach(|| segloc::relocalize::Relocalizer::new(prior, config))
            .map(|inner| Self { inner })
            .map_err(to_py)
    }

    /// Relocalize `query` (an `ObjectMap`) against the prior: a `RelocalizeResult`,
    /// accepted or refused. The GIL is released meanwhile. Raises `SegLocError` on an
    /// invalid query (too few landmarks, 4-DOF asked of a map that is not gravity-aligned).
    fn relocalize(&self, py: Python<'_>, query: &ObjectMap) -> PyResult<RelocalizeResult> {
        py.detach(|| self.inner.relocalize(&query.inner))
            .map(|inner| RelocalizeResult { inner })
            .map_err(to_py)
    }

    /// The configuration this relocalizer runs with.
    #[getter]
    fn config(&self) -> RelocalizeConfig {
        RelocalizeConfig {
            inner: self.inner.config().clone(),
        }
    }
}

/// The answer of one relocalization: the transform with its evidence, or the refusal's
/// reason, always with the diagnostics.
#[pyclass(module = "segloc", frozen)]
pub struct RelocalizeResult {
    inner: Relocalization,
}

#[pymethods]
impl RelocalizeResult {
    /// Whether the transform was accepted.
    #[getter]
    fn accepted(&self) -> bool {
        self.inner.is_accepted()
    }

    /// The accepted `prior_from_query`, (4, 4) homogeneous (maps query points into the
    /// prior's frame); None when refused.
    #[getter]
    fn prior_from_query<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.inner
            .accepted()
            .map(|a| isometry_to(py, &a.prior_from_query))
    }

    /// The best hypothesis' transform, accepted or not (for diagnosis only); None when
    /// there was no hypothesis.
    #[getter]
    fn best_guess<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.inner.best_guess().map(|t| isometry_to(py, &t))
    }

    /// The 6 × 6 information matrix of `prior_from_query`, tangent ordered (rotation,
    /// translation), right perturbation (GTSAM's `Pose3`); zeros when refused.
    #[getter]
    fn information<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let zeros = nalgebra::Matrix6::zeros();
        matrix6_to(py, self.inner.accepted().map_or(&zeros, |a| &a.information))
    }

    /// Inliers of the accepted transform, (K, 2): (prior landmark id, query landmark id).
    #[getter]
    fn inliers<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<u32>> {
        let pairs = self.inner.accepted().map_or(&[][..], |a| &a.inliers[..]);
        Array2::from_shape_fn((pairs.len(), 2), |(k, c)| {
            if c == 0 {
                pairs[k].0
            } else {
                pairs[k].1
            }
        })
        .into_pyarray(py)
    }

    /// Root-mean-square residual (m) over the best hypothesis' inliers; NaN without one.
    #[getter]
    fn rmse_m(&self) -> f64 {
        self.inner.rmse_m
    }

    /// Why the transform was refused (a sentence), or None when accepted.
    #[getter]
    fn refusal(&self) -> Option<String> {
        self.inner.refusal().map(|r| r.to_string())
    }

    /// The refusal's stable code (`too_few_landmarks`, `no_hypothesis`, `too_few_inliers`,
    /// `residual_too_large`, `degenerate_geometry`, `yaw_uncertain`, `ambiguous`), or None when accepted.
    #[getter]
    fn refusal_code(&self) -> Option<&'static str> {
        self.inner.refusal().map(|r| r.code())
    }

    /// Stage timings in milliseconds: associations_ms, graph_ms, clique_ms, alignment_ms,
    /// total_ms.
    #[getter]
    fn timings_ms<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(
            py,
            &serde_json::to_value(&self.inner.diagnostics.timings).map_err(to_py)?,
        )
    }

    /// Motion model used: 4 or 6.
    #[getter]
    fn dof(&self) -> u32 {
        self.inner.diagnostics.dof
    }

    /// Everything as nested dicts: the transform (rows), refusal (kind and numbers),
    /// inliers, rmse_m, information (rows) and the diagnostics (landmarks, associations,
    /// graph edges, hypotheses, timings).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &serde_json::to_value(&self.inner).map_err(to_py)?)
    }

    fn __repr__(&self) -> String {
        match &self.inner.outcome {
            Ok(a) => format!(
                "RelocalizeResult(accepted, {} inliers, rmse {:.2} cm)",
                a.inliers.len(),
                self.inner.rmse_m * 100.0
            ),
            Err(r) => format!("RelocalizeResult(refused: {r})"),
        }
    }
}
