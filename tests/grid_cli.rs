//! `segloc grid rocks|score` end to end, including bad input.

mod common;

use common::{assert_refused, assert_success, segloc, stderr_of};
use segloc_maps::{grid_to_string, read_grid_csv, LacGrid};

fn small_truth() -> LacGrid {
    let mut g = LacGrid::new(4, 0.15);
    g.height = vec![1.0; 16];
    g.rock[0] = true;
    g.rock[5] = true;
    g
}

#[test]
fn score_prints_exact_points() {
    let dir = tempfile::tempdir().unwrap();
    let truth = small_truth();
    let mut est = truth.clone();
    est.height[3] = f64::NAN;
    est.rock[5] = false;
    est.rock[6] = true;
    std::fs::write(dir.path().join("t.csv"), grid_to_string(&truth)).unwrap();
    std::fs::write(dir.path().join("e.csv"), grid_to_string(&est)).unwrap();
    let out = segloc()
        .args(["grid", "score"])
        .arg(dir.path().join("e.csv"))
        .arg("--groundtruth")
        .arg(dir.path().join("t.csv"))
        .arg("--json")
        .arg("--rock-picture")
        .arg(dir.path().join("r.png"))
        .output()
        .unwrap();
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["geometric"], 300.0 * 15.0 / 16.0);
    assert_eq!(v["rock_f1"], 0.5); // TP 1, FP 1, FN 1
    assert_eq!(v["rocks"], 150.0);
    assert_eq!(v["total"], 300.0 * 15.0 / 16.0 + 150.0 + 150.0);
    assert!(dir.path().join("r.png").exists());
    // text output
    let out = segloc()
        .args(["grid", "score"])
        .arg(dir.path().join("e.csv"))
        .arg("--groundtruth")
        .arg(dir.path().join("t.csv"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stdout).contains("total"));
}

#[test]
fn malformed_grid_exits_2_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let truth = small_truth();
    std::fs::write(dir.path().join("t.csv"), grid_to_string(&truth)).unwrap();
    let mut text = grid_to_string(&truth);
    text = text.replacen("0,1,-0.225,-0.075,1.000000,0", "0,1,-0.225,-0.075,abc,0", 1);
    assert!(text.contains("abc"));
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, &text).unwrap();
    let out = segloc()
        .args(["grid", "score"])
        .arg(&bad)
        .arg("--groundtruth")
        .arg(dir.path().join("t.csv"))
        .output()
        .unwrap();
    assert_refused(&out, "bad.csv:3");
    // mismatched sizes
    std::fs::write(
        dir.path().join("big.csv"),
        grid_to_string(&LacGrid::new(6, 0.15)),
    )
    .unwrap();
    let out = segloc()
        .args(["grid", "score"])
        .arg(dir.path().join("big.csv"))
        .arg("--groundtruth")
        .arg(dir.path().join("t.csv"))
        .output()
        .unwrap();
    assert_refused(&out, "grids differ");
    // a missing file
    let out = segloc()
        .args(["grid", "score", "/nonexistent/g.csv", "--groundtruth"])
        .arg(dir.path().join("t.csv"))
        .output()
        .unwrap();
    assert_refused(&out, "cannot read /nonexistent/g.csv");
    // the cause once, not repeated by the error chain
    let err = stderr_of(&out);
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
}

#[test]
fn rocks_from_a_small_traverse() {
    let dir = tempfile::tempdir().unwrap();
    // the rover drives along +x; one boulder at (3.05, 0.05) is seen every second
    let mut csv = String::from("frame,x,y,z,detections,boulders\n");
    for f in 0..200u64 {
        let x = 0.005 * f as f64;
        if f % 20 == 0 && f < 120 {
            csv.push_str(&format!("{f},{x:.4},0.0,0.1,1,\"[(3.05, 0.05, 0.1)]\"\n"));
        } else {
            csv.push_str(&format!("{f},{x:.4},0.0,0.1,0,[]\n"));
        }
    }
    let t = dir.path().join("traverse_1.csv");
    std::fs::write(&t, csv).unwrap();
    let g = dir.path().join("rocks.csv");
    let out = segloc()
        .args(["grid", "rocks", "--json", "--traverses"])
        .arg(&t)
        .arg("-o")
        .arg(&g)
        .output()
        .unwrap();
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // one traverse sees no boulder from two sessions: no viewpoint bias to estimate
    assert_eq!(v["view_bias_m"], 0.0, "{v}");
    assert_eq!(v["config"]["view_bias_m"], 0.0, "{v}");
    let grid = read_grid_csv(&g).unwrap();
    assert_eq!(grid.num_cells(), 32_400);
    assert_eq!(grid.filled_count(), 0);
    assert_eq!(grid.rock_count(), 1);
    let (i, j) = grid.cell_of(3.05, 0.05).unwrap();
    assert!(grid.rock[grid.index(i, j)]);
    let text = std::fs::read_to_string(&g).unwrap();
    assert!(text.starts_with("i,j,x,y,height,rock\n0,0,-13.425,-13.425,-inf,0\n"));
    // the printed defaults load back; bad ones exit 2 naming the file and the field,
    // the grid untouched
    let cfg = dir.path().join("evidence.toml");
    let rocks_with = |config: &[u8]| {
        std::fs::write(&cfg, config).unwrap();
        segloc()
            .args(["grid", "rocks", "--traverses"])
            .arg(&t)
            .arg("-o")
            .arg(&g)
            .arg("--evidence-config")
            .arg(&cfg)
            .output()
            .unwrap()
    };
    let printed = segloc()
        .args(["config", "print", "--evidence"])
        .output()
        .unwrap();
    assert_success(&printed);
    assert!(String::from_utf8_lossy(&printed.stdout).contains("[lander]"));
    assert_success(&rocks_with(&printed.stdout));
    assert_eq!(std::fs::read_to_string(&g).unwrap(), text);
    for (config, field) in [
        ("view_bias_m = 3.0\n", "view_bias_m"),
        (
            "[lander]\nmax_rock_height_m = -0.1\n",
            "lander.max_rock_height_m",
        ),
    ] {
        let out = rocks_with(config.as_bytes());
        assert_refused(&out, "evidence.toml");
        assert_refused(&out, field);
        assert_eq!(std::fs::read_to_string(&g).unwrap(), text);
    }
    // a malformed traverse: exit 2 naming the file and line
    std::fs::write(
        &t,
        "frame,x,y,z,detections,boulders\n1,0,0,0,1,\"[(1, 2)]\"\n",
    )
    .unwrap();
    let out = segloc()
        .args(["grid", "rocks", "--traverses"])
        .arg(&t)
        .arg("-o")
        .arg(&g)
        .output()
        .unwrap();
    assert_refused(&out, "traverse_1.csv:2");
}

#[test]
fn real_rock_map_scores_above_raw_counting() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let g = dir.path().join("rocks.csv");
    let out = segloc()
        .args(["grid", "rocks", "--traverses"])
        .args((1..=17).map(|n| data.join(format!("lunarloc/traverse_{n}.csv"))))
        .arg("-o")
        .arg(&g)
        .output()
        .unwrap();
    assert_success(&out);
    let out = segloc()
        .args(["grid", "score", "--json"])
        .arg(&g)
        .arg("--groundtruth")
        .arg(data.join("lac-groundtruth/moon_map_01_preset_1.csv"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["rock_f1"].as_f64().unwrap() >= 0.65, "{v}");
}
