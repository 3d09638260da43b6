//! Session 2: start somewhere else with a wrong guess of the start pose; every few seconds
//! relocalize a submap of the recent detections (odometry frame) against session 1's map,
//! turn accepted results into relocalization factors, re-optimise, and tell the planner.

use super::progress::{MissionProgress, MissionStage};
use super::trajectory::{
    detections_with_poses, frame_nearest, landmark_positions, TrajectoryGraph,
};
use super::{Attempt, MissionConfig, MissionError};
use crate::graph::{se3, RobustKernel};
use crate::landmarks::fuse_detections;
use crate::relocalize::Relocalizer;
use crate::sim::moon::Moon;
use crate::sim::session::{SessionConfig, SessionLog, SessionSim};
use nalgebra::Isometry3;

/// What session 2 produced.
pub struct LocalizedSession {
    /// The simulation log.
    pub log: SessionLog,
    /// Optimised `world_from_rover` of every frame (prior-map frame).
    pub poses: Vec<Isometry3<f64>>,
    /// Every relocalization attempt.
    pub attempts: Vec<Attempt>,
}

/// Run session 2 from `start`, believing it starts at `guess`, relocalizing against
/// `relocalizer` (session 1's map).
pub fn localize_session(
    moon: &Moon,
    config: &MissionConfig,
    relocalizer: &Relocalizer,
    start: [f64; 3],
    guess: [f64; 3],
    seed: u64,
    progress: &dyn MissionProgress,
) -> Result<LocalizedSession, MissionError> {
    let session = SessionConfig {
        duration_s: config.seconds_per_session,
        start,
        initial_guess: Some(guess),
        ..config.session.clone()
    };
    let mut sim = SessionSim::new(moon, &session, seed)?;
    let mut graph = TrajectoryGraph::new();
    let mut attempts = Vec::new();
    let mut next_attempt_s = config.relocalize_period_s;
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
        let changed = attempt(log, config, relocalizer, &mut graph, &mut attempts)?;
        if changed {
            graph.optimize()?;
            if let Some(world_from_session) = world_from_session_estimate(log, &graph) {
                sim.set_world_from_session_estimate(&world_from_session);
            }
        }
    }
    let log = sim.finish();
    graph.extend(&log, config)?;
    graph.optimize()?;
    let poses = graph.poses_in_prior();
    Ok(LocalizedSession {
        log,
        poses,
        attempts,
    })
}

/// One relocalization of the submap ending at the latest frame; returns whether a factor
/// was added.
fn attempt(
    log: &SessionLog,
    config: &MissionConfig,
    relocalizer: &Relocalizer,
    graph: &mut TrajectoryGraph,
    attempts: &mut Vec<Attempt>,
) -> Result<bool, MissionError> {
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
    // the submap in the odometry frame (the raw odometry estimate, as logged)
    let odometry: Vec<Isometry3<f64>> = log
        .frames
        .iter()
        .map(|f| log.ticks[f.tick].session_from_rover)
        .collect();
    let set = detections_with_poses(log, &odometry, first..k + 1, "session2", "odom");
    let query = fuse_detections(&set, &config.fusion);
    let mut record = Attempt::pending(2, now_s, query.len());
    let result = relocalizer.relocalize(&query);
    let reloc = match result {
        Ok(r) => r,
        Err(e) => {
            record.refusal = Some(format!("error: {e}"));
            attempts.push(record);
            return Ok(false);
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
        return Ok(false);
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
    record.accepted = true;
    record.error_m = Some(error_m);
    record.error_deg = Some(error_deg);
    record.error_yaw_deg = Some(error.rotation.euler_angles().2.to_degrees());
    record.wrong = error_m > config.wrong_translation_m || error_deg > config.wrong_rotation_deg;
    attempts.push(record);
    // information on the right perturbation of prior_from_odom → of prior_from_rover
    let ad = se3::adjoint(&odom_from_rover);
    let information =
        ad.transpose() * reloc.information * ad * config.relocalization_information_scale;
    let index = graph.add_relocalization(k, prior_from_rover, information)?;
    graph.graph.set_factor_kernel(
        index,
        RobustKernel::Cauchy {
            c: config.robust_scale,
        },
    )?;
    Ok(true)
}

/// The planner's `world_from_session`: the optimised latest pose composed with the inverse
/// of its odometry estimate (so the correction of the drift so far is included).
fn world_from_session_estimate(
    log: &SessionLog,
    graph: &TrajectoryGraph,
) -> Option<Isometry3<f64>> {
    let odom_from_prior = graph.odom_from_prior()?;
    let k = graph.frames.checked_sub(1)?;
    let odom_from_rover = graph.graph.pose(k as u64)?;
    let tick = log.frames.get(k)?.tick;
    let session_from_rover = log.ticks.get(tick)?.session_from_rover;
    Some(odom_from_prior.inverse() * odom_from_rover * session_from_rover.inverse())
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
