//! sphere2500 against GTSAM's reference numbers, when the benchmark data is present.
//!
//! The data ships with the `gtsam` package on PyPI (`gtsam/Data/`), not with segloc. Set
//! `SEGLOC_GTSAM_DATA` to that folder, or run `scripts/bench_posegraph.sh` once, which
//! installs it under `target/bench-venv`. Without it the tests print that they skipped.

use segloc::graph::file::{BuildOptions, GraphFile};
use segloc::graph::metrics::trajectory_error;
use segloc::graph::synthetic::corrupt_loop_closures;
use segloc::graph::{Initialization, RobustKernel, SolverConfig};
use std::path::{Path, PathBuf};

/// GTSAM 4.3 Levenberg–Marquardt on sphere2500, pose 0 fixed, chained initial estimate,
/// information reordered to (rotation, translation): `graph.error(result)`.
const GTSAM_FINAL_COST: f64 = 364.4948686054582;

fn data_dir() -> Option<PathBuf> {
    if let Ok(d) = std::env::var("SEGLOC_GTSAM_DATA") {
        return Some(PathBuf::from(d));
    }
    let target = std::env::var("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"));
    let lib = target.join("bench-venv").join("lib");
    for entry in std::fs::read_dir(lib).ok()?.flatten() {
        let d = entry.path().join("site-packages/gtsam/Data");
        if d.join("sphere2500.txt").exists() {
            return Some(d);
        }
    }
    None
}

fn sphere() -> Option<(GraphFile, GraphFile)> {
    let Some(dir) = data_dir() else {
        eprintln!("skipped: sphere2500.txt not found (set SEGLOC_GTSAM_DATA or run scripts/bench_posegraph.sh)");
        return None;
    };
    let file = GraphFile::read(&dir.join("sphere2500.txt")).expect("read sphere2500");
    let truth = GraphFile::read(&dir.join("sphere2500_groundtruth.txt")).expect("read truth");
    Some((file, truth))
}

#[test]
fn sphere2500_reaches_gtsam_cost() {
    let Some((file, _)) = sphere() else { return };
    assert_eq!(file.edges.len(), 4949);
    for init in [Initialization::None, Initialization::Chordal] {
        let mut graph = file.to_pose_graph(&BuildOptions::default()).unwrap();
        assert_eq!(graph.num_poses(), 2500);
        let config = SolverConfig {
            initialization: init,
            ..SolverConfig::default()
        };
        let report = graph.optimize(&config).unwrap();
        assert!(report.converged, "{init:?}: {:?}", report.termination);
        assert!(
            (report.initial_cost - 1_287_028.826_948_8).abs() < 1e-3,
            "{}",
            report.initial_cost
        );
        let rel = (report.final_cost - GTSAM_FINAL_COST).abs() / GTSAM_FINAL_COST;
        assert!(
            rel <= 1e-6,
            "{init:?}: {} vs {GTSAM_FINAL_COST}",
            report.final_cost
        );
    }
}

#[test]
fn sphere2500_gnc_rejects_wrong_loop_closures() {
    let Some((file, truth)) = sphere() else {
        return;
    };
    let mut corrupted = file.clone();
    let replaced = corrupt_loop_closures(&mut corrupted.edges, 0.1, 10.0, 1);
    assert_eq!(replaced.len(), 245);
    let robust = BuildOptions {
        loop_closure_kernel: RobustKernel::Gnc { c: 4.0 },
        ..BuildOptions::default()
    };
    let mut graph = corrupted.to_pose_graph(&robust).unwrap();
    graph.optimize(&SolverConfig::default()).unwrap();
    // Oracle: the corrupted file without the replaced closures, plain least squares.
    let mut oracle_file = corrupted.clone();
    oracle_file.edges = corrupted
        .edges
        .iter()
        .enumerate()
        .filter(|(k, _)| !replaced.contains(k))
        .map(|(_, e)| e.clone())
        .collect();
    let mut oracle = oracle_file.to_pose_graph(&BuildOptions::default()).unwrap();
    oracle.optimize(&SolverConfig::default()).unwrap();
    let poses = |g: &segloc::graph::PoseGraph| -> Vec<_> {
        (0..2500u64).map(|i| (i, g.pose(i).unwrap())).collect()
    };
    let gt = truth.initial_estimates();
    let e_gnc = trajectory_error(&poses(&graph), &gt, true).position_rmse_m;
    let e_oracle = trajectory_error(&poses(&oracle), &gt, true).position_rmse_m;
    let mut clean = file.to_pose_graph(&BuildOptions::default()).unwrap();
    clean.optimize(&SolverConfig::default()).unwrap();
    let e_clean = trajectory_error(&poses(&clean), &gt, true).position_rmse_m;
    eprintln!("ATE clean {e_clean:.4} m, GNC {e_gnc:.4} m, oracle {e_oracle:.4} m");
    assert!(
        (e_gnc / e_oracle - 1.0).abs() < 1e-3,
        "GNC {e_gnc} vs oracle {e_oracle}"
    );
    // Losing 245 of 2,450 true closures costs ~6% on this seed (the 5% target is not met
    // by the oracle either); guard against regressions beyond that.
    assert!(e_gnc < 1.1 * e_clean, "GNC {e_gnc} vs clean {e_clean}");
}

/// GTSAM 4.3 Levenberg–Marquardt (default parameters, from the file's vertices, first pose
/// held) on small public g2o files of the same package: `graph.error(result)`.
const GTSAM_SMALL_FILES: [(&str, f64); 3] = [
    // Optimum cost below 1: an absolute stopping threshold of 1e-5 stopped 4e-4 above it.
    ("Klaus3.g2o", 0.007_027_791_779_126_602),
    // Large residuals: Gauss–Newton converges linearly; GTSAM stops 2.4e-6 above segloc.
    ("pose3example.txt", 18_853.067_379_954_79),
    ("pose3example-grid.txt", 43.498_658_353_032_36),
];

#[test]
fn small_public_files_reach_gtsam_cost_or_lower_from_both_starts() {
    let Some(dir) = data_dir() else {
        eprintln!("skipped: gtsam Data not found (set SEGLOC_GTSAM_DATA or run scripts/bench_posegraph.sh)");
        return;
    };
    for (name, gtsam_cost) in GTSAM_SMALL_FILES {
        let file = GraphFile::read(&dir.join(name)).expect(name);
        assert!(file.repaired.is_empty(), "{name}");
        for init in [Initialization::None, Initialization::Chordal] {
            let mut graph = file.to_pose_graph(&BuildOptions::default()).unwrap();
            let config = SolverConfig {
                initialization: init,
                ..SolverConfig::default()
            };
            let report = graph.optimize(&config).unwrap();
            assert!(
                report.converged,
                "{name} {init:?}: {:?}",
                report.termination
            );
            assert!(
                report.final_cost <= gtsam_cost * (1.0 + 1e-6),
                "{name} {init:?}: {} vs GTSAM {gtsam_cost}",
                report.final_cost
            );
        }
    }
}
