//! The back end: a sliding window of recent frames and the points they share, refined by
//! bundle adjustment on the pose graph's stereo projection factors
//! ([`PoseGraph::optimize_bundle`]), Huber kernel, the oldest frame of the window held.

use crate::graph::{PoseGraph, RobustKernel, SolverConfig, StereoCalibration};
use nalgebra::{Isometry3, Matrix3, Point3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, VecDeque};

/// Sliding-window settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WindowConfig {
    /// Frames in the window (0 or 1 turns the bundle adjustment off).
    pub frames: usize,
    /// Pixel noise of a stereo measurement (isotropic), pixels.
    pub sigma_px: f64,
    /// Huber threshold on the whitened reprojection error.
    pub huber: f64,
    /// Levenberg–Marquardt iterations per frame.
    pub iterations: usize,
}

impl Default for WindowConfig {
    fn default() -> Self {
        Self {
            frames: 5,
            sigma_px: 1.0,
            huber: 1.5,
            iterations: 5,
        }
    }
}

/// One frame of the window: its pose and what it saw.
struct WindowFrame {
    id: u64,
    first_from_camera: Isometry3<f64>,
    /// `(track id, (u_left, u_right, v), point in this camera's frame)`.
    observations: Vec<(u64, Vector3<f64>, Point3<f64>)>,
}

/// The sliding window.
pub struct SlidingWindow {
    camera: StereoCalibration,
    config: WindowConfig,
    frames: VecDeque<WindowFrame>,
}

impl SlidingWindow {
    /// An empty window.
    pub fn new(camera: StereoCalibration, config: WindowConfig) -> Self {
        Self {
            camera,
            config,
            frames: VecDeque::new(),
        }
    }

    /// Moves every frame of the window by `correction` (a rigid motion of the first
    /// camera's frame, e.g. a tilt toward gravity): the frames keep their relative poses,
    /// and the oldest, held in the next refinement, carries it on.
    pub fn correct(&mut self, correction: &Isometry3<f64>) {
        for f in &mut self.frames {
            f.first_from_camera = correction * f.first_from_camera;
        }
    }

    /// Adds a frame and refines the window; returns the refined pose of the new frame, or
    /// `None` when nothing was refined. With `gyro_check` (the gyro's rotation
    /// `curr_from_prev` from the previous frame to this one and the largest disagreement,
    /// radians), a refinement that turns the new frame otherwise is dropped whole: a window
    /// of few points can twist a frame the gyro says did not turn.
    pub fn add_frame(
        &mut self,
        id: u64,
        first_from_camera: Isometry3<f64>,
        observations: &[(u64, Vector3<f64>, Point3<f64>)],
        gyro_check: Option<(UnitQuaternion<f64>, f64)>,
    ) -> Option<Isometry3<f64>> {
        if self.config.frames < 2 {
            return None;
        }
        self.frames.push_back(WindowFrame {
            id,
            first_from_camera,
            observations: observations.to_vec(),
        });
        while self.frames.len() > self.config.frames {
            self.frames.pop_front();
        }
        if self.frames.len() < 2 {
            return None;
        }
        let refined = self.solve()?;
        if let Some((curr_from_prev, max_rad)) = gyro_check {
            // against the previous frame's pose as it was given out, not as refined now
            let prev = self.frames[self.frames.len() - 2].first_from_camera;
            let curr = refined.get(&id)?;
            let refined_curr_from_prev = (curr.inverse() * prev).rotation;
            if refined_curr_from_prev.angle_to(&curr_from_prev) > max_rad {
                return None;
            }
        }
        for f in self.frames.iter_mut() {
            if let Some(p) = refined.get(&f.id) {
                f.first_from_camera = *p;
            }
        }
        refined.get(&id).copied()
    }

    /// One bundle adjustment of the window; the refined poses by frame id.
    fn solve(&self) -> Option<HashMap<u64, Isometry3<f64>>> {
        let mut seen: HashMap<u64, usize> = HashMap::new();
        for f in &self.frames {
            for (track, _, _) in &f.observations {
                *seen.entry(*track).or_default() += 1;
            }
        }
        let mut graph = PoseGraph::new();
        for f in &self.frames {
            graph.add_pose(f.id, f.first_from_camera).ok()?;
        }
        graph.fix(self.frames.front()?.id).ok()?;
        let information = Matrix3::identity() / (self.config.sigma_px * self.config.sigma_px);
        let kernel = RobustKernel::Huber {
            k: self.config.huber,
        };
        for f in &self.frames {
            for (track, uv, p_camera) in &f.observations {
                if seen.get(track).copied().unwrap_or(0) < 2 {
                    continue;
                }
                if !graph.contains(crate::graph::VarKey::Point(*track)) {
                    graph
                        .add_point(*track, f.first_from_camera * p_camera)
                        .ok()?;
                }
                graph
                    .add_stereo_observation(f.id, *track, *uv, self.camera, information, kernel)
                    .ok()?;
            }
        }
        let config = SolverConfig {
            max_iterations: self.config.iterations,
            log_iterations: false,
            ..SolverConfig::default()
        };
        graph.optimize_bundle(&config).ok()?;
        Some(
            self.frames
                .iter()
                .filter_map(|f| graph.pose(f.id).map(|p| (f.id, p)))
                .collect(),
        )
    }
}
