//! A stereo recording as the online localizer's frames: pixels in, `StreamFrame`s out.
//!
//! Each stereo pair of a sequence (a `.lac` recording, a `segloc sim render` folder, a
//! KITTI-layout folder) goes through three named stages:
//! 1. `odometry`: the stereo visual odometry ([`crate::vo`], helped by the gyro when the
//!    recording has one) gives the left camera's motion,
//!    turned into `odom_from_rover` through the camera's mount (the odometry frame is the
//!    rover frame at the first pair);
//! 2. `detect`: every `detect_period_s` the perception front end ([`crate::perception`])
//!    finds the boulders of the pair, kept within the range window and moved into the
//!    rover frame;
//! 3. `frame`: the two, with the IMU's gravity when the recording has it, make one
//!    [`StreamFrame`], the input of [`crate::localizer`]'s `Localizer::push_frame` and the
//!    record of a frames file (maps/FORMAT.md).
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use segloc::image_stream::{ImageStream, ImageStreamConfig};
//! use segloc::perception::GeometricSegmenter;
//! use segloc::vo::StereoSequence;
//! let sequence = StereoSequence::read_lac(std::path::Path::new("run.lac"))?;
//! let config = ImageStreamConfig::default();
//! let segmenter = Box::new(GeometricSegmenter::new(config.front_end.geometric.clone()));
//! let mut stream = ImageStream::new(sequence.calibration, config, segmenter)?;
//! for k in 0..sequence.frames.len() {
//!     let [(left, _), (right, _)] = sequence.load(k)?;
//!     let frame = &sequence.frames[k];
//!     let out = stream.push_pair(&left, &right, frame.time_s, frame.imu())?;
//!     println!("{} boulders at t = {}", out.frame.detections.len(), out.frame.t);
//! }
//! # Ok(())
//! # }
//! ```

use crate::graph::{se3, StereoCalibration};
use crate::perception::{FrontEnd, FrontEndConfig, GrayImage, PerceptionError, Segmenter};
use crate::vo::{
    FrameResult as VoFrame, ImuSample, StereoOdometry, StereoSequence, VoConfig, VoError,
};
use nalgebra::{Isometry3, Matrix6, Point3};
use segloc_maps::frames::{FrameDetection, StreamFrame};
use serde::{Deserialize, Serialize};

/// What can go wrong turning images into frames.
#[derive(Debug, thiserror::Error)]
pub enum ImageStreamError {
    /// The odometry (its configuration, or a sequence that cannot be read).
    #[error(transparent)]
    Vo(#[from] VoError),
    /// The front end (its configuration, or a pair it cannot process).
    #[error(transparent)]
    Perception(#[from] PerceptionError),
    /// A setting out of range (the message names the TOML field).
    #[error("invalid configuration: {0}")]
    Config(String),
}

/// Settings of the image stream (TOML-loadable; every field has a default).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImageStreamConfig {
    /// The stereo visual odometry.
    pub vo: VoConfig,
    /// The perception front end; its `mount` places the left camera on the rover.
    pub front_end: FrontEndConfig,
    /// Seconds between the pairs whose boulders are detected (the mission's cameras take
    /// one a second); 0 detects on every pair.
    pub detect_period_s: f64,
    /// Nearest kept boulder, depth along the optical axis, metres.
    pub min_range_m: f64,
    /// Farthest kept boulder, depth along the optical axis, metres.
    pub max_range_m: f64,
}

impl Default for ImageStreamConfig {
    fn default() -> Self {
        Self {
            vo: VoConfig::default(),
            front_end: FrontEndConfig::default(),
            detect_period_s: 1.0,
            min_range_m: 0.5,
            max_range_m: 7.0,
        }
    }
}

impl ImageStreamConfig {
    /// Checks the ranges, naming the TOML field.
    pub fn validate(&self) -> Result<(), ImageStreamError> {
        let bad = |m: &str| Err(ImageStreamError::Config(m.to_string()));
        if !(self.detect_period_s.is_finite() && self.detect_period_s >= 0.0) {
            return bad("detect_period_s must be a non-negative number");
        }
        if !(self.min_range_m.is_finite()
            && self.min_range_m >= 0.0
            && self.max_range_m > self.min_range_m)
        {
            return bad("max_range_m must exceed min_range_m >= 0");
        }
        self.vo.validate()?;
        Ok(())
    }
}

/// One pair's outcome.
#[derive(Clone, Debug)]
pub struct StreamOutput {
    /// The localizer's frame.
    pub frame: StreamFrame,
    /// What the odometry did on this pair (tracked features, inliers, lost, time).
    pub vo: VoFrame,
    /// The front end's time on this pair, milliseconds (`None`: no detection this pair).
    pub front_end_ms: Option<f64>,
}

/// The stages of the module docs, run pair by pair.
pub struct ImageStream {
    config: ImageStreamConfig,
    odometry: StereoOdometry,
    front_end: FrontEnd,
    rover_from_camera: Isometry3<f64>,
    last_detection_s: Option<f64>,
}

impl ImageStream {
    /// A stream for a camera with this calibration, detecting with `segmenter`.
    pub fn new(
        calibration: StereoCalibration,
        config: ImageStreamConfig,
        segmenter: Box<dyn Segmenter>,
    ) -> Result<Self, ImageStreamError> {
        config.validate()?;
        let mut odometry = StereoOdometry::new(calibration, config.vo.clone())?;
        odometry.set_gyro_mount(config.front_end.mount.rover_from_camera().rotation);
        let front_end = FrontEnd::new(config.front_end.clone(), segmenter)?;
        Ok(Self {
            rover_from_camera: config.front_end.mount.rover_from_camera(),
            config,
            odometry,
            front_end,
            last_detection_s: None,
        })
    }

    /// One rectified pair at `time_s`, with what the IMU measured when known.
    pub fn push_pair(
        &mut self,
        left: &GrayImage,
        right: &GrayImage,
        time_s: f64,
        imu: ImuSample,
    ) -> Result<StreamOutput, ImageStreamError> {
        let vo = self.odometry.process_with_imu(
            left,
            right,
            time_s,
            imu.gyro_rover_rad_s,
            imu.gravity_rover,
        );
        let gravity_rover = imu.gravity_rover;
        let odom_from_rover = self.rover_from_camera * vo.pose * self.rover_from_camera.inverse();
        let mut frame = StreamFrame::new(time_s, odom_from_rover);
        frame.gravity_rover = gravity_rover;
        frame.step_cov =
            step_covariance_rover(&vo, &self.rover_from_camera, self.config.vo.window.sigma_px);
        let front_end_ms = if self.detection_due(time_s) {
            let (detections, ms) = self.detect(left, right)?;
            frame.detections = detections;
            self.last_detection_s = Some(time_s);
            Some(ms)
        } else {
            None
        };
        Ok(StreamOutput {
            frame,
            vo,
            front_end_ms,
        })
    }

    /// Whether this pair's boulders are detected.
    fn detection_due(&self, time_s: f64) -> bool {
        match self.last_detection_s {
            None => true,
            // a hundredth of a frame of slack, so a 1 s period at 10 Hz is every tenth pair
            Some(last) => time_s - last >= self.config.detect_period_s - 1e-6,
        }
    }

    /// The front end's boulders within the range window, in the rover frame.
    fn detect(
        &mut self,
        left: &GrayImage,
        right: &GrayImage,
    ) -> Result<(Vec<FrameDetection>, f64), ImageStreamError> {
        let result = self.front_end.process(left, right)?;
        let detections = result
            .boulders
            .iter()
            .filter(|b| {
                let depth = b.position_camera[2];
                depth >= self.config.min_range_m
                    && depth <= self.config.max_range_m
                    && b.size_m.is_finite()
                    && b.size_m > 0.0
            })
            .map(|b| FrameDetection {
                p_rover: self.rover_from_camera * Point3::from(b.position_camera),
                size_m: Some(b.size_m),
                cov_rover: None,
            })
            .collect();
        Ok((detections, result.timing.total_ms))
    }
}

/// The covariance of a VO frame's motion as a frames file's `step_cov`: a right
/// perturbation of `prev_from_rover` in the rover's axes, from the motion refinement's `JᵀJ`
/// at `sigma_px` of image noise. `None` when the images gave no motion of their own (lost,
/// or the gyro's rotation kept): the localizer then uses its noise model.
pub fn step_covariance_rover(
    vo: &VoFrame,
    rover_from_camera: &Isometry3<f64>,
    sigma_px: f64,
) -> Option<Matrix6<f64>> {
    if vo.lost || vo.gyro_rotation {
        return None;
    }
    // a left perturbation of curr_from_prev is minus a right one of prev_from_curr: the
    // same covariance; X·A·Exp(ξ)·X⁻¹ = (X·A·X⁻¹)·Exp(Ad(X) ξ) moves it into the rover's axes
    let cov_camera = vo.information.try_inverse()? * (sigma_px * sigma_px);
    let ad = se3::adjoint(rover_from_camera);
    let cov = ad * cov_camera * ad.transpose();
    let cov = (cov + cov.transpose()) * 0.5;
    (cov.iter().all(|v| v.is_finite()) && cov.cholesky().is_some()).then_some(cov)
}

/// Every pair of `sequence` through an [`ImageStream`], in time order.
pub fn stream_sequence(
    sequence: &StereoSequence,
    config: ImageStreamConfig,
    segmenter: Box<dyn Segmenter>,
) -> Result<Vec<StreamOutput>, ImageStreamError> {
    let mut stream = ImageStream::new(sequence.calibration, config, segmenter)?;
    let mut outputs = Vec::with_capacity(sequence.frames.len());
    for (k, frame) in sequence.frames.iter().enumerate() {
        let [(left, _), (right, _)] = sequence.load(k)?;
        outputs.push(stream.push_pair(&left, &right, frame.time_s, frame.imu())?);
    }
    Ok(outputs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::GeometricSegmenter;
    use nalgebra::Vector3;

    fn calibration() -> StereoCalibration {
        StereoCalibration {
            fx: 100.0,
            fy: 100.0,
            skew: 0.0,
            cx: 64.0,
            cy: 36.0,
            baseline_m: 0.162,
        }
    }

    #[test]
    fn the_vo_covariance_moves_into_the_rover_axes() {
        // an optical camera (z forward, x right, y down) looking along the rover's x, 1 m
        // up: the camera's depth variance is the rover's x variance
        let rover_from_camera = Isometry3::from_parts(
            Vector3::new(0.0, 0.0, 1.0).into(),
            nalgebra::UnitQuaternion::from_matrix(&nalgebra::Matrix3::new(
                0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
            )),
        );
        let sigmas = [1e-3, 2e-3, 3e-3, 0.01, 0.02, 0.05]; // rx ry rz x y z of the camera
        let information = Matrix6::from_diagonal(&nalgebra::Vector6::from_iterator(
            sigmas.iter().map(|s| 1.0 / (s * s)),
        ));
        let vo = VoFrame {
            time_s: 0.1,
            pose: Isometry3::identity(),
            tracked: 100,
            inliers: 90,
            features: 100,
            lost: false,
            information,
            rotation_sigma_deg: 0.1,
            gyro_rotation: false,
            time_ms: 1.0,
            stages: Default::default(),
        };
        let cov = step_covariance_rover(&vo, &rover_from_camera, 1.0).unwrap();
        // rotations: camera z (optical axis) is rover x, camera x is rover −y, camera y
        // rover −z
        assert!((cov[(0, 0)].sqrt() - 3e-3).abs() < 1e-12);
        assert!((cov[(1, 1)].sqrt() - 1e-3).abs() < 1e-12);
        assert!((cov[(2, 2)].sqrt() - 2e-3).abs() < 1e-12);
        // translations, plus the lever of the 1 m mount under the rotations about x and y
        assert!((cov[(3, 3)] - (0.05f64.powi(2) + 1e-6)).abs() < 1e-12);
        assert!((cov[(4, 4)] - (0.01f64.powi(2) + 9e-6)).abs() < 1e-12);
        assert!((cov[(5, 5)] - 0.02f64.powi(2)).abs() < 1e-12);
        // nothing of its own when the rotation is the gyro's, or when lost
        let gyro = VoFrame {
            gyro_rotation: true,
            ..vo.clone()
        };
        assert!(step_covariance_rover(&gyro, &rover_from_camera, 1.0).is_none());
        let lost = VoFrame {
            lost: true,
            information: Matrix6::zeros(),
            ..vo
        };
        assert!(step_covariance_rover(&lost, &rover_from_camera, 1.0).is_none());
    }

    #[test]
    fn detections_follow_the_period_and_odometry_starts_at_the_rover() {
        let config = ImageStreamConfig {
            detect_period_s: 0.3,
            ..ImageStreamConfig::default()
        };
        let segmenter = Box::new(GeometricSegmenter::new(config.front_end.geometric.clone()));
        let mut stream = ImageStream::new(calibration(), config, segmenter).unwrap();
        let image = GrayImage::new(128, 72, vec![90; 128 * 72]).unwrap();
        let gravity = Some(Vector3::new(0.0, 0.0, -1.62));
        let imu = ImuSample {
            gravity_rover: gravity,
            gyro_rover_rad_s: Some(Vector3::zeros()),
        };
        let mut detected = Vec::new();
        for k in 0..7 {
            let out = stream
                .push_pair(&image, &image, 0.1 * k as f64, imu)
                .unwrap();
            assert_eq!(out.frame.gravity_rover, gravity);
            if k == 0 {
                assert!(out.frame.odom_from_rover.translation.vector.norm() < 1e-12);
            }
            detected.push(out.front_end_ms.is_some());
        }
        assert_eq!(detected, [true, false, false, true, false, false, true]);
    }

    #[test]
    fn bad_settings_name_the_field() {
        let config = ImageStreamConfig {
            max_range_m: 0.1,
            ..ImageStreamConfig::default()
        };
        let e = config.validate().unwrap_err().to_string();
        assert!(e.contains("max_range_m"), "{e}");
        let config = ImageStreamConfig {
            detect_period_s: f64::NAN,
            ..ImageStreamConfig::default()
        };
        let e = config.validate().unwrap_err().to_string();
        assert!(e.contains("detect_period_s"), "{e}");
    }
}
