//! `segloc.ObjectMap`: a map of boulder landmarks (`segloc_maps::ObjectMap`).

use crate::convert::{isometry_from, matrices3_from, points_from, points_to, stack_to, vector_to};
use crate::error::to_py;
use numpy::{PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use segloc::landmarks::{map_from_points, PointsMapOptions};

/// A map of boulder landmarks in one frame: centroids with covariance, size and provenance.
///
/// Build one with `ObjectMap.from_points`, `read_map`, `read_traverse` or
/// `fuse_detections`. Arrays returned by its properties are fresh copies.
#[pyclass(module = "segloc", frozen)]
#[derive(Clone)]
pub struct ObjectMap {
    pub(crate) inner: segloc_maps::ObjectMap,
}

impl From<segloc_maps::ObjectMap> for ObjectMap {
    fn from(inner: segloc_maps::ObjectMap) -> Self {
        Self { inner }
    }
}

#[pymethods]
impl ObjectMap {
    /// A map with one landmark per row of `points` (N, 3), ids 0..N in order.
    ///
    /// `sizes` (N,): boulder diameters in metres, NaN where unknown (sizes gate the
    /// candidate associations). `covariances` (N, 3, 3) in m²; without them every landmark
    /// gets the fusion's repeatability floor (isotropic). `gravity_aligned`: z is up, so a
    /// relocalization solves yaw and translation only (4-DOF). Raises `SegLocError` on a
    /// wrong shape, a non-finite coordinate or a bad covariance.
    #[staticmethod]
    #[pyo3(signature = (points, sizes=None, gravity_aligned=true, covariances=None, frame="points", session=""))]
    fn from_points(
        points: PyReadonlyArray2<'_, f64>,
        sizes: Option<PyReadonlyArray1<'_, f64>>,
        gravity_aligned: bool,
        covariances: Option<PyReadonlyArray3<'_, f64>>,
        frame: &str,
        session: &str,
    ) -> PyResult<Self> {
        let points = points_from(&points, "points")?;
        let sizes = sizes.map(|s| s.as_array().to_vec());
        let covariances = covariances
            .map(|c| matrices3_from(&c, "covariances"))
            .transpose()?;
        let options = PointsMapOptions {
            gravity_aligned,
            ..PointsMapOptions::default()
        };
        let mut map = map_from_points(&points, sizes.as_deref(), covariances.as_deref(), &options)
            .map_err(to_py)?;
        map.frame = frame.to_string();
        map.session = session.to_string();
        Ok(map.into())
    }

    /// Landmark centroids, (N, 3), metres, in landmark order.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_to(py, self.inner.landmarks.iter().map(|l| l.position))
    }

    /// Position covariances, (N, 3, 3), m².
    #[getter]
    fn covariances<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let covs: Vec<_> = self.inner.landmarks.iter().map(|l| l.covariance).collect();
        stack_to(py, &covs)
    }

    /// Boulder diameters, (N,), metres; NaN where unknown.
    #[getter]
    fn sizes<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vector_to(
            py,
            self.inner
                .landmarks
                .iter()
                .map(|l| l.size_m.unwrap_or(f64::NAN))
                .collect(),
        )
    }

    /// Landmark ids, (N,), unique within the map.
    #[getter]
    fn ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        let ids: Vec<u32> = self.inner.landmarks.iter().map(|l| l.id).collect();
        PyArray1::from_vec(py, ids)
    }

    /// Detections fused into each landmark, (N,).
    #[getter]
    fn observations<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        let counts: Vec<u32> = self
            .inner
            .landmarks
            .iter()
            .map(|l| l.observations)
            .collect();
        PyArray1::from_vec(py, counts)
    }

    /// Name of the frame the positions are expressed in.
    #[getter]
    fn frame(&self) -> &str {
        &self.inner.frame
    }

    /// Session or agent that built the map.
    #[getter]
    fn session(&self) -> &str {
        &self.inner.session
    }

    /// Whether z is up (gravity known): relocalization then defaults to 4-DOF.
    #[getter]
    fn gravity_aligned(&self) -> bool {
        self.inner.gravity_aligned
    }

    /// Free-form provenance (source file, fusion parameters, ...).
    #[getter]
    fn notes(&self) -> std::collections::BTreeMap<String, String> {
        self.inner.notes.clone()
    }

    /// The same map in another frame: `a_from_b` (4, 4) maps this map's points into frame
    /// `frame`; positions are moved and covariances rotated, everything else kept.
    #[pyo3(signature = (a_from_b, frame))]
    fn transformed(&self, a_from_b: PyReadonlyArray2<'_, f64>, frame: &str) -> PyResult<Self> {
        let t = isometry_from(&a_from_b, "a_from_b")?;
        Ok(self.inner.transformed(&t, frame).into())
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "ObjectMap({} landmarks, frame={:?}, session={:?}, gravity_aligned={})",
            self.inner.len(),
            self.inner.frame,
            self.inner.session,
            if self.inner.gravity_aligned {
                "True"
            } else {
                "False"
            }
        )
    }
}
