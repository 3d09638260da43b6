//! A session that starts lost: its simulator believes a wrong start pose, and a
//! [`Localizer`] against a prior map (session 1's map for session 2, the site's rock grid
//! for a lost session 1) takes every camera frame; whenever the localizer re-optimises, the
//! planner is told where the session's frame lies in the world. Until the first accepted
//! fix the planner drives on its odometry alone, avoiding only what its cameras see; from
//! then on it also avoids the prior map's well-observed rocks ([`known_rocks`]).

use super::progress::{MissionProgress, MissionStage};
use super::stream::push_new_frames;
use super::{MissionConfig, MissionError};
use crate::localizer::{Localizer, LocalizerConfig, SessionResult};
use crate::sim::session::{PlanarPose, SessionConfig, SessionLog, SessionSim};
use nalgebra::Point2;
use segloc_maps::ObjectMap;

/// The rocks of `prior_map` the planner should know of from its first relocalization on:
/// boulders of known size seen at least `prior_obstacle_min_observations` times, as
/// (centre x, y; radius) in the map's (world) frame. A survey prior (a rock grid, whose
/// landmarks no camera observed) gives none.
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

/// The settings of a lost session: `base` from the true `start`, believing it starts at
/// `guess`, for `duration_s`.
pub fn lost_session_config(
    base: &SessionConfig,
    duration_s: f64,
    start: PlanarPose,
    guess: PlanarPose,
) -> SessionConfig {
    SessionConfig {
        duration_s,
        start,
        initial_guess: Some(guess),
        ..base.clone()
    }
}

/// The localizer of a lost session and the planner's re-anchoring by its fixes.
pub struct LostStart {
    localizer: Localizer,
    pushed: usize,
    session: usize,
}

impl LostStart {
    /// A lost start of session `session` against `prior_map` with the localizer settings
    /// `localizer`; the planner of `sim` is given the map's known rocks when
    /// `prior_map_obstacles` is on.
    pub fn new(
        sim: &mut SessionSim,
        prior_map: &ObjectMap,
        (config, localizer): (&MissionConfig, LocalizerConfig),
        session: usize,
    ) -> Result<Self, MissionError> {
        if config.prior_map_obstacles {
            sim.set_known_rocks_world(known_rocks(prior_map, config));
        }
        Ok(Self {
            localizer: Localizer::new(Some(prior_map.clone()), localizer)?,
            pushed: 0,
            session,
        })
    }

    /// After a step of `sim`: report progress, give the localizer the new frames and, when
    /// it re-optimised with the session placed in the prior map, re-anchor the planner.
    pub fn after_step(
        &mut self,
        sim: &mut SessionSim,
        progress: &dyn MissionProgress,
    ) -> Result<(), MissionError> {
        let log = sim.log();
        progress.update(MissionStage::Driving {
            session: self.session,
            time_s: log.ticks.last().map_or(0.0, |t| t.time_s),
            duration_s: log.config.duration_s,
        });
        let reoptimized = push_new_frames(&mut self.localizer, log, &mut self.pushed)?;
        if let (true, Some(world_from_session)) = (reoptimized, self.localizer.prior_from_odom()) {
            sim.set_world_from_session_estimate(&world_from_session);
        }
        Ok(())
    }

    /// The localizer (its first fix, its current drift correction).
    pub fn localizer(&self) -> &Localizer {
        &self.localizer
    }

    /// The last frames of the finished `log`, and the localizer's final solve.
    pub fn finish(mut self, log: &SessionLog) -> Result<SessionResult, MissionError> {
        push_new_frames(&mut self.localizer, log, &mut self.pushed)?;
        Ok(self.localizer.finish()?)
    }
}
