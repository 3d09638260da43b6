//! `segloc map from-grid` end to end: rocks from a small hand-made grid, and bad grids
//! refused with exit 2 and no map written.

mod common;

use common::{assert_success, segloc, stderr_of};
use segloc_maps::{grid_to_string, read_map, LacGrid};

/// A 6 × 6 grid of 0.15 m: a two-cell rock and a lone rock cell.
fn small_grid() -> LacGrid {
    let mut g = LacGrid::new(6, 0.15);
    g.height = vec![1.5; 36];
    for (i, j) in [(1, 1), (1, 2), (4, 4)] {
        let k = g.index(i, j);
        g.rock[k] = true;
    }
    g
}

#[test]
fn rocks_become_landmarks_with_cell_covariances() {
    let dir = tempfile::tempdir().unwrap();
    let grid = dir.path().join("g.csv");
    std::fs::write(&grid, grid_to_string(&small_grid())).unwrap();
    let out_map = dir.path().join("site.map.json");
    let out = segloc()
        .args(["map", "from-grid"])
        .arg(&grid)
        .arg("-o")
        .arg(&out_map)
        .arg("--json")
        .output()
        .unwrap();
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["landmarks"], 2);
    assert_eq!(v["rock_cells"], 3);
    let map = read_map(&out_map).unwrap();
    assert!(map.gravity_aligned);
    let two = &map.landmarks[0];
    // cells (1,1) and (1,2): x = -0.225, y between -0.225 and -0.075
    assert!((two.position.x + 0.225).abs() < 1e-9);
    assert!((two.position.y + 0.15).abs() < 1e-9);
    assert!((two.position.z - 1.5).abs() < 1e-9);
    assert!((two.covariance[(0, 0)] - 0.15f64.powi(2) / 12.0).abs() < 1e-12);
    assert_eq!(two.size_m, Some(0.3));
    // --min-cells 2 keeps only the two-cell rock
    let out = segloc()
        .args(["map", "from-grid"])
        .arg(&grid)
        .arg("-o")
        .arg(&out_map)
        .args(["--min-cells", "2", "--json"])
        .output()
        .unwrap();
    assert_success(&out);
    assert_eq!(read_map(&out_map).unwrap().len(), 1);
}

#[test]
fn bad_grids_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let good = grid_to_string(&small_grid());
    let no_rocks = grid_to_string(&{
        let mut g = small_grid();
        g.rock = vec![false; 36];
        g
    });
    let missing_cell: String = good
        .lines()
        .filter(|l| !l.starts_with("2,3,"))
        .map(|l| format!("{l}\n"))
        .collect();
    let uneven = good.replacen("5,0,0.375,", "5,0,0.395,", 1);
    assert_ne!(uneven, good);
    for (name, text, expect) in [
        ("no_rocks.csv", no_rocks, "no rock cells"),
        ("missing.csv", missing_cell, "35 cells"),
        ("uneven.csv", uneven, "centred"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let out_map = dir.path().join(format!("{name}.map.json"));
        let out = segloc()
            .args(["map", "from-grid"])
            .arg(&path)
            .arg("-o")
            .arg(&out_map)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{name}");
        let err = stderr_of(&out);
        assert!(err.contains(name) && err.contains(expect), "{name}: {err}");
        assert!(!out_map.exists(), "{name}: a map was written");
    }
}
