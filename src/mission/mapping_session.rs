//! Session 1: start at a known pose, drive, and build the boulder map every later session
//! relocalizes against (in the optimised session frame, which is the world frame up to
//! drift since the start is known).

use super::trajectory::{
    detections_with_poses, frame_nearest, landmark_positions, TrajectoryGraph,
};
use super::{Attempt, MissionConfig, MissionError};
use crate::graph::{se3, RobustKernel};
use crate::landmarks::fuse_detections;
use crate::relocalize::Relocalizer;
use crate::sim::moon::Moon;
use crate::sim::session::{run_session, SessionConfig, SessionLog};
use nalgebra::Isometry3;
use segloc_maps::ObjectMap;

/// What session 1 produced.
pub struct MappedSession {
    /// The simulation log.
    pub log: SessionLog,
    /// Optimised `world_from_rover` of every frame.
    pub poses: Vec<Isometry3<f64>>,
    /// The boulder map (world frame), the prior of later sessions.
    pub map: ObjectMap,
    /// Loop-closure attempts (recent submaps against the session's own earlier map).
    pub attempts: Vec<Attempt>,
}

/// Run session 1 from `start` for the mission's duration and build its map.
pub fn map_session(
    moon: &Moon,
    config: &MissionConfig,
    start: [f64; 3],
    seed: u64,
) -> Result<MappedSession, MissionError> {
    let session = SessionConfig {
        duration_s: config.seconds_per_session,
        start,
        initial_guess: None,
        ..config.session.clone()
    };
    let log = run_session(moon, &session, seed)?;
    let mut graph = TrajectoryGraph::new();
    graph.extend(&log, config)?;
    let attempts = if config.loop_closures {
        loop_closures(&log, config, &mut graph)?
    } else {
        Vec::new()
    };
    graph.optimize()?;
    let poses = graph.poses_in_prior();
    let set = detections_with_poses(&log, &poses, 0..log.frames.len(), "session1", "world");
    let map = fuse_detections(&set, &config.fusion);
    Ok(MappedSession {
        log,
        poses,
        map,
        attempts,
    })
}

/// Every `relocalize_period_s`, relocalize the submap of the last `submap_window_s` against
/// the map of the frames older than `loop_closure_gap_s` before the submap (both in the
/// current estimate of the session frame, re-optimised after each closure); an accepted result becomes a between factor from the earlier frame
/// nearest the matched landmarks to the submap's last frame.
fn loop_closures(
    log: &SessionLog,
    config: &MissionConfig,
    graph: &mut TrajectoryGraph,
) -> Result<Vec<Attempt>, MissionError> {
    let frame_at = |t: f64| log.frames.iter().position(|f| f.time_s >= t);
    let mut attempts = Vec::new();
    let mut t = config.relocalize_period_s;
    let end = log.frames.last().map_or(0.0, |f| f.time_s);
    while t <= end + 1e-9 {
        let now = t;
        t += config.relocalize_period_s;
        let Some(k) = log.frames.iter().rposition(|f| f.time_s <= now + 1e-9) else {
            continue;
        };
        let first = frame_at(now - config.submap_window_s).unwrap_or(0);
        let Some(old_end) = frame_at(now - config.submap_window_s - config.loop_closure_gap_s)
        else {
            continue;
        };
        if old_end < 10 {
            continue;
        }
        // both maps placed with the current estimate (earlier loop closures applied), so
        // the old map is consistent with itself
        let odometry = graph.poses_in_prior();
        let old = fuse_detections(
            &detections_with_poses(log, &odometry, 0..old_end, "session1-old", "odom"),
            &config.fusion,
        );
        let query = fuse_detections(
            &detections_with_poses(log, &odometry, first..k + 1, "session1-recent", "odom"),
            &config.fusion,
        );
        let mut record = Attempt {
            session: 1,
            time_s: log.frames[k].time_s,
            query_landmarks: query.len(),
            accepted: false,
            refusal: None,
            inliers: 0,
            error_m: None,
            error_deg: None,
            error_yaw_deg: None,
            wrong: false,
        };
        let reloc = match Relocalizer::new(old.clone(), config.relocalize.clone())
            .and_then(|r| r.relocalize(&query))
        {
            Ok(r) => r,
            Err(e) => {
                record.refusal = Some(format!("error: {e}"));
                attempts.push(record);
                continue;
            }
        };
        record.inliers = reloc.inliers.len();
        let Some(old_from_recent) = reloc.prior_from_query else {
            record.refusal = Some(
                reloc
                    .refusal
                    .as_ref()
                    .map_or_else(|| "refused".to_string(), |r| r.to_string()),
            );
            attempts.push(record);
            continue;
        };
        // the earlier frame nearest the matched landmarks of the old map, and the recent
        // frame nearest the matched landmarks of the submap (least drift relative to them)
        let matched_old = landmark_positions(&old, reloc.inliers.iter().map(|(p, _)| *p));
        let matched_new = landmark_positions(&query, reloc.inliers.iter().map(|(_, q)| *q));
        let j = frame_nearest(&odometry, 0..old_end, &matched_old);
        let k = frame_nearest(&odometry, first..k + 1, &matched_new);
        let j_from_k = odometry[j].inverse() * old_from_recent * odometry[k];
        let truth = log
            .true_motion_between(log.frames[j].tick, log.frames[k].tick)
            .unwrap_or_else(Isometry3::identity);
        let error = truth.inverse() * j_from_k;
        let (error_m, error_deg) = (
            error.translation.vector.norm(),
            error.rotation.angle().to_degrees(),
        );
        record.accepted = true;
        record.error_m = Some(error_m);
        record.error_deg = Some(error_deg);
        record.error_yaw_deg = Some(error.rotation.euler_angles().2.to_degrees());
        record.wrong =
            error_m > config.wrong_translation_m || error_deg > config.wrong_rotation_deg;
        attempts.push(record);
        let ad = se3::adjoint(&odometry[k]);
        let information =
            ad.transpose() * reloc.information * ad * config.relocalization_information_scale;
        let kernel = RobustKernel::Cauchy {
            c: config.robust_scale,
        };
        graph
            .graph
            .add_between(j as u64, k as u64, j_from_k, information, kernel)?;
        graph.optimize()?;
    }
    Ok(attempts)
}
