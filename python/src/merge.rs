//! `segloc.merge_maps`: maps of several agents or sessions into one frame.

use crate::config::RelocalizeConfig;
use crate::convert::{config_from, isometry_to, json_to_py};
use crate::error::to_py;
use crate::object_map::ObjectMap;
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use segloc::merge::{MapStatus, MergeConfig, MergeReport};

/// Merge maps, each in its own frame, into the frame of `maps[reference]`: every pair
/// relocalized, one frame per map solved in a robust pose graph (a wrong pair is
/// out-voted), the same boulders fused. `config`: the `RelocalizeConfig` of the pairwise
/// relocalizations; keyword arguments override fields of the merge configuration (e.g.
/// `fuse_gate_m=0.05`). The GIL is released meanwhile. Raises `SegLocError` on bad input
/// (fewer than two maps, reference out of range, mixed gravity conventions).
#[pyfunction]
#[pyo3(signature = (maps, reference=0, config=None, **merge_config))]
pub fn merge_maps(
    py: Python<'_>,
    maps: Vec<PyRef<'_, ObjectMap>>,
    reference: usize,
    config: Option<&RelocalizeConfig>,
    merge_config: Option<&Bound<'_, PyDict>>,
) -> PyResult<MergeResult> {
    let merge: MergeConfig = config_from("merge configuration", merge_config)?;
    let relocalize = config.cloned().unwrap_or_default().inner;
    let maps: Vec<segloc_maps::ObjectMap> = maps.iter().map(|m| m.inner.clone()).collect();
    py.detach(|| segloc::merge::merge_maps(&maps, reference, &relocalize, &merge))
        .map(|inner| MergeResult { inner })
        .map_err(to_py)
}

/// What a merge produced: the fused map and where each input map was placed.
#[pyclass(module = "segloc", frozen)]
pub struct MergeResult {
    inner: MergeReport,
}

#[pymethods]
impl MergeResult {
    /// The merged map in the reference frame (merged maps only).
    #[getter]
    fn merged(&self) -> ObjectMap {
        self.inner.merged.clone().into()
    }

    /// Per input map, its `reference_from_map` (4, 4), or None when it stayed disconnected.
    #[getter]
    fn reference_from_map<'py>(&self, py: Python<'py>) -> Vec<Option<Bound<'py, PyArray2<f64>>>> {
        self.inner
            .maps
            .iter()
            .map(|m| m.reference_from_map.as_ref().map(|t| isometry_to(py, t)))
            .collect()
    }

    /// Per input map, whether it joined the reference frame.
    #[getter]
    fn merged_flags(&self) -> Vec<bool> {
        self.inner
            .maps
            .iter()
            .map(|m| m.status == MapStatus::Merged)
            .collect()
    }

    /// Landmarks fused from two or more maps.
    #[getter]
    fn fused(&self) -> usize {
        self.inner.fused
    }

    /// Everything as nested dicts (as `segloc map merge --json`, without the file names):
    /// maps, pairs, landmarks, fused, frame residual, timings.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &serde_json::to_value(&self.inner).map_err(to_py)?)
    }

    fn __repr__(&self) -> String {
        let merged = self.merged_flags().iter().filter(|m| **m).count();
        format!(
            "MergeResult({merged} of {} maps merged, {} landmarks, {} fused)",
            self.inner.maps.len(),
            self.inner.landmarks,
            self.inner.fused
        )
    }
}
