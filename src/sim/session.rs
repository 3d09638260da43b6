//! One driving session on the synthetic moon, logged for the mission downstream.
//!
//! Each 20 Hz tick: the navigator ([`crate::planning::navigator`]) picks a command from the
//! *estimated* pose and the obstacles it has detected; the rover ([`crate::sim::rover`])
//! moves on the terrain; visual odometry measures the step
//! ([`crate::sim::visual_odometry`]) and the estimate is integrated from it, with roll and
//! pitch taken from the IMU's gravity direction; collisions are checked against the true
//! world. Once a second (every `frame_period_ticks`) the cameras observe
//! ([`crate::sim::sensors`]): boulder detections, ground points and lander points, which
//! also feed the navigator's obstacle memory.
//!
//! # Frames
//! - *world*: the moon's frame, lander at the origin (LAC's frame);
//! - *rover*: body frame, x forward, y left, z up;
//! - *session*: the frame of this session's odometry estimate. The estimate starts at the
//!   initial guess of the start pose (`initial_guess`, the true start when `None`), so for a
//!   session started at a known pose the session frame is the world frame up to drift, and
//!   for a lost session it is off by the guess's error; the true `world_from_session` (at
//!   the start) is [`SessionLog::world_from_session`].
//!
//! # Downstream use
//! - relocalization submaps: [`SessionLog::detection_set`] over a time window (session
//!   frame, from the estimated poses);
//! - pose graph: one node per frame or tick with the estimate
//!   ([`TickRecord::session_from_rover`]) as initial value, odometry factors from
//!   [`SessionLog::odometry_between`] (or the raw per-tick [`TickRecord::vo_prev_from_cur`]),
//!   gravity in [`TickRecord::gravity_rover`]; trajectory error against
//!   [`TickRecord::world_from_rover`];
//! - height map: [`FrameRecord::ground`] points (rover frame) re-projected with optimised
//!   poses of [`FrameRecord::tick`];
//! - rock map: [`FrameRecord::boulders`] likewise;
//! - ground truth: [`crate::sim::moon::Moon::ground_truth_grid`].

use crate::planning::navigator::{NavMode, Navigator, NavigatorConfig};
use crate::planning::obstacles::{ObstacleConfig, ObstacleMemory};
use crate::planning::visibility::SeenGrid;
use crate::planning::waypoints::{waypoints, WaypointConfig};
use crate::planning::Pose2;
use crate::sim::ipex::{footprint_radius_m, LUNAR_GRAVITY_MPS2, SITE_HALF_EXTENT_M, TICK_S};
use crate::sim::ipex::{CX_PX, FOCAL_PX};
use crate::sim::moon::Moon;
use crate::sim::rover::{Command, RoverConfig, RoverState};
use crate::sim::sensors::{cameras, observe, BoulderObservation, GroundObservation, SensorConfig};
use crate::sim::visual_odometry::{gravity_in_rover, VisualOdometry, VoConfig};
use nalgebra::{
    Isometry2, Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector2, Vector3,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use segloc_maps::{Detection, DetectionSet};
use serde::{Deserialize, Serialize};
use std::time::Instant;

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
    /// Only rocks at least this large count as collisions, metres.
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
        Ok(())
    }
}

/// What the rover collided with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Obstruction {
    /// The rock at this index in [`Moon::rocks`].
    Rock(usize),
    /// The lander.
    Lander,
}

/// The log of one 20 Hz tick (state after the tick's motion).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickRecord {
    /// Time since the session start, seconds.
    pub time_s: f64,
    /// True pose.
    pub world_from_rover: Isometry3<f64>,
    /// Estimated pose (odometry integrated, roll and pitch from gravity), session frame.
    pub session_from_rover: Isometry3<f64>,
    /// Measured odometry step from the previous tick (identity at tick 0).
    pub vo_prev_from_cur: Isometry3<f64>,
    /// Gravity measured by the IMU, rover frame, m/s².
    pub gravity_rover: Vector3<f64>,
    /// Command applied during the tick.
    pub command: Command,
    /// Navigator mode.
    pub mode: NavMode,
    /// Collision at the end of the tick, if any.
    pub collision: Option<Obstruction>,
}

/// The log of one camera frame (both stereo pairs).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameRecord {
    /// Index of the tick it was taken at, into [`SessionLog::ticks`].
    pub tick: usize,
    /// Time, seconds.
    pub time_s: f64,
    /// Boulder detections (rover frame; `rock` gives the truth for evaluation).
    pub boulders: Vec<BoulderObservation>,
    /// Ground points (rover frame).
    pub ground: Vec<GroundObservation>,
    /// Points seen on the lander (rover frame).
    pub lander_points_rover: Vec<Point3<f64>>,
}

/// A short summary of a session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionSummary {
    /// Seed.
    pub seed: u64,
    /// Simulated seconds.
    pub duration_s: f64,
    /// Distance driven (true, horizontal), metres.
    pub distance_m: f64,
    /// Camera frames.
    pub frames: usize,
    /// Boulder detections (true and spurious).
    pub detections: usize,
    /// Spurious detections among them.
    pub spurious_detections: usize,
    /// Distinct rocks detected.
    pub distinct_rocks: usize,
    /// Ground points.
    pub ground_points: usize,
    /// Ticks in collision.
    pub collision_ticks: usize,
    /// Distinct collision events (runs of consecutive collision ticks).
    pub collisions: usize,
    /// Ticks outside |x|, |y| ≤ 19.5 m.
    pub out_of_bounds_ticks: usize,
    /// Odometry end-point error, metres (estimate mapped to the world with the true
    /// `world_from_session` vs truth).
    pub odometry_end_error_m: f64,
    /// Odometry end-point error as a fraction of the distance driven.
    pub odometry_drift_fraction: f64,
    /// Waypoints reached.
    pub waypoints_reached: usize,
    /// Waypoints skipped.
    pub waypoints_skipped: usize,
    /// Backup manoeuvres.
    pub backups: usize,
    /// Wall-clock seconds spent simulating.
    pub wall_time_s: f64,
    /// Simulated seconds per wall-clock second.
    pub realtime_factor: f64,
}

/// Everything one session produced.
#[derive(Clone, Debug)]
pub struct SessionLog {
    /// Seed it ran with.
    pub seed: u64,
    /// Configuration it ran with.
    pub config: SessionConfig,
    /// One record per 20 Hz tick; tick 0 is the start (no motion yet).
    pub ticks: Vec<TickRecord>,
    /// One record per camera frame.
    pub frames: Vec<FrameRecord>,
    /// (waypoints reached, skipped, backups).
    pub navigation_counts: (usize, usize, usize),
    /// Wall-clock seconds spent simulating.
    pub wall_time_s: f64,
}

impl SessionLog {
    /// The true transform from the session frame to the world, fixed at the start (what a
    /// relocalization against a world-frame map should find, up to odometry drift).
    pub fn world_from_session(&self) -> Isometry3<f64> {
        match self.ticks.first() {
            Some(t) => t.world_from_rover * t.session_from_rover.inverse(),
            None => Isometry3::identity(),
        }
    }

    /// Estimated motion between two ticks: `rover(a)_from_rover(b)` from the estimate.
    pub fn odometry_between(&self, a: usize, b: usize) -> Option<Isometry3<f64>> {
        let (ta, tb) = (self.ticks.get(a)?, self.ticks.get(b)?);
        Some(ta.session_from_rover.inverse() * tb.session_from_rover)
    }

    /// True motion between two ticks: `rover(a)_from_rover(b)`.
    pub fn true_motion_between(&self, a: usize, b: usize) -> Option<Isometry3<f64>> {
        let (ta, tb) = (self.ticks.get(a)?, self.ticks.get(b)?);
        Some(ta.world_from_rover.inverse() * tb.world_from_rover)
    }

    /// The boulder detections of the frames taken in `[from_s, to_s)`, in the session frame
    /// (estimated poses), as a `DetectionSet` for fusion and relocalization. `frame` of each
    /// detection is the frame's tick index, `size_m` the measured diameter; which rock each
    /// came from is in [`SessionLog::detection_truth`] (same order), not in the set.
    pub fn detection_set(&self, name: &str, from_s: f64, to_s: f64) -> DetectionSet {
        self.detections_with(name, "session", from_s, to_s, |t| t.session_from_rover)
    }

    /// For each detection of [`SessionLog::detection_set`] over the same window, in the same
    /// order: the index of the true rock in [`Moon::rocks`], `None` for a spurious one.
    pub fn detection_truth(&self, from_s: f64, to_s: f64) -> Vec<Option<usize>> {
        self.frames
            .iter()
            .filter(|f| f.time_s >= from_s && f.time_s < to_s && f.tick < self.ticks.len())
            .flat_map(|f| f.boulders.iter().map(|b| b.rock))
            .collect()
    }

    /// The same detections placed with the *true* poses, world frame (for evaluation).
    pub fn detection_set_true_poses(&self, name: &str, from_s: f64, to_s: f64) -> DetectionSet {
        self.detections_with(name, "world", from_s, to_s, |t| t.world_from_rover)
    }

    fn detections_with(
        &self,
        name: &str,
        frame: &str,
        from_s: f64,
        to_s: f64,
        pose: impl Fn(&TickRecord) -> Isometry3<f64>,
    ) -> DetectionSet {
        let mut set = DetectionSet::new(name, frame, true);
        for f in self
            .frames
            .iter()
            .filter(|f| f.time_s >= from_s && f.time_s < to_s)
        {
            let Some(t) = self.ticks.get(f.tick) else {
                continue;
            };
            let x_from_rover = pose(t);
            let rover = Point3::from(x_from_rover.translation.vector);
            for b in &f.boulders {
                set.detections.push(Detection {
                    frame: f.tick as u64,
                    p_world: x_from_rover * b.p_rover,
                    rover_position: Some(rover),
                    size_m: Some(2.0 * b.radius_m),
                    score: None,
                });
            }
        }
        set
    }

    /// Ground points of all frames in the session frame (estimated poses).
    pub fn ground_points_session(&self) -> Vec<Point3<f64>> {
        let mut out = Vec::new();
        for f in &self.frames {
            if let Some(t) = self.ticks.get(f.tick) {
                out.extend(f.ground.iter().map(|g| t.session_from_rover * g.p_rover));
            }
        }
        out
    }

    /// Horizontal distance driven (true), metres.
    pub fn distance_m(&self) -> f64 {
        self.ticks
            .windows(2)
            .map(|w| {
                let d = w[1].world_from_rover.translation.vector
                    - w[0].world_from_rover.translation.vector;
                d.x.hypot(d.y)
            })
            .sum()
    }

    /// Ticks with a collision.
    pub fn collision_ticks(&self) -> impl Iterator<Item = &TickRecord> {
        self.ticks.iter().filter(|t| t.collision.is_some())
    }

    /// The summary.
    pub fn summary(&self) -> SessionSummary {
        let duration_s = self.ticks.last().map_or(0.0, |t| t.time_s);
        let distance_m = self.distance_m();
        let detections: usize = self.frames.iter().map(|f| f.boulders.len()).sum();
        let spurious = self
            .frames
            .iter()
            .flat_map(|f| &f.boulders)
            .filter(|b| b.rock.is_none())
            .count();
        let mut rocks: Vec<usize> = self
            .frames
            .iter()
            .flat_map(|f| f.boulders.iter().filter_map(|b| b.rock))
            .collect();
        rocks.sort_unstable();
        rocks.dedup();
        let collisions = self
            .ticks
            .windows(2)
            .filter(|w| w[1].collision.is_some() && w[0].collision.is_none())
            .count()
            + usize::from(self.ticks.first().is_some_and(|t| t.collision.is_some()));
        let out_of_bounds = self
            .ticks
            .iter()
            .filter(|t| {
                let p = t.world_from_rover.translation.vector;
                p.x.abs() > SITE_HALF_EXTENT_M || p.y.abs() > SITE_HALF_EXTENT_M
            })
            .count();
        let end_error = self.ticks.last().map_or(0.0, |t| {
            let est = self.world_from_session() * t.session_from_rover;
            (est.translation.vector - t.world_from_rover.translation.vector).norm()
        });
        let (reached, skipped, backups) = self.navigation_counts;
        SessionSummary {
            seed: self.seed,
            duration_s,
            distance_m,
            frames: self.frames.len(),
            detections,
            spurious_detections: spurious,
            distinct_rocks: rocks.len(),
            ground_points: self.frames.iter().map(|f| f.ground.len()).sum(),
            collision_ticks: self.collision_ticks().count(),
            collisions,
            out_of_bounds_ticks: out_of_bounds,
            odometry_end_error_m: end_error,
            odometry_drift_fraction: if distance_m > 0.0 {
                end_error / distance_m
            } else {
                0.0
            },
            waypoints_reached: reached,
            waypoints_skipped: skipped,
            backups,
            wall_time_s: self.wall_time_s,
            realtime_factor: if self.wall_time_s > 0.0 {
                duration_s / self.wall_time_s
            } else {
                f64::INFINITY
            },
        }
    }
}

/// A session being simulated, one tick at a time (for interleaving relocalization).
pub struct SessionSim<'a> {
    moon: &'a Moon,
    config: SessionConfig,
    state: RoverState,
    vo: VisualOdometry,
    rng: ChaCha8Rng,
    navigator: Navigator,
    obstacles: ObstacleMemory,
    seen: SeenGrid,
    log: SessionLog,
    total_ticks: usize,
    wall: f64,
}

/// Roll and pitch of the rover from the gravity it measures (rover frame).
pub fn roll_pitch_from_gravity(g: &Vector3<f64>) -> (f64, f64) {
    let roll = (-g.y).atan2(-g.z);
    let pitch = g.x.atan2(g.y.hypot(g.z));
    (roll, pitch)
}

impl<'a> SessionSim<'a> {
    /// Set up a session on `moon` (tick 0 logged: the rover at its start, one camera frame).
    pub fn new(moon: &'a Moon, config: &SessionConfig, seed: u64) -> Result<Self, SessionError> {
        config.validate()?;
        let started = Instant::now();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let vo = VisualOdometry::new(&config.vo, rng.random());
        let state = RoverState::at_rest(config.start[0], config.start[1], config.start[2]);
        let guess = config.initial_guess.unwrap_or(config.start);
        let plan = waypoints(&config.waypoints, Vector2::new(guess[0], guess[1]));
        let navigator = Navigator::new(&config.navigator, plan);
        let world_from_rover = state.pose(moon);
        let gravity_rover = gravity_in_rover(
            &world_from_rover,
            LUNAR_GRAVITY_MPS2,
            config.sensors.gravity_sigma_rad,
            &mut rng,
        );
        let (roll, pitch) = roll_pitch_from_gravity(&gravity_rover);
        let session_from_rover = Isometry3::from_parts(
            Translation3::new(guess[0], guess[1], world_from_rover.translation.z),
            UnitQuaternion::from_euler_angles(roll, pitch, guess[2]),
        );
        let total_ticks = (config.duration_s / TICK_S).round() as usize;
        let mut sim = Self {
            moon,
            config: config.clone(),
            state,
            vo,
            rng,
            navigator,
            obstacles: ObstacleMemory::new(&config.obstacles),
            seen: SeenGrid::new(0.25),
            log: SessionLog {
                seed,
                config: config.clone(),
                ticks: Vec::with_capacity(total_ticks + 1),
                frames: Vec::new(),
                navigation_counts: (0, 0, 0),
                wall_time_s: 0.0,
            },
            total_ticks,
            wall: 0.0,
        };
        let collision = sim.collision(&world_from_rover);
        sim.log.ticks.push(TickRecord {
            time_s: 0.0,
            world_from_rover,
            session_from_rover,
            vo_prev_from_cur: Isometry3::identity(),
            gravity_rover,
            command: Command::default(),
            mode: NavMode::Drive,
            collision,
        });
        sim.take_frame();
        sim.wall += started.elapsed().as_secs_f64();
        Ok(sim)
    }

    /// The log so far.
    pub fn log(&self) -> &SessionLog {
        &self.log
    }

    /// Whether the session's duration has been simulated.
    pub fn done(&self) -> bool {
        self.log.ticks.len() > self.total_ticks
    }

    /// Tell the navigator where the session frame sits in the nav (world) frame, e.g. after
    /// a relocalization (`world_from_session` estimate). Waypoints and the lander move with it.
    pub fn set_world_from_session_estimate(&mut self, world_from_session: &Isometry3<f64>) {
        let (_, _, yaw) = world_from_session.rotation.euler_angles();
        let t = world_from_session.translation.vector;
        self.navigator
            .set_nav_from_session(Isometry2::new(Vector2::new(t.x, t.y), yaw));
    }

    fn collision(&self, world_from_rover: &Isometry3<f64>) -> Option<Obstruction> {
        let (x, y) = (
            world_from_rover.translation.x,
            world_from_rover.translation.y,
        );
        let r = self.config.collision_radius_m;
        if self.moon.distance_to_lander_m(x, y) < r {
            return Some(Obstruction::Lander);
        }
        let mut hit = None;
        self.moon
            .for_each_rock_near(x, y, r + self.moon.max_rock_radius_m(), |i, rock| {
                if rock.radius_m >= self.config.collision_min_rock_radius_m
                    && (rock.center.x - x).hypot(rock.center.y - y) < r + rock.radius_m
                    && hit.is_none()
                {
                    hit = Some(Obstruction::Rock(i));
                }
            });
        hit
    }

    fn take_frame(&mut self) {
        let Some(tick) = self.log.ticks.last().copied() else {
            return;
        };
        let obs = observe(
            self.moon,
            &tick.world_from_rover,
            &self.config.sensors,
            &mut self.rng,
        );
        let est = tick.session_from_rover;
        for b in &obs.boulders {
            let p = est * b.p_rover;
            self.obstacles.add_rock(Point2::new(p.x, p.y), b.radius_m);
        }
        // the ground the cameras saw (session frame)
        for camera in cameras() {
            let cam = Pose2::from_isometry3(&(est * camera.rover_from_camera));
            let half_fov = (CX_PX / FOCAL_PX).atan();
            let c = &self.config.sensors;
            self.seen.mark_view(
                cam,
                half_fov,
                c.min_range_m,
                c.max_range_m.min(c.ground_max_range_m),
            );
        }
        for q in &obs.lander_points_rover {
            let p = est * q;
            self.obstacles.add_point(Point2::new(p.x, p.y));
        }
        self.log.frames.push(FrameRecord {
            tick: self.log.ticks.len() - 1,
            time_s: tick.time_s,
            boulders: obs.boulders,
            ground: obs.ground,
            lander_points_rover: obs.lander_points_rover,
        });
    }

    /// Simulate one tick; returns false (doing nothing) once the duration is done.
    pub fn step(&mut self) -> bool {
        if self.done() {
            return false;
        }
        let started = Instant::now();
        let Some(prev) = self.log.ticks.last().copied() else {
            return false;
        };
        let k = self.log.ticks.len();
        let time_s = k as f64 * TICK_S;
        let pose = Pose2::from_isometry3(&prev.session_from_rover);
        // the rover stands on its own footprint: that ground is clear
        self.seen
            .mark_disc(pose.x, pose.y, self.config.collision_radius_m);
        let command = self
            .navigator
            .command(prev.time_s, pose, &self.obstacles, Some(&self.seen));
        self.state.step(command, &self.config.rover, TICK_S);
        let world_from_rover = self.state.pose(self.moon);
        let true_step = prev.world_from_rover.inverse() * world_from_rover;
        let vo_prev_from_cur = self.vo.measure(&true_step);
        let gravity_rover = gravity_in_rover(
            &world_from_rover,
            LUNAR_GRAVITY_MPS2,
            self.config.sensors.gravity_sigma_rad,
            &mut self.rng,
        );
        let integrated = prev.session_from_rover * vo_prev_from_cur;
        let (_, _, yaw) = integrated.rotation.euler_angles();
        let (roll, pitch) = roll_pitch_from_gravity(&gravity_rover);
        let session_from_rover = Isometry3::from_parts(
            integrated.translation,
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        );
        let collision = self.collision(&world_from_rover);
        self.log.ticks.push(TickRecord {
            time_s,
            world_from_rover,
            session_from_rover,
            vo_prev_from_cur,
            gravity_rover,
            command,
            mode: self.navigator.mode(),
            collision,
        });
        if k.is_multiple_of(self.config.frame_period_ticks) {
            self.take_frame();
        }
        self.log.navigation_counts = self.navigator.counts();
        self.wall += started.elapsed().as_secs_f64();
        self.log.wall_time_s = self.wall;
        true
    }

    /// The finished log.
    pub fn finish(mut self) -> SessionLog {
        self.log.wall_time_s = self.wall;
        self.log
    }
}

/// Drive one whole session on `moon` from `config.start` for `config.duration_s`.
pub fn run_session(
    moon: &Moon,
    config: &SessionConfig,
    seed: u64,
) -> Result<SessionLog, SessionError> {
    let mut sim = SessionSim::new(moon, config, seed)?;
    while sim.step() {}
    Ok(sim.finish())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::moon::MoonConfig;

    #[test]
    fn gravity_gives_roll_and_pitch() {
        let r = UnitQuaternion::from_euler_angles(0.1, -0.2, 1.0);
        let g = r.inverse() * Vector3::new(0.0, 0.0, -1.622);
        let (roll, pitch) = roll_pitch_from_gravity(&g);
        assert!((roll - 0.1).abs() < 1e-12 && (pitch + 0.2).abs() < 1e-12);
    }

    #[test]
    fn short_session_runs_and_logs() {
        let moon = Moon::generate(&MoonConfig::default(), 3).unwrap();
        let (x, y) = moon.nearest_clear_position(4.5, 0.0, 1.0, 0.08);
        let config = SessionConfig {
            duration_s: 30.0,
            start: [x, y, 1.5],
            ..SessionConfig::default()
        };
        let log = run_session(&moon, &config, 1).unwrap();
        assert_eq!(log.ticks.len(), 601);
        assert_eq!(log.frames.len(), 31);
        let s = log.summary();
        assert!(s.distance_m > 1.0, "{s:?}");
        assert!(s.detections > 0 && s.ground_points > 1000, "{s:?}");
        let set = log.detection_set("s1", 0.0, 100.0);
        assert_eq!(set.detections.len(), s.detections);
        // session frame = world frame at the start (known start pose), up to the IMU's tilt
        // error
        let w = log.world_from_session();
        assert!(w.translation.vector.norm() < 0.05 && w.rotation.angle() < 0.01);
    }

    #[test]
    fn rejects_bad_config() {
        let moon = Moon::generate(&MoonConfig::default(), 3).unwrap();
        let config = SessionConfig {
            duration_s: f64::NAN,
            ..SessionConfig::default()
        };
        assert!(run_session(&moon, &config, 1).is_err());
    }
}
