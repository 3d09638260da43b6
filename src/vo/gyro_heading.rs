//! The heading from the gyro, its bias estimated from the images.
//!
//! Gravity anchors the odometry's roll and pitch ([`super::gravity_tilt`]) but not its
//! heading, and on rendered drives the images' heading drifts about four times faster than
//! an integrated gyro's (docs/design/vo-gyro-heading.md). The gyro's error is a nearly
//! constant bias; the images' is zero-mean over minutes. So the difference of the gyro's
//! rate and the images' rate, averaged over `bias_time_constant_s`, estimates the bias, and
//! each frame's change of heading (its turn about the vertical) is taken from the gyro with
//! that bias removed, while the images keep the tilt and the translation. Without a gyro
//! rate or a gravity reference for a frame, its heading stays the images'.

use nalgebra::{Isometry3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// How the odometry takes its heading from the gyro.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VoGyroHeadingConfig {
    /// Take each frame's change of heading from the bias-corrected gyro (when the frame has
    /// a gyro rate and gravity's reference direction is known).
    pub enabled: bool,
    /// Time constant of the average of `gyro − images` rates that estimates the gyro's bias,
    /// seconds: longer averages more of the images' slowly varying error away, but follows
    /// a changing bias more slowly.
    pub bias_time_constant_s: f64,
    /// Largest rate difference between the gyro and the images taken into the average,
    /// rad/s: a frame whose image rotation is wrong by more is left out.
    pub max_rate_difference_rad_s: f64,
}

impl Default for VoGyroHeadingConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            bias_time_constant_s: 120.0,
            max_rate_difference_rad_s: 0.01,
        }
    }
}

impl VoGyroHeadingConfig {
    /// `Ok` when the time constant and the rate bound are finite and positive, else the
    /// name of the offending field.
    pub fn validate(&self) -> Result<(), &'static str> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.bias_time_constant_s) {
            return Err("gyro_heading.bias_time_constant_s must be positive");
        }
        if !positive(self.max_rate_difference_rad_s) {
            return Err("gyro_heading.max_rate_difference_rad_s must be positive");
        }
        Ok(())
    }
}

/// One frame's inputs to [`GyroHeading::correct`].
#[derive(Clone, Copy, Debug)]
pub struct HeadingInputs {
    /// The gyro's rotation `curr_from_prev` in the camera's frame, bias included.
    pub gyro_curr_from_prev: Option<UnitQuaternion<f64>>,
    /// Seconds since the previous frame.
    pub dt_s: Option<f64>,
    /// The vertical (up) in the first camera's frame, when gravity's reference is known.
    pub up_first: Option<Unit<Vector3<f64>>>,
    /// Whether the frame's rotation came from the images (false when the frame was lost or
    /// kept the gyro's rotation): only then does it inform the bias.
    pub measured: bool,
}

/// The gyro's bias estimate and the previous frame's orientation.
#[derive(Clone, Debug, Default)]
pub struct GyroHeading {
    /// The gyro's bias in the camera's frame, rad/s (rates in the `prev_from_curr` sense).
    bias_camera_rad_s: Vector3<f64>,
    /// Seconds of image rotation averaged into the bias so far.
    observed_s: f64,
    /// The previous frame's orientation `first_from_camera` as given out.
    previous: Option<UnitQuaternion<f64>>,
}

impl GyroHeading {
    /// The current bias estimate in the camera's frame, rad/s.
    pub fn bias_camera_rad_s(&self) -> Vector3<f64> {
        self.bias_camera_rad_s
    }

    /// `first_from_camera` with its change of heading since the previous frame replaced by
    /// the bias-corrected gyro's (turned about the vertical through the camera, so its
    /// position and tilt stay); first updates the bias from this frame when `measured`.
    pub fn correct(
        &mut self,
        config: &VoGyroHeadingConfig,
        first_from_camera: &Isometry3<f64>,
        inputs: &HeadingInputs,
    ) -> Isometry3<f64> {
        let current = first_from_camera.rotation;
        let previous = self.previous.replace(current);
        let (Some(prev), Some(gyro), Some(dt_s), Some(up)) = (
            previous,
            inputs.gyro_curr_from_prev,
            inputs.dt_s,
            inputs.up_first,
        ) else {
            return *first_from_camera;
        };
        if !(config.enabled && dt_s.is_finite() && dt_s > 0.0) {
            return *first_from_camera;
        }
        let image_rad = (prev.inverse() * current).scaled_axis();
        let gyro_rad = gyro.inverse().scaled_axis();
        if inputs.measured {
            self.update_bias(config, &(gyro_rad / dt_s - image_rad / dt_s), dt_s);
        }
        let corrected_rad = gyro_rad - self.bias_camera_rad_s * dt_s;
        // the change of heading is the turn about the vertical, in the first camera's frame
        let heading = |rad: &Vector3<f64>| up.dot(&(prev * rad));
        let delta = heading(&corrected_rad) - heading(&image_rad);
        if !delta.is_finite() {
            return *first_from_camera;
        }
        let rotation = UnitQuaternion::from_axis_angle(&up, delta) * current;
        self.previous = Some(rotation);
        Isometry3::from_parts(first_from_camera.translation, rotation)
    }

    /// Averages one frame's `gyro − images` rate difference into the bias: a plain mean
    /// until one time constant has been seen, an exponential average after.
    fn update_bias(&mut self, config: &VoGyroHeadingConfig, difference: &Vector3<f64>, dt_s: f64) {
        if !difference.iter().all(|v| v.is_finite())
            || difference.norm() > config.max_rate_difference_rad_s
        {
            return;
        }
        self.observed_s += dt_s;
        let weight = (dt_s / self.observed_s).max(dt_s / config.bias_time_constant_s);
        self.bias_camera_rad_s += (difference - self.bias_camera_rad_s) * weight.min(1.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `curr_from_prev` of a body turning at `rate` (prev_from_curr sense) for `dt`.
    fn curr_from_prev(rate_rad_s: Vector3<f64>, dt_s: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_scaled_axis(rate_rad_s * dt_s).inverse()
    }

    /// Heading error (about `up`) of `estimate` against `truth`.
    fn heading_error(
        truth: &UnitQuaternion<f64>,
        estimate: &UnitQuaternion<f64>,
        up: &Unit<Vector3<f64>>,
    ) -> f64 {
        up.dot(&(estimate * truth.inverse()).scaled_axis())
    }

    /// Mean absolute change of a heading error over `span` frames, after `warm_up` frames.
    fn drift_over(errors: &[f64], span: usize, warm_up: usize) -> f64 {
        let changes: Vec<f64> = (warm_up..errors.len() - span)
            .step_by(10)
            .map(|k| (errors[k + span] - errors[k]).abs())
            .collect();
        changes.iter().sum::<f64>() / changes.len() as f64
    }

    #[test]
    fn the_heading_follows_the_corrected_gyro_not_the_drifting_images() {
        // optical frame, level camera: up is -y
        let up = Unit::new_normalize(Vector3::new(0.0, -1.0, 0.0));
        let bias = Vector3::new(2e-5, -1e-4, 3e-5);
        let config = VoGyroHeadingConfig::default();
        let (dt, frames, span) = (0.1, 6000, 300);
        let mut heading = GyroHeading::default();
        let (mut truth, mut images) = (UnitQuaternion::identity(), UnitQuaternion::identity());
        let mut pose = Isometry3::identity();
        let inputs = |gyro, measured| HeadingInputs {
            gyro_curr_from_prev: gyro,
            dt_s: Some(dt),
            up_first: Some(up),
            measured,
        };
        heading.correct(&config, &pose, &inputs(None, false));
        let mut seed = 12345u64;
        let (mut fused_errors, mut image_errors) = (Vec::new(), Vec::new());
        for k in 0..frames {
            let rate = Vector3::new(0.0, -0.05 * (k as f64 * 0.01).sin(), 0.0);
            // the images' rate error: white, uniform within ±1.7e-3 rad/s about each axis
            let mut noise = || {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 3.4e-3
            };
            let image_rate = rate + Vector3::new(noise(), noise(), noise());
            truth *= curr_from_prev(rate, dt).inverse();
            images *= curr_from_prev(image_rate, dt).inverse();
            // this frame's image increment on top of the previous output
            let given = Isometry3::from_parts(
                pose.translation,
                pose.rotation * curr_from_prev(image_rate, dt).inverse(),
            );
            let gyro = Some(curr_from_prev(rate + bias, dt));
            pose = heading.correct(&config, &given, &inputs(gyro, true));
            fused_errors.push(heading_error(&truth, &pose.rotation, &up));
            image_errors.push(heading_error(&truth, &images, &up));
        }
        let fused = drift_over(&fused_errors, span, 1200);
        let image_only = drift_over(&image_errors, span, 1200);
        let gyro_only = bias.y.abs() * dt * span as f64;
        assert!(
            fused < 0.5 * gyro_only,
            "fused {fused}, gyro alone {gyro_only}"
        );
        assert!(
            fused < 0.5 * image_only,
            "fused {fused}, images alone {image_only}"
        );
        assert!((heading.bias_camera_rad_s().y - bias.y).abs() < 3e-5);
    }

    #[test]
    fn without_gravity_or_gyro_the_pose_is_untouched() {
        let mut heading = GyroHeading::default();
        let config = VoGyroHeadingConfig::default();
        let pose = Isometry3::from_parts(
            Vector3::new(1.0, 2.0, 3.0).into(),
            UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3),
        );
        let gyro = Some(curr_from_prev(Vector3::new(0.0, 0.1, 0.0), 0.1));
        for inputs in [
            HeadingInputs {
                gyro_curr_from_prev: gyro,
                dt_s: Some(0.1),
                up_first: None,
                measured: true,
            },
            HeadingInputs {
                gyro_curr_from_prev: None,
                dt_s: Some(0.1),
                up_first: Some(Vector3::y_axis()),
                measured: true,
            },
        ] {
            assert_eq!(heading.correct(&config, &pose, &inputs), pose);
        }
        assert_eq!(heading.bias_camera_rad_s(), Vector3::zeros());
    }

    #[test]
    fn bad_settings_are_named() {
        let config = VoGyroHeadingConfig {
            bias_time_constant_s: 0.0,
            ..VoGyroHeadingConfig::default()
        };
        assert!(config
            .validate()
            .unwrap_err()
            .contains("bias_time_constant_s"));
        assert!(VoGyroHeadingConfig::default().validate().is_ok());
    }
}
