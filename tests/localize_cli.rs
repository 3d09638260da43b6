//! `segloc localize` and `segloc sim export` end to end: a mission session exported as a
//! recorded drive, localized from the command line against the exported prior map and
//! scored against the exported truth; mapping then localizing; bad input.

mod common;

use common::{assert_refused, assert_success, segloc, stderr_of};
use std::path::{Path, PathBuf};

/// Positions of a TUM file by time (rounded to the microsecond).
fn read_tum(path: &Path) -> Vec<(i64, [f64; 3])> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            ((v[0] * 1e6).round() as i64, [v[1], v[2], v[3]])
        })
        .collect()
}

/// Export session `session` of seed 3 with `seconds` per session into `dir`.
fn export(dir: &Path, session: &str, seconds: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (frames, truth, prior) = (
        dir.join(format!("drive{session}.jsonl")),
        dir.join(format!("truth{session}.tum")),
        dir.join("prior.map.json"),
    );
    let out = segloc()
        .args([
            "sim",
            "export",
            "--seed",
            "3",
            "--session",
            session,
            "--seconds",
            seconds,
            "-o",
        ])
        .arg(&frames)
        .arg("--truth")
        .arg(&truth)
        .arg("--prior-map")
        .arg(&prior)
        .output()
        .unwrap();
    assert_success(&out);
    (frames, truth, prior)
}

#[test]
fn an_exported_session_localizes_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let (frames, truth, prior) = export(dir.path(), "2", "120");
    let tum = dir.path().join("out.tum");
    let out = segloc()
        .args(["localize", "--json", "--prior"])
        .arg(&prior)
        .arg("--frames")
        .arg(&frames)
        .arg("-o")
        .arg(&tum)
        .output()
        .unwrap();
    assert_success(&out);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["frames"], 121);
    assert!(
        summary["fixes"]["accepted"].as_u64().unwrap() >= 5,
        "{summary}"
    );
    assert!(summary["first_fix_t"].as_f64().unwrap() <= 60.0);
    assert_eq!(summary["prior_from_odom"].as_array().unwrap().len(), 4);
    assert!(summary["config"]["gate"].is_object());
    // the session's calibration of its odometry, to carry into the next session
    let bias = &summary["odometry_bias"];
    for field in ["scale_error", "yaw_drift_rad_per_m", "yaw_scale_error"] {
        assert!(bias[field].as_f64().is_some_and(f64::is_finite), "{bias}");
    }
    // the trajectory from the first fix on, within 2 cm of the truth
    let truth: std::collections::HashMap<i64, [f64; 3]> = read_tum(&truth).into_iter().collect();
    let estimate = read_tum(&tum);
    assert!(estimate.len() >= 60);
    let sum: f64 = estimate
        .iter()
        .map(|(t, p)| {
            let q = truth[t];
            (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>()
        })
        .sum();
    let rmse = (sum / estimate.len() as f64).sqrt();
    assert!(rmse < 0.02, "RMSE {rmse} m");
}

#[test]
fn a_mapping_session_then_a_session_against_its_map() {
    let dir = tempfile::tempdir().unwrap();
    let (frames_1, _, _) = export(dir.path(), "1", "20");
    let map = dir.path().join("session1.map.json");
    let tum = dir.path().join("s1.tum");
    let out = segloc()
        .args(["localize", "--frames"])
        .arg(&frames_1)
        .arg("-o")
        .arg(&tum)
        .arg("--map-out")
        .arg(&map)
        .output()
        .unwrap();
    assert_success(&out);
    assert_eq!(read_tum(&tum).len(), 21);
    assert!(map.exists());
    // 20 s of session 1, mapped here, cover too little of the site for session 2 to find
    // itself in 60 s: exit 1, the reasons counted, nothing written
    let (frames_2, _, _) = export(dir.path(), "2", "60");
    let tum_2 = dir.path().join("s2.tum");
    let out = segloc()
        .args(["localize", "--json", "--prior"])
        .arg(&map)
        .arg("--frames")
        .arg(&frames_2)
        .arg("-o")
        .arg(&tum_2)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr_of(&out));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["fixes"]["accepted"], 0);
    assert!(summary["fixes"]["refused"].as_u64().unwrap() > 0);
    assert!(summary["first_fix_t"].is_null());
    assert!(!tum_2.exists());
}

const GOOD: &str = r#"{"t": 0.0, "odom_from_rover": [0, 0, 0, 0, 0, 0, 1], "detections": [{"p_rover": [2, 0, 0.1], "size_m": 0.3}]}"#;

/// `localize` on a frames file with `text`: exit 2, the message names the file (and
/// `expect`), and no output is written.
fn refuses(text: &str, expect: &str) {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("drive.jsonl");
    std::fs::write(&frames, text).unwrap();
    let tum = dir.path().join("out.tum");
    let out = segloc()
        .args(["localize", "--frames"])
        .arg(&frames)
        .arg("-o")
        .arg(&tum)
        .output()
        .unwrap();
    assert_refused(&out, "drive.jsonl");
    assert_refused(&out, expect);
    assert!(!tum.exists());
    let err = stderr_of(&out);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_frames_files_are_refused_with_file_and_line() {
    refuses("", "no frames");
    refuses(&format!("{GOOD}\n{{\"t\": 1.0,"), ":2");
    refuses(&format!("{GOOD}\n{}", GOOD.replace("0.0,", "-1.0,")), ":2");
    refuses(&GOOD.replace("0, 0, 0, 1]", "0, 0, 0, 1.5]"), "quaternion");
    refuses(&GOOD.replace("[2, 0, 0.1]", "[2, 1e999, 0.1]"), ":1");
    refuses(
        &format!("{{\"format\": \"segloc-frames\", \"version\": 9}}\n{GOOD}"),
        "version",
    );
}

#[test]
fn a_prior_that_fails_to_load_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("drive.jsonl");
    std::fs::write(&frames, GOOD).unwrap();
    let prior = dir.path().join("prior.map.json");
    std::fs::write(&prior, "{\"format\": \"segloc-map\", ").unwrap();
    let tum = dir.path().join("out.tum");
    let out = segloc()
        .args(["localize", "--frames"])
        .arg(&frames)
        .arg("--prior")
        .arg(&prior)
        .arg("-o")
        .arg(&tum)
        .output()
        .unwrap();
    assert_refused(&out, "prior.map.json");
    assert!(!tum.exists());
}

#[test]
fn the_localizer_config_prints_and_loads() {
    let dir = tempfile::tempdir().unwrap();
    let out = segloc()
        .args(["localize", "--print-config"])
        .output()
        .unwrap();
    assert_success(&out);
    let config = dir.path().join("localizer.toml");
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("[gate]"), "{text}");
    std::fs::write(&config, text.replace("yaw_deg = 0.5", "yaw_deg = -0.5")).unwrap();
    let frames = dir.path().join("drive.jsonl");
    std::fs::write(&frames, GOOD).unwrap();
    let localize_with = |config: &Path| {
        segloc()
            .args(["localize", "--frames"])
            .arg(&frames)
            .arg("-o")
            .arg(dir.path().join("out.tum"))
            .arg("--localizer-config")
            .arg(config)
            .output()
            .unwrap()
    };
    let out = localize_with(&config);
    assert_refused(&out, "localizer.toml");
    assert_refused(&out, "gate.yaw_deg");
    // a carried calibration out of range is named too
    let calibration = dir.path().join("calibration.toml");
    std::fs::write(&calibration, "[calibration.known]\nscale_error = 3.0\n").unwrap();
    let out = localize_with(&calibration);
    assert_refused(&out, "calibration.known.scale_error");
}
