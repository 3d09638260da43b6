//! `segloc localize --images / --lac`: a rendered drive (stereo pairs, IMU gravity) through
//! the visual odometry, the perception front end and the online localizer in one pass; the
//! mapping session's trajectory scored against the render's truth; bad input.

mod common;

use common::{assert_refused, assert_success, segloc, stderr_of};
use nalgebra::{Isometry3, Matrix3, Quaternion, Translation3, UnitQuaternion, Vector3};
use std::path::Path;

/// The poses of a TUM file, by time in milliseconds.
fn read_tum(path: &Path) -> Vec<(i64, Isometry3<f64>)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            let q = UnitQuaternion::from_quaternion(Quaternion::new(v[7], v[4], v[5], v[6]));
            (
                (v[0] * 1e3).round() as i64,
                Isometry3::from_parts(Translation3::new(v[1], v[2], v[3]), q),
            )
        })
        .collect()
}

/// The IPEX front-left camera's optical frame in the rover frame.
fn rover_from_camera() -> Isometry3<f64> {
    let r = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    Isometry3::from_parts(
        Translation3::from(Vector3::new(0.28, 0.081, 0.131)),
        UnitQuaternion::from_matrix(&r),
    )
}

/// A 20 s drive rendered at 10 Hz and half resolution becomes a mapping session: every pair
/// is placed, the trajectory follows the truth, the map and the frames are written; the same
/// drive as a `.lac` recording then runs against that map.
#[test]
fn a_rendered_drive_maps_and_relocalizes_from_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let (images, lac) = (dir.path().join("drive"), dir.path().join("drive.lac"));
    let out = segloc()
        .args(["sim", "render", "--seed", "2", "--seconds", "20"])
        .args(["--every", "2", "--half", "-o"])
        .arg(&images)
        .arg("--lac")
        .arg(&lac)
        .output()
        .unwrap();
    assert_success(&out);
    let (tum, map, frames) = (
        dir.path().join("mapping.tum"),
        dir.path().join("site.map.json"),
        dir.path().join("frames.jsonl"),
    );
    let out = segloc()
        .args(["localize", "--json", "--images"])
        .arg(&images)
        .arg("-o")
        .arg(&tum)
        .arg("--map-out")
        .arg(&map)
        .arg("--frames-out")
        .arg(&frames)
        .output()
        .unwrap();
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let stream = &v["image_stream"];
    assert_eq!(stream["pairs"], 201, "{stream}");
    assert_eq!(stream["vo_lost_frames"], 0, "{stream}");
    // one detection pair a second: t = 0, 1, ..., 20
    assert_eq!(stream["detection_frames"], 21, "{stream}");
    assert!(stream["detections"].as_u64().unwrap() > 20, "{stream}");
    assert!(v["landmarks_in_map"].as_u64().unwrap() >= 5, "{v}");
    // the mapping session is anchored at its first frame: compare motions from there
    let estimate = read_tum(&tum);
    let truth = read_tum(&images.join("truth.tum"));
    assert_eq!(estimate.len(), truth.len());
    let camera_from_rover = rover_from_camera().inverse();
    let first_truth = truth[0].1 * camera_from_rover;
    let mut worst_m: f64 = 0.0;
    for ((t, e), (t_true, world_from_camera)) in estimate.iter().zip(&truth) {
        assert_eq!(t, t_true);
        let true_motion = first_truth.inverse() * world_from_camera * camera_from_rover;
        let estimated_motion = estimate[0].1.inverse() * e;
        worst_m = worst_m
            .max((true_motion.translation.vector - estimated_motion.translation.vector).norm());
    }
    assert!(worst_m < 0.10, "worst position error {worst_m} m");
    let written = segloc_maps::frames::read_frames(&frames).unwrap();
    assert_eq!(written.frames.len(), 201);
    // the same drive from the recording, against the map it made
    let out = segloc()
        .args(["localize", "--json", "--lac"])
        .arg(&lac)
        .arg("--prior")
        .arg(&map)
        .arg("-o")
        .arg(dir.path().join("relocalized.tum"))
        .output()
        .unwrap();
    let code = out.status.code();
    assert!(code == Some(0) || code == Some(1), "{}", stderr_of(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["image_stream"]["pairs"], 201, "{v}");
    assert!(v["fixes"]["accepted"].as_u64().unwrap() + v["fixes"]["refused"].as_u64().unwrap() > 0);
    assert_eq!(
        dir.path().join("relocalized.tum").exists(),
        code == Some(0),
        "a trajectory only with a fix"
    );
}

/// A folder that is not a render, two drives at once, a bad stream setting: exit 2, named.
#[test]
fn bad_image_drives_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("out.tum");
    let out = segloc()
        .args(["localize", "--images"])
        .arg(dir.path())
        .arg("-o")
        .arg(&out_path)
        .output()
        .unwrap();
    assert_refused(&out, "calibration.json");
    let out = segloc()
        .args(["localize", "--frames", "a.jsonl", "--lac", "b.lac", "-o"])
        .arg(&out_path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr_of(&out));
    let config = dir.path().join("stream.toml");
    std::fs::write(&config, "detect_period_s = -1\n").unwrap();
    std::fs::write(
        dir.path().join("calibration.json"),
        r#"{"fx": 457, "fy": 457, "cx": 320, "cy": 180, "baseline_m": 0.162}"#,
    )
    .unwrap();
    let out = segloc()
        .args(["localize", "--images"])
        .arg(dir.path())
        .arg("--stream-config")
        .arg(&config)
        .arg("-o")
        .arg(&out_path)
        .output()
        .unwrap();
    assert_refused(&out, "stream.toml");
    assert_refused(&out, "detect_period_s");
    assert!(!out_path.exists(), "no output on bad input");
}
