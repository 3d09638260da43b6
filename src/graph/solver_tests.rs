//! Tests of the optimiser on small graphs with known optima.

use super::*;
use nalgebra::{Isometry3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};

fn tx(x: f64) -> Isometry3<f64> {
    Isometry3::translation(x, 0.0, 0.0)
}

fn pose(xi: [f64; 6]) -> Isometry3<f64> {
    se3::exp(&Vector6::from_row_slice(&xi))
}

fn both_algorithms() -> [SolverConfig; 2] {
    [
        SolverConfig::default(),
        SolverConfig {
            algorithm: Algorithm::GaussNewton,
            ..SolverConfig::default()
        },
    ]
}

#[test]
fn consistent_chain_reaches_zero_cost() {
    for config in both_algorithms() {
        let mut g = PoseGraph::new();
        let steps = [
            pose([0.1, 0.2, 0.3, 1.0, 0.0, 0.0]),
            pose([-0.4, 0.1, 0.9, 0.5, 2.0, -1.0]),
            pose([1.2, -0.3, 0.2, 0.0, 0.0, 3.0]),
        ];
        g.add_pose(0, Isometry3::identity()).unwrap();
        for (k, _) in steps.iter().enumerate() {
            g.add_pose(k as u64 + 1, Isometry3::identity()).unwrap();
        }
        g.fix(0).unwrap();
        let info = Matrix6::identity() * 4.0;
        for (k, z) in steps.iter().enumerate() {
            g.add_between(k as u64, k as u64 + 1, *z, info, RobustKernel::None)
                .unwrap();
        }
        let report = g.optimize(&config).unwrap();
        assert!(report.converged, "{:?}", report.termination);
        assert!(report.final_cost < 1e-16, "{}", report.final_cost);
        let expected = steps[0] * steps[1] * steps[2];
        let got = g.pose(3).unwrap();
        assert!(se3::log(&(expected.inverse() * got)).norm() < 1e-9);
    }
}

#[test]
fn inconsistent_loop_has_the_analytic_least_squares_solution() {
    // x1 - x0 ≈ 1, x2 - x1 ≈ 1, x2 - x0 ≈ 2.3 with x0 = 0: optimum x1 = 1.1, x2 = 2.2 and
    // cost ½ · 3 · 0.1² (pure translations, so Log is exact).
    for config in both_algorithms() {
        let mut g = PoseGraph::new();
        for (id, x) in [(0, 0.0), (1, 0.7), (2, 2.9)] {
            g.add_pose(id, tx(x)).unwrap();
        }
        g.fix(0).unwrap();
        let info = Matrix6::identity();
        g.add_between(0, 1, tx(1.0), info, RobustKernel::None)
            .unwrap();
        g.add_between(1, 2, tx(1.0), info, RobustKernel::None)
            .unwrap();
        g.add_between(0, 2, tx(2.3), info, RobustKernel::None)
            .unwrap();
        let report = g.optimize(&config).unwrap();
        assert!(
            (report.final_cost - 0.015).abs() < 1e-12,
            "{}",
            report.final_cost
        );
        assert!((g.pose(1).unwrap().translation.x - 1.1).abs() < 1e-9);
        assert!((g.pose(2).unwrap().translation.x - 2.2).abs() < 1e-9);
    }
}

#[test]
fn information_weights_the_compromise() {
    // Same loop, but the loop closure is 4× more certain: x2 = 2.3 − e, with
    // (x1, x2) minimising (x1−1)² + (x2−x1−1)² + 4 (x2−2.3)² → x2 = 2.2667, x1 = x2/2.
    let mut g = PoseGraph::new();
    for id in 0..3 {
        g.add_pose(id, Isometry3::identity()).unwrap();
    }
    g.fix(0).unwrap();
    let info = Matrix6::identity();
    g.add_between(0, 1, tx(1.0), info, RobustKernel::None)
        .unwrap();
    g.add_between(1, 2, tx(1.0), info, RobustKernel::None)
        .unwrap();
    g.add_between(0, 2, tx(2.3), info * 4.0, RobustKernel::None)
        .unwrap();
    g.optimize(&SolverConfig::default()).unwrap();
    // d/dx1: 2x1 − x2 = 0; d/dx2: (x2 − x1 − 1) + 4(x2 − 2.3) = 0 → 4.5 x2 = 10.2.
    let x2 = 10.2 / 4.5;
    assert!((g.pose(2).unwrap().translation.x - x2).abs() < 1e-9);
    assert!((g.pose(1).unwrap().translation.x - x2 / 2.0).abs() < 1e-9);
}

#[test]
fn prior_anchors_the_gauge() {
    let mut g = PoseGraph::new();
    let z0 = pose([0.3, -0.2, 0.1, 5.0, 6.0, 7.0]);
    let z01 = pose([0.0, 0.0, 0.5, 1.0, 0.0, 0.0]);
    g.add_pose(0, Isometry3::identity()).unwrap();
    g.add_pose(1, Isometry3::identity()).unwrap();
    g.add_prior(0, z0, Matrix6::identity()).unwrap();
    g.add_between(0, 1, z01, Matrix6::identity(), RobustKernel::None)
        .unwrap();
    let report = g.optimize(&SolverConfig::default()).unwrap();
    assert_eq!(report.components.len(), 1);
    assert_eq!(report.components[0].anchor, Anchor::Prior);
    assert!(report.final_cost < 1e-16);
    assert!(se3::log(&((z0 * z01).inverse() * g.pose(1).unwrap())).norm() < 1e-9);
}

#[test]
fn relocalization_places_the_pose_in_the_prior_frame() {
    // world_from_prior F is fixed; the relocalizer says prior_from_rover = Z, so the
    // pose must become F · Z.
    let f = pose([0.0, 0.0, 1.0, 10.0, -3.0, 0.0]);
    let z = pose([0.1, 0.0, -0.4, 2.0, 1.0, 0.0]);
    let mut g = PoseGraph::new();
    g.add_frame(7, f).unwrap();
    g.fix(VarKey::Frame(7)).unwrap();
    g.add_pose(0, Isometry3::identity()).unwrap();
    g.add_relocalization(0, 7, z, Matrix6::identity() * 10.0)
        .unwrap();
    g.optimize(&SolverConfig::default()).unwrap();
    let x = g.pose(0).unwrap();
    assert!(se3::log(&((f * z).inverse() * x)).norm() < 1e-9);
}

#[test]
fn two_sessions_share_one_graph_through_a_frame() {
    // Session A's poses live in the world; session B's map frame is unknown. Two
    // relocalizations of B's rover in A's map (frame 1 = A's prior map at the world origin)
    // pin B's odometry chain. Everything is consistent, so the cost goes to zero.
    let mut g = PoseGraph::new();
    g.add_frame(1, Isometry3::identity()).unwrap();
    g.fix(VarKey::Frame(1)).unwrap();
    let truth = [
        pose([0.0, 0.0, 0.2, 3.0, 1.0, 0.0]),
        pose([0.0, 0.0, 0.4, 4.0, 1.5, 0.0]),
    ];
    g.add_pose(10, Isometry3::identity()).unwrap();
    g.add_pose(11, Isometry3::identity()).unwrap();
    g.add_between(
        10,
        11,
        truth[0].inv_mul(&truth[1]),
        Matrix6::identity(),
        RobustKernel::None,
    )
    .unwrap();
    g.add_relocalization(10, 1, truth[0], Matrix6::identity())
        .unwrap();
    g.add_relocalization(11, 1, truth[1], Matrix6::identity())
        .unwrap();
    let report = g.optimize(&SolverConfig::default()).unwrap();
    assert!(report.final_cost < 1e-14);
    assert!(se3::log(&(truth[1].inverse() * g.pose(11).unwrap())).norm() < 1e-8);
}

#[test]
fn disconnected_components_are_reported_and_auto_fixed() {
    let mut g = PoseGraph::new();
    for id in 0..5 {
        g.add_pose(id, tx(id as f64 * 0.9)).unwrap();
    }
    let info = Matrix6::identity();
    g.add_between(0, 1, tx(1.0), info, RobustKernel::None)
        .unwrap();
    g.add_between(2, 3, tx(1.0), info, RobustKernel::None)
        .unwrap();
    g.fix(2).unwrap();
    let report = g.optimize(&SolverConfig::default()).unwrap();
    let anchors: Vec<Anchor> = report.components.iter().map(|c| c.anchor).collect();
    assert_eq!(
        anchors,
        vec![
            Anchor::AutoFixed(VarKey::Pose(0)),
            Anchor::Fixed(VarKey::Pose(2)),
            Anchor::AutoFixed(VarKey::Pose(4)),
        ]
    );
    // The auto-fixed pose stays where it was.
    assert_eq!(g.pose(0).unwrap(), tx(0.0));
    assert!((g.pose(1).unwrap().translation.x - 1.0).abs() < 1e-9);
    assert!((g.pose(3).unwrap().translation.x - 2.8).abs() < 1e-9);
}

#[test]
fn analysis_is_reused_until_the_structure_changes() {
    let mut g = PoseGraph::new();
    for id in 0..3 {
        g.add_pose(id, tx(id as f64)).unwrap();
    }
    let info = Matrix6::identity();
    g.add_between(0, 1, tx(1.0), info, RobustKernel::None)
        .unwrap();
    g.add_between(1, 2, tx(1.0), info, RobustKernel::None)
        .unwrap();
    assert!(
        !g.optimize(&SolverConfig::default())
            .unwrap()
            .analysis_reused
    );
    g.set_value(VarKey::Pose(2), tx(3.0)).unwrap();
    let r = g.optimize(&SolverConfig::default()).unwrap();
    assert!(r.analysis_reused);
    assert!((g.pose(2).unwrap().translation.x - 2.0).abs() < 1e-9);
    g.add_pose(3, tx(3.0)).unwrap();
    g.add_between(2, 3, tx(1.0), info, RobustKernel::None)
        .unwrap();
    assert!(
        !g.optimize(&SolverConfig::default())
            .unwrap()
            .analysis_reused
    );
}

#[test]
fn large_rotations_converge_on_a_noisy_circle() {
    // A closed circle of 12 poses with perturbed initial estimates far from the optimum.
    let n = 12;
    let step = Isometry3::from_parts(
        Translation3::new(1.0, 0.0, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::TAU / n as f64),
    );
    let mut g = PoseGraph::new();
    let mut truth = Isometry3::identity();
    for id in 0..n {
        let noise = pose([
            0.3 * ((id * 7 % 5) as f64 - 2.0) / 2.0,
            0.2,
            -0.4,
            0.5,
            -0.3,
            0.2,
        ]);
        g.add_pose(id as u64, if id == 0 { truth } else { truth * noise })
            .unwrap();
        truth *= step;
    }
    g.fix(0).unwrap();
    for id in 0..n {
        g.add_between(
            id as u64,
            ((id + 1) % n) as u64,
            step,
            Matrix6::identity(),
            RobustKernel::None,
        )
        .unwrap();
    }
    let report = g.optimize(&SolverConfig::default()).unwrap();
    assert!(report.converged);
    assert!(report.final_cost < 1e-14, "{}", report.final_cost);
}

#[test]
fn chordal_initialisation_starts_close_to_the_optimum() {
    let synth = synthetic::generate(&synthetic::SyntheticConfig {
        poses: 300,
        loop_closures: 40,
        ..Default::default()
    });
    let build = || {
        synth
            .file
            .to_pose_graph(&file::BuildOptions::default())
            .unwrap()
    };
    let mut plain = build();
    let r_plain = plain.optimize(&SolverConfig::default()).unwrap();
    let mut chordal = build();
    let config = SolverConfig {
        initialization: Initialization::Chordal,
        ..SolverConfig::default()
    };
    let r_chordal = chordal.optimize(&config).unwrap();
    let rel = (r_plain.final_cost - r_chordal.final_cost).abs() / r_plain.final_cost;
    assert!(
        rel < 1e-6,
        "{} vs {}",
        r_plain.final_cost,
        r_chordal.final_cost
    );
    assert!(r_chordal.log[0].cost_before < r_plain.initial_cost);
}

#[test]
fn single_precision_factors_reach_the_double_precision_optimum() {
    // Large enough for single precision (a factor of at least 100,000 non-zeros).
    let synth = synthetic::generate(&synthetic::SyntheticConfig {
        poses: 2000,
        loop_closures: 300,
        ..Default::default()
    });
    let solve = |regime: f64| {
        let mut g = synth
            .file
            .to_pose_graph(&file::BuildOptions::default())
            .unwrap();
        let config = SolverConfig {
            single_precision_regime: regime,
            relative_tolerance: 1e-10,
            absolute_tolerance: 0.0,
            ..SolverConfig::default()
        };
        let report = g.optimize(&config).unwrap();
        (g, report)
    };
    let (double, r_double) = solve(f64::INFINITY);
    assert_eq!(r_double.single_precision_factorizations, 0);
    let (mixed, r_mixed) = solve(0.0);
    assert!(r_mixed.factor_nnz >= 100_000, "{}", r_mixed.factor_nnz);
    assert!(r_mixed.converged, "{:?}", r_mixed.termination);
    // Every factorisation was in single precision, and the refined steps still converge to
    // the same optimum.
    assert_eq!(
        r_mixed.single_precision_factorizations,
        r_mixed.factorizations
    );
    let rel = (r_mixed.final_cost - r_double.final_cost).abs() / r_double.final_cost;
    assert!(
        rel < 1e-9,
        "{} vs {}",
        r_mixed.final_cost,
        r_double.final_cost
    );
    for id in 0..2000 {
        let a = double.pose(id).unwrap();
        let b = mixed.pose(id).unwrap();
        assert!(se3::log(&(a.inverse() * b)).norm() < 1e-6, "pose {id}");
    }
}

#[test]
fn small_factors_stay_in_double_precision() {
    // Under 100,000 non-zeros a single-precision factor gains nothing: never used.
    let synth = synthetic::generate(&synthetic::SyntheticConfig {
        poses: 400,
        loop_closures: 60,
        ..Default::default()
    });
    let mut g = synth
        .file
        .to_pose_graph(&file::BuildOptions::default())
        .unwrap();
    let config = SolverConfig {
        single_precision_regime: 0.0,
        ..SolverConfig::default()
    };
    let report = g.optimize(&config).unwrap();
    assert!(report.factor_nnz < 100_000, "{}", report.factor_nnz);
    assert!(report.converged && report.factorizations > 0);
    assert_eq!(report.single_precision_factorizations, 0);
}

#[test]
fn gnc_rejects_a_wrong_loop_closure() {
    let synth = synthetic::generate(&synthetic::SyntheticConfig {
        poses: 200,
        loop_closures: 20,
        ..Default::default()
    });
    let mut clean = synth.file.clone();
    let options = file::BuildOptions {
        loop_closure_kernel: RobustKernel::Gnc { c: 4.0 },
        ..Default::default()
    };
    let replaced = synthetic::corrupt_loop_closures(&mut clean.edges, 0.2, 10.0, 5);
    assert!(replaced.len() >= 2, "{replaced:?}");
    let mut g_bad = clean.to_pose_graph(&options).unwrap();
    let report = g_bad.optimize(&SolverConfig::default()).unwrap();
    assert!(report.gnc_stages > 1);
    // Every wrong closure ends beyond the truncation, every good factor inside it.
    for (k, f) in g_bad.factors().iter().enumerate() {
        let r = f.residual(&g_bad.poses);
        let s = f.mahalanobis2(&r);
        assert_eq!(s > 16.0, replaced.contains(&k), "factor {k}: s = {s}");
    }
    // The result is the least-squares solution without the wrong closures.
    let mut oracle_file = clean.clone();
    oracle_file.edges = clean
        .edges
        .iter()
        .enumerate()
        .filter(|(k, _)| !replaced.contains(k))
        .map(|(_, e)| e.clone())
        .collect();
    let mut oracle = oracle_file
        .to_pose_graph(&file::BuildOptions::default())
        .unwrap();
    oracle.optimize(&SolverConfig::default()).unwrap();
    for key in oracle.keys() {
        let d = se3::log(&(oracle.value(*key).unwrap().inverse() * g_bad.value(*key).unwrap()));
        assert!(d.norm() < 1e-4, "{key}: {}", d.norm());
    }
}

/// A triangle of poses whose loop closure disagrees with the odometry by `miss` metres,
/// every information matrix `scale · I`, started away from the optimum.
fn triangle(miss: f64, scale: f64) -> PoseGraph {
    let mut g = PoseGraph::new();
    g.add_pose(0, Isometry3::identity()).unwrap();
    g.add_pose(1, pose([0.2, -0.1, 0.3, 1.4, 0.3, -0.2]))
        .unwrap();
    g.add_pose(2, pose([-0.3, 0.2, 1.9, 0.5, 1.6, 0.4]))
        .unwrap();
    g.fix(0).unwrap();
    let info = Matrix6::identity() * scale;
    let turn = pose([0.0, 0.0, std::f64::consts::FRAC_PI_2, 1.0, 0.0, 0.0]);
    g.add_between(0, 1, turn, info, RobustKernel::None).unwrap();
    g.add_between(1, 2, turn, info, RobustKernel::None).unwrap();
    let closure = turn * turn * tx(miss);
    g.add_between(0, 2, closure, info, RobustKernel::None)
        .unwrap();
    g
}

/// The optimum of `g` by Gauss–Newton run until rounding stops it.
fn reference_optimum(mut g: PoseGraph) -> f64 {
    let config = SolverConfig {
        algorithm: Algorithm::GaussNewton,
        relative_tolerance: 0.0,
        extrapolated_tolerance: 0.0,
        decrement_tolerance: 0.0,
        step_tolerance: 1e-15,
        max_iterations: 60,
        ..SolverConfig::default()
    };
    g.optimize(&config).unwrap().final_cost
}

#[test]
fn stopping_rule_reaches_a_tiny_optimum_whatever_the_scale() {
    // Optimum cost about 1e-6 at unit information; the same problem scaled by 1e-8
    // (optimum about 1e-14) must stop at the same relative accuracy.
    for scale in [1.0, 1e-8, 1e6] {
        let optimum = reference_optimum(triangle(2.5e-3, scale));
        assert!(optimum > 0.0);
        let mut g = triangle(2.5e-3, scale);
        let report = g.optimize(&SolverConfig::default()).unwrap();
        assert!(report.converged, "scale {scale}: {:?}", report.termination);
        let rel = (report.final_cost - optimum) / optimum;
        assert!(
            rel.abs() <= 1e-6,
            "scale {scale}: {} vs optimum {optimum} ({rel:e})",
            report.final_cost
        );
        if scale == 1.0 {
            assert!((5e-7..5e-6).contains(&optimum), "{optimum}");
        }
    }
    // GTSAM's absolute tolerance (1e-5) alone stops far above the scaled optimum.
    let optimum = reference_optimum(triangle(2.5e-3, 1e-8));
    let mut g = triangle(2.5e-3, 1e-8);
    let absolute = SolverConfig {
        absolute_tolerance: 1e-5,
        ..SolverConfig::default()
    };
    let report = g.optimize(&absolute).unwrap();
    assert!(report.final_cost > optimum * 2.0, "{}", report.final_cost);
}

#[test]
fn a_linearly_converging_run_stops_only_when_little_is_left() {
    // Large residuals (inconsistent measurements): Gauss–Newton converges linearly, and a
    // relative decrease of 1e-5 alone leaves more than 1e-6 of the cost to go.
    let optimum = reference_optimum(triangle(3.0, 1.0));
    let mut g = triangle(3.0, 1.0);
    let report = g.optimize(&SolverConfig::default()).unwrap();
    assert!(report.converged, "{:?}", report.termination);
    let rel = (report.final_cost - optimum) / optimum;
    assert!(rel.abs() <= 1e-6, "{} vs {optimum}", report.final_cost);
}
