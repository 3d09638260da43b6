//! The command line end to end: outputs, exit codes, and bad input.

mod common;

use common::{assert_refused, assert_success, segloc, stderr_of};
use std::path::Path;

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn sim_field_relocalizes_and_writes_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = segloc()
        .args(["sim", "field", "--json", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_success(&out);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["status"], "ok");
    assert_eq!(report["field"]["correct"], true);
    for f in [
        "prior_map.json",
        "query_map.json",
        "prior_detections.csv",
        "report.json",
    ] {
        assert!(dir.path().join(f).exists(), "{f} missing");
    }
    // The written maps relocalize through the CLI too.
    let out = segloc()
        .args(["relocalize", "--json", "--prior"])
        .arg(dir.path().join("prior_map.json"))
        .arg("--query")
        .arg(dir.path().join("query_map.json"))
        .output()
        .unwrap();
    assert_success(&out);
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["prior_from_query"].as_array().unwrap().len(), 4);
    assert!(r["inliers"].as_u64().unwrap() >= 6);
    assert!(r["config"]["verification"].is_object());
}

#[test]
fn map_build_and_info_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let field = segloc()
        .args(["sim", "field", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(field.status.code(), Some(0));
    let map = dir.path().join("built.json");
    let out = segloc()
        .args(["map", "build"])
        .arg(dir.path().join("prior_detections.csv"))
        .arg("-o")
        .arg(&map)
        .output()
        .unwrap();
    assert_success(&out);
    let out = segloc()
        .args(["map", "info", "--json"])
        .arg(&map)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(info["landmarks"].as_u64().unwrap() > 20);
    assert_eq!(info["gravity_aligned"], true);
}

#[test]
fn unrelated_maps_exit_1_with_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    let b = dir.path().join("b");
    assert_eq!(
        segloc()
            .args(["sim", "field", "--seed", "3", "--out"])
            .arg(&a)
            .output()
            .unwrap()
            .status
            .code(),
        Some(0)
    );
    assert_eq!(
        segloc()
            .args(["sim", "field", "--seed", "4", "--out"])
            .arg(&b)
            .output()
            .unwrap()
            .status
            .code(),
        Some(0)
    );
    let out = segloc()
        .args(["relocalize", "--json", "--prior"])
        .arg(a.join("prior_map.json"))
        .arg("--query")
        .arg(b.join("query_map.json"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr_of(&out));
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["status"], "no_match");
    assert!(r["reason"].as_str().unwrap().len() > 5);
}

#[test]
fn bad_inputs_exit_2_naming_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = write(
        d,
        "good.csv",
        "frame,x,y,z,detections,boulders\n1,0,0,0,0,[]\n20,0,0,0,3,\"[(1.0, 2.0, 0.1), (2.0, 1.0, 0.2), (3.0, 3.0, 0.1)]\"\n",
    );
    let cases: Vec<(std::path::PathBuf, &str)> = vec![
        (d.join("missing.csv"), "missing.csv"),
        (
            write(d, "badrow.csv", "frame,x,y,z,detections,boulders\n1,0,0,0,0,[]\n2,0,zero,0,0,[]\n"),
            "badrow.csv:3",
        ),
        (
            write(d, "nan.csv", "frame,x,y,z,detections,boulders\n1,0,0,0,1,\"[(nan, 0.0, 0.0)]\"\n"),
            "nan.csv:2",
        ),
        (write(d, "empty.json", "{\"format\": \"segloc-map\", \"version\": 1, \"frame\": \"w\", \"session\": \"s\", \"gravity_aligned\": true, \"landmarks\": []}\n"), "0 landmarks"),
        (write(d, "future.json", "{\"format\": \"segloc-map\", \"version\": 99, \"frame\": \"w\", \"session\": \"s\", \"gravity_aligned\": true, \"landmarks\": []}\n"), "version 99"),
        (write(d, "truncated.json", "{\"format\": \"segloc-map\", \"version\": 1, \"frame\": \"w\",\n"), "truncated.json"),
        (good.clone(), "at least 3"),
    ];
    for (path, expected) in cases {
        let out = segloc()
            .args(["relocalize", "--prior"])
            .arg(&good)
            .arg("--query")
            .arg(&path)
            .output()
            .unwrap();
        assert_refused(&out, expected);
        let err = stderr_of(&out);
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn a_failed_build_leaves_no_output_file() {
    let dir = tempfile::tempdir().unwrap();
    let bad = write(
        dir.path(),
        "bad.csv",
        "frame,x,y,z,detections,boulders\n1,0,0\n",
    );
    let out_path = dir.path().join("out.json");
    let out = segloc()
        .args(["map", "build"])
        .arg(&bad)
        .arg("-o")
        .arg(&out_path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(!out_path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "temporary files left behind"
    );
}

#[test]
fn config_prints_and_loads_back() {
    let dir = tempfile::tempdir().unwrap();
    let check = |path: &Path| {
        segloc()
            .arg("--config")
            .arg(path)
            .args(["config", "check"])
            .output()
            .unwrap()
    };
    let out = segloc().args(["config", "print"]).output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    let path = write(dir.path(), "c.toml", &String::from_utf8_lossy(&out.stdout));
    assert_success(&check(&path));
    let bad = write(
        dir.path(),
        "bad.toml",
        "[verification]\nmin_inliers = \"many\"\n",
    );
    let out = check(&bad);
    assert_refused(&out, "bad.toml");
    // well-formed but meaningless: a negative noise figure of the landmark fusion
    let bad = write(
        dir.path(),
        "noise.toml",
        "[landmarks]\npose_sigma_m = -0.01\n",
    );
    let out = check(&bad);
    assert_refused(&out, "noise.toml");
    assert_refused(&out, "pose_sigma_m");
}

#[test]
fn usage_errors_exit_2() {
    let out = segloc()
        .args(["relocalize", "--prior", "x"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = segloc()
        .args(["relocalize", "--prior", "a", "--query", "b", "--dof", "5"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn bench_associate_reports_selection_and_quality() {
    let dir = tempfile::tempdir().unwrap();
    // Four points, all-to-all, identity transform.
    let mut text = String::from("4 4 16 0.1 0.05 4\n");
    let pts = ["0 0 0", "3 0 0.2", "0 4 0.1", "5 5 0.4"];
    for p in pts.iter().chain(pts.iter()) {
        text.push_str(p);
        text.push('\n');
    }
    for i in 0..4 {
        for j in 0..4 {
            text.push_str(&format!("{i} {j}\n"));
        }
    }
    let problem = write(dir.path(), "p.txt", &text);
    write(dir.path(), "p.txt.gt", "0 5 10 15\n");
    let out = segloc()
        .args(["bench", "associate", "--json", "--repeat", "2"])
        .arg(&problem)
        .output()
        .unwrap();
    assert_success(&out);
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let selected: Vec<u64> = r["selected"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(selected, vec![0, 5, 10, 15]);
    assert_eq!(r["precision"], 1.0);
    assert!(r["time_ms"].as_f64().unwrap() >= 0.0);
}
