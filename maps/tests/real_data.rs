//! Reads the real LunarLoc traverses and the LAC ground-truth grid (from `SEGLOC_DATA`,
//! default `../../shared/data` relative to this crate) and checks their counts.
//!
//! Without the data the tests are skipped with a message, except under `CI=true`, where a
//! missing data directory is a failure.

use std::path::PathBuf;
use std::time::Instant;

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use segloc_maps::*;

fn data_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("SEGLOC_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data"))
        });
    if dir.join("lunarloc").is_dir() {
        return Some(dir);
    }
    let ci = std::env::var("CI").is_ok_and(|v| v == "true" || v == "1");
    assert!(
        !ci,
        "CI=true but the real data is missing at {} (set SEGLOC_DATA)",
        dir.display()
    );
    eprintln!(
        "skipping: no real data at {} (set SEGLOC_DATA)",
        dir.display()
    );
    None
}

/// (traverse, rows, total detections, rows with detections)
const TRAVERSES: [(u32, usize, usize, usize); 17] = [
    (1, 6503, 1283, 315),
    (2, 6619, 1280, 325),
    (3, 6474, 1261, 312),
    (4, 18660, 3376, 923),
    (5, 10761, 1884, 525),
    (6, 6731, 1060, 326),
    (7, 7603, 6263, 1713),
    (8, 13701, 2374, 656),
    (9, 11554, 1695, 483),
    (10, 17119, 2982, 811),
    (11, 7337, 874, 292),
    (12, 7251, 871, 292),
    (13, 30450, 14494, 4517),
    (14, 6664, 2911, 976),
    (15, 19087, 6722, 2730),
    (16, 2168, 755, 317),
    (17, 9238, 3701, 1233),
];

#[test]
fn all_traverses_parse_with_expected_counts() {
    let Some(data) = data_dir() else { return };
    let start = Instant::now();
    let traverses: Vec<Traverse> = TRAVERSES
        .iter()
        .map(|(n, ..)| {
            read_lunarloc_traverse(&data.join(format!("lunarloc/traverse_{n}.csv")))
                .unwrap_or_else(|e| panic!("{e}"))
        })
        .collect();
    let elapsed = start.elapsed();
    eprintln!(
        "parsed 17 traverses in {:.1} ms",
        elapsed.as_secs_f64() * 1e3
    );
    for (t, &(n, rows, dets, rows_with)) in traverses.iter().zip(&TRAVERSES) {
        assert_eq!(t.name, format!("traverse_{n}"));
        assert_eq!(t.frames.len(), rows, "{}", t.name);
        assert_eq!(t.num_detections(), dets, "{}", t.name);
        let with = t.frames.iter().filter(|f| !f.boulders.is_empty()).count();
        assert_eq!(with, rows_with, "{}", t.name);
        assert_eq!(t.frames[0].frame, 1);
        assert!(t.frames.windows(2).all(|w| w[0].frame < w[1].frame));
        let d = t.detections();
        assert_eq!(d.len(), dets);
        assert_eq!(d.session, t.name);
        assert!(d.gravity_aligned);
        assert!(d.validate().is_ok());
        assert_eq!(t.trajectory().len(), rows);
    }
}

#[test]
fn ground_truth_grid_counts_and_exact_rewrite() {
    let Some(data) = data_dir() else { return };
    let path = data.join("lac-groundtruth/moon_map_01_preset_1.csv");
    let grid = read_grid_csv(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(grid.cells_per_side, LAC_CELLS_PER_SIDE);
    assert_eq!(grid.cell_size_m, LAC_CELL_SIZE_M);
    assert_eq!(grid.num_cells(), 32_400);
    assert_eq!(grid.filled_count(), 32_400);
    assert_eq!(grid.rock_count(), 848);
    assert_eq!(grid, {
        let mut g = LacGrid::new_lac();
        g.height.clone_from(&grid.height);
        g.rock.clone_from(&grid.rock);
        g
    });
    // writing it back gives the original file byte for byte
    let original = std::fs::read_to_string(&path).unwrap();
    assert_eq!(grid_to_string(&grid), original);
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("grid.csv");
    write_grid_csv(&grid, &copy).unwrap();
    assert_eq!(read_grid_csv(&copy).unwrap(), grid);
}

#[test]
fn traverses_live_in_the_ground_truth_world() {
    let Some(data) = data_dir() else { return };
    let grid = read_grid_csv(&data.join("lac-groundtruth/moon_map_01_preset_1.csv")).unwrap();
    let (mut on_rock, mut inside) = (0usize, 0usize);
    let mut clearance = Vec::new();
    for n in 1..=17 {
        let t = read_lunarloc_traverse(&data.join(format!("lunarloc/traverse_{n}.csv"))).unwrap();
        for f in &t.frames {
            for b in &f.boulders {
                if let Some((i, j)) = grid.cell_of(b.x, b.y) {
                    inside += 1;
                    // a boulder centroid may sit on the edge of its rock cell
                    let near_rock = (i.saturating_sub(1)..=(i + 1).min(179)).any(|ii| {
                        (j.saturating_sub(1)..=(j + 1).min(179))
                            .any(|jj| grid.rock[grid.index(ii, jj)])
                    });
                    on_rock += usize::from(near_rock);
                }
            }
            if let Some((i, j)) = grid.cell_of(f.rover_position.x, f.rover_position.y) {
                clearance.push(f.rover_position.z - grid.height[grid.index(i, j)]);
            }
        }
    }
    let frac = on_rock as f64 / inside as f64;
    clearance.sort_by(f64::total_cmp);
    let median = clearance[clearance.len() / 2];
    eprintln!("{frac:.3} of {inside} boulder centroids on or next to a rock cell; median rover clearance {median:.3} m");
    assert!(frac > 0.7, "{frac}");
    assert!((0.05..0.2).contains(&median), "{median}");
}

#[test]
fn real_detections_round_trip_through_every_format() {
    let Some(data) = data_dir() else { return };
    let t = read_lunarloc_traverse(&data.join("lunarloc/traverse_3.csv")).unwrap();
    let iso = Isometry3::from_parts(
        Translation3::new(12.0, -3.0, 0.4),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 1.2),
    );
    let moved = t.transformed(&iso).detections();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("query.csv");
    write_detections(&moved, &p).unwrap();
    assert_eq!(read_any_detections(&p).unwrap(), moved);

    let mut map = ObjectMap::new("world", &t.name, true);
    map.notes.insert("source".into(), "traverse_3.csv".into());
    for (id, d) in t.detections().detections.iter().enumerate() {
        map.landmarks.push(Landmark::new(
            id as u32,
            d.p_world,
            Matrix3::identity() * 1e-4,
        ));
    }
    let mp = dir.path().join("map.json");
    write_map(&map, &mp).unwrap();
    assert_eq!(read_map(&mp).unwrap(), map);
    let moved_map = map.transformed(&iso, "query");
    for (a, b) in moved_map.positions().iter().zip(moved.positions()) {
        assert!((a - b).norm() < 1e-9);
    }
}
