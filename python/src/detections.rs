//! `segloc.Detections`: one session's boulder detections, and their fusion into landmarks.

use crate::convert::{config_from, points_to, vector_to};
use crate::error::to_py;
use crate::object_map::ObjectMap;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use segloc::landmarks::FusionConfig;
use std::path::PathBuf;

/// Boulder detections of one session (many per boulder), as read from a segloc detections
/// CSV or a LunarLoc traverse CSV. `fuse_detections` turns them into a map.
#[pyclass(module = "segloc", frozen)]
pub struct Detections {
    inner: segloc_maps::DetectionSet,
}

#[pymethods]
impl Detections {
    /// Detected centroids, (N, 3), metres, in the set's frame.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_to(py, self.inner.detections.iter().map(|d| d.p_world))
    }

    /// Rover positions at each detection, (N, 3); NaN rows where unknown.
    #[getter]
    fn rover_positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let nan = nalgebra::Point3::new(f64::NAN, f64::NAN, f64::NAN);
        points_to(
            py,
            self.inner
                .detections
                .iter()
                .map(|d| d.rover_position.unwrap_or(nan)),
        )
    }

    /// Boulder diameters, (N,), metres; NaN where unknown.
    #[getter]
    fn sizes<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vector_to(
            py,
            self.inner
                .detections
                .iter()
                .map(|d| d.size_m.unwrap_or(f64::NAN))
                .collect(),
        )
    }

    /// Camera frame index of each detection, (N,).
    #[getter]
    fn frames<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.inner.detections.iter().map(|d| d.frame).collect())
    }

    /// Session or agent id.
    #[getter]
    fn session(&self) -> &str {
        &self.inner.session
    }

    /// Whether z is up (gravity known).
    #[getter]
    fn gravity_aligned(&self) -> bool {
        self.inner.gravity_aligned
    }

    fn __len__(&self) -> usize {
        self.inner.detections.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Detections({} detections, session={:?})",
            self.inner.detections.len(),
            self.inner.session
        )
    }
}

/// Read boulder detections: a segloc detections CSV or a LunarLoc traverse CSV. Raises
/// `SegLocError` naming the file and line.
#[pyfunction]
pub fn read_detections(py: Python<'_>, path: PathBuf) -> PyResult<Detections> {
    py.detach(|| segloc_maps::read_any_detections(&path))
        .map(|inner| Detections { inner })
        .map_err(to_py)
}

/// Fuse detections into landmarks, one per boulder (clustering, robust centroids,
/// covariances). Keyword arguments override fields of the fusion configuration (the
/// `[landmarks]` section of `segloc config print`), e.g. `cluster_radius_m=0.2`.
#[pyfunction]
#[pyo3(signature = (detections, **config))]
pub fn fuse_detections(
    py: Python<'_>,
    detections: &Detections,
    config: Option<&Bound<'_, PyDict>>,
) -> PyResult<ObjectMap> {
    let config: FusionConfig = config_from("fusion configuration", config)?;
    Ok(py
        .detach(|| segloc::landmarks::fuse_detections(&detections.inner, &config))
        .into())
}
