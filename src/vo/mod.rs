//! Stereo visual odometry (issue 27): a rectified stereo sequence becomes the left camera's
//! trajectory in the frame of the first left camera.
//!
//! The front end tracks Shi–Tomasi corners spread over a grid ([`corners`]) from frame to
//! frame with pyramidal Lucas–Kanade and a forward–backward check ([`klt`]), matches them
//! along the rectified rows ([`stereo_match`]), triangulates them with the pair's
//! [`StereoCalibration`](crate::graph::StereoCalibration), and finds the motion by RANSAC and
//! a robust 3D–2D refinement ([`motion`]). The back end ([`window`]) refines a sliding
//! window of frames and their points by bundle adjustment on the pose graph's stereo
//! projection factors. [`StereoOdometry`] runs the stages ([`odometry`]); [`sequence`] reads
//! sequences (KITTI layout; a `segloc sim render` folder in [`rendered_sequence`], a `.lac`
//! recording in [`lac_sequence`]), [`tum`] writes trajectories and [`mod@segment_drift`] scores
//! them as KITTI does.

pub mod corners;
pub mod error;
pub mod gravity_tilt;
pub mod gyro_heading;
pub mod keyframe;
pub mod klt;
pub mod lac_sequence;
pub mod motion;
pub mod odometry;
pub mod pyramid;
pub mod rendered_sequence;
pub mod segment_drift;
pub mod sequence;
pub mod stage_times;
pub mod stereo_match;
pub mod translation_given_rotation;
pub mod tum;
pub mod window;

pub use error::VoError;
pub use odometry::{FrameResult, StereoOdometry, VoConfig};
pub use segment_drift::{segment_drift, SegmentDrift};
pub use sequence::{FrameImages, ImuSample, SequenceFrame, StereoSequence};
pub use stage_times::StageTimes;

/// Runs the odometry over a sequence, checking that every image has the size of the first.
/// Each frame's `time_ms` is the odometry's own: reading and decoding the images (PNG files,
/// a `.lac` member) is not counted, as a rover's cameras hand over raw pixels.
pub fn run_sequence(
    sequence: &StereoSequence,
    config: &VoConfig,
) -> Result<Vec<FrameResult>, VoError> {
    let mut vo = StereoOdometry::new(sequence.calibration, config.clone())?;
    if let Some(rover_from_camera) = sequence.rover_from_camera {
        vo.set_gyro_mount(rover_from_camera);
    }
    let mut results = Vec::with_capacity(sequence.frames.len());
    let mut size = None;
    for (k, frame) in sequence.frames.iter().enumerate() {
        let [(left, left_name), (right, right_name)] = sequence.load(k)?;
        let expected = *size.get_or_insert((left.width, left.height));
        for (image, path) in [(&left, &left_name), (&right, &right_name)] {
            if (image.width, image.height) != expected {
                return Err(VoError::Sequence {
                    path: path.clone(),
                    message: format!(
                        "image is {} × {}, the sequence's first is {} × {}",
                        image.width, image.height, expected.0, expected.1
                    ),
                });
            }
        }
        results.push(vo.process_with_imu(
            &left,
            &right,
            frame.time_s,
            frame.gyro_rover_rad_s,
            frame.gravity_rover,
        ));
    }
    Ok(results)
}
