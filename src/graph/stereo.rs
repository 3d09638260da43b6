//! A rectified stereo camera as the stereo projection factor sees it: the projection of a
//! point in the left camera's frame to `(u_left, u_right, v)` pixels and its Jacobian, as
//! GTSAM's `StereoCamera` / `Cal3_S2Stereo`.
//!
//! The camera frame is the left camera's: x right, y down, z forward (optical axis); the
//! right camera sits at `+baseline_m` along x.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Intrinsics of a rectified stereo pair (both cameras share them).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StereoCalibration {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Skew, pixels.
    pub skew: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Distance between the two optical centres, metres.
    pub baseline_m: f64,
}

/// Why a calibration was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationProblem {
    /// A value is NaN or infinite.
    #[error("non-finite value in the stereo calibration")]
    NonFinite,
    /// A focal length is zero or negative.
    #[error("focal length must be positive (fx = {fx}, fy = {fy})")]
    FocalLength {
        /// fx.
        fx: f64,
        /// fy.
        fy: f64,
    },
    /// The baseline is zero or negative.
    #[error("baseline must be positive, got {0} m")]
    Baseline(f64),
}

impl StereoCalibration {
    /// Checks that every value is finite and the focal lengths and baseline positive.
    pub fn validate(&self) -> Result<(), CalibrationProblem> {
        let values = [
            self.fx,
            self.fy,
            self.skew,
            self.cx,
            self.cy,
            self.baseline_m,
        ];
        if !values.iter().all(|v| v.is_finite()) {
            return Err(CalibrationProblem::NonFinite);
        }
        if self.fx <= 0.0 || self.fy <= 0.0 {
            return Err(CalibrationProblem::FocalLength {
                fx: self.fx,
                fy: self.fy,
            });
        }
        if self.baseline_m <= 0.0 {
            return Err(CalibrationProblem::Baseline(self.baseline_m));
        }
        Ok(())
    }

    /// `(u_left, u_right, v)` of a point `q` in the left camera's frame, or `None` when it
    /// is not in front of the camera (`q.z ≤ 0`).
    pub fn project(&self, q: &Vector3<f64>) -> Option<Vector3<f64>> {
        if q.z <= 0.0 || !q.z.is_finite() {
            return None;
        }
        let inv_z = 1.0 / q.z;
        let u_left = self.fx * q.x * inv_z + self.skew * q.y * inv_z + self.cx;
        let u_right = u_left - self.fx * self.baseline_m * inv_z;
        let v = self.fy * q.y * inv_z + self.cy;
        Some(Vector3::new(u_left, u_right, v))
    }

    /// `∂(u_left, u_right, v)/∂q` at a point in front of the camera.
    pub fn projection_jacobian(&self, q: &Vector3<f64>) -> Matrix3<f64> {
        let inv_z = 1.0 / q.z;
        let inv_z2 = inv_z * inv_z;
        let du_dz = -(self.fx * q.x + self.skew * q.y) * inv_z2;
        let fb = self.fx * self.baseline_m;
        Matrix3::new(
            self.fx * inv_z,
            self.skew * inv_z,
            du_dz,
            self.fx * inv_z,
            self.skew * inv_z,
            du_dz + fb * inv_z2,
            0.0,
            self.fy * inv_z,
            -self.fy * q.y * inv_z2,
        )
    }

    /// The point in the left camera's frame seen at `(u_left, u_right, v)`, or `None` for a
    /// disparity `u_left − u_right` that is not positive.
    pub fn backproject(&self, uv: &Vector3<f64>) -> Option<Vector3<f64>> {
        let disparity = uv.x - uv.y;
        if disparity <= 0.0 || !disparity.is_finite() {
            return None;
        }
        let z = self.fx * self.baseline_m / disparity;
        let y = (uv.z - self.cy) * z / self.fy;
        let x = (uv.x - self.cx - self.skew * y / z) * z / self.fx;
        Some(Vector3::new(x, y, z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kitti() -> StereoCalibration {
        StereoCalibration {
            fx: 721.5,
            fy: 720.0,
            skew: 0.3,
            cx: 609.6,
            cy: 172.9,
            baseline_m: 0.537,
        }
    }

    #[test]
    fn projection_jacobian_matches_finite_differences() {
        let cal = kitti();
        let q = Vector3::new(-2.0, 1.3, 9.0);
        let j = cal.projection_jacobian(&q);
        let h = 1e-6;
        for k in 0..3 {
            let mut d = Vector3::zeros();
            d[k] = h;
            let (Some(p), Some(m)) = (cal.project(&(q + d)), cal.project(&(q - d))) else {
                panic!("point left the image");
            };
            let col = (p - m) / (2.0 * h);
            assert!((col - j.column(k)).abs().max() < 1e-5, "column {k}");
        }
    }

    #[test]
    fn backprojection_inverts_projection() {
        let cal = kitti();
        let q = Vector3::new(3.0, -0.4, 17.0);
        let uv = cal.project(&q).unwrap();
        assert!((cal.backproject(&uv).unwrap() - q).norm() < 1e-9);
        assert!(cal.project(&Vector3::new(0.0, 0.0, -1.0)).is_none());
    }

    #[test]
    fn bad_calibrations_are_refused() {
        let mut cal = kitti();
        cal.baseline_m = 0.0;
        assert!(matches!(
            cal.validate(),
            Err(CalibrationProblem::Baseline(_))
        ));
        let mut cal = kitti();
        cal.fy = -1.0;
        assert!(matches!(
            cal.validate(),
            Err(CalibrationProblem::FocalLength { .. })
        ));
        assert!(kitti().validate().is_ok());
    }
}
