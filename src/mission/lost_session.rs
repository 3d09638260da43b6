//! Session 2: start somewhere else with a wrong guess of the start pose; every few seconds
//! relocalize a submap of the recent detections (odometry frame) against session 1's map,
//! turn accepted results into relocalization factors, re-optimise, and tell the planner.

use super::boulder_adjustment::{
    adjust_in_place, BoulderAdjustmentConfig, BoulderAdjustmentReport,
};
use super::fix_gate::{agrees, Tolerance};
use super::lander_factor::{add_lander_factors, add_lander_factors_optimized};
use super::odometry_bias::OdometryBias;
use super::progress::{MissionProgress, MissionStage};
use super::submap::{detections_with_poses, frame_nearest, landmark_positions};
use super::trajectory::TrajectoryGraph;
use super::{Attempt, MissionConfig, MissionError};
use crate::graph::{se3, RobustKernel};
use crate::landmarks::{fuse_detections, FusionConfig};
use crate::relocalize::Relocalizer;
use crate::sim::moon::Moon;
use crate::sim::session::{SessionConfig, SessionLog, SessionSim};
use nalgebra::{Isometry3, Point2};
use segloc_maps::ObjectMap;

/// What session 2 produced.
pub struct LocalizedSession {
    /// The simulation log.
    pub log: SessionLog,
    /// Optimised `world_from_rover` of every frame (prior-map frame).
    pub poses: Vec<Isometry3<f64>>,
    /// Every relocalization attempt.
    pub attempts: Vec<Attempt>,
    /// The odometry's biases as estimated at the end of the session.
    pub odometry_bias: OdometryBias,
    /// Position RMSE of the pose graph's poses (before the mission's terrain height
    /// alignment changes `poses`), metres.
    pub rmse_graph_m: f64,
    /// What the boulder adjustment did (`None`: off).
    pub adjustment: Option<BoulderAdjustmentReport>,
    /// Position RMSE of the pose graph's poses before the boulder adjustment, metres.
    pub rmse_before_adjustment_m: f64,
}

/// The rocks of `prior_map` the planner should know of from its first relocalization on:
/// boulders of known size seen at least `prior_obstacle_min_observations` times, as
/// (centre x, y; radius) in the map's (world) frame.
pub fn known_rocks(prior_map: &ObjectMap, config: &MissionConfig) -> Vec<(Point2<f64>, f64)> {
    prior_map
        .landmarks
        .iter()
        .filter(|l| l.observations >= config.prior_obstacle_min_observations)
        .filter_map(|l| {
            let size = l.size_m?;
            Some((Point2::new(l.position.x, l.position.y), 0.5 * size))
        })
        .collect()
}

/// What session 2 knows of session 1.
#[derive(Clone, Copy)]
pub struct PriorSession<'a> {
    /// Session 1's map, prepared for relocalization.
    pub relocalizer: &'a Relocalizer,
    /// Session 1's map, whose rocks the planner avoids once it knows where it is (with
    /// `prior_map_obstacles`).
    pub map: &'a ObjectMap,
}

/// Run session 2 from `start`, believing it starts at `guess`, relocalizing against
/// session 1's map (`prior`).
pub fn localize_session(
    moon: &Moon,
    config: &MissionConfig,
    prior: PriorSession,
    start: [f64; 3],
    guess: [f64; 3],
    seed: u64,
    progress: &dyn MissionProgress,
) -> Result<LocalizedSession, MissionError> {
    let session = SessionConfig {
        duration_s: config.session_seconds()[1],
        start,
        initial_guess: Some(guess),
        ..config.session_2().clone()
    };
    let mut sim = SessionSim::new(moon, &session, seed)?;
    if config.prior_map_obstacles {
        sim.set_known_rocks_world(known_rocks(prior.map, config));
    }
    let mut graph = TrajectoryGraph::new();
    let mut attempts = Vec::new();
    let mut next_attempt_s = config.relocalize_period_s;
    let mut gate = Gate::default();
    // frames whose lander points have been fitted
    let mut lander_done = 0;
    while sim.step() {
        let log = sim.log();
        progress.update(MissionStage::Driving {
            session: 2,
            time_s: log.ticks.last().map_or(0.0, |t| t.time_s),
            duration_s: session.duration_s,
        });
        let Some(last) = log.frames.last() else {
            continue;
        };
        if last.time_s + 1e-9 < next_attempt_s || log.frames.len() <= graph.frames {
            continue;
        }
        next_attempt_s += config.relocalize_period_s;
        graph.extend(log, config)?;
        let candidate = attempt(log, config, prior.relocalizer, &graph, &mut attempts)?;
        let confirmed = candidate.map_or_else(Vec::new, |c| gate.admit(c, &graph, config));
        let mut changed = !confirmed.is_empty();
        for c in confirmed {
            let record = &mut attempts[c.attempt];
            record.accepted = true;
            record.refusal = None;
            graph.add_relocalization(
                c.k,
                c.prior_from_rover,
                c.information,
                RobustKernel::Cauchy {
                    c: config.robust_scale,
                },
            )?;
            gate.last_fix_frame = Some(gate.last_fix_frame.map_or(c.k, |f| f.max(c.k)));
        }
        if changed {
            graph.optimize()?;
        }
        if config.lander_factors && graph.odom_from_prior().is_some() {
            let frames = graph.frames;
            changed |=
                add_lander_factors_optimized(&mut graph, log, lander_done..frames, true, config)?;
            lander_done = frames;
        }
        if changed {
            if config.calibrate_odometry {
                graph.calibrate(config, config.calibration_rounds)?;
            }
            if let Some(world_from_session) = world_from_session_estimate(log, &graph) {
                sim.set_world_from_session_estimate(&world_from_session);
            }
        }
    }
    let log = sim.finish();
    graph.extend(&log, config)?;
    graph.optimize()?;
    if config.lander_factors && graph.odom_from_prior().is_some() {
        let frames = graph.frames;
        add_lander_factors(&mut graph, &log, lander_done..frames, true, config)?;
        graph.optimize()?;
    }
    if config.calibrate_odometry && graph.num_fixes() > 0 {
        graph.calibrate(config, config.calibration_rounds)?;
    }
    let rmse_before_adjustment_m = super::trajectory::rmse_m(&log, &graph.poses_in_prior());
    // session 2 keeps session 1's viewpoint bias, which the rock map uses too
    let adjustment_config = BoulderAdjustmentConfig {
        estimate_view_bias: false,
        ..config.boulder_adjustment.clone()
    };
    let adjustment = adjust_in_place(&mut graph, &log, &config.fusion, &adjustment_config)?;
    let poses = graph.poses_in_prior();
    let rmse_graph_m = super::trajectory::rmse_m(&log, &poses);
    Ok(LocalizedSession {
        log,
        poses,
        attempts,
        odometry_bias: graph.bias,
        rmse_graph_m,
        adjustment,
        rmse_before_adjustment_m,
    })
}

/// A relocalization the relocalizer accepted, before the gate has confirmed it.
struct Candidate {
    /// The relocalized frame.
    k: usize,
    /// Its measured pose in the prior map.
    prior_from_rover: Isometry3<f64>,
    /// Information of the measurement (right perturbation of `prior_from_rover`).
    information: nalgebra::Matrix6<f64>,
    /// Index of its record among the attempts.
    attempt: usize,
}

/// The state of the consistency gate ([`super::fix_gate`]).
#[derive(Default)]
struct Gate {
    /// The last result that was not confirmed, waiting for the next one.
    pending: Option<Candidate>,
    /// The latest frame with a relocalization in the graph.
    last_fix_frame: Option<usize>,
}

impl Gate {
    /// The candidates to add to the graph now (none, this one, or the pending one and this
    /// one).
    fn admit(
        &mut self,
        c: Candidate,
        graph: &TrajectoryGraph,
        config: &MissionConfig,
    ) -> Vec<Candidate> {
        if !config.gate_relocalizations {
            return vec![c];
        }
        let tolerance = Tolerance::of_gate(config);
        let pose = |k: usize| graph.pose_or_identity(k);
        if let (Some(odom_from_prior), Some(last)) = (graph.odom_from_prior(), self.last_fix_frame)
        {
            let predicted = odom_from_prior.inverse() * pose(c.k);
            let (sigma_m, sigma_yaw) = graph.odometry_sigma(last, c.k, config);
            let widened = tolerance.widened(sigma_m, sigma_yaw, 3.0);
            if agrees(&predicted, &c.prior_from_rover, &widened) {
                self.pending = None;
                return vec![c];
            }
        }
        if let Some(p) = self.pending.take() {
            let carried = p.prior_from_rover * pose(p.k).inverse() * pose(c.k);
            let (sigma_m, sigma_yaw) = graph.odometry_sigma(p.k, c.k, config);
            // before the first fix the odometry between the two is still uncalibrated (its
            // yaw-rate error bends both submaps alike while the rover turns on the spot), so
            // the first pair must agree more tightly
            let n_sigma = if self.last_fix_frame.is_none() {
                config.gate_bootstrap_sigmas
            } else {
                3.0
            };
            if agrees(
                &carried,
                &c.prior_from_rover,
                &tolerance.widened(sigma_m, sigma_yaw, n_sigma),
            ) {
                return vec![p, c];
            }
        }
        self.pending = Some(c);
        Vec::new()
    }
}

/// One relocalization of the submap ending at the latest frame; returns the result when the
/// relocalizer accepted it (recorded as awaiting confirmation by the gate).
fn attempt(
    log: &SessionLog,
    config: &MissionConfig,
    relocalizer: &Relocalizer,
    graph: &TrajectoryGraph,
    attempts: &mut Vec<Attempt>,
) -> Result<Option<Candidate>, MissionError> {
    let k = log.frames.len() - 1;
    let now_s = log.frames[k].time_s;
    let mut first = log
        .frames
        .iter()
        .position(|f| f.time_s >= now_s - config.submap_window_s)
        .unwrap_or(0);
    // odometry's yaw error grows with the angle turned: keep the submap to the frames within
    // `submap_max_turn_deg` of turning back from now (but at least `submap_min_window_s`)
    let mut turned = 0.0;
    let mut j = k;
    while j > first {
        let (a, b) = (log.frames[j - 1].tick, log.frames[j].tick);
        turned += (a..b)
            .filter_map(|t| log.ticks.get(t + 1))
            .map(|t| t.vo_prev_from_cur.rotation.euler_angles().2.abs())
            .sum::<f64>();
        if turned > config.submap_max_turn_deg.to_radians()
            && now_s - log.frames[j].time_s >= config.submap_min_window_s
        {
            break;
        }
        j -= 1;
    }
    first = j;
    // the submap in the odometry frame: the odometry chain with the current bias estimate
    // taken out, placed at the graph's estimate of its first frame (only the shape matters
    // to the relocalizer; the placement keeps the submap's frame near the graph's)
    // (roll and pitch stay the logged ones, which the IMU's gravity fixes: composing the
    // odometry's tilt would let it drift)
    let start = log.ticks[log.frames[first].tick].session_from_rover;
    let mut odometry = vec![Isometry3::identity(); first];
    for (i, p) in graph
        .corrected_odometry(first..k + 1)
        .into_iter()
        .enumerate()
    {
        let p = start * p;
        let logged = log.ticks[log.frames[first + i].tick].session_from_rover;
        let (roll, pitch, _) = se3::rpy_from_rotation(&logged.rotation);
        let (_, _, yaw) = se3::rpy_from_rotation(&p.rotation);
        odometry.push(Isometry3::from_parts(
            p.translation,
            se3::rotation_from_rpy(roll, pitch, yaw),
        ));
    }
    let set = detections_with_poses(log, &odometry, first..k + 1, "session2", "odom");
    // placed by a barely calibrated odometry: the pose error, not the stereo's, dominates
    let fusion = FusionConfig {
        pose_sigma_m: config.lost_submap_pose_sigma_m,
        ..config.fusion.clone()
    };
    let query = fuse_detections(&set, &fusion);
    let mut record = Attempt::pending(2, now_s, query.len());
    let result = relocalizer.relocalize(&query);
    let reloc = match result {
        Ok(r) => r,
        Err(e) => {
            record.refusal = Some(format!("error: {e}"));
            attempts.push(record);
            return Ok(None);
        }
    };
    record.inliers = reloc.inliers.len();
    record.yaw_sigma_deg = Some(yaw_sigma_deg(&reloc.information));
    let Some(prior_from_odom) = reloc.prior_from_query else {
        record.refusal = Some(
            reloc
                .refusal
                .as_ref()
                .map_or_else(|| "refused".to_string(), |r| r.to_string()),
        );
        attempts.push(record);
        return Ok(None);
    };
    // anchor: the frame nearest the matched landmarks (least drift relative to them)
    let matched = landmark_positions(&query, reloc.inliers.iter().map(|(_, q)| *q));
    let k = frame_nearest(&odometry, first..k + 1, &matched);
    let odom_from_rover = odometry[k];
    let world_from_rover_true = log.ticks[log.frames[k].tick].world_from_rover;
    let prior_from_rover = prior_from_odom * odom_from_rover;
    let error = world_from_rover_true.inverse() * prior_from_rover;
    let error_m = error.translation.vector.norm();
    let error_deg = error.rotation.angle().to_degrees();
    record.refusal = Some("not confirmed by the pose graph or the next relocalization".into());
    record.error_m = Some(error_m);
    record.error_deg = Some(error_deg);
    record.error_yaw_deg = Some(error.rotation.euler_angles().2.to_degrees());
    record.wrong = error_m > config.wrong_translation_m || error_deg > config.wrong_rotation_deg;
    attempts.push(record);
    // information on the right perturbation of prior_from_odom → of prior_from_rover
    let ad = se3::adjoint(&odom_from_rover);
    let information =
        ad.transpose() * reloc.information * ad * config.relocalization_information_scale;
    Ok(Some(Candidate {
        k,
        prior_from_rover,
        information,
        attempt: attempts.len() - 1,
    }))
}

/// The planner's `world_from_session`: the latest frame's drift correction in the prior
/// map's frame ([`TrajectoryGraph::prior_from_session`]), once that frame is known.
fn world_from_session_estimate(
    log: &SessionLog,
    graph: &TrajectoryGraph,
) -> Option<Isometry3<f64>> {
    graph.odom_from_prior()?;
    graph.prior_from_session(log, graph.frames.checked_sub(1)?)
}

/// Standard deviation of the yaw (rotation about z, tangent index 2) implied by an
/// information matrix, degrees (infinite when it is singular).
pub fn yaw_sigma_deg(information: &nalgebra::Matrix6<f64>) -> f64 {
    information
        .try_inverse()
        .map(|c| c[(2, 2)])
        .filter(|v| v.is_finite() && *v >= 0.0)
        .map_or(f64::INFINITY, |v| v.sqrt().to_degrees())
}
