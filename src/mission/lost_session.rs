//! Session 2: start somewhere else with a wrong guess of the start pose and drive, feeding
//! every camera frame to a [`crate::localizer::Localizer`] against session 1's map; whenever
//! the localizer re-optimises, tell the planner where the session's frame lies in the world
//! (the lost start of [`super::lost_start`]).

use super::lost_start::{lost_session_config, LostStart};
use super::progress::MissionProgress;
use super::stream::{rmse_m, scored_attempts};
use super::{Attempt, MissionConfig, MissionError};
use crate::localizer::boulder_adjustment::BoulderAdjustmentReport;
use crate::localizer::odometry_bias::OdometryBias;
use crate::sim::moon::Moon;
use crate::sim::rendered_sensors::RenderedSensors;
use crate::sim::session::{SessionLog, SessionSim};
use nalgebra::Isometry3;
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
    /// The frame at which the session was first placed in the prior map (`None`: never).
    pub first_fix_frame: Option<usize>,
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
    mut rendered: Option<&mut RenderedSensors>,
) -> Result<LocalizedSession, MissionError> {
    let (start, guess) = start_guess;
    let duration_s = config.session_seconds()[1];
    let session = lost_session_config(config.session_2(), duration_s, start, guess);
    let mut sim = SessionSim::with_rendered_sensors(moon, &session, seed, rendered.as_deref_mut())?;
    let mut lost = LostStart::new(&mut sim, prior_map, (config, config.localizer.clone()), 2)?;
    while sim.step() {
        lost.after_step(&mut sim, progress)?;
    }
    let log = sim.finish();
    if let Some(e) = rendered.and_then(|r| r.boulders.take_error()) {
        return Err(e.into());
    }
    let result = lost.finish(&log)?;
    let attempts = scored_attempts(2, &result.attempts, &log, config);
    Ok(LocalizedSession {
        rmse_graph_m: rmse_m(&log, &result.poses),
        rmse_before_adjustment_m: rmse_m(&log, &result.poses_before_adjustment),
        poses: result.poses,
        attempts,
        odometry_bias: result.odometry_bias,
        adjustment: result.adjustment,
        first_fix_frame: result.first_fix_frame,
        log,
    })
}
