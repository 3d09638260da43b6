//! The mission on rendered images end to end (`segloc mission --sensors rendered --half`):
//! every camera frame's stereo pairs rendered and run through the perception front end,
//! whose boulders feed the maps, the relocalization and the planner, and the odometry from
//! the stereo VO on the front pair rendered at 10 Hz.

mod common;

use common::{assert_success, segloc, stderr_of};

#[test]
fn short_rendered_mission_reports_perception() {
    let dir = tempfile::tempdir().unwrap();
    let output = segloc()
        .args([
            "mission",
            "--seed",
            "2",
            "--seconds",
            "30",
            "--sensors",
            "rendered",
            "--half",
            "--json",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_success(&output);
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(v["sessions"].as_array().map(Vec::len), Some(2));
    // every VO pair of each session, with the odometry's and the true pose, in a CSV
    for session in [1, 2] {
        let csv =
            std::fs::read_to_string(dir.path().join(format!("session{session}_vo.csv"))).unwrap();
        let mut lines = csv.lines();
        assert!(lines.next().unwrap().starts_with("time_s,tracked,inliers"));
        assert_eq!(lines.clone().count(), 301);
        assert!(lines.all(|l| l.split(',').count() == 16));
    }
    let p = &v["perception"];
    // two pairs (front, back) per camera frame, 31 frames per 30 s session
    assert_eq!(p["pairs"].as_u64(), Some(2 * 2 * 31), "{p}");
    assert_eq!(p["width_px"].as_u64(), Some(640), "{p}");
    assert_eq!(p["segmenter"].as_str(), Some("geometric"), "{p}");
    assert!(p["rocks"].as_u64().unwrap() > 0, "{p}");
    assert!(p["detections"].as_u64().unwrap() > 0, "{p}");
    for key in ["recall", "precision"] {
        let x = p[key].as_f64().unwrap_or(-1.0);
        assert!(x > 0.0 && x <= 1.0, "perception.{key}: {p}");
    }
    let e = &p["centroid_error_m"];
    let (median, p90) = (e["median"].as_f64().unwrap(), e["p90"].as_f64().unwrap());
    // a match is within 0.3 × size of the rock's visible centre
    assert!(median >= 0.0 && median <= p90 && p90 < 0.5, "{p}");
    assert!(p["render_ms"]["median"].as_f64().unwrap() > 0.0, "{p}");
    let front_end = &p["front_end_ms"];
    assert!(front_end["median"].as_f64().unwrap() > 0.0, "{p}");
    assert!(
        front_end["p99"].as_f64() >= front_end["median"].as_f64(),
        "{p}"
    );
    // the detections went into the maps: a LAC score and a prior map
    assert!(v["prior_landmarks"].as_u64().unwrap() > 0, "{v}");
    assert!(v["lac"]["rocks"].is_number() && v["lac"]["geometric"].is_number());
    assert_eq!(
        v["config"]["perception"]["sensors"].as_str(),
        Some("rendered")
    );
    // the odometry came from the images: a pair every other tick, 301 a session
    assert_eq!(
        v["config"]["perception"]["odometry"].as_str(),
        Some("images")
    );
    for s in v["sessions"].as_array().unwrap() {
        // no drawn biases: the odometry came from the images
        assert!(s["odometry_bias"]["estimated"].is_object(), "{s}");
        assert!(s["odometry_bias"].get("drawn").is_none(), "{s}");
        let vo = &s["image_odometry"];
        assert_eq!(vo["pairs"].as_u64(), Some(301), "{vo}");
        assert!(vo["lost"].as_u64().unwrap() < 30, "{vo}");
        assert!(vo["vo_ms"]["median"].as_f64().unwrap() > 0.0, "{vo}");
        let without_global = s["rmse_without_global_m"].as_f64().unwrap();
        assert!(
            without_global < 0.5,
            "odometry alone {without_global} m off in 30 s"
        );
    }
}

#[test]
fn image_options_without_rendered_sensors_are_bad_input() {
    for args in [
        &["mission", "--half"][..],
        &["mission", "--sensors", "model", "--segmenter", "onnx"],
        &["mission", "--sensors", "pixels"],
        &["mission", "--vo", "model"],
    ] {
        let output = segloc().args(args).output().unwrap();
        assert_eq!(
            output.status.code(),
            Some(2),
            "{args:?}: {}",
            stderr_of(&output)
        );
    }
}
