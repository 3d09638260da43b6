//! Session 2: start somewhere else with a wrong guess of the start pose and drive, feeding
//! every camera frame to a [`Localizer`] against session 1's map; whenever the localizer
//! re-optimises, tell the planner where the session's frame lies in the world.

use super::progress::{MissionProgress, MissionStage};
use super::stream::{push_new_frames, rmse_m, scored_attempts};
use super::{Attempt, MissionConfig, MissionError};
use crate::localizer::boulder_adjustment::BoulderAdjustmentReport;
use crate::localizer::odometry_bias::OdometryBias;
use crate::localizer::Localizer;
use crate::sim::moon::Moon;
use crate::sim::rendered_boulders::RenderedBoulders;
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

/// Run session 2 from `start`, believing it starts at `guess`, localizing against session
/// 1's map `prior_map` (`config` with session 1's calibrated fusion).
pub fn localize_session(
    moon: &Moon,
    config: &MissionConfig,
    prior_map: &ObjectMap,
    start_guess: ([f64; 3], [f64; 3]),
    seed: u64,
    progress: &dyn MissionProgress,
) -> Result<LocalizedSession, MissionError> {
    localize_session_with(moon, config, prior_map, start_guess, seed, progress, None)
}

/// [`localize_session`], the boulders detected on rendered images by `rendered` when given.
pub fn localize_session_with(
    moon: &Moon,
    config: &MissionConfig,
    prior_map: &ObjectMap,
    start_guess: ([f64; 3], [f64; 3]),
    seed: u64,
    progress: &dyn MissionProgress,
    mut rendered: Option<&mut RenderedBoulders>,
) -> Result<LocalizedSession, MissionError> {
    let (start, guess) = start_guess;
    let session = SessionConfig {
        duration_s: config.session_seconds()[1],
        start,
        initial_guess: Some(guess),
        ..config.session_2().clone()
    };
    let mut sim =
        SessionSim::with_rendered_boulders(moon, &session, seed, rendered.as_deref_mut())?;
    if config.prior_map_obstacles {
        sim.set_known_rocks_world(known_rocks(prior_map, config));
    }
    let mut localizer = Localizer::new(Some(prior_map.clone()), config.localizer.clone())?;
    let mut pushed = 0;
    while sim.step() {
        let log = sim.log();
        progress.update(MissionStage::Driving {
            session: 2,
            time_s: log.ticks.last().map_or(0.0, |t| t.time_s),
            duration_s: session.duration_s,
        });
        let reoptimized = push_new_frames(&mut localizer, log, &mut pushed)?;
        if let (true, Some(world_from_session)) = (reoptimized, localizer.prior_from_odom()) {
            sim.set_world_from_session_estimate(&world_from_session);
        }
    }
    let log = sim.finish();
    if let Some(e) = rendered.and_then(|r| r.take_error()) {
        return Err(e.into());
    }
    push_new_frames(&mut localizer, &log, &mut pushed)?;
    let result = localizer.finish()?;
    let attempts = scored_attempts(2, &result.attempts, &log, config);
    Ok(LocalizedSession {
        rmse_graph_m: rmse_m(&log, &result.poses),
        rmse_before_adjustment_m: rmse_m(&log, &result.poses_before_adjustment),
        poses: result.poses,
        attempts,
        odometry_bias: result.odometry_bias,
        adjustment: result.adjustment,
        log,
    })
}
