//! Session 1 started lost against its site's rock grid (`session_1_start =
//! "lost_vs_grid"`): the rover is set down with a seeded wrong guess of its start pose, so
//! its odometry frame is not the site's. The site's ground-truth rock grid (the LAC grid of
//! 0.15 m cells the rocks score is computed against, heights from its height layer) becomes
//! a prior map ([`map_from_rock_cells`]), and the session drives as session 2 does
//! ([`super::lost_start`]): a localizer against that prior takes every frame and its fixes
//! re-anchor the planner, for the whole session.
//!
//! Once the first fix anchors the session, a mapping localizer starts at that frame, fed
//! the frames' odometry poses moved into the world by the anchor (its planar part and
//! height) and their times counted from it: it maps as a session started at a known pose
//! there would (loop closures, lander factors, viewpoint-bias calibration, boulder
//! adjustment), and its map is session 2's prior. The frames before the anchor take the
//! grid localizer's poses. Without any fix the session's map is the grid localizer's.

use super::grid_fit;
use super::lost_start::{lost_session_config, LostStart};
use super::mapping_session::{mapped_session, LostStart1Outcome, MappedSession};
use super::progress::MissionProgress;
use super::stream::{frame_input, scored_attempts};
use super::{MissionConfig, MissionError};
use crate::align::refine::RefineConfig;
use crate::landmarks::from_grid::map_from_rock_cells;
use crate::landmarks::GridRocksConfig;
use crate::localizer::{Localizer, LocalizerConfig, LocalizerError, SessionResult};
use crate::sim::moon::Moon;
use crate::sim::rendered_sensors::RenderedSensors;
use crate::sim::session::{PlanarPose, SessionLog, SessionSim};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use segloc_maps::{LacGrid, ObjectMap};
use serde::{Deserialize, Serialize};

/// Mixed into the mission's seed for session 1's start-guess error ("s1 guess").
const GUESS_STREAM: u64 = 0x7331_2067_7565_7373;

/// How session 1 starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Session1Start {
    /// At `start_1`, known: its odometry frame is the world frame.
    #[default]
    Known,
    /// Lost (a seeded wrong guess), relocalized against the site's ground-truth rock grid.
    LostVsGrid,
}

/// Session 1's lost start (TOML section `[session_1_lost]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LostStart1Config {
    /// Bounds of the seeded error of session 1's start guess [dx, dy, dyaw] (m, m, rad):
    /// each drawn uniformly within ± its bound.
    pub guess_error_max: [f64; 3],
    /// The grid's rock cells as prior landmarks.
    pub grid_rocks: GridRocksConfig,
    /// The grid localizer's consistency tolerance in standard deviations of the landmarks'
    /// covariances (`localizer.relocalize.consistency.sigma_multiplier`, fixed tolerances (0)
    /// against session maps; docs/design/covariance-tolerances.md).
    pub sigma_multiplier: f64,
    /// … and its residual gate in RMS residuals the covariances predict
    /// (`localizer.relocalize.verification.rmse_multiplier`).
    pub rmse_multiplier: f64,
    /// The end's horizontal fit of the session's map onto the grid's rocks (mutual nearest
    /// neighbours, robust least squares; x, y and yaw).
    pub map_fit: RefineConfig,
    /// … used when at least this many rocks pair up (else the fit onto the grid
    /// localizer's poses alone places the session).
    pub map_fit_min_pairs: usize,
    /// The end's height fit uses the ground points within this range of the rover, metres
    /// (0: no height fit; the grid localizer's poses give the height).
    pub height_fit_max_range_m: f64,
    /// … when there are at least this many.
    pub height_fit_min_points: usize,
}

impl Default for LostStart1Config {
    /// Up to 2 m off in x and y and any heading.
    fn default() -> Self {
        Self {
            guess_error_max: [2.0, 2.0, std::f64::consts::PI],
            grid_rocks: GridRocksConfig::default(),
            sigma_multiplier: 2.0,
            rmse_multiplier: 1.0,
            map_fit: RefineConfig {
                gate_m: 0.15,
                // a grid rock's centroid is known to a cell's quantisation (σ 4.3 cm)
                cauchy_scale_m: 0.05,
                inlier_threshold_m: 0.15,
                ..RefineConfig::default()
            },
            map_fit_min_pairs: 20,
            height_fit_max_range_m: 4.0,
            height_fit_min_points: 100,
        }
    }
}

impl LostStart1Config {
    /// Check the values; errors name the TOML path (`session_1_lost.…`).
    pub fn validate(&self) -> Result<(), MissionError> {
        if self
            .guess_error_max
            .iter()
            .any(|v| !(v.is_finite() && *v >= 0.0))
        {
            return Err(MissionError::InvalidConfig(format!(
                "session_1_lost.guess_error_max must be finite and non-negative, got {:?}",
                self.guess_error_max
            )));
        }
        for (name, v, max) in [
            ("sigma_multiplier", self.sigma_multiplier, 10.0),
            ("rmse_multiplier", self.rmse_multiplier, 10.0),
            ("height_fit_max_range_m", self.height_fit_max_range_m, 100.0),
            ("map_fit.gate_m", self.map_fit.gate_m, 10.0),
            ("map_fit.cauchy_scale_m", self.map_fit.cauchy_scale_m, 10.0),
            (
                "map_fit.inlier_threshold_m",
                self.map_fit.inlier_threshold_m,
                10.0,
            ),
        ] {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err(MissionError::InvalidConfig(format!(
                    "session_1_lost.{name} must be within [0, {max}], got {v}"
                )));
            }
        }
        if !(self.map_fit.gate_m > 0.0 && self.map_fit.cauchy_scale_m > 0.0) {
            return Err(MissionError::InvalidConfig(
                "session_1_lost.map_fit.gate_m and cauchy_scale_m must be positive".into(),
            ));
        }
        self.grid_rocks.validate().map_err(|e| {
            let message = match e {
                segloc_maps::MapError::InvalidData { message, .. } => message,
                other => other.to_string(),
            };
            MissionError::InvalidConfig(format!("session_1_lost.{message}"))
        })
    }

    /// The grid localizer's settings: `localizer` with the covariance-driven tolerances.
    pub fn localizer(&self, localizer: &LocalizerConfig) -> LocalizerConfig {
        let mut grid = localizer.clone();
        grid.relocalize.consistency.sigma_multiplier = self.sigma_multiplier;
        grid.relocalize.verification.rmse_multiplier = self.rmse_multiplier;
        grid
    }

    /// Session 1's start guess for the mission of `seed`: `start` moved by an error drawn
    /// from the seed within `guess_error_max`.
    pub fn guess(&self, start: PlanarPose, seed: u64) -> PlanarPose {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ GUESS_STREAM);
        let mut guess = start;
        for (g, bound) in guess.iter_mut().zip(self.guess_error_max) {
            if bound > 0.0 {
                *g += rng.random_range(-bound..bound);
            }
        }
        guess
    }
}

/// The site's rock grid as session 1's prior map (world frame).
pub fn grid_prior(site: &LacGrid, config: &LostStart1Config) -> Result<ObjectMap, MissionError> {
    map_from_rock_cells(site, &config.grid_rocks, "site rock grid").map_err(MissionError::GridPrior)
}

/// The planar part (x, y, yaw) and height of `pose`: the anchor of a gravity-aligned frame.
fn anchor(pose: &Isometry3<f64>) -> Isometry3<f64> {
    let (_, _, yaw) = pose.rotation.euler_angles();
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
    )
}

/// Session 1's mapping localizer once anchored (see the module docs).
struct AnchoredMapping {
    localizer: Localizer,
    /// The log frame the localizer's frame 0 is.
    first_frame: usize,
    /// Session time of that frame, seconds.
    t0: f64,
    world_from_odom: Isometry3<f64>,
    pushed: usize,
}

impl AnchoredMapping {
    fn new(
        log: &SessionLog,
        first_frame: usize,
        world_from_odom: &Isometry3<f64>,
        config: &MissionConfig,
    ) -> Result<Self, LocalizerError> {
        Ok(Self {
            localizer: Localizer::new(None, config.localizer.clone())?,
            first_frame,
            t0: log.frames.get(first_frame).map_or(0.0, |f| f.time_s),
            world_from_odom: anchor(world_from_odom),
            pushed: 0,
        })
    }

    /// Give the localizer the frames of `log` it has not had, moved into the world.
    fn push_new(&mut self, log: &SessionLog) -> Result<(), LocalizerError> {
        while let Some(mut frame) = frame_input(log, self.first_frame + self.pushed, false) {
            frame.odom_from_rover = self.world_from_odom * frame.odom_from_rover;
            frame.t -= self.t0;
            if self.pushed == 0 {
                frame.path = None;
            }
            self.localizer.push_frame(&frame)?;
            self.pushed += 1;
        }
        Ok(())
    }
}

/// Run session 1 from the true `start`, lost (see the module docs).
pub fn grid_start_session_with(
    moon: &Moon,
    config: &MissionConfig,
    start: PlanarPose,
    seeds: (u64, u64),
    progress: &dyn MissionProgress,
    mut rendered: Option<&mut RenderedSensors>,
) -> Result<MappedSession, MissionError> {
    let (mission_seed, seed) = seeds;
    let site = moon.ground_truth_grid();
    let prior = grid_prior(&site, &config.session_1_lost)?;
    let guess = config.session_1_lost.guess(start, mission_seed);
    let session = lost_session_config(&config.session, config.seconds_per_session, start, guess);
    let mut sim = SessionSim::with_rendered_sensors(moon, &session, seed, rendered.as_deref_mut())?;
    let grid_localizer = config.session_1_lost.localizer(&config.localizer);
    let mut lost = LostStart::new(&mut sim, &prior, (config, grid_localizer), 1)?;
    let mut mapping: Option<AnchoredMapping> = None;
    while sim.step() {
        lost.after_step(&mut sim, progress)?;
        if mapping.is_none() {
            let l = lost.localizer();
            if let (Some(first), Some(w)) = (l.first_fix_frame(), l.prior_from_odom()) {
                mapping = Some(AnchoredMapping::new(sim.log(), first, &w, config)?);
            }
        }
        if let Some(m) = mapping.as_mut() {
            m.push_new(sim.log())?;
        }
    }
    let log = sim.finish();
    if let Some(e) = rendered.and_then(|r| r.boulders.take_error()) {
        return Err(e.into());
    }
    let grid = lost.finish(&log)?;
    let outcome = LostStart1Outcome {
        attempts: scored_attempts(1, &grid.attempts, &log, config),
        first_fix_frame: grid.first_fix_frame,
        prior_landmarks: prior.len(),
        map_fit_pairs: None,
        height_fit_points: None,
    };
    match mapping {
        Some(m) => finish_anchored(m, (log, &site, &prior), grid, outcome, config),
        None => Ok(unanchored(log, grid, outcome, config)),
    }
}

/// The mapping localizer's session, its frames before the anchor placed by the grid's.
fn finish_anchored(
    mut mapping: AnchoredMapping,
    (log, site, prior): (SessionLog, &LacGrid, &ObjectMap),
    grid: SessionResult,
    mut outcome: LostStart1Outcome,
    config: &MissionConfig,
) -> Result<MappedSession, MissionError> {
    mapping.push_new(&log)?;
    let (first, t0) = (mapping.first_frame, mapping.t0);
    let mut result = mapping.localizer.finish()?;
    // the mapping localizer's frame k is the log's frame first + k
    let tail = SessionLog {
        frames: log.frames.get(first..).unwrap_or_default().to_vec(),
        ..log.clone()
    };
    let mut closures = scored_attempts(1, &result.attempts, &tail, config);
    for a in &mut closures {
        a.time_s += t0;
    }
    let fit = grid_fit::world_from_anchor(
        (site, prior),
        &tail,
        (&grid.poses, &result.poses),
        first,
        &result.map,
        &config.session_1_lost,
    );
    outcome.map_fit_pairs = fit.map_fit_pairs;
    outcome.height_fit_points = fit.height_points;
    let world_from_anchor = fit.world_from_anchor;
    // the frames before the anchor keep the grid localizer's poses, their height from the
    // grid's height layer too
    let lost = &config.session_1_lost;
    let dz_before = grid_fit::height_fit(site, &log, &grid.poses, &Isometry3::identity(), lost)
        .map_or(0.0, |(dz, _)| dz);
    let before = |poses: &[Isometry3<f64>]| -> Vec<Isometry3<f64>> {
        let mut before = poses.get(..first).unwrap_or_default().to_vec();
        for p in &mut before {
            p.translation.vector.z += dz_before;
        }
        before
    };
    let mut poses = before(&grid.poses);
    poses.extend(result.poses.iter().map(|p| world_from_anchor * p));
    let mut poses_before_adjustment = before(&grid.poses_before_adjustment);
    poses_before_adjustment.extend(
        result
            .poses_before_adjustment
            .iter()
            .map(|p| world_from_anchor * p),
    );
    result.poses = poses;
    result.poses_before_adjustment = poses_before_adjustment;
    let frame = result.map.frame.clone();
    result.map = result.map.transformed(&world_from_anchor, &frame);
    Ok(mapped_session(log, result, closures, Some(outcome), config))
}

/// A session the grid never placed: the grid localizer's poses and map.
fn unanchored(
    log: SessionLog,
    grid: SessionResult,
    outcome: LostStart1Outcome,
    config: &MissionConfig,
) -> MappedSession {
    mapped_session(log, grid, Vec::new(), Some(outcome), config)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_guess_is_seeded_and_bounded() {
        let c = LostStart1Config::default();
        let start = [4.5, 0.0, 1.0];
        let a = c.guess(start, 3);
        assert_eq!(a, c.guess(start, 3));
        assert_ne!(a, c.guess(start, 4));
        for (k, bound) in c.guess_error_max.iter().enumerate() {
            assert!((a[k] - start[k]).abs() <= *bound);
        }
        let none = LostStart1Config {
            guess_error_max: [0.0; 3],
            ..c
        };
        assert_eq!(none.guess(start, 3), start);
    }

    #[test]
    fn bad_values_name_their_toml_path() {
        let mut c = LostStart1Config::default();
        c.guess_error_max[2] = -1.0;
        let err = c.validate().unwrap_err().to_string();
        assert!(err.contains("session_1_lost.guess_error_max"), "{err}");
        let mut c = LostStart1Config::default();
        c.grid_rocks.min_cells = 0;
        let err = c.validate().unwrap_err().to_string();
        assert!(err.contains("session_1_lost.grid_rocks.min_cells"), "{err}");
    }
}
