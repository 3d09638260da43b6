//! `segloc map from-grid` end to end: rocks from a small hand-made grid, and bad grids
//! refused with exit 2 and no map written.

mod common;

use common::{assert_refused, assert_success, segloc};
use segloc_maps::{grid_to_string, read_grid_csv, read_map, LacGrid};
use std::path::PathBuf;

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
        assert_refused(&out, name);
        assert_refused(&out, expect);
        assert!(!out_map.exists(), "{name}: a map was written");
    }
}

/// The LAC ground-truth grid written as a rock raster (a PNG mask, top row = largest y,
/// and a heights CSV of the same shape), placed by its top-left corner.
fn lac_grid_as_raster(grid: &LacGrid, dir: &std::path::Path) -> (PathBuf, PathBuf) {
    let n = grid.cells_per_side;
    let mut png = image::GrayImage::new(n as u32, n as u32);
    let mut heights = String::new();
    for row in 0..n {
        let j = n - 1 - row; // row 0 is the top: the largest y
        let line: Vec<String> = (0..n)
            .map(|i| {
                let k = grid.index(i, j);
                if grid.rock[k] {
                    png.put_pixel(i as u32, row as u32, image::Luma([255]));
                }
                format!("{}", grid.height[k])
            })
            .collect();
        heights.push_str(&line.join(","));
        heights.push('\n');
    }
    let (mask_path, heights_path) = (dir.join("rocks.png"), dir.join("heights.csv"));
    png.save(&mask_path).unwrap();
    std::fs::write(&heights_path, heights).unwrap();
    (mask_path, heights_path)
}

#[test]
fn a_rock_raster_gives_the_grid_rocks_and_places_a_real_traverse() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let grid_csv = data.join("lac-groundtruth/moon_map_01_preset_1.csv");
    let grid = read_grid_csv(&grid_csv).unwrap();
    let (mask, heights) = lac_grid_as_raster(&grid, dir.path());
    let from_grid = dir.path().join("grid.map.json");
    let from_raster = dir.path().join("raster.map.json");
    assert_success(
        &segloc()
            .args(["map", "from-grid"])
            .arg(&grid_csv)
            .arg("-o")
            .arg(&from_grid)
            .output()
            .unwrap(),
    );
    let out = segloc()
        .args(["map", "from-grid"])
        .arg(&mask)
        .args(["--cell-size", "0.15", "--origin", "-13.5,13.5", "--heights"])
        .arg(&heights)
        .arg("-o")
        .arg(&from_raster)
        .arg("--json")
        .output()
        .unwrap();
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["heights"], true);
    // the same rocks (in another order): every raster rock at a grid rock's centre
    let (a, b) = (
        read_map(&from_grid).unwrap(),
        read_map(&from_raster).unwrap(),
    );
    assert_eq!(a.len(), b.len());
    for l in &b.landmarks {
        let same = a
            .landmarks
            .iter()
            .any(|m| (m.position - l.position).norm() < 1e-6 && m.size_m == l.size_m);
        assert!(
            same,
            "raster rock {} at {:?} is not a grid rock",
            l.id, l.position
        );
    }
    // and a real traverse finds itself on it
    let out = segloc()
        .args(["relocalize", "--prior"])
        .arg(&from_raster)
        .arg("--query")
        .arg(data.join("lunarloc/traverse_7.csv"))
        .arg("--json")
        .output()
        .unwrap();
    assert_success(&out);
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let t = &r["prior_from_query"];
    let offset = (t[0][3].as_f64().unwrap()).hypot(t[1][3].as_f64().unwrap());
    assert!(
        offset < 0.05,
        "traverse 7 placed {offset} m from its true pose: {r}"
    );
}

#[test]
fn bad_rasters_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mask = dir.path().join("mask.csv");
    std::fs::write(&mask, "0,1,0\n1,1,0\n").unwrap();
    let short_heights = dir.path().join("h.csv");
    std::fs::write(&short_heights, "1,1,1\n").unwrap();
    let ragged = dir.path().join("ragged.csv");
    std::fs::write(&ragged, "0,1,0\n1,1\n").unwrap();
    let out_map = dir.path().join("out.map.json");
    let cases: [(&[&str], &std::path::Path, &str); 4] = [
        (
            &["--cell-size", "0.15"],
            &mask,
            "needs both --cell-size and --origin",
        ),
        (
            &["--cell-size", "0", "--origin", "0,0"],
            &mask,
            "cell size must be a positive",
        ),
        (
            &[
                "--cell-size",
                "0.15",
                "--origin",
                "0,0",
                "--heights",
                short_heights.to_str().unwrap(),
            ],
            &mask,
            "but the rock mask has 2 × 3",
        ),
        (
            &["--cell-size", "0.15", "--origin", "0,0"],
            &ragged,
            "ragged.csv:2",
        ),
    ];
    for (args, input, expect) in cases {
        let out = segloc()
            .args(["map", "from-grid"])
            .arg(input)
            .args(args)
            .arg("-o")
            .arg(&out_map)
            .output()
            .unwrap();
        assert_refused(&out, expect);
        assert!(!out_map.exists(), "{args:?}: a map was written");
    }
}
