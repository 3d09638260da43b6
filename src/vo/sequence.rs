//! Stereo sequences: the calibration, the frames in time order and where their images are,
//! and the ground truth when there is one. Read from the KITTI odometry layout here
//! (`image_l/NNNNNN.png`, `image_r/NNNNNN.png`, `calib.txt` with the projection matrices P0
//! and P1, optional `poses.txt`; frame k at t = 0.1·k s), from a `segloc sim render` folder
//! ([`super::rendered_sequence`]) or from a `.lac` recording ([`super::lac_sequence`]).

use super::VoError;
use crate::graph::StereoCalibration;
use crate::perception::lac::{LacRecording, FRONT_LEFT, FRONT_RIGHT};
use crate::perception::{read_gray_png, GrayImage};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where one stereo frame's images are.
#[derive(Clone, Debug)]
pub enum FrameImages {
    /// Two PNG files.
    Files {
        /// Left image.
        left: PathBuf,
        /// Right image.
        right: PathBuf,
    },
    /// A frame of a `.lac` recording (its front stereo pair).
    Lac {
        /// The recording, shared by the sequence's frames.
        recording: Arc<LacRecording>,
        /// The recording's frame number.
        frame: u64,
    },
}

/// One stereo frame.
#[derive(Clone, Debug)]
pub struct SequenceFrame {
    /// Time, seconds.
    pub time_s: f64,
    /// Its images.
    pub images: FrameImages,
    /// The IMU's gravity in the rover frame at this frame, when the recording has it.
    pub gravity_rover: Option<Vector3<f64>>,
    /// The gyro's mean angular rate since the previous frame, rover frame, rad/s, when the
    /// recording has it.
    pub gyro_rover_rad_s: Option<Vector3<f64>>,
}

impl SequenceFrame {
    /// What the IMU measured at this frame.
    pub fn imu(&self) -> ImuSample {
        ImuSample {
            gravity_rover: self.gravity_rover,
            gyro_rover_rad_s: self.gyro_rover_rad_s,
        }
    }
}

/// What the IMU measured at one frame (rover frame).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImuSample {
    /// Gravity, m/s².
    pub gravity_rover: Option<Vector3<f64>>,
    /// The gyro's mean angular rate since the previous frame, rad/s.
    pub gyro_rover_rad_s: Option<Vector3<f64>>,
}

/// A stereo sequence: calibration and frames in time order.
#[derive(Clone, Debug)]
pub struct StereoSequence {
    /// The rectified pair's intrinsics and baseline.
    pub calibration: StereoCalibration,
    /// Frames, strictly increasing in time.
    pub frames: Vec<SequenceFrame>,
    /// Ground truth `first_from_camera` per frame, when the sequence has it.
    pub truth: Option<Vec<Isometry3<f64>>>,
    /// The left camera's mounting rotation `rover_from_camera`, when known: the odometry
    /// needs it to use the frames' gyro rates.
    pub rover_from_camera: Option<UnitQuaternion<f64>>,
}

fn read(path: &Path) -> Result<String, VoError> {
    std::fs::read_to_string(path).map_err(|source| VoError::Io {
        path: path.into(),
        source,
    })
}

fn parse_row(path: &Path, line: usize, text: &str, count: usize) -> Result<Vec<f64>, VoError> {
    let bad = |message: String| VoError::Parse {
        path: path.into(),
        line,
        message,
    };
    let body = match text.split_once(':') {
        Some((_, rest)) => rest,
        None => text,
    };
    let values = body
        .split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| bad(format!("'{t}' is not a number")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    if values.len() != count {
        return Err(bad(format!(
            "expected {count} numbers, found {}",
            values.len()
        )));
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err(bad("non-finite value".into()));
    }
    Ok(values)
}

/// Reads a KITTI `calib.txt`: P0 and P1 (the first two lines).
pub fn read_kitti_calibration(path: &Path) -> Result<StereoCalibration, VoError> {
    let text = read(path)?;
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    if lines.len() < 2 {
        return Err(VoError::Parse {
            path: path.into(),
            line: lines.len() + 1,
            message: "expected the projection matrices P0 and P1".into(),
        });
    }
    let p0 = parse_row(path, lines[0].0, lines[0].1, 12)?;
    let p1 = parse_row(path, lines[1].0, lines[1].1, 12)?;
    let calibration = StereoCalibration {
        fx: p0[0],
        fy: p0[5],
        skew: p0[1],
        cx: p0[2],
        cy: p0[6],
        baseline_m: if p1[0] != 0.0 { -p1[3] / p1[0] } else { 0.0 },
    };
    calibration.validate().map_err(|e| VoError::Parse {
        path: path.into(),
        line: lines[0].0,
        message: e.to_string(),
    })?;
    Ok(calibration)
}

/// Reads KITTI poses (3 × 4 row-major `first_from_camera` per line).
pub fn read_kitti_poses(path: &Path) -> Result<Vec<Isometry3<f64>>, VoError> {
    let text = read(path)?;
    let mut poses = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let v = parse_row(path, i + 1, line, 12)?;
        let r = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
        if (r.transpose() * r - Matrix3::identity()).abs().max() > 1e-3 {
            return Err(VoError::Parse {
                path: path.into(),
                line: i + 1,
                message: "the rotation block is not a rotation".into(),
            });
        }
        let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&r));
        poses.push(Isometry3::from_parts(
            Translation3::new(v[3], v[7], v[11]),
            rotation,
        ));
    }
    Ok(poses)
}

/// The frame number of a file name `NNNNNN.png`.
fn frame_number(path: &Path) -> Option<u64> {
    path.file_stem()?.to_str()?.parse().ok()
}

impl StereoSequence {
    /// Reads a KITTI-layout folder. Every left image needs its right image.
    pub fn read_kitti(dir: &Path) -> Result<Self, VoError> {
        let calibration = read_kitti_calibration(&dir.join("calib.txt"))?;
        let left_dir = dir.join("image_l");
        let entries = std::fs::read_dir(&left_dir).map_err(|source| VoError::Io {
            path: left_dir.clone(),
            source,
        })?;
        let mut numbered = Vec::new();
        for entry in entries {
            let path = entry
                .map_err(|source| VoError::Io {
                    path: left_dir.clone(),
                    source,
                })?
                .path();
            if path.extension().and_then(|e| e.to_str()) != Some("png") {
                continue;
            }
            let n = frame_number(&path).ok_or_else(|| VoError::Sequence {
                path: path.clone(),
                message: "the name is not a frame number (NNNNNN.png)".into(),
            })?;
            numbered.push((n, path));
        }
        numbered.sort();
        if numbered.is_empty() {
            return Err(VoError::Sequence {
                path: left_dir,
                message: "no PNG images".into(),
            });
        }
        for pair in numbered.windows(2) {
            if pair[0].0 == pair[1].0 {
                return Err(VoError::Sequence {
                    path: pair[1].1.clone(),
                    message: format!(
                        "frame {} (t = {:.1} s) is also {}: duplicated timestamp",
                        pair[1].0,
                        0.1 * pair[1].0 as f64,
                        pair[0].1.display()
                    ),
                });
            }
        }
        let mut frames = Vec::with_capacity(numbered.len());
        for (n, left) in numbered {
            let right = dir
                .join("image_r")
                .join(left.file_name().unwrap_or_default());
            if !right.is_file() {
                return Err(VoError::Sequence {
                    path: right,
                    message: format!("missing right image for {}", left.display()),
                });
            }
            frames.push(SequenceFrame {
                time_s: 0.1 * n as f64,
                images: FrameImages::Files { left, right },
                gravity_rover: None,
                gyro_rover_rad_s: None,
            });
        }
        let truth_path = dir.join("poses.txt");
        let truth = if truth_path.is_file() {
            Some(read_kitti_poses(&truth_path)?)
        } else {
            None
        };
        if let Some(t) = &truth {
            if t.len() != frames.len() {
                return Err(VoError::Sequence {
                    path: truth_path,
                    message: format!("{} poses for {} frames", t.len(), frames.len()),
                });
            }
        }
        Ok(Self {
            calibration,
            frames,
            truth,
            rover_from_camera: None,
        })
    }

    /// The left and right images of frame `k`, each with a name for messages.
    pub fn load(&self, k: usize) -> Result<[(GrayImage, PathBuf); 2], VoError> {
        let frame = self.frames.get(k).ok_or_else(|| VoError::Sequence {
            path: PathBuf::new(),
            message: format!("no frame {k}"),
        })?;
        match &frame.images {
            FrameImages::Files { left, right } => Ok([
                (read_gray_png(left)?, left.clone()),
                (read_gray_png(right)?, right.clone()),
            ]),
            FrameImages::Lac { recording, frame } => {
                let (left, right) = recording.front_pair(*frame)?;
                let name = |camera: &str| {
                    recording
                        .path
                        .join(format!("{camera}/grayscale/frame {frame}"))
                };
                Ok([(left, name(FRONT_LEFT)), (right, name(FRONT_RIGHT))])
            }
        }
    }
}

/// World poses re-expressed in the first pose's frame (`first_from_camera`); empty for none.
pub(crate) fn first_from_camera(world_from_camera: &[Isometry3<f64>]) -> Vec<Isometry3<f64>> {
    let Some(first) = world_from_camera.first() else {
        return Vec::new();
    };
    let first_inv = first.inverse();
    world_from_camera.iter().map(|p| first_inv * p).collect()
}

/// Checks that frame times strictly increase; `path` names the sequence.
pub(crate) fn check_times(frames: &[SequenceFrame], path: &Path) -> Result<(), VoError> {
    for (k, pair) in frames.windows(2).enumerate() {
        if pair[1].time_s.partial_cmp(&pair[0].time_s) != Some(std::cmp::Ordering::Greater) {
            return Err(VoError::Sequence {
                path: path.into(),
                message: format!(
                    "frame {} is at t = {} s, not after frame {} (t = {} s): timestamps must \
                     strictly increase",
                    k + 1,
                    pair[1].time_s,
                    k,
                    pair[0].time_s
                ),
            });
        }
    }
    Ok(())
}
