//! A `.lac` recording as a stereo sequence: the frames where both front cameras have a
//! grayscale image ([`LacRecording::front_stereo_frames`]), timed by `frames.csv` (mission time) or, where it
//! has none, by the simulator's 20 Hz frame number; the IPEX front pair's calibration scaled
//! to the images' size; gravity from the recorded accelerometer; the recorded rover poses as
//! ground truth when every frame has one.

use super::sequence::{check_times, first_from_camera, FrameImages, SequenceFrame, StereoSequence};
use super::VoError;
use crate::perception::lac::LacRecording;
use crate::perception::StereoCamera;
use nalgebra::{Isometry3, Vector3};
use std::path::Path;
use std::sync::Arc;

/// LAC's simulator frame period, seconds (20 Hz).
const LAC_FRAME_S: f64 = 0.05;

impl StereoSequence {
    /// Reads a `.lac` recording (see the module docs). Images of another size than the
    /// IPEX 1280 × 720 must be a uniform scaling of it.
    pub fn read_lac(path: &Path) -> Result<Self, VoError> {
        let recording = Arc::new(LacRecording::open(path)?);
        let numbers = recording.front_stereo_frames()?;
        // the calibration follows the images' size: read it from the first left image
        let first_image = recording.front_pair(numbers[0])?.0;
        let camera = StereoCamera::ipex()
            .for_size(first_image.width, first_image.height)
            .map_err(|e| VoError::Sequence {
                path: path.into(),
                message: e.to_string(),
            })?;
        let calibration = camera.calibration();
        let frames: Vec<SequenceFrame> = numbers
            .iter()
            .map(|&frame| {
                let record = recording.frame(frame);
                let imu = record.and_then(|f| f.imu.as_ref());
                SequenceFrame {
                    time_s: record
                        .and_then(|f| f.time_s)
                        .unwrap_or(frame as f64 * LAC_FRAME_S),
                    images: FrameImages::Lac {
                        recording: Arc::clone(&recording),
                        frame,
                    },
                    // the accelerometer of a resting rover reads minus gravity
                    gravity_rover: imu
                        .map(|imu| -Vector3::from(imu.accel))
                        .filter(|g| g.iter().all(|v| v.is_finite()) && g.norm() > 0.0),
                    gyro_rover_rad_s: imu
                        .map(|imu| Vector3::from(imu.gyro))
                        .filter(|w| w.iter().all(|v| v.is_finite())),
                }
            })
            .collect();
        check_times(&frames, path)?;
        let truth = rover_truth(&recording, &numbers);
        Ok(Self {
            calibration,
            frames: without_a_silent_gyro(frames),
            truth,
            rover_from_camera: Some(
                crate::perception::CameraMount::ipex_front_left()
                    .rover_from_camera()
                    .rotation,
            ),
        })
    }
}

/// A gyro that reads exactly zero on every frame is not there (recordings written before
/// `sim render` had one, or without an IMU): its rates are dropped.
fn without_a_silent_gyro(mut frames: Vec<SequenceFrame>) -> Vec<SequenceFrame> {
    let silent = frames
        .iter()
        .all(|f| f.gyro_rover_rad_s.is_none_or(|w| w == Vector3::zeros()));
    if silent {
        for f in &mut frames {
            f.gyro_rover_rad_s = None;
        }
    }
    frames
}

/// `first_from_left_camera` per frame from the recorded `world_from_rover`, when every frame
/// has one.
fn rover_truth(recording: &LacRecording, frames: &[u64]) -> Option<Vec<Isometry3<f64>>> {
    let rover_from_camera = crate::perception::CameraMount::ipex_front_left().rover_from_camera();
    let world_from_camera: Option<Vec<Isometry3<f64>>> = frames
        .iter()
        .map(|&f| {
            recording
                .frame(f)
                .and_then(|r| r.pose)
                .map(|p| p * rover_from_camera)
        })
        .collect();
    Some(first_from_camera(&world_from_camera?))
}
