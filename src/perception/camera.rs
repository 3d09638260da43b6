//! The rectified stereo camera model (pinhole, no distortion) and the IPEX front pair.
//!
//! Pixel convention: integer coordinates are pixel centres, `u` to the right, `v` down.
//! The camera (optical) frame has x right, y down, z forward (metres).

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::PerceptionError;

/// IPEX front cameras at 1280 × 720: focal length in pixels (70° horizontal field of view).
pub const IPEX_FOCAL_PX: f64 = 914.015;
/// IPEX image width at full resolution.
pub const IPEX_WIDTH: usize = 1280;
/// IPEX image height at full resolution.
pub const IPEX_HEIGHT: usize = 720;
/// IPEX front stereo baseline, metres.
pub const IPEX_BASELINE_M: f64 = 0.162;

/// A rectified stereo pair: shared intrinsics of the left and right image and the baseline.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StereoCamera {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Horizontal focal length, pixels.
    pub fx: f64,
    /// Vertical focal length, pixels.
    pub fy: f64,
    /// Principal point column, pixels.
    pub cx: f64,
    /// Principal point row, pixels.
    pub cy: f64,
    /// Distance between the two optical centres, metres (right camera at +x of the left).
    pub baseline_m: f64,
}

impl Default for StereoCamera {
    fn default() -> Self {
        StereoCamera::ipex()
    }
}

impl StereoCamera {
    /// The IPEX front stereo pair at 1280 × 720.
    pub fn ipex() -> Self {
        StereoCamera {
            width: IPEX_WIDTH,
            height: IPEX_HEIGHT,
            fx: IPEX_FOCAL_PX,
            fy: IPEX_FOCAL_PX,
            cx: 640.0,
            cy: 360.0,
            baseline_m: IPEX_BASELINE_M,
        }
    }

    /// The pinhole model the stereo factors and the visual odometry use (no skew).
    pub fn calibration(&self) -> crate::graph::StereoCalibration {
        crate::graph::StereoCalibration {
            fx: self.fx,
            fy: self.fy,
            skew: 0.0,
            cx: self.cx,
            cy: self.cy,
            baseline_m: self.baseline_m,
        }
    }

    /// This camera for images of `width × height`: the same camera scaled, if the size is a
    /// uniform scaling of this one (so `ipex().for_size(640, 360)` is the IPEX camera at half
    /// resolution); otherwise an error naming both sizes.
    pub fn for_size(&self, width: usize, height: usize) -> Result<Self, PerceptionError> {
        if width == self.width && height == self.height {
            return Ok(*self);
        }
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        if width == 0 || height == 0 || (sx - sy).abs() > 1e-9 {
            return Err(PerceptionError::ImageSize {
                path: "<image>".into(),
                message: format!(
                    "image is {width} × {height}, but the camera model is {} × {} \
                     (only uniform scalings of it are supported)",
                    self.width, self.height
                ),
            });
        }
        Ok(self.scaled(sx, width, height))
    }

    /// The camera for images scaled by `factor` (so that a pixel centre at `u` maps to
    /// `(u + 0.5) * factor - 0.5`), with the given output size.
    pub fn scaled(&self, factor: f64, width: usize, height: usize) -> Self {
        StereoCamera {
            width,
            height,
            fx: self.fx * factor,
            fy: self.fy * factor,
            cx: (self.cx + 0.5) * factor - 0.5,
            cy: (self.cy + 0.5) * factor - 0.5,
            baseline_m: self.baseline_m,
        }
    }

    /// The angular size of one pixel at the image centre, radians (α in s = σ · D · α).
    pub fn angular_resolution_rad(&self) -> f64 {
        1.0 / self.fx
    }

    /// Depth (metres along z) of a disparity in pixels; `None` unless positive and finite.
    pub fn depth_from_disparity(&self, disparity_px: f64) -> Option<f64> {
        (disparity_px.is_finite() && disparity_px > 0.0)
            .then(|| self.fx * self.baseline_m / disparity_px)
    }

    /// Disparity in pixels of a point at `depth_m`.
    pub fn disparity_from_depth(&self, depth_m: f64) -> f64 {
        self.fx * self.baseline_m / depth_m
    }

    /// The point of pixel `(u, v)` at depth `depth_m`, in the left camera frame.
    pub fn back_project(&self, u: f64, v: f64, depth_m: f64) -> Point3<f64> {
        Point3::new(
            (u - self.cx) / self.fx * depth_m,
            (v - self.cy) / self.fy * depth_m,
            depth_m,
        )
    }

    /// The pixel of a point in the left camera frame (`None` behind the camera).
    pub fn project(&self, p_camera: &Point3<f64>) -> Option<(f64, f64)> {
        (p_camera.z > 0.0).then(|| {
            (
                self.fx * p_camera.x / p_camera.z + self.cx,
                self.fy * p_camera.y / p_camera.z + self.cy,
            )
        })
    }
}

/// Where the left camera of the stereo pair sits on the rover: `rover_from_camera` maps the
/// optical frame (x right, y down, z forward) into the rover body frame (x forward, y left,
/// z up).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CameraMount {
    /// Position of the left camera's optical centre in the rover frame, metres.
    pub position_m: [f64; 3],
    /// Roll, pitch, yaw of the camera's viewing frame (x forward, y left, z up) in the rover
    /// frame, radians.
    pub roll_pitch_yaw_rad: [f64; 3],
}

impl Default for CameraMount {
    fn default() -> Self {
        CameraMount::ipex_front_left()
    }
}

impl CameraMount {
    /// The IPEX front-left camera: (0.28, 0.081, 0.131) m, looking straight ahead.
    pub fn ipex_front_left() -> Self {
        CameraMount {
            position_m: [0.28, 0.081, 0.131],
            roll_pitch_yaw_rad: [0.0; 3],
        }
    }

    /// The transform from the optical frame to the rover frame.
    pub fn rover_from_camera(&self) -> Isometry3<f64> {
        // body-style camera frame (x fwd, y left, z up) from optical (x right, y down, z fwd)
        let body_from_optical = UnitQuaternion::from_matrix(&nalgebra::Matrix3::new(
            0.0, 0.0, 1.0, //
            -1.0, 0.0, 0.0, //
            0.0, -1.0, 0.0,
        ));
        let [r, p, y] = self.roll_pitch_yaw_rad;
        let rover_from_body = UnitQuaternion::from_euler_angles(r, p, y);
        let [x, yy, z] = self.position_m;
        Isometry3::from_parts(
            Translation3::from(Vector3::new(x, yy, z)),
            rover_from_body * body_from_optical,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_resolution_keeps_rays() {
        let full = StereoCamera::ipex();
        let half = full.for_size(640, 360).unwrap();
        assert!((half.fx - 457.0075).abs() < 1e-9);
        // the half-res pixel (i, j) covers full-res (2i + 0.5, 2j + 0.5)
        let p = full.back_project(2.0 * 100.0 + 0.5, 2.0 * 50.0 + 0.5, 4.0);
        let q = half.back_project(100.0, 50.0, 4.0);
        assert!((p - q).norm() < 1e-12);
        // depth from disparity is scale invariant
        let z_full = full.depth_from_disparity(45.0).unwrap();
        let z_half = half.depth_from_disparity(22.5).unwrap();
        assert!((z_full - z_half).abs() < 1e-12);
        assert!((z_full - 3.29).abs() < 0.01);
    }

    #[test]
    fn non_uniform_size_is_refused() {
        assert!(StereoCamera::ipex().for_size(1280, 700).is_err());
        assert!(StereoCamera::ipex().for_size(0, 0).is_err());
    }

    #[test]
    fn optical_axis_points_forward_in_rover_frame() {
        let t = CameraMount::ipex_front_left().rover_from_camera();
        let p = t * Point3::new(0.0, 0.0, 2.0);
        assert!((p - Point3::new(2.28, 0.081, 0.131)).norm() < 1e-12);
        let right = t * Point3::new(1.0, 0.0, 0.0);
        assert!((right.y - (0.081 - 1.0)).abs() < 1e-12);
        let down = t * Point3::new(0.0, 1.0, 0.0);
        assert!((down.z - (0.131 - 1.0)).abs() < 1e-12);
    }
}
