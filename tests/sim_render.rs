//! `segloc sim render`: a short drive rendered at half resolution, its layout, the `.lac`
//! that `segloc detect --lac` reads, and the refusals of bad input.

mod common;

use common::{assert_refused, assert_success, segloc};

#[test]
fn short_render_writes_the_documented_layout() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("frames");
    let lac = tmp.path().join("drive.lac");
    let run = segloc()
        .args([
            "sim",
            "render",
            "--seed",
            "2",
            "--seconds",
            "2",
            "--every",
            "20",
        ])
        .args(["--half", "-o"])
        .arg(&out)
        .arg("--lac")
        .arg(&lac)
        .output()
        .unwrap();
    assert_success(&run);
    for name in [
        "000000_0.png",
        "000000_1.png",
        "000000_ids.png",
        "000000_depth.png",
        "000040_0.png",
        "000040_1.png",
        "calibration.json",
        "truth.tum",
        "rover_truth.tum",
        "imu.csv",
        "rocks.json",
    ] {
        assert!(out.join(name).is_file(), "{name} missing");
    }
    let calibration: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("calibration.json")).unwrap())
            .unwrap();
    assert_eq!(calibration["width"], 640);
    assert_eq!(calibration["baseline_m"], 0.162);
    let truth = std::fs::read_to_string(out.join("truth.tum")).unwrap();
    let poses = truth.lines().filter(|l| !l.starts_with('#')).count();
    assert_eq!(poses, 3);
    let imu = std::fs::read_to_string(out.join("imu.csv")).unwrap();
    assert_eq!(imu.lines().count(), 4);
    let rocks: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("rocks.json")).unwrap()).unwrap();
    assert_eq!(rocks["frames"].as_array().unwrap().len(), 3);
    assert!(!rocks["rocks"].as_array().unwrap().is_empty());
    // the recording plays back through the perception front end
    let csv = tmp.path().join("detections.csv");
    let detect = segloc()
        .args(["detect", "--lac"])
        .arg(&lac)
        .arg("-o")
        .arg(&csv)
        .output()
        .unwrap();
    assert_success(&detect);
    assert!(csv.is_file());
}

#[test]
fn refuses_bad_input_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let busy = tmp.path().join("busy");
    std::fs::create_dir(&busy).unwrap();
    std::fs::write(busy.join("keep.txt"), "x").unwrap();
    let run = segloc()
        .args(["sim", "render", "--seconds", "1", "--half", "-o"])
        .arg(&busy)
        .output()
        .unwrap();
    assert_refused(&run, "not empty");
    assert!(busy.join("keep.txt").is_file());
    let fresh = tmp.path().join("fresh");
    let run = segloc()
        .args(["sim", "render", "--seconds", "1", "--half"])
        .args(["--sun-elevation", "-5", "-o"])
        .arg(&fresh)
        .output()
        .unwrap();
    assert_refused(&run, "sun_elevation_deg");
    assert!(!fresh.exists());
    let config = tmp.path().join("render.toml");
    std::fs::write(&config, "read_noise_dn = -1.0\n").unwrap();
    let run = segloc()
        .args(["sim", "render", "--seconds", "1", "--render-config"])
        .arg(&config)
        .arg("-o")
        .arg(&fresh)
        .output()
        .unwrap();
    assert_refused(&run, "read_noise_dn");
    assert!(!fresh.exists());
}

/// `segloc eval render` on one half-resolution frame: the JSON has the documented blocks and
/// names the segmenter, and the breakdown follows the front end's own masks; a sun below the
/// horizon is refused naming the field.
#[test]
fn eval_render_scores_a_frame_and_refuses_a_bad_sun() {
    let tmp = tempfile::tempdir().unwrap();
    let breakdown = tmp.path().join("breakdown.jsonl");
    let run = segloc()
        .args(["eval", "render", "--seeds", "3", "--sun-deg", "15"])
        .args(["--seconds", "2", "--every", "100", "--half", "--json"])
        .arg("--breakdown")
        .arg(&breakdown)
        .output()
        .unwrap();
    assert_success(&run);
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(v["overall"]["frames"], 1);
    for key in ["recall", "precision", "centroid_error_median_m"] {
        assert!(v["overall"].get(key).is_some(), "{key}: {v}");
    }
    assert_eq!(v["by_range"].as_array().map(Vec::len), Some(3));
    assert_eq!(v["segmenter"], "geometric");
    let text = std::fs::read_to_string(&breakdown).unwrap();
    let rocks: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(!rocks.is_empty());
    for rock in &rocks {
        let verdict = rock["mask_verdict"].as_str().unwrap();
        if rock["detected"] == true {
            assert_eq!(verdict, "boulder", "{rock}");
        }
    }
    let run = segloc()
        .args(["eval", "render", "--seeds", "3", "--half"])
        .args(["--sun-deg", "-2"])
        .output()
        .unwrap();
    assert_refused(&run, "sun_elevation_deg");
}
