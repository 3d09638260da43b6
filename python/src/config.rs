//! `segloc.RelocalizeConfig`: every stage's parameters of the relocalizer.

use crate::convert::{config_from, json_to_py};
use crate::error::to_py;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use segloc::align::Dof;

/// The relocalizer's configuration, one section per stage (as `segloc config print`).
///
/// `RelocalizeConfig(dof=6, verification={"min_inliers": 8})`: `dof` is 4 (yaw +
/// translation), 6 (full rigid motion) or None (4 when both maps are gravity-aligned);
/// every other keyword names a section (`landmarks`, `associations`, `consistency`,
/// `clique`, `refine`, `verification`) given as a dict of the fields to change. Unknown
/// sections or fields raise `SegLocError`.
#[pyclass(module = "segloc", frozen)]
#[derive(Clone, Default)]
pub struct RelocalizeConfig {
    pub(crate) inner: segloc::relocalize::RelocalizeConfig,
}

#[pymethods]
impl RelocalizeConfig {
    #[new]
    #[pyo3(signature = (dof=None, **sections))]
    fn new(dof: Option<u32>, sections: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut inner: segloc::relocalize::RelocalizeConfig =
            config_from("relocalize configuration", sections)?;
        inner.dof = match dof {
            None => None,
            Some(4) => Some(Dof::Four),
            Some(6) => Some(Dof::Six),
            Some(other) => return Err(to_py(format!("dof must be 4, 6 or None, got {other}"))),
        };
        Ok(Self { inner })
    }

    /// A configuration from TOML text, as written by `segloc config print`.
    #[staticmethod]
    fn from_toml(text: &str) -> PyResult<Self> {
        toml::from_str(text)
            .map(|inner| Self { inner })
            .map_err(|e| to_py(format!("relocalize configuration: {e}")))
    }

    /// The configuration as TOML text (what `segloc --config FILE` reads).
    fn to_toml(&self) -> PyResult<String> {
        toml::to_string(&self.inner).map_err(to_py)
    }

    /// The configuration as nested dicts.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &serde_json::to_value(&self.inner).map_err(to_py)?)
    }

    /// The motion model: 4, 6 or None (chosen from the maps' gravity alignment).
    #[getter]
    fn dof(&self) -> Option<u32> {
        self.inner.dof.map(|d| d.count())
    }

    fn __repr__(&self) -> String {
        format!("RelocalizeConfig(dof={:?}, ...)", self.dof())
    }
}
