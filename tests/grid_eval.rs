//! Global localization against the real LAC ground-truth rock grid: three LunarLoc
//! traverses, each under random rigid transforms, and their mirror images.

mod common;

use segloc::eval::grid::{evaluate_grid, GridEvalOptions};
use segloc::relocalize::RelocalizeConfig;

#[test]
fn three_traverses_placed_against_the_grid_and_mirrors_refused() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let options = GridEvalOptions {
        traverses: vec![3, 7, 12],
        cell_size_m: 0.15,
        trials: 2,
        submaps: false,
        submap_s: 60.0,
        negatives: true,
        seed: 5,
        extra_rocks: 0,
        grid_rocks: Default::default(),
    };
    let report = evaluate_grid(&data, &options, &RelocalizeConfig::default(), |_, _| {}).unwrap();
    assert_eq!(report.prior_landmarks, 578);
    let t = &report.traverses;
    assert_eq!(t.queries, 6);
    assert_eq!(t.within_5cm, 6, "{t:?}");
    assert_eq!(report.negatives.accepted, 0, "{:?}", report.negatives);
    // the tolerances followed the grid's covariances
    let q = &report.queries[0];
    assert!(q.epsilon_max_m > 0.1, "{q:?}");
}

#[test]
fn coarser_grids_load_and_bad_cell_sizes_are_refused() {
    let Some(data) = common::data_dir() else {
        return;
    };
    for (cell, factor) in [(0.3, 2.0f64), (0.45, 3.0)] {
        let map = segloc::eval::grid::grid_prior(&data, cell, &Default::default(), 0, 1).unwrap();
        let cov = map.landmarks[0].covariance;
        assert!((cov[(0, 0)] - (0.15 * factor).powi(2) / 12.0).abs() < 1e-12);
    }
    assert!(segloc::eval::grid::grid_prior(&data, 0.2, &Default::default(), 0, 1).is_err());
    let big = segloc::eval::grid::grid_prior(&data, 0.15, &Default::default(), 1422, 1).unwrap();
    assert_eq!(big.len(), 2000);
}

#[test]
fn traverses_in_sparse_ground_are_placed_against_the_coarsest_grid() {
    let Some(data) = common::data_dir() else {
        return;
    };
    // 14 and 17 land where the site's rocks are sparse: the bounding box's chance count
    // refused them by one inlier (docs/design/grid-coarse-cells.md, rule 3)
    let options = GridEvalOptions {
        traverses: vec![14, 17],
        cell_size_m: 0.45,
        trials: 1,
        submaps: false,
        submap_s: 60.0,
        negatives: true,
        seed: 1,
        extra_rocks: 0,
        grid_rocks: Default::default(),
    };
    let report = evaluate_grid(&data, &options, &RelocalizeConfig::default(), |_, _| {}).unwrap();
    let t = &report.traverses;
    assert_eq!((t.queries, t.within_15cm), (2, 2), "{t:?}");
    assert_eq!(report.negatives.accepted, 0, "{:?}", report.negatives);
}
