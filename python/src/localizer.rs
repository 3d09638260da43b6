//! `segloc.Localizer`: the online, per-frame localizer fed by a recorded drive.

use crate::convert::{config_from, isometry_to, points_to, stack_to};
use crate::error::to_py;
use crate::object_map::ObjectMap;
use nalgebra::Matrix4;
use numpy::{PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use segloc::localizer::{LocalizerConfig, LocalizerEvent};
use segloc_maps::StreamFrame;
use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard};

/// One camera frame of a drive: time, odometry pose, gravity, boulder detections in the
/// rover frame (read with `read_frames`).
#[pyclass(module = "segloc", frozen)]
pub struct Frame {
    inner: StreamFrame,
}

#[pymethods]
impl Frame {
    /// Time, s.
    #[getter]
    fn t(&self) -> f64 {
        self.inner.t
    }

    /// The odometry's pose of the rover, (4, 4) (rover coordinates into the odometry frame).
    #[getter]
    fn odom_from_rover<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        isometry_to(py, &self.inner.odom_from_rover)
    }

    /// Boulder centroids detected in this frame, (N, 3), rover frame, m.
    #[getter]
    fn detections<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_to(py, self.inner.detections.iter().map(|d| d.p_rover))
    }

    fn __repr__(&self) -> String {
        format!(
            "Frame(t={}, {} detections)",
            self.inner.t,
            self.inner.detections.len()
        )
    }
}

/// Read a frames file (JSON Lines, one camera frame a line; `maps/FORMAT.md`). Raises
/// `SegLocError` naming the file and line.
#[pyfunction]
pub fn read_frames(py: Python<'_>, path: PathBuf) -> PyResult<Vec<Frame>> {
    let file = py
        .detach(|| segloc_maps::read_frames(&path))
        .map_err(to_py)?;
    Ok(file
        .frames
        .into_iter()
        .map(|inner| Frame { inner })
        .collect())
}

/// The online localizer of one session: `push_frame` each frame in time order, then
/// `finish`.
///
/// `Localizer(prior=None, **config)`: against a prior `ObjectMap` (None: a mapping
/// session, anchored at its first frame, closing loops on its own map). Keyword arguments
/// override sections of the localizer configuration (`segloc localize --print-config`).
/// With a prior, the detections are corrected for the viewpoint bias the prior recorded,
/// as `segloc localize` does.
#[pyclass(module = "segloc", frozen)]
pub struct Localizer {
    inner: Mutex<Option<segloc::localizer::Localizer>>,
}

impl Localizer {
    /// The localizer under its lock (`None` once finished).
    fn lock(&self) -> PyResult<MutexGuard<'_, Option<segloc::localizer::Localizer>>> {
        self.inner
            .lock()
            .map_err(|_| to_py("the localizer panicked"))
    }
}

/// The error of a call after `finish`.
fn finished() -> PyErr {
    to_py("the localizer has finished")
}

#[pymethods]
impl Localizer {
    #[new]
    #[pyo3(signature = (prior=None, **config))]
    fn new(prior: Option<&ObjectMap>, config: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let config: LocalizerConfig = config_from("localizer configuration", config)?;
        let prior = prior.map(|p| p.inner.clone());
        let config = match &prior {
            Some(map) => config.calibrated_for(map),
            None => config,
        };
        let localizer = segloc::localizer::Localizer::new(prior, config).map_err(to_py)?;
        Ok(Self {
            inner: Mutex::new(Some(localizer)),
        })
    }

    /// Take the next frame: returns a `FrameResult` with the current estimate of the
    /// rover's pose in the prior's frame (None until the first fix) and the fixes made.
    /// Raises `SegLocError` on a bad frame (time not increasing, ...) or after `finish`.
    fn push_frame(&self, py: Python<'_>, frame: &Frame) -> PyResult<FrameResult> {
        py.detach(|| {
            let mut guard = self.lock()?;
            let localizer = guard.as_mut().ok_or_else(finished)?;
            localizer.push_frame(&frame.inner).map_err(to_py)
        })
        .map(|out| FrameResult {
            frame: out.frame,
            prior_from_rover: out.prior_from_rover.map(|t| t.to_homogeneous()),
            fixes: out
                .events
                .iter()
                .filter_map(|e| match e {
                    LocalizerEvent::Fix { frame, inliers, .. } => Some((*frame, *inliers)),
                    _ => None,
                })
                .collect(),
            time_ms: out.time_ms,
        })
    }

    /// End the session: the final adjustment of poses and boulders. Returns a
    /// `SessionResult`; the localizer takes no frame after it.
    fn finish(&self, py: Python<'_>) -> PyResult<SessionResult> {
        py.detach(|| {
            let localizer = self.lock()?.take().ok_or_else(finished)?;
            localizer.finish().map_err(to_py)
        })
        .map(|inner| SessionResult { inner })
    }
}

/// What the localizer returned for one frame.
#[pyclass(module = "segloc", frozen)]
pub struct FrameResult {
    /// Index of the frame.
    #[pyo3(get)]
    frame: usize,
    prior_from_rover: Option<Matrix4<f64>>,
    /// Fixes that entered the pose graph during this frame: (anchored frame, inliers).
    #[pyo3(get)]
    fixes: Vec<(usize, usize)>,
    /// Wall time of the call, ms.
    #[pyo3(get)]
    time_ms: f64,
}

#[pymethods]
impl FrameResult {
    /// The rover's pose in the prior map's frame, (4, 4), once known; else None.
    #[getter]
    fn prior_from_rover<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.prior_from_rover
            .as_ref()
            .map(|m| crate::convert::matrix_to(py, m))
    }
}

/// A finished session: optimised poses, the session's boulder map, the attempts.
#[pyclass(module = "segloc", frozen)]
pub struct SessionResult {
    inner: segloc::localizer::SessionResult,
}

#[pymethods]
impl SessionResult {
    /// Optimised `prior_from_rover` of every frame, (N, 4, 4).
    #[getter]
    fn poses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let poses: Vec<Matrix4<f64>> = self
            .inner
            .poses
            .iter()
            .map(|p| p.to_homogeneous())
            .collect();
        stack_to(py, &poses)
    }

    /// The session's boulder map, in the frame of `poses`.
    #[getter]
    fn map(&self) -> ObjectMap {
        self.inner.map.clone().into()
    }

    /// Index of the first frame whose pose was known in the prior's frame.
    #[getter]
    fn first_fix_frame(&self) -> Option<usize> {
        self.inner.first_fix_frame
    }

    /// Relocalization attempts (a mapping session: loop closures): (accepted, refused).
    #[getter]
    fn attempts(&self) -> (usize, usize) {
        let accepted = self.inner.attempts.iter().filter(|a| a.accepted()).count();
        (accepted, self.inner.attempts.len() - accepted)
    }
}
