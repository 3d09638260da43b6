//! Where a frame's time goes: the wall-clock time of each stage of
//! [`StereoOdometry`](super::StereoOdometry), milliseconds.

use serde::Serialize;
use std::time::Instant;

/// Per-stage wall-clock times of one frame, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StageTimes {
    /// The left pyramid and the right image as floats.
    pub pyramid_ms: f64,
    /// KLT tracking of the previous frame's features (forward–backward).
    pub track_ms: f64,
    /// Left–right matching of the tracked features and of the new corners.
    pub stereo_ms: f64,
    /// RANSAC, refinement and the gyro check.
    pub motion_ms: f64,
    /// Corner detection in the empty cells.
    pub corners_ms: f64,
    /// The sliding window's bundle adjustment.
    pub window_ms: f64,
}

impl StageTimes {
    /// The stages' names and times, in pipeline order.
    pub fn named(&self) -> [(&'static str, f64); 6] {
        [
            ("pyramid", self.pyramid_ms),
            ("track", self.track_ms),
            ("stereo", self.stereo_ms),
            ("motion", self.motion_ms),
            ("corners", self.corners_ms),
            ("window", self.window_ms),
        ]
    }
}

/// Milliseconds since `start`, and restarts it.
pub(super) fn lap_ms(start: &mut Instant) -> f64 {
    let now = Instant::now();
    let ms = (now - *start).as_secs_f64() * 1e3;
    *start = now;
    ms
}
