//! Stereo bundle adjustment and visual odometry end to end (issue 27): GTSAM's stereo VO
//! example when its files are present, the real KITTI frames, and bad input (exit 2).

mod common;

use std::path::{Path, PathBuf};

/// GTSAM's Data/ folder: `SEGLOC_GTSAM_DATA`, else the benchmark virtual environment's.
fn gtsam_data() -> Option<PathBuf> {
    let dir = std::env::var_os("SEGLOC_GTSAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/work/venv-g2o/lib/python3.11/site-packages/gtsam/Data"));
    if dir.join("VO_stereo_factors_large.txt").is_file() {
        Some(dir)
    } else {
        eprintln!(
            "SKIPPED: GTSAM's VO example not found at {} (set SEGLOC_GTSAM_DATA)",
            dir.display()
        );
        None
    }
}

#[test]
fn gtsam_stereo_example_reaches_gtsams_cost() {
    let Some(d) = gtsam_data() else { return };
    let out = common::segloc()
        .args(["graph", "stereo-ba", "--json", "--calibration"])
        .arg(d.join("VO_calibration.txt"))
        .arg("--poses")
        .arg(d.join("VO_camera_poses_large.txt"))
        .arg("--factors")
        .arg(d.join("VO_stereo_factors_large.txt"))
        .output()
        .unwrap();
    common::assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // GTSAM 4.3 LM on the same problem (rotations projected onto SO(3)): 1577.025490.
    let cost = v["final_cost"].as_f64().unwrap();
    assert!(
        (cost - 1577.025490).abs() / 1577.025490 < 1e-6,
        "final cost {cost}"
    );
    assert_eq!(v["landmarks"].as_u64(), Some(2634));
}

fn kitti() -> Option<PathBuf> {
    let data = common::data_dir()?;
    Some(data.join("kitti-vo").join("sequence_1"))
}

#[test]
fn kitti_frames_give_a_small_end_point_error() {
    let Some(seq) = kitti() else { return };
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("frames.csv");
    let out = common::segloc()
        .args(["eval", "vo", "--json", "--from-frame", "11", "--kitti"])
        .arg(&seq)
        .arg("--per-frame")
        .arg(&csv)
        .output()
        .unwrap();
    common::assert_success(&out);
    let rows = std::fs::read_to_string(&csv).unwrap();
    let mut lines = rows.lines();
    assert!(lines
        .next()
        .unwrap()
        .starts_with("t,tracked,inliers,features,lost"));
    assert_eq!(lines.count(), 51, "one row a frame");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let t = v["translation_error_percent"].as_f64().unwrap();
    let r = v["rotation_error_deg"].as_f64().unwrap();
    assert_eq!(v["lost_frames"].as_u64(), Some(0));
    // A regression guard at the figures measured in BENCHMARKS.md (0.89 %, 1.01°): most of
    // the rotation error is the truth's interpolated frames 0-11
    // (docs/design/vo-kitti-truth.md); from frame 11 on, the 0.3° (0.23° measured).
    assert!(t < 1.5 && r < 1.5, "translation {t} %, rotation {r}°");
    let later = &v["from_frame"];
    assert_eq!(later["frame"].as_u64(), Some(11));
    let r11 = later["rotation_error_deg"].as_f64().unwrap();
    let t11 = later["translation_error_percent"].as_f64().unwrap();
    assert!(r11 < 0.3 && t11 < 1.5, "from frame 11: {t11} %, {r11}°");
}

fn copy_sequence(from: &Path, to: &Path, frames: usize) {
    for sub in ["image_l", "image_r"] {
        std::fs::create_dir_all(to.join(sub)).unwrap();
        for k in 0..frames {
            let name = format!("{k:06}.png");
            std::fs::copy(from.join(sub).join(&name), to.join(sub).join(&name)).unwrap();
        }
    }
    std::fs::copy(from.join("calib.txt"), to.join("calib.txt")).unwrap();
}

#[test]
fn bad_sequences_are_refused_naming_the_file() {
    let Some(seq) = kitti() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("vo.tum");
    let run = |d: &Path| {
        common::segloc()
            .args(["vo", "--kitti"])
            .arg(d)
            .arg("-o")
            .arg(&out_path)
            .output()
            .unwrap()
    };

    let missing = dir.path().join("missing_right");
    copy_sequence(&seq, &missing, 3);
    std::fs::remove_file(missing.join("image_r/000001.png")).unwrap();
    let o = run(&missing);
    common::assert_refused(&o, "image_r/000001.png");

    let bad_cal = dir.path().join("bad_cal");
    copy_sequence(&seq, &bad_cal, 2);
    let cal = std::fs::read_to_string(bad_cal.join("calib.txt")).unwrap();
    std::fs::write(
        bad_cal.join("calib.txt"),
        cal.replacen("7.070912000000e+02", "-7.07e+02", 1),
    )
    .unwrap();
    let o = run(&bad_cal);
    common::assert_refused(&o, "calib.txt");
    common::assert_refused(&o, "focal");

    let sizes = dir.path().join("sizes");
    copy_sequence(&seq, &sizes, 2);
    let small = image::GrayImage::new(100, 50);
    small.save(sizes.join("image_r/000001.png")).unwrap();
    let o = run(&sizes);
    common::assert_refused(&o, "image_r/000001.png");

    let dup = dir.path().join("dup");
    copy_sequence(&seq, &dup, 2);
    std::fs::copy(dup.join("image_l/000001.png"), dup.join("image_l/01.png")).unwrap();
    std::fs::copy(dup.join("image_r/000001.png"), dup.join("image_r/01.png")).unwrap();
    let o = run(&dup);
    common::assert_refused(&o, "duplicated");
    assert!(!out_path.exists(), "no output on bad input");
}

/// A 4 s drive of the mission's planner rendered at 10 Hz, half resolution, as a folder and
/// as a `.lac` recording; the odometry runs on both and is scored against the render's truth.
#[test]
fn rendered_drive_as_folder_and_lac() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    let lac = dir.path().join("drive.lac");
    let out = common::segloc()
        .args([
            "sim",
            "render",
            "--seed",
            "2",
            "--seconds",
            "4",
            "--every",
            "2",
            "--half",
        ])
        .arg("-o")
        .arg(&frames)
        .arg("--lac")
        .arg(&lac)
        .output()
        .unwrap();
    common::assert_success(&out);
    for source in [["--images", ""], ["--lac", ""]] {
        let path = if source[0] == "--images" {
            &frames
        } else {
            &lac
        };
        let out = common::segloc()
            .args(["eval", "vo", "--json", source[0]])
            .arg(path)
            .output()
            .unwrap();
        common::assert_success(&out);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        // ticks 0, 2, ..., 80
        assert_eq!(v["frames"], 41, "{}: {v}", source[0]);
        // the odometry runs end to end and says where it lost track; its accuracy on the
        // rendered moon is measured in BENCHMARKS.md (the smooth regolith gives few corners)
        let error_m = v["translation_error_m"].as_f64().unwrap();
        let distance_m = v["distance_m"].as_f64().unwrap();
        assert!(
            distance_m > 0.3 && error_m < distance_m,
            "{}: {v}",
            source[0]
        );
        assert!(
            v["lost_frames"].as_u64().unwrap() < 41,
            "{}: {v}",
            source[0]
        );
    }
    let tum = dir.path().join("vo.tum");
    let out = common::segloc()
        .args(["vo", "--images"])
        .arg(&frames)
        .arg("-o")
        .arg(&tum)
        .output()
        .unwrap();
    common::assert_success(&out);
    assert_eq!(
        std::fs::read_to_string(&tum)
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with('#'))
            .count(),
        41
    );
    // a missing right image is refused, naming it, and nothing is written
    let right = std::fs::read_dir(&frames)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with("_1.png"))
        .unwrap();
    std::fs::remove_file(&right).unwrap();
    let out_tum = dir.path().join("none.tum");
    let out = common::segloc()
        .args(["vo", "--images"])
        .arg(&frames)
        .arg("-o")
        .arg(&out_tum)
        .output()
        .unwrap();
    common::assert_refused(&out, "missing right image");
    common::assert_refused(&out, &right.to_string_lossy());
    assert!(!out_tum.exists());
}

/// The odometry's parallel stages (tracking, matching, corners, RANSAC) give the same poses
/// on one thread as on two, byte for byte: a 3 s rendered drive at half resolution.
#[test]
fn one_and_two_threads_give_identical_poses() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    let out = common::segloc()
        .args([
            "sim",
            "render",
            "--seed",
            "3",
            "--seconds",
            "3",
            "--every",
            "2",
            "--half",
        ])
        .arg("-o")
        .arg(&frames)
        .output()
        .unwrap();
    common::assert_success(&out);
    let poses = |threads: &str| {
        let path = dir.path().join(format!("vo-{threads}.tum"));
        let out = common::segloc()
            .env("RAYON_NUM_THREADS", threads)
            .args(["vo", "--images"])
            .arg(&frames)
            .arg("-o")
            .arg(&path)
            .output()
            .unwrap();
        common::assert_success(&out);
        std::fs::read_to_string(&path).unwrap()
    };
    let (one, two) = (poses("1"), poses("2"));
    // ticks 0, 2, ..., 60
    assert_eq!(one.lines().count(), 31, "{one}");
    assert_eq!(one, two, "one thread and two threads differ");
}
