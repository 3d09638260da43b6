//! Session 1 started lost against its site's rock grid (`segloc mission --session1-start
//! lost-vs-grid`): a short mission through the CLI's JSON, and the option's configuration.

mod common;

use common::{assert_refused, segloc, stderr_of};

#[test]
fn lost_session_one_is_placed_by_the_grid() {
    let output = segloc()
        .args([
            "mission",
            "--seed",
            "1",
            "--seconds",
            "120",
            "--session1-start",
            "lost-vs-grid",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", stderr_of(&output));
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(v["config"]["session_1_start"], "lost_vs_grid");
    let lost = &v["sessions"][0]["lost_start"];
    assert_eq!(lost["prior"], "site rock grid", "{lost}");
    assert!(lost["prior_landmarks"].as_u64().unwrap() > 100, "{lost}");
    let first_fix_s = lost["first_fix_s"].as_f64().expect("session 1 was placed");
    assert!(first_fix_s < 100.0, "{lost}");
    assert!(lost["fixes"]["accepted"].as_u64().unwrap() > 0, "{lost}");
    assert_eq!(lost["fixes"]["wrong_accepted"], 0, "{lost}");
    // placed to within a few centimetres from the first fix on (the known start's
    // session 1 is at 0.5–1 cm)
    let rmse = lost["rmse_after_first_fix_m"].as_f64().unwrap();
    assert!(rmse < 0.05, "session 1 RMSE after its first fix {rmse} m");
    // session 2 relocalizes against session 1's map as with a known start
    let lost_2 = &v["sessions"][1]["lost_start"];
    assert_eq!(lost_2["prior"], "session 1 map", "{lost_2}");
    assert_eq!(v["relocalizations"]["wrong_accepted"], 0);
}

#[test]
fn a_known_start_reports_no_lost_start_for_session_one() {
    let output = segloc()
        .args(["mission", "--seed", "2", "--seconds", "30", "--json"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", stderr_of(&output));
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(v["config"]["session_1_start"], "known");
    assert!(v["sessions"][0].get("lost_start").is_none());
    assert!(v["sessions"][1]["lost_start"].is_object());
}

#[test]
fn bad_lost_start_config_is_bad_input_naming_the_toml_path() {
    let dir = tempfile::tempdir().unwrap();
    for (text, expected) in [
        (
            "session_1_start = \"lost_vs_grid\"\n[session_1_lost]\nguess_error_max = [1.0, -1.0, 0.0]\n",
            "session_1_lost.guess_error_max",
        ),
        (
            "[session_1_lost.grid_rocks]\nmin_cells = 0\n",
            "session_1_lost.grid_rocks.min_cells",
        ),
        ("session_1_start = \"lost\"\n", "session_1_start"),
    ] {
        let path = dir.path().join("mission.toml");
        std::fs::write(&path, text).unwrap();
        let output = segloc()
            .args(["mission", "--seconds", "5", "--mission-config"])
            .arg(&path)
            .output()
            .unwrap();
        assert_refused(&output, expected);
        assert_refused(&output, "mission.toml");
    }
}
