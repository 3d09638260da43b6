//! The two-session mission (issue 4): session 1 maps the site from a known start, session 2
//! starts lost and finds itself from the boulders, and the LAC height and rock maps are
//! built from the optimised poses of both and scored against the synthetic moon's truth.
//!
//! Stages, one file each:
//! - [`mapping_session`]: session 1 — drive from a known start, every camera frame fed to a
//!   mapping [`crate::localizer::Localizer`] (loop closures, boulder adjustment), whose map
//!   is the prior of session 2;
//! - [`grid_start`]: session 1 started lost instead (`session_1_start = "lost_vs_grid"`),
//!   relocalizing against the site's rock grid until anchored, then mapping as above;
//! - [`lost_start`]: the lost start both of those lost sessions share (a localizer against
//!   a prior map whose fixes re-anchor the planner);
//! - [`lost_session`]: session 2 — drive with a wrong start guess, every camera frame fed to
//!   a [`crate::localizer::Localizer`] against session 1's map, whose corrections tell the
//!   planner where it is;
//! - [`stream`]: a simulated session as the localizer's frames, and the truth that scores
//!   the localizer's output;
//! - [`terrain_height`]: the trajectories' heights aligned on the ground both sessions saw;
//! - [`maps`]: height and rock maps, LAC score;
//! - [`report`]: the JSON report and the pictures;
//! - [`trace`]: the mission frame by frame for playback, and with the cargo feature
//!   `rerun`, `recording`: a `.rrd` recording of it for the Rerun viewer;
//! - [`progress`]: where a running mission is, for a progress display.
//!
//! ```no_run
//! use segloc::mission::{run_mission, MissionConfig};
//! let report = run_mission(7, &MissionConfig::default()).unwrap();
//! println!("{}", serde_json::to_string(&report.report).unwrap());
//! ```

mod config_file;
pub mod grid_fit;
pub mod grid_start;
pub mod lost_session;
pub mod lost_start;
pub mod mapping_session;
pub mod maps;
pub mod perception;
pub mod progress;
#[cfg(feature = "rerun")]
pub mod recording;
pub mod report;
pub mod stream;
pub mod terrain_height;
pub mod trace;

use crate::graph::GraphError;
use crate::localizer::{LocalizerConfig, LocalizerError};
use crate::mapping::{RockGridConfig, ScoreError};
use crate::perception::Segmenter;
use crate::sim::moon::{Moon, MoonConfig, MoonError};
use crate::sim::rendered_boulders::PerceptionSummary;
use crate::sim::session::{SessionConfig, SessionError};
use serde::{Deserialize, Serialize};
use std::time::Instant;

pub use progress::{MissionProgress, MissionStage, Silent};
pub use report::{
    Attempt, LostStartReport, MissionOutput, MissionReport, RelocalizationCounts, SessionReport,
};
pub use trace::MissionTrace;

/// Errors running a mission.
#[derive(Debug, thiserror::Error)]
pub enum MissionError {
    /// A configuration value is out of range.
    #[error("invalid mission configuration: {0}")]
    InvalidConfig(String),
    /// The moon could not be generated.
    #[error(transparent)]
    Moon(#[from] MoonError),
    /// A session could not start.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// The pose graph failed.
    #[error("pose graph: {0}")]
    Graph(#[from] GraphError),
    /// The localizer failed.
    #[error(transparent)]
    Localizer(#[from] LocalizerError),
    /// The maps could not be scored.
    #[error(transparent)]
    Score(#[from] ScoreError),
    /// The renderer of `perception.sensors = "rendered"` could not be built.
    #[error(transparent)]
    Render(#[from] crate::sim::render::RenderError),
    /// The site's rock grid could not be made a prior map (`session_1_start =
    /// "lost_vs_grid"`).
    #[error("the site's rock grid as session 1's prior: {0}")]
    GridPrior(segloc_maps::MapError),
    /// The perception front end failed.
    #[error("perception: {0}")]
    Perception(#[from] crate::perception::PerceptionError),
}

/// Parameters of a mission.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MissionConfig {
    /// Simulated seconds per session.
    pub seconds_per_session: f64,
    /// The synthetic moon.
    pub moon: MoonConfig,
    /// Session parameters (start and duration are set by the mission).
    pub session: SessionConfig,
    /// Session 2's parameters when they differ from session 1's (`None`: the same).
    pub session_2: Option<SessionConfig>,
    /// Session 2's simulated seconds when they differ from session 1's (`None`: the same).
    pub seconds_session_2: Option<f64>,
    /// Session 1's start, world frame [x, y, yaw] (moved to the nearest clear ground).
    pub start_1: [f64; 3],
    /// Session 2's true start, world frame [x, y, yaw] (moved to the nearest clear ground).
    pub start_2: [f64; 3],
    /// Error of session 2's start guess [dx, dy, dyaw] (m, m, rad).
    pub guess_error_2: [f64; 3],
    /// How session 1 starts: `"known"` (at `start_1`, its odometry frame the world's) or
    /// `"lost_vs_grid"` (a seeded wrong guess, relocalized against the site's rock grid).
    pub session_1_start: grid_start::Session1Start,
    /// Session 1's lost start (with `session_1_start = "lost_vs_grid"`).
    pub session_1_lost: grid_start::LostStart1Config,
    /// Session 2's planner avoids the rocks of session 1's map from its first accepted
    /// relocalization on, placed with its latest estimate of where it is, whether or not
    /// its own cameras see them (a rock hidden behind a crest and then below the image is
    /// still known).
    pub prior_map_obstacles: bool,
    /// … rocks of session 1's map seen at least this many times.
    pub prior_obstacle_min_observations: u32,
    /// An accepted relocalization off by more than this (m) counts as wrong.
    pub wrong_translation_m: f64,
    /// An accepted relocalization off by more than this (degrees) counts as wrong.
    pub wrong_rotation_deg: f64,
    /// Rock map from fused boulders.
    pub rock_grid: RockGridConfig,
    /// Terrain-relative height alignment of both sessions' poses before the maps.
    pub terrain_height: terrain_height::TerrainHeightConfig,
    /// Both sessions' localizers (session 2's fusion takes session 1's calibrated
    /// viewpoint bias). Default: the library's, with the odometry calibration's priors set
    /// to the simulated odometry's drift; a `[localizer]` table in a partial TOML file
    /// starts from the library's own defaults (print the whole config to keep them).
    pub localizer: LocalizerConfig,
    /// Where the boulder detections come from (sensor model or rendered images).
    pub perception: perception::PerceptionConfig,
}

impl Default for MissionConfig {
    /// Session 1 maps the site on the LAC coverage loops for 600 s; session 2 drives loops
    /// from 9.5 m out ([`WaypointConfig::outer_loops`]) for 300 s, the ground session 1
    /// rarely reaches (the trade-off against its accuracy: docs/how-it-works.md, "Known
    /// limits").
    ///
    /// [`WaypointConfig::outer_loops`]: crate::planning::waypoints::WaypointConfig::outer_loops
    fn default() -> Self {
        Self {
            seconds_per_session: 600.0,
            moon: MoonConfig::default(),
            session: coverage_session(),
            session_2: Some(outer_loops_session()),
            seconds_session_2: Some(300.0),
            start_1: [4.5, 0.0, std::f64::consts::FRAC_PI_2],
            start_2: [-4.5, 0.0, -std::f64::consts::FRAC_PI_2],
            guess_error_2: [0.8, -0.6, 0.25],
            session_1_start: grid_start::Session1Start::Known,
            session_1_lost: grid_start::LostStart1Config::default(),
            prior_map_obstacles: true,
            prior_obstacle_min_observations: 3,
            wrong_translation_m: 0.10,
            wrong_rotation_deg: 1.0,
            rock_grid: RockGridConfig::default(),
            terrain_height: terrain_height::TerrainHeightConfig::default(),
            localizer: localizer_for(&coverage_session().vo),
            perception: perception::PerceptionConfig::default(),
        }
    }
}

/// The localizer's defaults with the odometry calibration's priors set to the simulated
/// odometry's own errors (its 1 σ scale error, yaw drift per metre and yaw-rate scale
/// error): the mission knows the
/// statistics of its sensor, where the library's defaults are loose enough for an unknown
/// one (docs/design/odometry-bias-prior.md).
fn localizer_for(odometry: &crate::sim::visual_odometry::VoConfig) -> LocalizerConfig {
    let mut localizer = LocalizerConfig::default();
    localizer.calibration.prior_scale = odometry.scale_error_sigma;
    localizer.calibration.prior_yaw_drift_rad_per_m = odometry.yaw_drift_sigma_rad_per_m;
    localizer.calibration.prior_yaw_scale = odometry.yaw_scale_error_sigma;
    // with priors as tight as the sensor's, the plain alternation is as good: accelerated,
    // seeds 1-20 moved within noise both ways (docs/design/odometry-bias-prior.md)
    localizer.calibration.rounds = 2;
    localizer.calibration.anderson_depth = 0;
    localizer
}

impl MissionConfig {
    /// Both sessions on the LAC coverage loops (around the lander, then at 8 m and 12.5 m)
    /// at 0.45 m/s for 600 s each: session 2 re-drives session 1's loops for twice as long
    /// as the default's 300 s on the outer ones.
    pub fn lac_coverage() -> Self {
        MissionConfig {
            session_2: None,
            seconds_session_2: None,
            ..MissionConfig::default()
        }
    }

    /// The mission before the coverage loops became the default: both sessions 300 s on the
    /// spiral around the lander (the default before 2026-11-24; docs/experiments.md).
    pub fn spiral_only() -> Self {
        MissionConfig {
            seconds_per_session: 300.0,
            session: SessionConfig::default(),
            session_2: None,
            seconds_session_2: None,
            ..MissionConfig::default()
        }
    }
}

/// Session settings of [`MissionConfig::lac_coverage`].
fn coverage_session() -> SessionConfig {
    let mut session = SessionConfig {
        waypoints: crate::planning::waypoints::WaypointConfig::lac_coverage(),
        ..spiral_session()
    };
    session.navigator.arcs.speed_mps = 0.45;
    session
}

/// Shortest arc horizon of the mission's planner (seconds, see
/// [`crate::planning::arc_planner::ArcPlannerConfig::min_horizon_s`]).
const MISSION_MIN_ARC_HORIZON_S: f64 = 2.0;

/// Session settings of session 2 by default: loops from 9.5 m out, outside the ring
/// session 1 covers best.
fn outer_loops_session() -> SessionConfig {
    let mut session = spiral_session();
    session.waypoints = crate::planning::waypoints::WaypointConfig::outer_loops();
    session
}

/// Session settings on the spiral around the lander (session 2 before the outer loops).
fn spiral_session() -> SessionConfig {
    let mut session = SessionConfig::default();
    session.navigator.arcs.min_horizon_s = MISSION_MIN_ARC_HORIZON_S;
    session
}

impl MissionConfig {
    /// Simulated seconds of session 1 and session 2.
    pub fn session_seconds(&self) -> [f64; 2] {
        [
            self.seconds_per_session,
            self.seconds_session_2.unwrap_or(self.seconds_per_session),
        ]
    }

    /// Session 2's parameters.
    pub fn session_2(&self) -> &SessionConfig {
        self.session_2.as_ref().unwrap_or(&self.session)
    }

    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), MissionError> {
        let bad = |m: &str| Err(MissionError::InvalidConfig(m.to_string()));
        if self
            .session_seconds()
            .iter()
            .any(|s| !(s.is_finite() && *s > 0.0 && *s <= 1e5))
        {
            return bad("seconds_per_session and seconds_session_2 must be within (0, 1e5]");
        }
        if let Err(e) = self.localizer.validate() {
            return bad(&format!("localizer.{e}"));
        }
        if [self.wrong_translation_m, self.wrong_rotation_deg]
            .iter()
            .any(|v| !(v.is_finite() && *v > 0.0))
        {
            return bad("wrong_translation_m and wrong_rotation_deg must be positive");
        }
        let all = self
            .start_1
            .iter()
            .chain(&self.start_2)
            .chain(&self.guess_error_2);
        if all.clone().any(|v| !v.is_finite()) {
            return bad("starts and guess error must be finite");
        }
        self.session_1_lost.validate()?;
        for (name, session) in [("session", &self.session), ("session_2", self.session_2())] {
            if let Err(e) = session.validate() {
                return bad(&format!("{name}: {e}"));
            }
        }
        self.perception.validate()
    }
}

/// The two sessions of a mission, driven.
pub struct Sessions {
    /// The synthetic moon.
    pub moon: Moon,
    /// The configuration with session 1's calibrated fusion (what session 2 ran with).
    pub config: MissionConfig,
    /// Session 1: mapped from a known start.
    pub one: mapping_session::MappedSession,
    /// Session 2: localized against session 1's map.
    pub two: lost_session::LocalizedSession,
    /// How the front end did on both sessions' rendered frames (`None`: the sensor model).
    pub perception: Option<PerceptionSummary>,
}

/// Drive both sessions of the mission on the moon of `seed` (no maps, no score).
pub fn drive_sessions(
    seed: u64,
    config: &MissionConfig,
    progress: &dyn MissionProgress,
) -> Result<Sessions, MissionError> {
    drive_sessions_with(seed, config, progress, None)
}

/// [`drive_sessions`] with the segmenter of `perception.sensors = "rendered"` (default: the
/// geometric one).
pub fn drive_sessions_with(
    seed: u64,
    config: &MissionConfig,
    progress: &dyn MissionProgress,
    segmenter: Option<Box<dyn Segmenter>>,
) -> Result<Sessions, MissionError> {
    config.validate()?;
    let moon = Moon::generate(&config.moon, seed)?;
    let mut rendered = config.perception.rendered_sensors(&moon, seed, segmenter)?;
    let clear = |s: [f64; 3], session: &SessionConfig| {
        let min_rock = session.collision_min_rock_radius_m;
        let (x, y) = moon.nearest_clear_position(s[0], s[1], 1.0, min_rock);
        [x, y, s[2]]
    };
    let start_1 = clear(config.start_1, &config.session);
    let start_2 = clear(config.start_2, config.session_2());
    let e = config.guess_error_2;
    let guess_2 = [start_2[0] + e[0], start_2[1] + e[1], start_2[2] + e[2]];
    let one = match config.session_1_start {
        grid_start::Session1Start::Known => mapping_session::map_session_with(
            &moon,
            config,
            start_1,
            seed.wrapping_mul(2),
            progress,
            rendered.as_mut(),
        )?,
        grid_start::Session1Start::LostVsGrid => grid_start::grid_start_session_with(
            &moon,
            config,
            start_1,
            (seed, seed.wrapping_mul(2)),
            progress,
            rendered.as_mut(),
        )?,
    };
    // session 2 and the maps fuse boulders with session 1's calibrated viewpoint bias
    let config = one.calibrated(config);
    let two = lost_session::localize_session_with(
        &moon,
        &config,
        &one.map,
        (start_2, guess_2),
        seed.wrapping_mul(2).wrapping_add(1),
        progress,
        rendered.as_mut(),
    )?;
    Ok(Sessions {
        moon,
        config,
        one,
        two,
        perception: rendered.map(|r| r.boulders.summary()),
    })
}

/// Run the two-session mission on the moon of `seed`.
pub fn run_mission(seed: u64, config: &MissionConfig) -> Result<MissionOutput, MissionError> {
    run_mission_with_progress(seed, config, &Silent)
}

/// [`run_mission`], telling `progress` where it is.
pub fn run_mission_with_progress(
    seed: u64,
    config: &MissionConfig,
    progress: &dyn MissionProgress,
) -> Result<MissionOutput, MissionError> {
    run_mission_with(seed, config, progress, None)
}

/// [`run_mission_with_progress`] with the segmenter of `perception.sensors = "rendered"`
/// (default: the geometric one).
pub fn run_mission_with(
    seed: u64,
    config: &MissionConfig,
    progress: &dyn MissionProgress,
    segmenter: Option<Box<dyn Segmenter>>,
) -> Result<MissionOutput, MissionError> {
    let started = Instant::now();
    let Sessions {
        moon,
        config,
        one: mut session_1,
        two: mut session_2,
        perception,
    } = drive_sessions_with(seed, config, progress, segmenter)?;
    let config = &config;
    progress.update(MissionStage::Mapping);
    let dz = terrain_height::height_corrections(
        &[
            (&session_1.log, &session_1.poses),
            (&session_2.log, &session_2.poses),
        ],
        &config.terrain_height,
    );
    if let [dz_1, dz_2] = dz.as_slice() {
        session_1.poses = terrain_height::apply(&session_1.poses, dz_1);
        session_2.poses = terrain_height::apply(&session_2.poses, dz_2);
    }

    let truth = moon.ground_truth_grid();
    let mission_seconds = config.session_seconds().iter().sum();
    let maps = maps::build_maps(
        &[
            (&session_1.log, &session_1.poses),
            (&session_2.log, &session_2.poses),
        ],
        &truth,
        mission_seconds,
        config,
    )?;
    let wall_s = started.elapsed().as_secs_f64();
    let mut output = report::assemble(seed, config, &session_1, &session_2, maps, truth, wall_s);
    output.report.perception = perception;
    output.trace = MissionTrace::collect(
        &moon,
        &session_1.map,
        &[
            (&session_1.log, &session_1.poses),
            (&session_2.log, &session_2.poses),
        ],
    );
    Ok(output)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_is_valid_and_round_trips_through_toml() {
        let c = MissionConfig::default();
        c.validate().unwrap();
        let text = toml::to_string(&c).unwrap();
        let back: MissionConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, c);
        let partial: MissionConfig = toml::from_str("seconds_per_session = 60.0").unwrap();
        assert_eq!(partial.seconds_per_session, 60.0);
    }

    #[test]
    fn the_calibration_priors_are_the_simulated_odometrys_drift() {
        let c = MissionConfig::default();
        let odometry = crate::sim::visual_odometry::VoConfig::default();
        assert_eq!(
            c.localizer.calibration.prior_scale,
            odometry.scale_error_sigma
        );
        assert_eq!(
            c.localizer.calibration.prior_yaw_drift_rad_per_m,
            odometry.yaw_drift_sigma_rad_per_m
        );
    }

    #[test]
    fn rejects_bad_config() {
        let mut bad_localizer = MissionConfig::default();
        bad_localizer.localizer.schedule.relocalize_period_s = 0.0;
        let mut bad_robust = MissionConfig::default();
        bad_robust.localizer.factors.robust_scale = -1.0;
        let mut bad_submap = MissionConfig::default();
        bad_submap.localizer.submap.pose_sigma_m = -0.1;
        let mut bad_fusion = MissionConfig::default();
        bad_fusion.localizer.fusion.pose_sigma_m = f64::NAN;
        let mut bad_lost_start = MissionConfig::default();
        bad_lost_start.session_1_lost.guess_error_max = [1.0, f64::NAN, 0.0];
        for bad in [
            MissionConfig {
                seconds_per_session: f64::NAN,
                ..MissionConfig::default()
            },
            bad_localizer,
            bad_robust,
            MissionConfig {
                guess_error_2: [f64::INFINITY, 0.0, 0.0],
                ..MissionConfig::default()
            },
            bad_submap,
            bad_fusion,
            bad_lost_start,
        ] {
            assert!(matches!(
                run_mission(1, &bad),
                Err(MissionError::InvalidConfig(_))
            ));
        }
    }
}
