//! The parameters of one simulated session ([`SessionConfig`]) and the error of a bad one.

use crate::planning::navigator::NavigatorConfig;
use crate::planning::obstacles::ObstacleConfig;
use crate::planning::waypoints::WaypointConfig;
use crate::sim::ipex::{footprint_radius_m, SITE_HALF_EXTENT_M};
use crate::sim::rover::RoverConfig;
use crate::sim::sensors::SensorConfig;
use crate::sim::visual_odometry::VoConfig;
use serde::{Deserialize, Serialize};

/// Errors starting a session.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SessionError {
    /// A configuration value is out of range.
    #[error("invalid session configuration: {0}")]
    InvalidConfig(String),
}

/// A planar pose in the world (or nav) frame: x, y (metres) and yaw (radians).
pub type PlanarPose = [f64; 3];

/// Parameters of one session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SessionConfig {
    /// Simulated duration, seconds.
    pub duration_s: f64,
    /// True start pose, world frame: [x, y, yaw].
    pub start: PlanarPose,
    /// What the rover believes its start pose is (nav frame); `None`: the truth.
    pub initial_guess: Option<PlanarPose>,
    /// Camera frames (detections, ground points) every this many ticks (20 = 1 Hz).
    pub frame_period_ticks: usize,
    /// A collision is logged when a rock's edge or the lander comes within this distance of
    /// the rover's centre, metres (default: the footprint's circumscribed radius, ≈ 0.47 m).
    pub collision_radius_m: f64,
    /// Only rocks at least this large count as collisions: the rock's size as a radius
    /// (the mean radius of its footprint, [`crate::sim::moon::Moon::rock_size_radius_m`]),
    /// metres; contact is with the footprint itself.
    pub collision_min_rock_radius_m: f64,
    /// Drive limits.
    pub rover: RoverConfig,
    /// Cameras.
    pub sensors: SensorConfig,
    /// Odometry errors.
    pub vo: VoConfig,
    /// Navigator and arc planner.
    pub navigator: NavigatorConfig,
    /// Which detected rocks are obstacles.
    pub obstacles: ObstacleConfig,
    /// Ground counts as seen (for the planner) within this distance of a stereo ground
    /// point, metres: only ground the cameras actually measured, not what lies hidden
    /// behind a crest or in a dip inside their view cone. 0: the whole view cone (out to the
    /// ground points' range) counts as seen.
    pub seen_ground_point_radius_m: f64,
    /// … but towards the camera only this far along the line of sight, metres (ground just
    /// in front of a measured point may lie hidden in a dip: its own points would show it).
    /// Unset: the whole disc.
    pub seen_ground_toward_camera_m: Option<f64>,
    /// Ground counts as seen once seen in this many camera frames (a visible rock is missed
    /// in one frame now and then; the ground the rover stood on is known at once). Measured
    /// at 2 and 3 over 60 seeds (docs/experiments.md): no
    /// fewer collisions, so 1.
    pub seen_ground_min_views: u8,
    /// Ground within this distance of the start pose is known to be clear, metres: the
    /// rover is set down on clear ground, and the ring just beyond its footprint is below
    /// every camera's view until it drives. With the arcs' `known_radius_m` at 0 (every arc
    /// point on ground seen or stood on), this is the only ground taken on trust.
    pub start_clear_radius_m: f64,
    /// Waypoint pattern.
    pub waypoints: WaypointConfig,
}

impl Default for SessionConfig {
    fn default() -> Self {
        Self {
            duration_s: 120.0,
            start: [4.5, 0.0, std::f64::consts::FRAC_PI_2],
            initial_guess: None,
            frame_period_ticks: 20,
            collision_radius_m: footprint_radius_m(),
            collision_min_rock_radius_m: 0.08,
            rover: RoverConfig::default(),
            sensors: SensorConfig::default(),
            vo: VoConfig::default(),
            navigator: NavigatorConfig::default(),
            obstacles: ObstacleConfig::default(),
            seen_ground_point_radius_m: 0.35,
            seen_ground_toward_camera_m: None,
            seen_ground_min_views: 1,
            start_clear_radius_m: 1.0,
            waypoints: WaypointConfig::default(),
        }
    }
}

impl SessionConfig {
    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), SessionError> {
        let bad = |m: &str| Err(SessionError::InvalidConfig(m.to_string()));
        if !(self.duration_s.is_finite() && self.duration_s >= 0.0 && self.duration_s <= 1e6) {
            return bad("duration_s must be within 0..1e6");
        }
        if self.start.iter().any(|v| !v.is_finite())
            || self
                .initial_guess
                .is_some_and(|g| g.iter().any(|v| !v.is_finite()))
        {
            return bad("start and initial_guess must be finite");
        }
        if self.start[0].abs() > SITE_HALF_EXTENT_M || self.start[1].abs() > SITE_HALF_EXTENT_M {
            return bad("start must lie within |x|, |y| ≤ 19.5 m");
        }
        if self.frame_period_ticks == 0 {
            return bad("frame_period_ticks must be at least 1");
        }
        if !self.collision_radius_m.is_finite() || !self.collision_min_rock_radius_m.is_finite() {
            return bad("collision radii must be finite");
        }
        let bias = self.sensors.gravity_bias_rad;
        if !(bias.is_finite() && (0.0..=0.1).contains(&bias)) {
            return bad("sensors.gravity_bias_rad must be within 0..=0.1 (radians)");
        }
        if !(self.start_clear_radius_m.is_finite() && self.start_clear_radius_m >= 0.0) {
            return bad("start_clear_radius_m must be a non-negative number");
        }
        if self
            .seen_ground_toward_camera_m
            .is_some_and(|t| !(t.is_finite() && t >= 0.0))
        {
            return bad("seen_ground_toward_camera_m must be a non-negative number");
        }
        self.obstacles
            .validate()
            .map_err(|e| SessionError::InvalidConfig(e.to_string()))?;
        if !self.navigator.glance.is_valid() {
            return bad(
                "navigator.glance: period_s, turn_rate_rps and timeout_s must be positive, \
                 the ranges and angles finite and hold_s not negative",
            );
        }
        Ok(())
    }
}
