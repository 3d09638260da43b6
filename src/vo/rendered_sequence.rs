//! A `segloc sim render` folder as a stereo sequence (layout in `docs/render-format.md`):
//! `NNNNNN_0.png` / `NNNNNN_1.png` per rendered tick, `calibration.json` (intrinsics,
//! baseline, `tick_s`), the IMU's gravity per tick when there is an `imu.csv` and, as ground
//! truth, `truth.tum` (`world_from_left_camera`, whose times are the frames' times).

use super::sequence::{check_times, first_from_camera, FrameImages, SequenceFrame, StereoSequence};
use super::VoError;
use crate::graph::StereoCalibration;
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The fields of `calibration.json` the odometry needs.
#[derive(Deserialize)]
struct RenderedCalibration {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    baseline_m: f64,
    #[serde(default = "default_tick_s")]
    tick_s: f64,
    #[serde(default)]
    rover_from_left_camera: Option<RenderedMount>,
}

/// `rover_from_left_camera` of `calibration.json` (its rotation is what the odometry needs).
#[derive(Deserialize)]
struct RenderedMount {
    quaternion_xyzw: [f64; 4],
}

fn default_tick_s() -> f64 {
    0.05
}

/// The calibration, the tick and the left camera's mounting rotation when the file has it.
type Calibration = (StereoCalibration, f64, Option<UnitQuaternion<f64>>);

fn read_calibration(path: &Path) -> Result<Calibration, VoError> {
    let text = std::fs::read_to_string(path).map_err(|source| VoError::Io {
        path: path.into(),
        source,
    })?;
    let c: RenderedCalibration = serde_json::from_str(&text).map_err(|e| VoError::Parse {
        path: path.into(),
        line: e.line(),
        message: e.to_string(),
    })?;
    let calibration = StereoCalibration {
        fx: c.fx,
        fy: c.fy,
        skew: 0.0,
        cx: c.cx,
        cy: c.cy,
        baseline_m: c.baseline_m,
    };
    calibration.validate().map_err(|e| VoError::Parse {
        path: path.into(),
        line: 0,
        message: e.to_string(),
    })?;
    if !(c.tick_s.is_finite() && c.tick_s > 0.0) {
        return Err(VoError::Parse {
            path: path.into(),
            line: 0,
            message: format!("tick_s must be positive, got {}", c.tick_s),
        });
    }
    let mount = match c.rover_from_left_camera {
        None => None,
        Some(m) => {
            let [x, y, z, w] = m.quaternion_xyzw;
            let q = nalgebra::Quaternion::new(w, x, y, z);
            if !(q.coords.iter().all(|v| v.is_finite()) && (q.norm() - 1.0).abs() < 1e-3) {
                return Err(VoError::Parse {
                    path: path.into(),
                    line: 0,
                    message: "rover_from_left_camera.quaternion_xyzw is not a unit quaternion"
                        .into(),
                });
            }
            Some(UnitQuaternion::from_quaternion(q))
        }
    };
    Ok((calibration, c.tick_s, mount))
}

/// The ticks of the left images `NNNNNN_0.png` in `dir`, sorted, with their paths.
fn left_images(dir: &Path) -> Result<Vec<(u64, PathBuf)>, VoError> {
    let entries = std::fs::read_dir(dir).map_err(|source| VoError::Io {
        path: dir.into(),
        source,
    })?;
    let mut ticks = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|source| VoError::Io {
                path: dir.into(),
                source,
            })?
            .path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if let Some(tick) = name
            .strip_suffix("_0.png")
            .and_then(|t| t.parse::<u64>().ok())
        {
            ticks.push((tick, path));
        }
    }
    ticks.sort();
    if ticks.is_empty() {
        return Err(VoError::Sequence {
            path: dir.into(),
            message: "no left images (NNNNNN_0.png): not a `segloc sim render` folder".into(),
        });
    }
    Ok(ticks)
}

/// One `imu.csv` row: gravity and, in the eight-column file, the gyro's rate.
type ImuRow = (Vector3<f64>, Option<Vector3<f64>>);

/// `imu.csv` (`frame,time_s,gravity_x,gravity_y,gravity_z[,gyro_x,gyro_y,gyro_z]`, rover
/// frame) by tick; empty when the folder has none.
fn read_imu(path: &Path) -> Result<BTreeMap<u64, ImuRow>, VoError> {
    let mut rows = BTreeMap::new();
    if !path.is_file() {
        return Ok(rows);
    }
    let text = std::fs::read_to_string(path).map_err(|source| VoError::Io {
        path: path.into(),
        source,
    })?;
    for (k, line) in text.lines().enumerate().skip(1) {
        let bad = |message: String| VoError::Parse {
            path: path.into(),
            line: k + 1,
            message,
        };
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 5 && fields.len() != 8 {
            return Err(bad(format!(
                "expected 5 or 8 fields, found {}",
                fields.len()
            )));
        }
        let tick: u64 = fields[0]
            .parse()
            .map_err(|_| bad(format!("frame '{}' is not a whole number", fields[0])))?;
        let mut values = [0.0; 6];
        for (value, text) in values.iter_mut().zip(&fields[2..]) {
            *value = text
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("'{text}' is not a finite number")))?;
        }
        let gravity = Vector3::new(values[0], values[1], values[2]);
        let gyro = (fields.len() == 8).then(|| Vector3::new(values[3], values[4], values[5]));
        rows.insert(tick, (gravity, gyro));
    }
    Ok(rows)
}

impl StereoSequence {
    /// Reads a `segloc sim render` folder. Every left image needs its right image; with a
    /// `truth.tum`, it must have one pose per frame, and its times are the frames' times
    /// (otherwise tick × `tick_s`).
    pub fn read_rendered(dir: &Path) -> Result<Self, VoError> {
        let (calibration, tick_s, rover_from_camera) =
            read_calibration(&dir.join("calibration.json"))?;
        let imu = read_imu(&dir.join("imu.csv"))?;
        let mut frames = Vec::new();
        for (tick, left) in left_images(dir)? {
            let right = dir.join(format!("{tick:06}_1.png"));
            if !right.is_file() {
                return Err(VoError::Sequence {
                    path: right,
                    message: format!("missing right image for {}", left.display()),
                });
            }
            frames.push(SequenceFrame {
                time_s: tick as f64 * tick_s,
                images: FrameImages::Files { left, right },
                gravity_rover: imu.get(&tick).map(|(g, _)| *g),
                gyro_rover_rad_s: imu.get(&tick).and_then(|(_, w)| *w),
            });
        }
        let truth_path = dir.join("truth.tum");
        let truth = if truth_path.is_file() {
            let poses = segloc_maps::read_tum(&truth_path)?;
            if poses.len() != frames.len() {
                return Err(VoError::Sequence {
                    path: truth_path,
                    message: format!("{} poses for {} frames", poses.len(), frames.len()),
                });
            }
            for (frame, (t, _)) in frames.iter_mut().zip(&poses) {
                frame.time_s = *t;
            }
            let world_from_camera: Vec<Isometry3<f64>> = poses.iter().map(|(_, p)| *p).collect();
            Some(first_from_camera(&world_from_camera))
        } else {
            None
        };
        check_times(&frames, &truth_path)?;
        Ok(Self {
            calibration,
            frames,
            truth,
            rover_from_camera,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::{write_gray_png, GrayImage};

    fn folder(dir: &Path, ticks: &[u64], right: bool) {
        std::fs::write(
            dir.join("calibration.json"),
            r#"{"width": 8, "height": 4, "fx": 10, "fy": 10, "cx": 4, "cy": 2, "baseline_m": 0.162, "tick_s": 0.05}"#,
        )
        .unwrap();
        let image = GrayImage::new(8, 4, vec![0; 32]).unwrap();
        for t in ticks {
            write_gray_png(&image, &dir.join(format!("{t:06}_0.png"))).unwrap();
            if right {
                write_gray_png(&image, &dir.join(format!("{t:06}_1.png"))).unwrap();
            }
        }
    }

    #[test]
    fn reads_a_rendered_folder_in_tick_order() {
        let dir = tempfile::tempdir().unwrap();
        folder(dir.path(), &[40, 20], true);
        let s = StereoSequence::read_rendered(dir.path()).unwrap();
        assert_eq!(s.frames.len(), 2);
        assert!(
            (s.frames[0].time_s - 1.0).abs() < 1e-12 && (s.frames[1].time_s - 2.0).abs() < 1e-12
        );
        assert!((s.calibration.baseline_m - 0.162).abs() < 1e-12 && s.truth.is_none());
        assert!(s.frames[0].gravity_rover.is_none());
        std::fs::write(
            dir.path().join("imu.csv"),
            "frame,time_s,gravity_x,gravity_y,gravity_z\n20,1.0,0,0,-1.62\n",
        )
        .unwrap();
        let s = StereoSequence::read_rendered(dir.path()).unwrap();
        assert_eq!(
            s.frames[0].gravity_rover,
            Some(Vector3::new(0.0, 0.0, -1.62))
        );
        assert!(s.frames[1].gravity_rover.is_none());
        assert!(s.frames[0].gyro_rover_rad_s.is_none() && s.rover_from_camera.is_none());
        std::fs::write(
            dir.path().join("imu.csv"),
            "frame,time_s,gravity_x,gravity_y,gravity_z,gyro_x,gyro_y,gyro_z\n20,1.0,0,0,-1.62,0,0,0.5\n",
        )
        .unwrap();
        let s = StereoSequence::read_rendered(dir.path()).unwrap();
        assert_eq!(
            s.frames[0].gyro_rover_rad_s,
            Some(Vector3::new(0.0, 0.0, 0.5))
        );
        std::fs::write(dir.path().join("imu.csv"), "header\n20,1.0,0,0,1,2\n").unwrap();
        let e = StereoSequence::read_rendered(dir.path())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("imu.csv:2") && e.contains("5 or 8 fields"),
            "{e}"
        );
        std::fs::write(dir.path().join("imu.csv"), "header\n20,1.0,0,x,1\n").unwrap();
        let e = StereoSequence::read_rendered(dir.path())
            .unwrap_err()
            .to_string();
        assert!(e.contains("imu.csv:2") && e.contains("'x'"), "{e}");
        let [(left, _), (right, name)] = s.load(1).unwrap();
        assert_eq!((left.width, right.height), (8, 4));
        assert!(name.ends_with("000040_1.png"));
    }

    #[test]
    fn refuses_incomplete_or_inconsistent_folders() {
        let dir = tempfile::tempdir().unwrap();
        folder(dir.path(), &[20], false);
        let e = StereoSequence::read_rendered(dir.path())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("000020_1.png") && e.contains("missing right image"),
            "{e}"
        );
        let dir = tempfile::tempdir().unwrap();
        folder(dir.path(), &[20, 40], true);
        std::fs::write(dir.path().join("truth.tum"), "1 0 0 0 0 0 0 1\n").unwrap();
        let e = StereoSequence::read_rendered(dir.path())
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 poses for 2 frames"), "{e}");
        std::fs::write(
            dir.path().join("truth.tum"),
            "2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n",
        )
        .unwrap();
        let e = StereoSequence::read_rendered(dir.path())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("truth.tum:2") && e.contains("strictly increasing"),
            "{e}"
        );
        std::fs::write(
            dir.path().join("calibration.json"),
            r#"{"fx": -1, "fy": 10, "cx": 4, "cy": 2, "baseline_m": 0.1}"#,
        )
        .unwrap();
        let e = StereoSequence::read_rendered(dir.path())
            .unwrap_err()
            .to_string();
        assert!(e.contains("calibration.json"), "{e}");
    }
}
