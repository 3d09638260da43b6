//! `segloc demo`: the main job on built-in data, end to end through the binary.

mod common;

use common::{assert_refused, segloc};

#[test]
fn demo_runs_the_mission_and_writes_report_pictures_and_recording() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("short.toml");
    std::fs::write(&config, "seconds_per_session = 60.0\n").unwrap();
    let out_dir = dir.path().join("demo");
    let output = segloc()
        .args(["demo", "--seed", "4", "--mission-config"])
        .arg(&config)
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(output.status.success(), "{output:?}");
    let stdout = String::from_utf8_lossy(&output.stdout);
    for line in [
        "session 1:",
        "session 2:",
        "relocalizations:",
        "LAC: geometric",
    ] {
        assert!(stdout.contains(line), "no {line:?} in\n{stdout}");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["seed"], 4);
    assert_eq!(report["config"]["seconds_per_session"], 60.0);
    assert_eq!(report["sessions"].as_array().unwrap().len(), 2);
    for png in ["height_error.png", "rock_map.png", "trajectories.png"] {
        let bytes = std::fs::read(out_dir.join(png)).unwrap();
        assert!(bytes.starts_with(b"\x89PNG"), "{png} is not a PNG");
    }
    let recording = out_dir.join("mission.rrd");
    if cfg!(feature = "rerun") {
        let bytes = std::fs::read(&recording).unwrap();
        assert!(bytes.len() > 100_000, "recording of {} bytes", bytes.len());
        assert!(
            bytes.starts_with(b"RRF"),
            "not a Rerun file: {:?}",
            &bytes[..4]
        );
    } else {
        assert!(!recording.exists());
    }
    // no temporary files left behind
    for entry in std::fs::read_dir(&out_dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(
            !name.contains("partial") && !name.starts_with('.'),
            "{name}"
        );
    }
}

#[test]
fn demo_refuses_a_bad_mission_config_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("bad.toml");
    // malformed, and well-formed but out of range (a session's field): both name the file
    for (text, field) in [
        ("seconds_per_session = \"long\"\n", "seconds_per_session"),
        (
            "[session]\nseen_ground_toward_camera_m = -1.0\n",
            "seen_ground_toward_camera_m",
        ),
        (
            "[session_2.obstacles]\nsize_quantile = 1.5\n",
            "size_quantile",
        ),
        (
            "[session.obstacles]\nnear_merge_radius_m = -0.1\n",
            "near_merge_radius_m",
        ),
    ] {
        std::fs::write(&config, text).unwrap();
        let output = segloc()
            .args(["demo", "--mission-config"])
            .arg(&config)
            .arg("--out")
            .arg(dir.path().join("demo"))
            .output()
            .unwrap();
        assert_refused(&output, "bad.toml");
        assert_refused(&output, field);
        assert!(!dir.path().join("demo").exists());
    }
}
