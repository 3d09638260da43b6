//! Session 1: start at a known pose, drive, and build the boulder map every later session
//! relocalizes against (in the optimised session frame, which is the world frame up to
//! drift since the start is known).

use super::trajectory::{detections_with_poses, TrajectoryGraph};
use super::{MissionConfig, MissionError};
use crate::landmarks::fuse_detections;
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
    graph.optimize()?;
    let poses = graph.poses_in_prior();
    let set = detections_with_poses(&log, &poses, 0..log.frames.len(), "session1", "world");
    let map = fuse_detections(&set, &config.fusion);
    Ok(MappedSession { log, poses, map })
}
