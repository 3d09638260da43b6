//! Session 1: start at a known pose, drive, and build the boulder map every later session
//! relocalizes against (in the optimised session frame, which is the world frame up to
//! drift since the start is known).

use super::progress::{MissionProgress, MissionStage};
use super::stream::{push_new_frames, rmse_m, scored_attempts};
use super::{Attempt, MissionConfig, MissionError};
use crate::landmarks::FusionConfig;
use crate::localizer::boulder_adjustment::BoulderAdjustmentReport;
use crate::localizer::odometry_bias::OdometryBias;
use crate::localizer::view_bias::ViewBiasCalibration;
use crate::localizer::{Localizer, SessionResult};
use crate::sim::moon::Moon;
use crate::sim::rendered_sensors::RenderedSensors;
use crate::sim::session::{SessionConfig, SessionLog, SessionSim};
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
    /// The odometry's biases as estimated at the end of the session.
    pub odometry_bias: OdometryBias,
    /// Position RMSE of the pose graph's poses (before the mission's terrain height
    /// alignment changes `poses`), metres.
    pub rmse_graph_m: f64,
    /// What the boulder adjustment did (`None`: off).
    pub adjustment: Option<BoulderAdjustmentReport>,
    /// Position RMSE of the pose graph's poses before the boulder adjustment, metres.
    pub rmse_before_adjustment_m: f64,
    /// The viewpoint-bias calibration at the end of the session from its short passes.
    pub view_bias: ViewBiasCalibration,
    /// The viewpoint-bias size fraction the boulder adjustment estimated from every pass,
    /// if it did: the map was fused with it (else with `view_bias`'s), and later sessions
    /// and the maps use it too.
    pub adjusted_view_bias: Option<f64>,
    /// How a lost start against the site's rock grid went (`None`: a known start).
    pub lost_start: Option<LostStart1Outcome>,
}

/// How session 1's lost start against the site's rock grid went
/// ([`super::grid_start`]).
pub struct LostStart1Outcome {
    /// The relocalizations against the grid, scored.
    pub attempts: Vec<Attempt>,
    /// The frame at which the grid first placed the session (`None`: never).
    pub first_fix_frame: Option<usize>,
    /// Landmarks of the grid's prior map.
    pub prior_landmarks: usize,
    /// Rocks of the session's map paired with the grid's by the end's horizontal fit
    /// (`None`: no fit; fewer than `session_1_lost.map_fit_min_pairs`: not applied).
    pub map_fit_pairs: Option<usize>,
    /// Ground points behind the end's height fit onto the grid's heights (`None`: none).
    pub height_fit_points: Option<usize>,
}

impl MappedSession {
    /// `config` with this session's calibrated fusion parameters, for the sessions and
    /// maps that follow.
    pub fn calibrated(&self, config: &MissionConfig) -> MissionConfig {
        let fusion = self.view_bias.fusion(&config.localizer.fusion);
        let mut calibrated = config.clone();
        calibrated.localizer.fusion = FusionConfig {
            view_bias_size_fraction: self
                .adjusted_view_bias
                .unwrap_or(fusion.view_bias_size_fraction),
            ..fusion
        };
        calibrated
    }
}

/// Run session 1 from `start` for the mission's duration, feeding every camera frame to a
/// mapping [`Localizer`] (with online loop closures, its corrections re-anchor the planner),
/// and build its map.
pub fn map_session(
    moon: &Moon,
    config: &MissionConfig,
    start: [f64; 3],
    seed: u64,
    progress: &dyn MissionProgress,
) -> Result<MappedSession, MissionError> {
    map_session_with(moon, config, start, seed, progress, None)
}

/// [`map_session`], the boulders detected on rendered images by `rendered` when given.
pub fn map_session_with(
    moon: &Moon,
    config: &MissionConfig,
    start: [f64; 3],
    seed: u64,
    progress: &dyn MissionProgress,
    mut rendered: Option<&mut RenderedSensors>,
) -> Result<MappedSession, MissionError> {
    let session = SessionConfig {
        duration_s: config.seconds_per_session,
        start,
        initial_guess: None,
        ..config.session.clone()
    };
    let mut sim = SessionSim::with_rendered_sensors(moon, &session, seed, rendered.as_deref_mut())?;
    let mut localizer = Localizer::new(None, config.localizer.clone())?;
    let mut pushed = 0;
    while sim.step() {
        progress.update(MissionStage::Driving {
            session: 1,
            time_s: sim.log().ticks.last().map_or(0.0, |t| t.time_s),
            duration_s: session.duration_s,
        });
        let reoptimized = push_new_frames(&mut localizer, sim.log(), &mut pushed)?;
        if let (true, Some(planner_from_session)) = (reoptimized, localizer.online_corrections()) {
            sim.reanchor_planner(&planner_from_session);
        }
    }
    let log = sim.finish();
    if let Some(e) = rendered.and_then(|r| r.boulders.take_error()) {
        return Err(e.into());
    }
    push_new_frames(&mut localizer, &log, &mut pushed)?;
    let result = localizer.finish()?;
    let attempts = scored_attempts(1, &result.attempts, &log, config);
    Ok(mapped_session(log, result, attempts, None, config))
}

/// Session 1's figures from its localizer's `result` (poses one per frame of `log`) and
/// its scored `attempts`.
pub(super) fn mapped_session(
    log: SessionLog,
    result: SessionResult,
    attempts: Vec<Attempt>,
    lost_start: Option<LostStart1Outcome>,
    config: &MissionConfig,
) -> MappedSession {
    MappedSession {
        rmse_graph_m: rmse_m(&log, &result.poses),
        rmse_before_adjustment_m: rmse_m(&log, &result.poses_before_adjustment),
        poses: result.poses,
        map: result.map,
        attempts,
        odometry_bias: result.odometry_bias,
        adjustment: result.adjustment,
        view_bias: result
            .view_bias
            .unwrap_or_else(|| ViewBiasCalibration::new(&config.localizer.view_bias)),
        adjusted_view_bias: result.adjusted_view_bias,
        lost_start,
        log,
    }
}
