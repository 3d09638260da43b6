//! segloc's Python module (`segloc._segloc`, re-exported by `segloc/__init__.py`).
//!
//! Bindings only: every function converts its arguments, calls the segloc library and
//! converts the answer back. Numbers cross as numpy arrays; errors as `segloc.SegLocError`
//! with the library's message (which names the file and line for bad input). Long calls
//! release the GIL.
#![warn(missing_docs)]
#![warn(clippy::too_many_lines)]

mod config;
mod convert;
mod detections;
mod error;
mod files;
mod localizer;
mod merge;
mod object_map;
mod pose_graph;
mod relocalizer;

use pyo3::prelude::*;

/// The Rust half of the `segloc` package.
#[pymodule]
fn _segloc(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("SegLocError", m.py().get_type::<error::SegLocError>())?;
    m.add_class::<object_map::ObjectMap>()?;
    m.add_class::<detections::Detections>()?;
    m.add_class::<config::RelocalizeConfig>()?;
    m.add_class::<relocalizer::Relocalizer>()?;
    m.add_class::<relocalizer::RelocalizeResult>()?;
    m.add_class::<merge::MergeResult>()?;
    m.add_class::<pose_graph::PoseGraphResult>()?;
    m.add_class::<localizer::Frame>()?;
    m.add_class::<localizer::FrameResult>()?;
    m.add_class::<localizer::Localizer>()?;
    m.add_class::<localizer::SessionResult>()?;
    m.add_function(wrap_pyfunction!(files::read_map, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_map, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_traverse, m)?)?;
    m.add_function(wrap_pyfunction!(detections::read_detections, m)?)?;
    m.add_function(wrap_pyfunction!(detections::fuse_detections, m)?)?;
    m.add_function(wrap_pyfunction!(merge::merge_maps, m)?)?;
    m.add_function(wrap_pyfunction!(pose_graph::optimize_pose_graph, m)?)?;
    m.add_function(wrap_pyfunction!(localizer::read_frames, m)?)?;
    Ok(())
}
