//! Tests of the boulder adjustment.

use super::*;
use crate::localizer::LocalizerConfig;
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use segloc_maps::frames::{FrameDetection, StreamFrame};

/// Two laps of a 4 m circle between two rings of boulders (radius 0.1 and 0.25 m),
/// one frame per step, detections within 6 m on the face `face_fraction` × size in
/// front of each centre (no noise), an odometry `scale` long that turns `yaw_rad` too
/// far every step; with the true poses.
fn two_laps(scale: f64, yaw_rad: f64, face_fraction: f64) -> (FrameLog, Vec<Isometry3<f64>>) {
    let boulders: Vec<Point3<f64>> = (0..24)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 24.0;
            let r = if k % 2 == 0 { 2.0 } else { 6.5 };
            Point3::new(r * a.cos(), r * a.sin(), 0.1)
        })
        .collect();
    let pose_at = |a: f64| {
        Isometry3::from_parts(
            Translation3::new(4.0 * a.cos(), 4.0 * a.sin(), 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, a + std::f64::consts::FRAC_PI_2),
        )
    };
    let steps = 120;
    let (mut log, mut truth) = (FrameLog::default(), Vec::new());
    let mut odom_from_rover = pose_at(0.0);
    for k in 0..=steps {
        let a = k as f64 * 2.0 * std::f64::consts::TAU / steps as f64;
        let world_from_rover = pose_at(a);
        if k > 0 {
            let prev = pose_at((k - 1) as f64 * 2.0 * std::f64::consts::TAU / steps as f64);
            let step = prev.inverse() * world_from_rover;
            odom_from_rover *= Isometry3::from_parts(
                Translation3::from(step.translation.vector * scale),
                step.rotation * UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad),
            );
        }
        let mut frame = StreamFrame::new(k as f64, odom_from_rover);
        frame.detections = boulders
            .iter()
            .enumerate()
            .map(|(k, b)| {
                let radius_m = if k % 4 < 2 { 0.1 } else { 0.25 };
                let centre = world_from_rover.inverse() * b;
                let toward = -Vector3::new(centre.x, centre.y, 0.0).normalize();
                let face = centre + toward * (face_fraction * 2.0 * radius_m);
                (face, radius_m)
            })
            .filter(|(p, _)| p.coords.xy().norm() < 6.0)
            .map(|(p_rover, radius_m)| FrameDetection {
                p_rover,
                size_m: Some(2.0 * radius_m),
                cov_rover: None,
            })
            .collect();
        log.push(&frame);
        truth.push(world_from_rover);
    }
    (log, truth)
}

/// Position RMSE of `estimates` against `truth`.
fn rmse_m(truth: &[Isometry3<f64>], estimates: &[Isometry3<f64>]) -> f64 {
    let sum: f64 = truth
        .iter()
        .zip(estimates)
        .map(|(t, e)| (t.translation.vector - e.translation.vector).norm_squared())
        .sum();
    (sum / truth.len().max(1) as f64).sqrt()
}

#[test]
fn the_boulders_undo_the_odometry_drift() {
    // exact detections of the centres, an odometry 3 % long turning 0.1° a step too far
    let (log, truth) = two_laps(1.03, 0.0017, 0.0);
    let mission = LocalizerConfig::default();
    let mut graph = TrajectoryGraph::new();
    graph.extend(&log, &mission).unwrap();
    graph.optimize().unwrap();
    let before = rmse_m(&truth, &graph.poses_in_prior());
    assert!(before > 0.3, "the odometry alone is off by {before} m");
    let fusion = FusionConfig::default();
    // the poses start up to a metre off, more than a cluster radius: the clusters
    // need the rounds to follow the poses
    // (the viewpoint bias is not estimated here: with an odometry this far off, a
    // wrong fraction, which moves every detection along its line of sight, trades
    // against the odometry's scale)
    let config = BoulderAdjustmentConfig {
        rounds: 3,
        estimate_view_bias: false,
        ..BoulderAdjustmentConfig::default()
    };
    let report = adjust_in_place(&mut graph, &log, &fusion, &config)
        .unwrap()
        .unwrap();
    let after = rmse_m(&truth, &graph.poses_in_prior());
    assert!(after < 0.01, "{before} m -> {after} m, {report:?}");
    assert_eq!(report.boulders, 24);
    assert_eq!(report.outliers, 0);
    // the odometry factors, 3 % off, still pull a little against the exact detections
    assert!(
        report.rms_residual_m < 0.01,
        "{before} m -> {after} m, {report:?}"
    );
    // off: the graph is left alone
    let off = BoulderAdjustmentConfig {
        enabled: false,
        ..config
    };
    assert!(adjust_in_place(&mut graph, &log, &fusion, &off)
        .unwrap()
        .is_none());
}

#[test]
fn the_viewpoint_bias_comes_out_of_the_boulders_seen_from_both_sides() {
    let f = 1.0 / 6.0;
    let (log, truth) = two_laps(1.002, 0.0002, f);
    let mission = LocalizerConfig::default();
    let mut graph = TrajectoryGraph::new();
    graph.extend(&log, &mission).unwrap();
    graph.optimize().unwrap();
    let before = rmse_m(&truth, &graph.poses_in_prior());
    // the fusion starts from a fraction 0.05 short
    let fusion = FusionConfig {
        view_bias_size_fraction: f - 0.05,
        ..FusionConfig::default()
    };
    let config = BoulderAdjustmentConfig::default();
    let report = adjust_in_place(&mut graph, &log, &fusion, &config)
        .unwrap()
        .unwrap();
    let after = rmse_m(&truth, &graph.poses_in_prior());
    let estimate = report.view_bias_size_fraction.unwrap();
    assert!(
        (estimate - f).abs() < 0.01,
        "{estimate} for {f}: {report:?}"
    );
    assert!(
        report.view_bias_standard_error.unwrap() < 0.01,
        "{report:?}"
    );
    assert!(
        after < 0.005 && after < before,
        "{before} m -> {after} m, {report:?}"
    );
}

#[test]
fn validation_names_the_field() {
    assert!(BoulderAdjustmentConfig::default().validate().is_ok());
    let bad = BoulderAdjustmentConfig {
        model_sigma_m: -1.0,
        ..BoulderAdjustmentConfig::default()
    };
    assert!(bad.validate().unwrap_err().contains("model_sigma_m"));
}

#[test]
fn the_parabola_through_three_costs() {
    // cost = (f − 0.17)² / 0.004² + 10: minimum 0.17, curvature 2 / 0.004², σ 0.004 / √2
    let cost = |f: f64| (f - 0.17).powi(2) / (0.004f64.powi(2)) + 10.0;
    let (f0, h) = (0.15, 0.03);
    let (f, sigma) = parabola_minimum(f0, h, [cost(f0 - h), cost(f0), cost(f0 + h)]).unwrap();
    assert!((f - 0.17).abs() < 1e-12, "{f}");
    assert!((sigma - 0.004 / 2f64.sqrt()).abs() < 1e-12, "{sigma}");
    // far off: at most two steps
    let far = |f: f64| (f - 0.5).powi(2);
    let (f, _) = parabola_minimum(f0, h, [far(f0 - h), far(f0), far(f0 + h)]).unwrap();
    assert!((f - (f0 + 2.0 * h)).abs() < 1e-12, "{f}");
    // not curving upwards: no estimate
    assert!(parabola_minimum(f0, h, [1.0, 2.0, 1.0]).is_none());
    assert!(parabola_minimum(f0, h, [1.0, 2.0, 3.0]).is_none());
}
