//! Boulder adjustment: a bundle adjustment of a session's poses and the boulders it saw.
//!
//! The pose graph ties the frames by odometry, gravity, the lander and loop closures; a loop
//! closure aligns a whole submap rigidly. Every detection, though, is a stereo measurement of
//! its boulder in the rover frame, good to millimetres up close, and a boulder passed on
//! several passes ties all of their frames together. This stage adds every boulder as a
//! landmark variable ([`crate::graph::VarKey::Point`]) and every detection as a point
//! observation ([`crate::graph::PoseGraph::add_point_observation`]) to the session's graph,
//! and solves poses and boulders together:
//!
//! 1. place every detection with the current poses (the viewpoint bias taken out, the
//!    fusion's range gate applied) and cluster them into boulders ([`cluster_points`]);
//! 2. each boulder seen at least [`BoulderAdjustmentConfig::min_observations`] times
//!    becomes a landmark, initialised at its stereo-weighted centroid; each of its
//!    detections a factor weighted by the stereo noise (depth along the line of sight) and
//!    a model error, with a Cauchy kernel against wrong clusters. The viewpoint-bias
//!    correction of a detection scales with its *boulder's* size (the median of its
//!    detections' measures), not with its own noisy measure;
//! 3. optimise the graph with all its own factors kept; with more than one
//!    [`BoulderAdjustmentConfig::rounds`], start again from 1 with the new poses (the
//!    clusters follow them: needed when the poses are off by more than a cluster radius,
//!    not after a session's loop closures).
//!
//! **The viewpoint bias.** A stereo centroid lies on the boulder's visible face, in front
//! of its centre by a fraction `f` of its size. A wrong `f` does not average out: a
//! boulder seen from two sides lands as two points `2 Δf × size` apart, and the adjustment
//! bends the trajectory to reconcile them (docs/design/boulder-adjustment.md). With
//! [`BoulderAdjustmentConfig::estimate_view_bias`], `f` is estimated with the poses and
//! boulders from its profile: the adjustment is solved at the fusion's `f` and a step either
//! side (warm-started), and once more at the minimum of the parabola through the three
//! costs. Boulders seen from one side only say nothing about `f`; those seen from several
//! sides, over the whole session, pin it to a few thousandths.
//!
//! A session's loop closures summarise the same detections, fused with the `f` of their
//! time: the caller may drop them first ([`TrajectoryGraph::without_loop_closures`]), as
//! session 1 does. The adjusted poses are returned in a graph without the landmarks, so
//! that the session goes on with the factors it had.

use super::frame_log::FrameLog;
use super::trajectory::TrajectoryGraph;
use crate::field_error::FieldError;
use crate::graph::{GraphError, RobustKernel, SolverConfig};
use crate::landmarks::cluster::cluster_points;
use crate::landmarks::estimate::{detection_information, median, stereo_weighted};
use crate::landmarks::view_bias::corrected;
use crate::landmarks::FusionConfig;
use nalgebra::{Isometry3, Matrix3, Point3};
use segloc_maps::Detection;
use serde::{Deserialize, Serialize};

/// Parameters of the boulder adjustment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BoulderAdjustmentConfig {
    /// Run the stage.
    pub enabled: bool,
    /// Rounds of clustering and optimisation (docs/design/boulder-adjustment.md).
    pub rounds: usize,
    /// Boulders with fewer detections are left out.
    pub min_observations: usize,
    /// Model error (1 σ, m) added in every direction to each detection: what is left of
    /// the viewpoint bias after its correction, and the boulder's shape.
    pub model_sigma_m: f64,
    /// Cauchy width of the detection residuals, in σ (docs/design/boulder-adjustment.md).
    pub cauchy_sigmas: f64,
    /// Estimate the detections' viewpoint-bias size fraction with the poses and boulders:
    /// solve at the fusion's fraction and `view_bias_step` either side, and once more at
    /// the minimum of the parabola through the three costs (the profile of the fraction).
    pub estimate_view_bias: bool,
    /// The step of the fraction's profile.
    pub view_bias_step: f64,
    /// … an estimate with a larger standard error (from the parabola's curvature) is not
    /// used.
    pub max_standard_error: f64,
    /// Each profile moves the fraction by at most `2 × view_bias_step`; while the move is
    /// that long (the minimum lies beyond), profile again from there, up to this many
    /// profiles a round (1: a single profile). See docs/design/boulder-adjustment.md.
    pub view_bias_max_profiles: usize,
    /// The solver stops once a step lowers the cost by less than this fraction (session 1's
    /// graph holds some 10,000 observations).
    pub relative_tolerance: f64,
}

impl Default for BoulderAdjustmentConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            rounds: 1,
            min_observations: 3,
            model_sigma_m: 0.01,
            cauchy_sigmas: 5.0,
            relative_tolerance: 1e-4,
            estimate_view_bias: true,
            view_bias_step: 0.03,
            max_standard_error: 0.02,
            view_bias_max_profiles: 4,
        }
    }
}

impl BoulderAdjustmentConfig {
    /// Whether the stage runs (enabled, at least one round).
    pub fn runs(&self) -> bool {
        self.enabled && self.rounds > 0
    }

    /// Checks the values; the message names the field.
    pub fn validate(&self) -> Result<(), FieldError> {
        if !(self.model_sigma_m.is_finite() && self.model_sigma_m >= 0.0) {
            return Err(FieldError::new(
                "model_sigma_m",
                "must be finite and non-negative",
            ));
        }
        if !(self.cauchy_sigmas.is_finite() && self.cauchy_sigmas > 0.0) {
            return Err(FieldError::new("cauchy_sigmas", "must be positive"));
        }
        if !(self.relative_tolerance.is_finite() && self.relative_tolerance > 0.0) {
            return Err(FieldError::new("relative_tolerance", "must be positive"));
        }
        if self.rounds > 20 {
            return Err(FieldError::new("rounds", "must be at most 20"));
        }
        if !(1..=20).contains(&self.view_bias_max_profiles) {
            return Err(FieldError::new(
                "view_bias_max_profiles",
                "must be between 1 and 20",
            ));
        }
        Ok(())
    }
}

/// What the adjustment did (last round).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BoulderAdjustmentReport {
    /// Boulders adjusted with the poses.
    pub boulders: usize,
    /// Detections used as observations.
    pub observations: usize,
    /// Observations the Cauchy kernel weighs below one half (more than its width off).
    pub outliers: usize,
    /// Root-mean-square distance of the inlier detections from their boulders, metres.
    pub rms_residual_m: f64,
    /// The viewpoint-bias size fraction the last round adjusted with, when the adjustment
    /// estimated it (`None`: the fusion's own).
    pub view_bias_size_fraction: Option<f64>,
    /// Its standard error.
    pub view_bias_standard_error: Option<f64>,
    /// Solves of the graph with the boulders (one per round, three more per estimate of
    /// the viewpoint bias).
    pub solves: usize,
    /// Wall-clock time of the whole adjustment, milliseconds.
    pub time_ms: f64,
}

/// One detection placed with the current poses.
struct Placed {
    frame: usize,
    /// As measured, in the world.
    raw: Detection,
    /// With the viewpoint bias of its own measured size taken out (what is clustered).
    detection: Detection,
}

/// One detection in the adjustment.
struct Observation {
    /// Its factor in the graph.
    factor: usize,
}

/// The boulders and detections added to a graph.
struct Added {
    observations: Vec<Observation>,
    boulders: usize,
}

/// Place the detections of every frame with `poses`, the viewpoint bias taken out and the
/// fusion's range gate applied.
fn place(log: &FrameLog, poses: &[Isometry3<f64>], fusion: &FusionConfig) -> Vec<Placed> {
    let mut out = Vec::new();
    for (k, (f, pose)) in log.frames.iter().zip(poses).enumerate() {
        let rover = Point3::from(pose.translation.vector);
        for d in &f.detections {
            let size_m = d.size_m.unwrap_or(0.0);
            let seen = Detection {
                frame: k as u64,
                p_world: pose * d.p_rover,
                rover_position: Some(rover),
                size_m: d.size_m,
                score: None,
            };
            let range = (seen.p_world - rover).xy().norm();
            if range < fusion.min_range_m || range > fusion.max_range_m {
                continue;
            }
            let bias_m = fusion.view_bias_m + fusion.view_bias_size_fraction * size_m;
            out.push(Placed {
                frame: k,
                detection: corrected(&seen, bias_m),
                raw: seen,
            });
        }
    }
    out
}

/// [`adjust`] `graph` in place when `config` enables it; the report of what it did.
pub fn adjust_in_place(
    graph: &mut TrajectoryGraph,
    log: &FrameLog,
    fusion: &FusionConfig,
    config: &BoulderAdjustmentConfig,
) -> Result<Option<BoulderAdjustmentReport>, GraphError> {
    if !config.runs() {
        return Ok(None);
    }
    let (adjusted, report) = adjust(graph, log, fusion, config)?;
    *graph = adjusted;
    Ok(Some(report))
}

/// Adjust the poses of `graph` (the session `log`'s pose graph, in its own frame) and the
/// boulders they saw together; returns the graph with its own factors and the adjusted
/// poses, and what the last round did.
pub fn adjust(
    graph: &TrajectoryGraph,
    log: &FrameLog,
    fusion: &FusionConfig,
    config: &BoulderAdjustmentConfig,
) -> Result<(TrajectoryGraph, BoulderAdjustmentReport), GraphError> {
    let started = std::time::Instant::now();
    let mut adjusted = graph.clone();
    let mut report = BoulderAdjustmentReport::default();
    let mut fusion = fusion.clone();
    let mut solves = 0;
    for _ in 0..config.rounds {
        let poses: Vec<Isometry3<f64>> = (0..adjusted.frames)
            .map(|k| adjusted.pose_or_identity(k))
            .collect();
        let clusters = boulder_clusters(&place(log, &poses, &fusion), &fusion, config);
        let mut solve = |fraction: f64, start: Option<&TrajectoryGraph>| {
            solves += 1;
            let fusion = FusionConfig {
                view_bias_size_fraction: fraction,
                ..fusion.clone()
            };
            solve_with_boulders(&adjusted, log, &poses, &clusters, &fusion, start, config)
        };
        let (mut solved, mut added) = solve(fusion.view_bias_size_fraction, None)?;
        let mut estimated = None;
        if config.estimate_view_bias {
            let h = config.view_bias_step;
            let mut f0 = fusion.view_bias_size_fraction;
            for _ in 0..config.view_bias_max_profiles {
                let Some((f, sigma)) = profile_minimum(&mut solve, &solved, f0, config)? else {
                    break;
                };
                (solved, added) = solve(f, Some(&solved))?;
                estimated = Some((f, sigma));
                // a move shorter than the clamp found the minimum
                let found = (f - f0).abs() < profile_reach(h) * (1.0 - 1e-9);
                f0 = f;
                if found {
                    break;
                }
            }
        }
        if let Some((f, _)) = estimated {
            fusion.view_bias_size_fraction = f;
        }
        report = summarise(&solved, &added, config);
        report.solves = solves;
        report.view_bias_size_fraction = estimated.map(|(f, _)| f);
        report.view_bias_standard_error = estimated.map(|(_, s)| s);
        // poses and frames (a session placed in a prior map has its frame variable)
        for key in adjusted.graph().keys().to_vec() {
            if let Some(value) = solved.graph().value(key) {
                adjusted.graph_mut().set_value(key, value)?;
            }
        }
    }
    report.time_ms = started.elapsed().as_secs_f64() * 1e3;
    Ok((adjusted, report))
}

/// The viewpoint-bias fraction's profile around `f0` (`solved` is the solution at `f0`):
/// the solutions at `f0 ± view_bias_step`, warm-started from it, and the minimum of the
/// parabola through the three costs with its standard error, when usable (within
/// 0–0.5, standard error within `max_standard_error`).
fn profile_minimum(
    solve: &mut impl FnMut(
        f64,
        Option<&TrajectoryGraph>,
    ) -> Result<(TrajectoryGraph, Added), GraphError>,
    solved: &TrajectoryGraph,
    f0: f64,
    config: &BoulderAdjustmentConfig,
) -> Result<Option<(f64, f64)>, GraphError> {
    let h = config.view_bias_step;
    let (below, _) = solve(f0 - h, Some(solved))?;
    let (above, _) = solve(f0 + h, Some(solved))?;
    let costs = [
        below.graph().cost(),
        solved.graph().cost(),
        above.graph().cost(),
    ];
    Ok(parabola_minimum(f0, h, costs)
        .filter(|(f, sigma)| (0.0..=0.5).contains(f) && *sigma <= config.max_standard_error))
}

/// The farthest one profile of step `h` moves the fraction: [`parabola_minimum`]'s clamp.
fn profile_reach(h: f64) -> f64 {
    2.0 * h
}

/// The minimum of the parabola through the costs at `f0 − h`, `f0`, `f0 + h`, kept within
/// `2 h` of `f0`, and its standard error (the cost is half the sum of squared
/// Mahalanobis residuals, so its curvature is `1 / σ²`); `None` when the costs do not
/// curve upwards.
fn parabola_minimum(f0: f64, h: f64, [below, at, above]: [f64; 3]) -> Option<(f64, f64)> {
    let curvature = (above - 2.0 * at + below) / (h * h);
    let slope = (above - below) / (2.0 * h);
    if !(curvature.is_finite() && curvature > 0.0 && slope.is_finite()) {
        return None;
    }
    let reach = profile_reach(h);
    let step = (-slope / curvature).clamp(-reach, reach);
    Some((f0 + step, curvature.sqrt().recip()))
}

/// A copy of `graph` with the boulders `clusters` (indices into the placement with
/// `poses`) and their detections, the viewpoint bias taken out with `fusion`'s, solved
/// from `start`'s values when given (the same boulders: a warm start).
fn solve_with_boulders(
    graph: &TrajectoryGraph,
    log: &FrameLog,
    poses: &[Isometry3<f64>],
    clusters: &[Vec<u32>],
    fusion: &FusionConfig,
    start: Option<&TrajectoryGraph>,
    config: &BoulderAdjustmentConfig,
) -> Result<(TrajectoryGraph, Added), GraphError> {
    let mut with_boulders = graph.clone();
    let placed = place(log, poses, fusion);
    let added = add_boulders(&mut with_boulders, &placed, clusters, poses, fusion, config)?;
    if let Some(start) = start {
        for key in with_boulders.graph().keys().to_vec() {
            if let Some(value) = start.graph().value(key) {
                with_boulders.graph_mut().set_value(key, value)?;
            }
        }
    }
    with_boulders.graph_mut().optimize(&SolverConfig {
        relative_tolerance: config.relative_tolerance,
        log_iterations: false,
        ..SolverConfig::default()
    })?;
    Ok((with_boulders, added))
}

/// The clusters of `placed` detections with enough of them to be a boulder.
fn boulder_clusters(
    placed: &[Placed],
    fusion: &FusionConfig,
    config: &BoulderAdjustmentConfig,
) -> Vec<Vec<u32>> {
    let points: Vec<Point3<f64>> = placed.iter().map(|p| p.detection.p_world).collect();
    let mut clusters = cluster_points(&points, fusion.cluster_radius_m);
    clusters.retain(|members| members.len() >= config.min_observations.max(2));
    clusters
}

/// Add the boulders `clusters` of the `placed` detections (placed with `poses`) and
/// their detections to `graph`.
fn add_boulders(
    graph: &mut TrajectoryGraph,
    placed: &[Placed],
    clusters: &[Vec<u32>],
    poses: &[Isometry3<f64>],
    fusion: &FusionConfig,
    config: &BoulderAdjustmentConfig,
) -> Result<Added, GraphError> {
    let stereo_only = FusionConfig {
        pose_sigma_m: 0.0,
        ..fusion.clone()
    };
    let model = Matrix3::identity() * config.model_sigma_m.powi(2);
    let kernel = RobustKernel::Cauchy {
        c: config.cauchy_sigmas,
    };
    let mut observations = Vec::new();
    let mut boulders = 0u64;
    for members in clusters {
        // the boulder's size, not each detection's noisy measure of it (15 % in the
        // simulation), scales the correction: a per-detection size, regressed on, would
        // shrink the fraction the adjustment estimates by the size noise
        let mut sizes: Vec<f64> = members
            .iter()
            .filter_map(|&i| placed[i as usize].raw.size_m)
            .collect();
        let bias_m = fusion.view_bias_m + fusion.view_bias_size_fraction * median(&mut sizes);
        let corrected: Vec<(usize, Detection)> = members
            .iter()
            .map(|&i| {
                let p = &placed[i as usize];
                (p.frame, corrected(&p.raw, bias_m))
            })
            .collect();
        let detections: Vec<&Detection> = corrected.iter().map(|(_, d)| d).collect();
        let Some((centroid, _)) = stereo_weighted(&detections, fusion) else {
            continue;
        };
        graph.graph_mut().add_point(boulders, centroid)?;
        for (frame, detection) in &corrected {
            let rover = detection.rover_position.unwrap_or_else(Point3::origin);
            let world = detection_information(&detection.p_world, &rover, &stereo_only);
            let Some(cov_world) = world.try_inverse() else {
                continue;
            };
            let pose = &poses[*frame];
            let r = pose.rotation.to_rotation_matrix().into_inner();
            let cov_rover = r.transpose() * cov_world * r + model;
            let Some(information) = cov_rover.try_inverse() else {
                continue;
            };
            let information = (information + information.transpose()) * 0.5;
            let factor = graph.graph_mut().add_point_observation(
                *frame as u64,
                boulders,
                pose.inverse() * detection.p_world,
                information,
                kernel,
            )?;
            observations.push(Observation { factor });
        }
        boulders += 1;
    }
    Ok(Added {
        observations,
        boulders: boulders as usize,
    })
}

/// The current value of every variable of `graph`, in its variable order.
fn graph_values(graph: &TrajectoryGraph) -> Vec<Isometry3<f64>> {
    graph
        .graph()
        .keys()
        .iter()
        .filter_map(|k| graph.graph().value(*k))
        .collect()
}

/// The report of a solved graph with boulders.
fn summarise(
    graph: &TrajectoryGraph,
    added: &Added,
    config: &BoulderAdjustmentConfig,
) -> BoulderAdjustmentReport {
    let values = graph_values(graph);
    let (mut outliers, mut sum2, mut inliers) = (0, 0.0, 0usize);
    for o in &added.observations {
        let Some(f) = graph.graph().factors().get(o.factor) else {
            continue;
        };
        let r = f.residual(&values);
        let e = r.fixed_rows::<3>(3);
        let m2 = (e.transpose() * f.information().fixed_view::<3, 3>(3, 3) * e)[0];
        if m2 > config.cauchy_sigmas.powi(2) {
            outliers += 1;
        } else {
            sum2 += e.norm_squared();
            inliers += 1;
        }
    }
    BoulderAdjustmentReport {
        boulders: added.boulders,
        observations: added.observations.len(),
        outliers,
        rms_residual_m: (sum2 / inliers.max(1) as f64).sqrt(),
        ..BoulderAdjustmentReport::default()
    }
}

#[cfg(test)]
mod tests {
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

    /// [`two_laps`] with the odometry 0.2 % long and 0.0002 rad per metre off, boulder
    /// faces 1/6 of their size in front of their centres, and its pose graph solved on the
    /// odometry alone.
    fn two_laps_solved() -> (FrameLog, Vec<Isometry3<f64>>, TrajectoryGraph) {
        let (log, truth) = two_laps(1.002, 0.0002, 1.0 / 6.0);
        let mut graph = TrajectoryGraph::new();
        graph.extend(&log, &LocalizerConfig::default()).unwrap();
        graph.optimize().unwrap();
        (log, truth, graph)
    }

    #[test]
    fn the_viewpoint_bias_comes_out_of_the_boulders_seen_from_both_sides() {
        let f = 1.0 / 6.0;
        let (log, truth, mut graph) = two_laps_solved();
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
    fn the_profile_walks_to_a_fraction_beyond_one_step() {
        // the fusion starts at 0 (no viewpoint bias calibrated online), 0.17 short: one
        // profile moves at most 2 × 0.03
        let f = 1.0 / 6.0;
        let (log, truth, start) = two_laps_solved();
        let fusion = FusionConfig {
            view_bias_size_fraction: 0.0,
            ..FusionConfig::default()
        };
        let adjusted = |profiles: usize| {
            let config = BoulderAdjustmentConfig {
                view_bias_max_profiles: profiles,
                ..BoulderAdjustmentConfig::default()
            };
            let (graph, report) = adjust(&start, &log, &fusion, &config).unwrap();
            (rmse_m(&truth, &graph.poses_in_prior()), report)
        };
        let (one_rmse, one) = adjusted(1);
        assert!(
            (one.view_bias_size_fraction.unwrap() - 0.06).abs() < 1e-9,
            "{one:?}"
        );
        let (rmse, report) = adjusted(BoulderAdjustmentConfig::default().view_bias_max_profiles);
        let estimate = report.view_bias_size_fraction.unwrap();
        assert!(
            (estimate - f).abs() < 0.01,
            "{estimate} for {f}: {report:?}"
        );
        assert!(rmse < 0.005 && rmse < one_rmse, "{one_rmse} m -> {rmse} m");
    }

    #[test]
    fn validation_names_the_field() {
        assert!(BoulderAdjustmentConfig::default().validate().is_ok());
        let defaults = BoulderAdjustmentConfig::default;
        for (bad, field) in [
            (
                BoulderAdjustmentConfig {
                    model_sigma_m: -1.0,
                    ..defaults()
                },
                "model_sigma_m",
            ),
            (
                BoulderAdjustmentConfig {
                    view_bias_max_profiles: 0,
                    ..defaults()
                },
                "view_bias_max_profiles",
            ),
        ] {
            let message = bad.validate().unwrap_err().to_string();
            assert!(message.contains(field), "{message}");
        }
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
}
