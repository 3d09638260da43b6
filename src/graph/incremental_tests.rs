//! Tests of the incremental graph: skipped updates, window updates against the batch
//! optimum, rebuilds, unanchored components.

use super::*;
use crate::graph::file::BuildOptions;
use crate::graph::synthetic::{self, SyntheticConfig};

/// Pose 0 fixed and four unit steps along x (identity information), not yet solved.
fn unit_chain(config: IncrementalConfig) -> IncrementalGraph {
    let mut g = PoseGraph::new();
    g.add_pose(0, Isometry3::identity()).unwrap();
    g.fix(0).unwrap();
    let mut inc = IncrementalGraph::new(g, config);
    let z = Isometry3::translation(1.0, 0.0, 0.0);
    for id in 1..5 {
        inc.add_odometry(id - 1, id, z, Matrix6::identity())
            .unwrap();
    }
    inc
}

/// A loop closure 0 → 4 of 3.5 m on [`unit_chain`]: the optimum puts pose 4 at 3.6 m.
fn close_unit_chain(inc: &mut IncrementalGraph) {
    inc.graph_mut()
        .add_between(
            0,
            4,
            Isometry3::translation(3.5, 0.0, 0.0),
            Matrix6::identity(),
            RobustKernel::None,
        )
        .unwrap();
}

/// A synthetic graph of `poses` poses and `loop_closures` closures, and the pose graph
/// of its first `keep` poses (the rest is appended by the test).
fn truncated_synthetic(
    poses: usize,
    loop_closures: usize,
    keep: u64,
) -> (synthetic::SyntheticGraph, PoseGraph) {
    let synth = synthetic::generate(&SyntheticConfig {
        poses,
        loop_closures,
        ..SyntheticConfig::default()
    });
    let mut base = synth.file.clone();
    base.vertices.retain(|v| v.id < keep);
    base.edges.retain(|e| e.from < keep && e.to < keep);
    let graph = base.to_pose_graph(&BuildOptions::default()).unwrap();
    (synth, graph)
}

/// A copy of `inc`'s graph optimised to tight convergence, and its relative cost gap.
fn batch_gap(inc: &IncrementalGraph) -> (PoseGraph, f64) {
    let mut full = inc.graph().clone();
    let batch = full
        .optimize(&SolverConfig {
            relative_tolerance: 1e-12,
            absolute_tolerance: 0.0,
            ..SolverConfig::default()
        })
        .unwrap();
    let gap = (inc.graph().cost() - batch.final_cost) / batch.final_cost;
    (full, gap)
}

/// Appends pose `to` by the synthetic graph's odometry edge `to − 1 → to`; returns the
/// edge's information.
fn append_synthetic_odometry(
    inc: &mut IncrementalGraph,
    synth: &synthetic::SyntheticGraph,
    to: u64,
) -> Matrix6<f64> {
    let e = synth.odometry()[(to - 1) as usize];
    inc.add_odometry(e.from, e.to, e.measured, e.information)
        .unwrap();
    e.information
}

#[test]
fn odometry_appends_keep_the_optimum_without_solving() {
    let (_, graph) = truncated_synthetic(400, 30, 300);
    let mut inc = IncrementalGraph::new(graph, IncrementalConfig::default());
    assert!(inc.update().unwrap().optimized);
    let info = Matrix6::identity() * 100.0;
    let z = Isometry3::translation(1.0, 0.0, 0.0);
    for id in 300..310 {
        inc.add_odometry(id - 1, id, z, info).unwrap();
        let r = inc.update().unwrap();
        assert!(!r.optimized);
        assert_eq!(r.new_factors, 1);
    }
    // The skipped updates agree with a full optimisation.
    let cost = inc.update().unwrap().cost;
    let mut full = inc.into_graph();
    let report = full.optimize(&SolverConfig::default()).unwrap();
    assert!((report.initial_cost - cost).abs() <= 1e-9 * cost.max(1.0));
    assert!((report.final_cost - cost).abs() <= 1e-6 * cost.max(1.0));
}

/// Loop closures appended one by one to a 600-pose graph: the incremental updates land
/// on the batch optimum of the same graph within the linearisation error.
#[test]
fn incremental_loop_closures_match_the_batch_optimum() {
    let (synth, graph) = truncated_synthetic(700, 40, 600);
    let mut inc = IncrementalGraph::new(graph, IncrementalConfig::default());
    assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
    let odometry = synth.odometry();
    let mut incremental = 0;
    for id in 600u64..615 {
        let e = odometry[(id - 1) as usize];
        inc.add_odometry(e.from, e.to, e.measured, e.information)
            .unwrap();
        let back = id - 45;
        let z = synth.truth[back as usize].inv_mul(&synth.truth[id as usize]);
        inc.graph_mut()
            .add_between(back, id, z, e.information, RobustKernel::None)
            .unwrap();
        let r = inc.update().unwrap();
        if r.method == UpdateMethod::Incremental {
            incremental += 1;
        }
        let (full, gap) = batch_gap(&inc);
        let cost = inc.graph().cost();
        assert!((-1e-9..1e-4).contains(&gap), "update {id}: gap {gap:e}");
        // The model's cost estimate is close to the true cost.
        assert!((r.cost - cost).abs() < 1e-3 * cost, "{} vs {cost}", r.cost);
        // Positions: the linearisation error of the old factors shows as a small
        // rotation of weakly constrained parts of the graph (centimetres at 100 m).
        for v in 0..=id {
            let p = inc.graph().pose(v).unwrap().translation.vector;
            let q = full.pose(v).unwrap().translation.vector;
            assert!((p - q).norm() < 0.15, "pose {v}: {}", (p - q).norm());
        }
    }
    assert!(incremental >= 4, "only {incremental} incremental updates");
}

/// With a tight relinearisation threshold a loop closure reaching past the window is
/// absorbed by building the model again at the incremental estimate (no batch), and
/// lands on the batch optimum.
#[test]
fn far_incremental_estimates_are_relinearised_without_a_batch() {
    let (synth, graph) = truncated_synthetic(400, 30, 300);
    let config = IncrementalConfig {
        relinearize_threshold: 0.02,
        window_variables: 20,
        window_iterations: 3,
        ..IncrementalConfig::default()
    };
    let mut inc = IncrementalGraph::new(graph, config);
    assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
    let info = append_synthetic_odometry(&mut inc, &synth, 300);
    let z = synth.truth[250].inv_mul(&synth.truth[300]);
    inc.graph_mut()
        .add_between(250, 300, z, info, RobustKernel::None)
        .unwrap();
    let r = inc.update().unwrap();
    assert_eq!(r.method, UpdateMethod::Relinearized, "{r:?}");
    let (_, gap) = batch_gap(&inc);
    assert!((-1e-9..1e-6).contains(&gap), "gap {gap:e}");
    // The next update starts from the new linearisation.
    append_synthetic_odometry(&mut inc, &synth, 301);
    assert_eq!(inc.update().unwrap().method, UpdateMethod::Skipped);
}

/// A tiny chain where the incremental update must equal the exact optimum: with linear
/// (translation-only) factors the quadratic model is exact, whether the closure lies in
/// the window or reaches into the settled part.
#[test]
fn incremental_update_is_exact_on_a_linear_problem() {
    for window in [1, 2, 100] {
        let mut inc = unit_chain(IncrementalConfig {
            relinearize_threshold: 1.0,
            window_variables: window,
            ..IncrementalConfig::default()
        });
        assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
        close_unit_chain(&mut inc);
        let r = inc.update().unwrap();
        assert_eq!(r.method, UpdateMethod::Incremental, "window {window}");
        let x4 = inc.graph().pose(4).unwrap().translation.x;
        assert!((x4 - 3.6).abs() < 1e-9, "window {window}: {x4}");
        let x2 = inc.graph().pose(2).unwrap().translation.x;
        assert!((x2 - 1.8).abs() < 1e-9, "window {window}: {x2}");
        assert!((r.cost - inc.graph().cost()).abs() < 1e-12);
    }
}

/// Loop closures reaching past a small window into the settled part, and a window that
/// outgrows its limit: the updates stay incremental (the model is built again when the
/// window is full) and on the batch optimum.
#[test]
fn closures_into_the_settled_part_and_a_full_window() {
    let (synth, graph) = truncated_synthetic(500, 30, 400);
    let config = IncrementalConfig {
        window_variables: 10,
        max_window_variables: 14,
        ..IncrementalConfig::default()
    };
    let mut inc = IncrementalGraph::new(graph, config);
    assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
    let mut methods = Vec::new();
    for id in 400u64..412 {
        let info = append_synthetic_odometry(&mut inc, &synth, id);
        let back = id - 30;
        let z = synth.truth[back as usize].inv_mul(&synth.truth[id as usize]);
        inc.graph_mut()
            .add_between(back, id, z, info, RobustKernel::None)
            .unwrap();
        let r = inc.update().unwrap();
        methods.push(r.method);
        let (_, gap) = batch_gap(&inc);
        assert!((-1e-9..1e-4).contains(&gap), "update {id}: gap {gap:e}");
        assert!((r.cost - inc.graph().cost()).abs() < 1e-3 * r.cost);
    }
    assert!(!methods.contains(&UpdateMethod::Batch), "{methods:?}");
    assert!(methods.contains(&UpdateMethod::Relinearized), "{methods:?}");
    assert!(methods.contains(&UpdateMethod::Incremental), "{methods:?}");
}

/// A second, unanchored chain (a session before its first relocalization) is held by
/// its first pose as in the batch, so updates on the anchored chain stay incremental;
/// the factor that joins the chains makes the holding be decided again.
#[test]
fn an_unanchored_component_is_held_like_the_batch_holds_it() {
    let (synth, mut graph) = truncated_synthetic(400, 30, 300);
    let step = Isometry3::translation(1.0, 0.0, 0.0);
    let info = Matrix6::identity() * 100.0;
    graph
        .add_pose(10_000, Isometry3::translation(0.0, 50.0, 0.0))
        .unwrap();
    for id in 10_001..10_005u64 {
        let initial = graph.pose(id - 1).unwrap() * step;
        graph.add_pose(id, initial).unwrap();
        graph
            .add_between(id - 1, id, step, info, RobustKernel::None)
            .unwrap();
    }
    let mut inc = IncrementalGraph::new(graph, IncrementalConfig::default());
    assert_eq!(inc.update().unwrap().method, UpdateMethod::Batch);
    let mut methods = Vec::new();
    for id in 300u64..310 {
        let info = append_synthetic_odometry(&mut inc, &synth, id);
        let z = synth.truth[id as usize - 50].inv_mul(&synth.truth[id as usize]);
        inc.graph_mut()
            .add_between(id - 50, id, z, info, RobustKernel::None)
            .unwrap();
        methods.push(inc.update().unwrap().method);
        let (_, gap) = batch_gap(&inc);
        assert!((-1e-9..1e-4).contains(&gap), "update {id}: gap {gap:e}");
    }
    // The first closure corrects a metre of drift (a rebuild); none needs a batch.
    assert!(!methods.contains(&UpdateMethod::Batch), "{methods:?}");
    assert!(methods.contains(&UpdateMethod::Incremental), "{methods:?}");
    // Join the chains: the second one is now anchored through the first.
    let to_b = Isometry3::translation(0.0, 10.0, 0.0);
    inc.graph_mut()
        .add_between(309, 10_000, to_b, info, RobustKernel::None)
        .unwrap();
    let r = inc.update().unwrap();
    assert_ne!(r.method, UpdateMethod::Incremental, "{r:?}");
    let (full, gap) = batch_gap(&inc);
    assert!((-1e-9..1e-6).contains(&gap), "gap {gap:e}");
    let b0 = inc.graph().pose(10_000).unwrap().translation.vector;
    assert!((b0 - full.pose(10_000).unwrap().translation.vector).norm() < 1e-3);
}

#[test]
fn a_loop_closure_triggers_a_full_solve() {
    let mut inc = unit_chain(IncrementalConfig {
        incremental: false,
        ..IncrementalConfig::default()
    });
    assert!(inc.update().unwrap().optimized);
    close_unit_chain(&mut inc);
    let r = inc.update().unwrap();
    assert!(r.optimized);
    let x4 = inc.graph().pose(4).unwrap().translation.x;
    // Four unit steps against one 3.5 closure, equal weights: x4 = 3.6.
    assert!((x4 - 3.6).abs() < 1e-9, "{x4}");
}
