//! A `.lac` recording as a stereo sequence: the frames where both `FrontLeft` and
//! `FrontRight` have a grayscale image, timed by `frames.csv` (mission time) or, where it
//! has none, by the simulator's 20 Hz frame number; the IPEX front pair's calibration scaled
//! to the images' size; the recorded rover poses as ground truth when every frame has one.

use super::sequence::{check_times, FrameImages, SequenceFrame, StereoSequence};
use super::VoError;
use crate::graph::StereoCalibration;
use crate::perception::lac::{ImageKind, LacRecording};
use crate::perception::StereoCamera;
use nalgebra::Isometry3;
use std::path::Path;

/// LAC's simulator frame period, seconds (20 Hz).
const LAC_FRAME_S: f64 = 0.05;

impl StereoSequence {
    /// Reads a `.lac` recording (see the module docs). Images of another size than the
    /// IPEX 1280 × 720 must be a uniform scaling of it.
    pub fn read_lac(path: &Path) -> Result<Self, VoError> {
        let recording = LacRecording::open(path)?;
        let (left_cam, right_cam) = ("FrontLeft", "FrontRight");
        let numbers = recording.stereo_frames(left_cam, right_cam);
        let Some(&first) = numbers.first() else {
            return Err(VoError::Sequence {
                path: path.into(),
                message: format!(
                    "no frame has both {left_cam} and {right_cam} grayscale images (cameras: {:?})",
                    recording.cameras()
                ),
            });
        };
        let first_image = recording
            .image(left_cam, ImageKind::Grayscale, first)?
            .ok_or_else(|| VoError::Sequence {
                path: path.into(),
                message: format!("frame {first} has no {left_cam} image"),
            })?;
        let camera = StereoCamera::ipex()
            .for_size(first_image.width, first_image.height)
            .map_err(|e| VoError::Sequence {
                path: path.into(),
                message: e.to_string(),
            })?;
        let calibration = StereoCalibration {
            fx: camera.fx,
            fy: camera.fy,
            skew: 0.0,
            cx: camera.cx,
            cy: camera.cy,
            baseline_m: camera.baseline_m,
        };
        let frames: Vec<SequenceFrame> = numbers
            .iter()
            .map(|&frame| SequenceFrame {
                time_s: recording
                    .frame(frame)
                    .and_then(|f| f.time_s)
                    .unwrap_or(frame as f64 * LAC_FRAME_S),
                images: FrameImages::Lac { frame },
            })
            .collect();
        check_times(&frames, path)?;
        let truth = rover_truth(&recording, &numbers);
        Ok(Self {
            calibration,
            frames,
            truth,
            lac: Some(recording),
        })
    }
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
    let world_from_camera = world_from_camera?;
    let first_inv = world_from_camera.first()?.inverse();
    Some(world_from_camera.iter().map(|p| first_inv * p).collect())
}
