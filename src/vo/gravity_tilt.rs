//! The IMU's gravity as a roll–pitch anchor of the odometry.
//!
//! The images fix the camera's rotation frame to frame only, so its tilt drifts like its
//! heading (on rendered drives most of the rotation drift is tilt: docs/design/vo-gravity.md).
//! Gravity is seen directly: the accelerometer's reading, moved into the camera's frame and
//! then into the first camera's by the estimated orientation, should always point the same
//! way. The reference direction is the mean over the first `reference_frames` frames; after
//! that every frame's orientation is turned by `gain` of the tilt between its gravity and
//! the reference (about the axis perpendicular to both, so the heading is untouched): a
//! complementary filter whose time constant is `1 / gain` frames. A constant bias of the
//! accelerometer tilts the reference and every reading alike, so it cancels.

use nalgebra::{Isometry3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// How the odometry uses the IMU's gravity.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VoGravityConfig {
    /// Anchor roll and pitch to gravity when the frames carry it (and the camera's mount is
    /// known).
    pub enabled: bool,
    /// Share of the tilt between a frame's gravity and the reference removed at that frame
    /// (0 to 1).
    pub gain: f64,
    /// Frames whose gravity, in the first camera's frame, is averaged into the reference.
    pub reference_frames: usize,
}

impl Default for VoGravityConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            gain: 0.05,
            reference_frames: 20,
        }
    }
}

/// The reference direction of gravity in the first camera's frame, and the correction.
#[derive(Clone, Debug, Default)]
pub struct GravityAnchor {
    sum: Vector3<f64>,
    frames: usize,
}

impl GravityAnchor {
    /// The vertical (up, against gravity) in the first camera's frame, once the reference
    /// frames have been averaged.
    pub fn up_first(&self, config: &VoGravityConfig) -> Option<Unit<Vector3<f64>>> {
        if self.frames < config.reference_frames.max(1) {
            return None;
        }
        Unit::try_new(-self.sum, 1e-9)
    }

    /// `first_from_camera` with its tilt turned toward the reference by the configured
    /// gain, given gravity measured in the camera's frame (any length); the frames of the
    /// reference are only accumulated. A zero or non-finite reading changes nothing.
    pub fn correct(
        &mut self,
        config: &VoGravityConfig,
        first_from_camera: &Isometry3<f64>,
        gravity_camera: &Vector3<f64>,
    ) -> Isometry3<f64> {
        if !gravity_camera.iter().all(|v| v.is_finite()) {
            return *first_from_camera;
        }
        let Some(g_camera) = Unit::try_new(*gravity_camera, 1e-9) else {
            return *first_from_camera;
        };
        let g_first = first_from_camera.rotation * g_camera;
        if self.frames < config.reference_frames {
            self.sum += g_first.into_inner();
            self.frames += 1;
            return *first_from_camera;
        }
        let Some(reference) = Unit::try_new(self.sum, 1e-9) else {
            return *first_from_camera;
        };
        let Some(tilt) = UnitQuaternion::rotation_between_axis(&g_first, &reference) else {
            return *first_from_camera;
        };
        let step = UnitQuaternion::identity().slerp(&tilt, config.gain.clamp(0.0, 1.0));
        Isometry3::from_parts(
            first_from_camera.translation,
            step * first_from_camera.rotation,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drifted_tilt_is_pulled_back_and_the_heading_kept() {
        let config = VoGravityConfig {
            gain: 0.5,
            reference_frames: 1,
            ..VoGravityConfig::default()
        };
        let down = Vector3::new(0.0, 1.0, 0.0); // optical frame: y down
        let mut anchor = GravityAnchor::default();
        let level = Isometry3::identity();
        assert_eq!(anchor.correct(&config, &level, &down), level);
        // the estimate drifted 1 degree of pitch (about x) and turned 30 degrees (about y,
        // the vertical); the camera itself is level, so gravity still reads straight down
        let heading = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.5);
        let drift = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1f64.to_radians());
        let drifted = Isometry3::from_parts(Vector3::new(1.0, 2.0, 3.0).into(), drift * heading);
        let mut pose = drifted;
        for _ in 0..30 {
            pose = anchor.correct(&config, &pose, &down);
        }
        let left = pose.rotation.angle_to(&heading);
        assert!(left < 1e-6, "tilt left: {left}");
        assert_eq!(pose.translation, drifted.translation);
    }
}
