//! Map files and LunarLoc traverses.

use crate::error::to_py;
use crate::object_map::ObjectMap;
use pyo3::prelude::*;
use segloc::landmarks::{fuse_detections, FusionConfig};
use std::path::PathBuf;

/// Read a segloc map file (versioned JSON). Raises `SegLocError` naming the file (and line).
#[pyfunction]
pub fn read_map(py: Python<'_>, path: PathBuf) -> PyResult<ObjectMap> {
    py.detach(|| segloc_maps::read_map(&path))
        .map(ObjectMap::from)
        .map_err(to_py)
}

/// Write `map` to `path` as a segloc map file, atomically (a temporary file, then renamed).
#[pyfunction]
pub fn write_map(py: Python<'_>, map: &ObjectMap, path: PathBuf) -> PyResult<()> {
    py.detach(|| segloc_maps::write_map(&map.inner, &path))
        .map_err(to_py)
}

/// Read a LunarLoc traverse CSV and fuse its detections into landmarks with the default
/// fusion, as `segloc map build` does. Raises `SegLocError` naming the file and line.
#[pyfunction]
pub fn read_traverse(py: Python<'_>, path: PathBuf) -> PyResult<ObjectMap> {
    py.detach(|| {
        let traverse = segloc_maps::read_lunarloc_traverse(&path)?;
        let mut map = fuse_detections(&traverse.detections(), &FusionConfig::default());
        map.notes
            .insert("source".into(), path.display().to_string());
        Ok::<_, segloc_maps::MapError>(map)
    })
    .map(ObjectMap::from)
    .map_err(to_py)
}
