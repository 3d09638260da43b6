//! The stereo visual odometry: a pipeline of named stages per frame.
//!
//! 1. `track`: the previous frame's features into the current left image (pyramidal KLT,
//!    forward–backward checked);
//! 2. `match_stereo`: each tracked feature along its row in the right image;
//! 3. `estimate_motion`: RANSAC on the previous frame's 3D points and the current
//!    measurements, refined (3D–2D, Huber);
//! 4. `replenish`: new corners in the cells left empty, matched and triangulated;
//! 5. `window`: a sliding window of recent frames and their points refined by bundle
//!    adjustment on the pose graph's stereo factors (the oldest frame held).

use super::corners::{cell_of, detect_corners, grid_size, CornerConfig};
use super::gravity_tilt::{GravityAnchor, VoGravityConfig};
use super::gyro_heading::{GyroHeading, HeadingInputs, VoGyroHeadingConfig};
use super::keyframe::{Keyframe, KeyframeConfig};
use super::klt::{track, KltConfig};
use super::motion::{
    estimate_motion, rotation_sigma_rad, Correspondence, MotionConfig, MotionEstimate,
};
use super::pyramid::{FloatImage, Pyramid};
use super::stage_times::{lap_ms, StageTimes};
use super::stereo_match::{match_point, StereoMatchConfig};
use super::translation_given_rotation::translation_given_rotation;
use super::window::{SlidingWindow, WindowConfig};
use super::VoError;
use crate::graph::StereoCalibration;
use crate::perception::GrayImage;
use nalgebra::{Isometry3, Matrix6, Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Configuration of the visual odometry, one section per stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VoConfig {
    /// Pyramid levels of the tracker (each halves the image): four reach a rover's
    /// turn in place between 10 Hz frames.
    pub pyramid_levels: usize,
    /// Corner detection.
    pub corners: CornerConfig,
    /// Frame-to-frame tracking.
    pub klt: KltConfig,
    /// Left–right matching.
    pub stereo: StereoMatchConfig,
    /// Motion estimation.
    pub motion: MotionConfig,
    /// Sliding-window bundle adjustment.
    pub window: WindowConfig,
    /// The gyro's part, when the frames carry its rates.
    pub gyro: VoGyroConfig,
    /// Keyframe anchoring of the motion (see [`super::keyframe`]).
    pub keyframe: KeyframeConfig,
    /// The IMU's gravity as a roll–pitch anchor (see [`super::gravity_tilt`]).
    pub gravity: VoGravityConfig,
    /// The heading from the bias-corrected gyro (see [`super::gyro_heading`]).
    pub gyro_heading: VoGyroHeadingConfig,
}

/// How the odometry uses a gyro.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VoGyroConfig {
    /// Use the gyro's rates (default true): the motion predicted for tracking takes the
    /// gyro's rotation, and a frame whose image motion fails or disagrees with it keeps the
    /// gyro's rotation and finds its translation alone.
    pub enabled: bool,
    /// Largest angle between a frame's rotation from the images (motion estimate or window
    /// refinement) and the gyro's before the images' is refused, degrees (default 0.1;
    /// see docs/design/vo-gyro.md).
    pub max_disagreement_deg: f64,
    /// Largest change of the translation from the predicted one (the last frame's) that a
    /// translation found alone may make, metres (default 0.05: a rover's camera moves a few
    /// centimetres between 10 Hz frames; a few wrong inliers can propose decimetres).
    pub max_translation_jump_m: f64,
}

impl Default for VoGyroConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            max_disagreement_deg: 0.1,
            max_translation_jump_m: 0.05,
        }
    }
}

impl Default for VoConfig {
    fn default() -> Self {
        Self {
            pyramid_levels: 4,
            corners: CornerConfig::default(),
            klt: KltConfig::default(),
            stereo: StereoMatchConfig::default(),
            motion: MotionConfig::default(),
            window: WindowConfig::default(),
            gyro: VoGyroConfig::default(),
            keyframe: KeyframeConfig::default(),
            gravity: VoGravityConfig::default(),
            gyro_heading: VoGyroHeadingConfig::default(),
        }
    }
}

impl VoConfig {
    /// Checks the ranges, naming the TOML path of a bad value.
    pub fn validate(&self) -> Result<(), VoError> {
        let bad = |m: &str| Err(VoError::Config(m.to_string()));
        if self.pyramid_levels == 0 || self.pyramid_levels > 6 {
            return bad("pyramid_levels must be 1 to 6");
        }
        if self.corners.cell_px < 4 {
            return bad("corners.cell_px must be at least 4");
        }
        if self.klt.half_window_px == 0 || self.klt.iterations == 0 {
            return bad("klt.half_window_px and klt.iterations must be positive");
        }
        if !(self.stereo.max_disparity_px > self.stereo.min_disparity_px
            && self.stereo.min_disparity_px >= 0.0)
        {
            return bad("stereo.max_disparity_px must exceed stereo.min_disparity_px >= 0");
        }
        if !(self.motion.inlier_px > 0.0 && self.motion.huber_px > 0.0) {
            return bad("motion.inlier_px and motion.huber_px must be positive");
        }
        if self.gyro.max_disagreement_deg.is_nan() || self.gyro.max_disagreement_deg <= 0.0 {
            return bad("gyro.max_disagreement_deg must be positive");
        }
        if self.gyro.max_translation_jump_m.is_nan() || self.gyro.max_translation_jump_m <= 0.0 {
            return bad("gyro.max_translation_jump_m must be positive");
        }
        self.gyro_heading
            .validate()
            .map_err(|m| VoError::Config(m.into()))?;
        if self.keyframe.max_frames == 0 || !(0.0..=1.0).contains(&self.keyframe.min_own_fraction) {
            return bad(
                "keyframe.max_frames must be positive, keyframe.min_own_fraction in [0, 1]",
            );
        }
        Ok(())
    }
}

/// A frame's motion as stages 1–3 found it.
struct Motion {
    curr_from_prev: Isometry3<f64>,
    /// Inliers of the motion.
    inliers: usize,
    /// The refinement's `JᵀJ`.
    information: Matrix6<f64>,
    /// True when the rotation is the gyro's (the image motion failed or disagreed with it).
    gyro_rotation: bool,
}

/// A tracked feature: where it is in the current left image, its point in the current
/// left camera's frame and in the keyframe's.
#[derive(Clone, Copy, Debug)]
struct Feature {
    id: u64,
    x: f32,
    y: f32,
    p_camera: Point3<f64>,
    p_key: Point3<f64>,
}

/// What one frame gave.
#[derive(Clone, Debug, Serialize)]
pub struct FrameResult {
    /// Frame time, seconds.
    pub time_s: f64,
    /// `first_from_camera`: the left camera's pose in the first left camera's frame.
    #[serde(skip)]
    pub pose: Isometry3<f64>,
    /// Features tracked from the previous frame (after the forward–backward check).
    pub tracked: usize,
    /// Inliers of the motion.
    pub inliers: usize,
    /// Features held after replenishing.
    pub features: usize,
    /// True when the motion could not be estimated (the pose is the constant-velocity
    /// prediction).
    pub lost: bool,
    /// `JᵀJ` of the motion refinement (px⁻², (rotation, translation)); zero when lost.
    #[serde(skip)]
    pub information: Matrix6<f64>,
    /// The motion's worst-known rotation direction, one standard deviation at 1 px of image
    /// noise, degrees (infinite when lost).
    pub rotation_sigma_deg: f64,
    /// True when the frame's rotation is the gyro's (the image motion failed or disagreed
    /// with it) and only its translation came from the images.
    pub gyro_rotation: bool,
    /// Processing time of the frame, from decoded images to its pose, milliseconds.
    pub time_ms: f64,
    /// Where that time went, stage by stage.
    pub stages: StageTimes,
}

/// Stereo visual odometry over a sequence of rectified pairs.
pub struct StereoOdometry {
    camera: StereoCalibration,
    config: VoConfig,
    previous: Option<Pyramid>,
    features: Vec<Feature>,
    next_id: u64,
    first_from_camera: Isometry3<f64>,
    last_motion: Isometry3<f64>,
    window: SlidingWindow,
    frame_index: u64,
    /// The camera's mounting rotation `rover_from_camera`, for gyro rates given in the rover
    /// frame; `None` until [`StereoOdometry::set_gyro_mount`].
    gyro_mount: Option<UnitQuaternion<f64>>,
    previous_time_s: Option<f64>,
    /// The keyframe the motion is measured against.
    key: Keyframe,
    /// The reference direction of gravity.
    gravity: GravityAnchor,
    /// The gyro's bias estimate and the heading taken from it.
    heading: GyroHeading,
}

/// The motion expected for a frame, before its images are seen.
struct Prediction {
    /// `curr_from_prev`: constant velocity, with the gyro's rotation when known.
    curr_from_prev: Isometry3<f64>,
    /// The gyro's rotation `curr_from_prev`, when the frame has a rate.
    gyro_rotation: Option<UnitQuaternion<f64>>,
}

impl StereoOdometry {
    /// A new odometry for a camera.
    pub fn new(camera: StereoCalibration, config: VoConfig) -> Result<Self, VoError> {
        config.validate()?;
        camera
            .validate()
            .map_err(|e| VoError::Config(format!("camera: {e}")))?;
        let window = SlidingWindow::new(camera, config.window.clone());
        Ok(Self {
            camera,
            config,
            previous: None,
            features: Vec::new(),
            next_id: 0,
            first_from_camera: Isometry3::identity(),
            last_motion: Isometry3::identity(),
            window,
            frame_index: 0,
            gyro_mount: None,
            previous_time_s: None,
            key: Keyframe::new(),
            gravity: GravityAnchor::default(),
            heading: GyroHeading::default(),
        })
    }

    /// Tells the odometry how its left camera is mounted (`rover_from_camera`), so that
    /// [`StereoOdometry::process_with_gyro`] can turn rover-frame gyro rates into camera
    /// rotations.
    pub fn set_gyro_mount(&mut self, rover_from_camera: UnitQuaternion<f64>) {
        self.gyro_mount = Some(rover_from_camera);
    }

    /// Processes one pair (same size, checked by the caller) at `time_s`.
    pub fn process(&mut self, left: &GrayImage, right: &GrayImage, time_s: f64) -> FrameResult {
        self.process_with_gyro(left, right, time_s, None)
    }

    /// Processes one pair with the gyro's mean angular rate since the previous pair (rover
    /// frame, rad/s). The rate is used when the mount is set and `use_gyro` is on: the
    /// motion predicted for tracking takes its rotation, and so does the motion of a frame
    /// whose tracking is lost.
    pub fn process_with_gyro(
        &mut self,
        left: &GrayImage,
        right: &GrayImage,
        time_s: f64,
        gyro_rover_rad_s: Option<Vector3<f64>>,
    ) -> FrameResult {
        self.process_with_imu(left, right, time_s, gyro_rover_rad_s, None)
    }

    /// [`StereoOdometry::process_with_gyro`] with the IMU's gravity in the rover frame too:
    /// the roll and pitch are then anchored to it (see [`super::gravity_tilt`]; the mount
    /// of [`StereoOdometry::set_gyro_mount`] moves it into the camera's frame).
    pub fn process_with_imu(
        &mut self,
        left: &GrayImage,
        right: &GrayImage,
        time_s: f64,
        gyro_rover_rad_s: Option<Vector3<f64>>,
        gravity_rover: Option<Vector3<f64>>,
    ) -> FrameResult {
        let start = Instant::now();
        let mut lap = start;
        let mut stages = StageTimes::default();
        let predicted = self.predicted_motion(time_s, gyro_rover_rad_s);
        let dt_s = self.previous_time_s.map(|t0| time_s - t0);
        self.previous_time_s = Some(time_s);
        let (pyramid, right) = rayon::join(
            || Pyramid::new(left, self.config.pyramid_levels),
            || FloatImage::from_gray(right),
        );
        stages.pyramid_ms = lap_ms(&mut lap);
        let (tracked, estimate) = match self.previous.take() {
            Some(prev) => self.track_and_estimate(&prev, &pyramid, &right, &predicted, &mut stages),
            None => (0, None),
        };
        let lost = self.frame_index > 0 && estimate.is_none();
        let (inliers, information, gyro_rotation) = match &estimate {
            Some(m) => (m.inliers, m.information, m.gyro_rotation),
            None => (0, Matrix6::zeros(), false),
        };
        let curr_from_prev = match estimate {
            Some(m) => m.curr_from_prev,
            None => predicted.curr_from_prev,
        };
        if self.frame_index > 0 {
            self.first_from_camera *= curr_from_prev.inverse();
            self.last_motion = curr_from_prev;
        }
        self.replenish(&pyramid, &right, &mut stages);
        lap = Instant::now();
        let own = self
            .features
            .iter()
            .filter(|f| f.id < self.key.first_later_id)
            .count();
        let observations: Vec<(u64, Vector3<f64>, Point3<f64>)> = self
            .features
            .iter()
            .filter_map(|f| {
                self.camera
                    .project(&f.p_camera.coords)
                    .map(|uv| (f.id, uv, f.p_camera))
            })
            .collect();
        let gyro_check = predicted
            .gyro_rotation
            .map(|r| (r, self.config.gyro.max_disagreement_deg.to_radians()));
        if let Some(refined) = self.window.add_frame(
            self.frame_index,
            self.first_from_camera,
            &observations,
            gyro_check,
        ) {
            self.first_from_camera = refined;
        }
        self.anchor_tilt(gravity_rover);
        self.take_gyro_heading(&HeadingInputs {
            gyro_curr_from_prev: predicted.gyro_rotation,
            dt_s,
            up_first: self.gravity.up_first(&self.config.gravity),
            measured: !lost && !gyro_rotation,
        });
        stages.window_ms = lap_ms(&mut lap);
        self.next_keyframe(lost, own);
        self.previous = Some(pyramid);
        self.frame_index += 1;
        FrameResult {
            time_s,
            pose: self.first_from_camera,
            tracked,
            inliers,
            features: self.features.len(),
            lost,
            information,
            rotation_sigma_deg: if lost {
                f64::INFINITY
            } else {
                rotation_sigma_rad(&information, 1.0).to_degrees()
            },
            gyro_rotation,
            time_ms: start.elapsed().as_secs_f64() * 1e3,
            stages,
        }
    }

    /// Turns the pose's tilt toward gravity's reference direction (when gravity and the
    /// mount are known and the anchor is on), and the window and keyframe with it.
    fn anchor_tilt(&mut self, gravity_rover: Option<Vector3<f64>>) {
        let (Some(g), Some(rover_from_camera)) = (gravity_rover, self.gyro_mount) else {
            return;
        };
        if !self.config.gravity.enabled {
            return;
        }
        let g_camera = rover_from_camera.inverse() * g;
        let anchored =
            self.gravity
                .correct(&self.config.gravity, &self.first_from_camera, &g_camera);
        self.turn_to(anchored);
    }

    /// Replaces the frame's change of heading by the bias-corrected gyro's (see
    /// [`super::gyro_heading`]), and turns the window and keyframe with it.
    fn take_gyro_heading(&mut self, inputs: &HeadingInputs) {
        let turned =
            self.heading
                .correct(&self.config.gyro_heading, &self.first_from_camera, inputs);
        self.turn_to(turned);
    }

    /// Moves the frame to `corrected` (the same position, turned), and the window and the
    /// keyframe with it, so that the next refinement (which holds the window's oldest frame)
    /// and the next motion keep the correction.
    fn turn_to(&mut self, corrected: Isometry3<f64>) {
        let correction = corrected * self.first_from_camera.inverse();
        self.window.correct(&correction);
        self.key.first_from_key = correction * self.key.first_from_key;
        self.first_from_camera = corrected;
    }

    /// After a frame: makes it the keyframe when one is due (its points become every
    /// feature's keyframe points), else counts it.
    fn next_keyframe(&mut self, lost: bool, own: usize) {
        if self
            .key
            .due(&self.config.keyframe, lost, own, self.features.len())
        {
            self.key = Keyframe {
                first_from_key: self.first_from_camera,
                frames: 0,
                first_later_id: self.next_id,
            };
            for f in &mut self.features {
                f.p_key = f.p_camera;
            }
        } else {
            self.key.frames += 1;
        }
    }

    /// The prediction of this frame's motion against the keyframe (`curr_from_key`), given
    /// the prediction against the previous frame and the previous frame's `prev_from_key`.
    fn anchored(prediction: &Prediction, prev_from_key: &Isometry3<f64>) -> Prediction {
        Prediction {
            curr_from_prev: prediction.curr_from_prev * prev_from_key,
            gyro_rotation: prediction.gyro_rotation.map(|r| r * prev_from_key.rotation),
        }
    }

    /// The motion `curr_from_prev` expected for this frame: the last one (constant
    /// velocity), its rotation replaced by the gyro's when there is one (also returned).
    fn predicted_motion(&self, time_s: f64, gyro_rover_rad_s: Option<Vector3<f64>>) -> Prediction {
        let gyro = gyro_rover_rad_s
            .filter(|w| self.config.gyro.enabled && w.iter().all(|v| v.is_finite()));
        match (gyro, self.gyro_mount, self.previous_time_s) {
            (Some(w), Some(rover_from_camera), Some(t0)) if time_s > t0 => {
                let rotation = camera_rotation_from_gyro(&w, time_s - t0, &rover_from_camera);
                Prediction {
                    curr_from_prev: Isometry3::from_parts(self.last_motion.translation, rotation),
                    gyro_rotation: Some(rotation),
                }
            }
            _ => Prediction {
                curr_from_prev: self.last_motion,
                gyro_rotation: None,
            },
        }
    }

    /// Stage 3: the motion from the correspondences, checked against the gyro when there is
    /// one: an image motion that fails or turns otherwise than the gyro is replaced by the
    /// gyro's rotation with the translation the correspondences give for it. Returns the
    /// estimate and whether the gyro's rotation was kept.
    fn estimate_checked(
        &self,
        correspondences: &[Correspondence],
        prediction: &Prediction,
    ) -> (Option<MotionEstimate>, bool) {
        let image = estimate_motion(
            &self.camera,
            correspondences,
            &prediction.curr_from_prev,
            &self.config.motion,
        );
        let Some(gyro) = prediction.gyro_rotation else {
            return (image, false);
        };
        let max_rad = self.config.gyro.max_disagreement_deg.to_radians();
        if image
            .as_ref()
            .is_some_and(|m| m.curr_from_prev.rotation.angle_to(&gyro) <= max_rad)
        {
            return (image, false);
        }
        let max_jump = self.config.gyro.max_translation_jump_m;
        let fallback =
            translation_given_rotation(&self.camera, correspondences, &gyro, &self.config.motion)
                .filter(|m| {
                    (m.curr_from_prev.translation.vector
                        - prediction.curr_from_prev.translation.vector)
                        .norm()
                        <= max_jump
                });
        let kept = fallback.is_some();
        (fallback, kept)
    }

    /// Stages 1–3: tracks the features, matches them in the right image and estimates the
    /// motion; keeps the features with a new 3D point.
    fn track_and_estimate(
        &mut self,
        prev: &Pyramid,
        curr: &Pyramid,
        right: &FloatImage,
        prediction: &Prediction,
        stages: &mut StageTimes,
    ) -> (usize, Option<Motion>) {
        let mut lap = Instant::now();
        let predicted_motion = &prediction.curr_from_prev;
        let points: Vec<(f32, f32)> = self.features.iter().map(|f| (f.x, f.y)).collect();
        let predicted: Vec<Option<(f32, f32)>> = self
            .features
            .iter()
            .map(|f| {
                let p_curr = predicted_motion * f.p_camera;
                let uv = self.camera.project(&p_curr.coords)?;
                Some((uv.x as f32, uv.z as f32))
            })
            .collect();
        let moved = track(prev, curr, &points, &predicted, &self.config.klt);
        stages.track_ms = lap_ms(&mut lap);
        let stereo = &self.config.stereo;
        let disparities: Vec<Option<f32>> = moved
            .par_iter()
            .with_min_len(8)
            .map(|m| m.and_then(|(x, y)| match_point(curr.base(), right, x, y, stereo)))
            .collect();
        // the motion is measured against the keyframe's points (the previous frame's when
        // it is the keyframe)
        let prev_from_key = if self.config.keyframe.enabled {
            self.key.key_from(&self.first_from_camera).inverse()
        } else {
            Isometry3::identity()
        };
        let mut kept = Vec::new();
        let mut correspondences = Vec::new();
        for ((f, m), disparity) in self.features.iter().zip(moved).zip(disparities) {
            let Some((x, y)) = m else { continue };
            let u_right = disparity.map_or(f64::NAN, |d| (x - d) as f64);
            correspondences.push(Correspondence {
                p_prev: f.p_key,
                uv: Vector3::new(x as f64, u_right, y as f64),
            });
            kept.push((*f, x, y, disparity));
        }
        let tracked = kept.len();
        stages.stereo_ms = lap_ms(&mut lap);
        let anchored = Self::anchored(prediction, &prev_from_key);
        let (estimate, gyro_rotation) = self.estimate_checked(&correspondences, &anchored);
        self.features.clear();
        if let Some(m) = &estimate {
            for ((f, x, y, disparity), inlier) in kept.into_iter().zip(&m.inliers) {
                let Some(d) = disparity.filter(|_| *inlier) else {
                    continue;
                };
                let uv = Vector3::new(x as f64, (x - d) as f64, y as f64);
                if let Some(p) = self.camera.backproject(&uv) {
                    self.features.push(Feature {
                        id: f.id,
                        x,
                        y,
                        p_camera: Point3::from(p),
                        p_key: f.p_key,
                    });
                }
            }
        }
        let result = estimate.map(|m| Motion {
            // the estimate is `curr_from_key`
            curr_from_prev: m.curr_from_prev * prev_from_key.inverse(),
            inliers: m.inliers.iter().filter(|&&b| b).count(),
            information: m.information,
            gyro_rotation,
        });
        stages.motion_ms = lap_ms(&mut lap);
        (tracked, result)
    }

    /// Stage 4: new corners in empty cells, matched and triangulated.
    fn replenish(&mut self, pyramid: &Pyramid, right: &FloatImage, stages: &mut StageTimes) {
        let mut lap = Instant::now();
        let base = pyramid.base();
        let (cols, rows) = grid_size(base, &self.config.corners);
        let mut occupied = vec![false; cols * rows];
        for f in &self.features {
            occupied[cell_of(f.x, f.y, base, &self.config.corners)] = true;
        }
        let corners = detect_corners(base, &self.config.corners, &occupied);
        stages.corners_ms = lap_ms(&mut lap);
        let stereo = &self.config.stereo;
        let key_from_curr = self.key.key_from(&self.first_from_camera);
        let matched: Vec<Option<f32>> = corners
            .par_iter()
            .with_min_len(8)
            .map(|&(x, y)| match_point(base, right, x, y, stereo))
            .collect();
        for ((x, y), disparity) in corners.into_iter().zip(matched) {
            let Some(d) = disparity else {
                continue;
            };
            let uv = Vector3::new(x as f64, (x - d) as f64, y as f64);
            if let Some(p) = self.camera.backproject(&uv) {
                let p_camera = Point3::from(p);
                self.features.push(Feature {
                    id: self.next_id,
                    x,
                    y,
                    p_camera,
                    p_key: key_from_curr * p_camera,
                });
                self.next_id += 1;
            }
        }
        stages.stereo_ms += lap_ms(&mut lap);
    }
}

/// The left camera's rotation `curr_from_prev` over `dt_s` seconds from a gyro's mean rate
/// in the rover frame, for a camera mounted as `rover_from_camera`.
pub fn camera_rotation_from_gyro(
    gyro_rover_rad_s: &Vector3<f64>,
    dt_s: f64,
    rover_from_camera: &UnitQuaternion<f64>,
) -> UnitQuaternion<f64> {
    let prev_from_curr_rover = UnitQuaternion::from_scaled_axis(gyro_rover_rad_s * dt_s);
    let prev_from_curr_camera =
        rover_from_camera.inverse() * prev_from_curr_rover * rover_from_camera;
    prev_from_curr_camera.inverse()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_yaw_rate_turns_a_forward_camera_about_its_down_axis() {
        // optical frame: x right, y down, z forward; rover: x forward, y left, z up
        let rover_from_camera = UnitQuaternion::from_matrix(&nalgebra::Matrix3::new(
            0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
        ));
        let r = camera_rotation_from_gyro(&Vector3::new(0.0, 0.0, 0.5), 0.2, &rover_from_camera);
        // turning left by 0.1 rad: a point straight ahead moves to the camera's right
        let p = r * Point3::new(0.0, 0.0, 1.0);
        assert!(
            (p.x - 0.1f64.sin()).abs() < 1e-12 && p.y.abs() < 1e-12,
            "{p}"
        );
    }

    #[test]
    fn a_partial_toml_keeps_the_other_defaults() {
        let config: VoConfig = toml::from_str("[corners]\ncell_px = 30\n").unwrap();
        assert_eq!(config.corners.cell_px, 30);
        assert_eq!(config.pyramid_levels, VoConfig::default().pyramid_levels);
        config.validate().unwrap();
    }
}
