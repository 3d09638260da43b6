//! What happened in a mission, frame by frame, kept for playback: true, estimated and
//! odometry-only rover poses, the boulders each frame saw (placed with the estimated
//! pose), the moon's rocks and session 1's map. The Rerun recording
//! (`mission::recording`, cargo feature `rerun`) is written from it.

use crate::sim::moon::Moon;
use crate::sim::session::SessionLog;
use nalgebra::{Isometry3, Point3};
use segloc_maps::ObjectMap;

use super::stream::odometry_in_world;

/// One camera frame (1 Hz) of a session.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceFrame {
    /// Session time, seconds.
    pub time_s: f64,
    /// The true rover pose.
    pub world_from_rover_true: Isometry3<f64>,
    /// The pose-graph estimate after the session (with the global factors).
    pub world_from_rover_estimate: Isometry3<f64>,
    /// Odometry alone, aligned at the true start.
    pub world_from_rover_odometry: Isometry3<f64>,
    /// The boulders detected in this frame, placed with the estimated pose.
    pub p_world_boulders: Vec<Point3<f64>>,
}

/// One session's frames.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SessionTrace {
    /// Session number (1-based).
    pub session: usize,
    /// Every camera frame.
    pub frames: Vec<TraceFrame>,
}

/// A rock of the synthetic moon.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceRock {
    /// Centre, world frame.
    pub p_world: Point3<f64>,
    /// Radius, metres.
    pub radius_m: f64,
}

/// The whole mission for playback.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MissionTrace {
    /// The moon's rocks (the truth).
    pub rocks: Vec<TraceRock>,
    /// Session 1's fused boulder map (the prior of session 2), world frame.
    pub prior_landmarks: Vec<TraceRock>,
    /// Per session.
    pub sessions: Vec<SessionTrace>,
}

impl MissionTrace {
    /// Collect the trace of a mission: `sessions` holds each session's log and its
    /// estimated world poses (one per frame).
    pub fn collect(
        moon: &Moon,
        prior: &ObjectMap,
        sessions: &[(&SessionLog, &[Isometry3<f64>])],
    ) -> Self {
        let rocks = moon
            .rocks()
            .iter()
            .enumerate()
            .map(|(i, r)| TraceRock {
                p_world: r.center,
                radius_m: moon.rock_size_radius_m(i),
            })
            .collect();
        let prior_landmarks = prior
            .landmarks
            .iter()
            .map(|l| TraceRock {
                p_world: l.position,
                radius_m: l.size_m.map_or(0.05, |diameter| 0.5 * diameter),
            })
            .collect();
        let sessions = sessions
            .iter()
            .enumerate()
            .map(|(k, (log, poses))| session_trace(k + 1, log, poses))
            .collect();
        MissionTrace {
            rocks,
            prior_landmarks,
            sessions,
        }
    }
}

fn session_trace(session: usize, log: &SessionLog, poses: &[Isometry3<f64>]) -> SessionTrace {
    let odometry = odometry_in_world(log);
    let frames = log
        .frames
        .iter()
        .zip(poses)
        .zip(odometry)
        .filter_map(|((f, estimate), odometry)| {
            let truth = log.ticks.get(f.tick)?;
            Some(TraceFrame {
                time_s: f.time_s,
                world_from_rover_true: truth.world_from_rover,
                world_from_rover_estimate: *estimate,
                world_from_rover_odometry: odometry,
                p_world_boulders: f.boulders.iter().map(|b| estimate * b.p_rover).collect(),
            })
        })
        .collect();
    SessionTrace { session, frames }
}
