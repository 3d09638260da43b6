//! One driving session on the synthetic moon, logged for the mission downstream.
//!
//! Each 20 Hz tick: the navigator ([`crate::planning::navigator`]) picks a command from the
//! *estimated* pose and the obstacles it has detected; the rover ([`crate::sim::rover`])
//! moves on the terrain; visual odometry measures the step
//! ([`crate::sim::visual_odometry`]) and the estimate is integrated from it, with roll and
//! pitch taken from the IMU's gravity direction; collisions are checked against the true
//! world. Once a second (every `frame_period_ticks`) the cameras observe
//! ([`crate::sim::sensors`]): boulder detections, ground points and lander points, which
//! also feed the navigator's obstacle memory. With [`SessionSim::with_rendered_sensors`]
//! the boulder detections come instead from the perception front end on rendered stereo
//! pairs ([`crate::sim::rendered_boulders`]), and with image odometry set there the steps
//! from the stereo visual odometry on the rendered front pair
//! ([`crate::sim::rendered_odometry`]).
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

use crate::planning::navigator::{NavMode, Navigator};
use crate::planning::obstacles::ObstacleMemory;
use crate::planning::visibility::SeenGrid;
use crate::planning::waypoints::waypoints;
use crate::planning::Pose2;
use crate::sim::ipex::{CX_PX, CY_PX, FOCAL_PX};
use crate::sim::ipex::{LUNAR_GRAVITY_MPS2, TICK_S};
use crate::sim::moon::Moon;
use crate::sim::rendered_sensors::RenderedSensors;
use crate::sim::rover::{Command, RoverState};
use crate::sim::sensors::{cameras, observe, observe_far};
use crate::sim::visual_odometry::{gravity_in_rover, VisualOdometry};
use nalgebra::{Isometry2, Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

/// Mixed into a session's seed for the far measurements' stream ("far grnd").
const FAR_STREAM: u64 = 0x6661_7220_6772_6e64;

/// Mixed into a session's seed for the direction of the IMU's gravity bias ("g bias").
const GRAVITY_BIAS_STREAM: u64 = 0x0067_2062_6961_7300;

/// The IMU's constant gravity bias for a session: a rotation by `bias_rad` about a
/// horizontal rover axis whose direction is drawn from the session's seed.
pub fn gravity_bias(bias_rad: f64, seed: u64) -> UnitQuaternion<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ GRAVITY_BIAS_STREAM);
    let direction: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let axis = nalgebra::Unit::new_normalize(nalgebra::Vector3::new(
        direction.cos(),
        direction.sin(),
        0.0,
    ));
    UnitQuaternion::from_axis_angle(&axis, bias_rad)
}

pub use crate::sim::session_log::{
    FrameRecord, Obstruction, SessionLog, SessionSummary, TickRecord,
};

pub use crate::sim::session_config::{PlanarPose, SessionConfig, SessionError};

/// A session being simulated, one tick at a time (for interleaving relocalization).
pub struct SessionSim<'a> {
    moon: &'a Moon,
    config: SessionConfig,
    state: RoverState,
    vo: VisualOdometry,
    rng: ChaCha8Rng,
    /// The far measurements' own stream ([`observe_far`]).
    far_rng: ChaCha8Rng,
    /// The IMU's constant gravity bias ([`gravity_bias`]), applied to every reading.
    gravity_bias: UnitQuaternion<f64>,
    navigator: Navigator,
    obstacles: ObstacleMemory,
    seen: SeenGrid,
    /// The frame the planner works in (navigator pose, obstacle memory, seen ground), from
    /// the session (odometry) frame: identity until a loop closure corrects the drift.
    planner_from_session: Isometry3<f64>,
    /// `planner_from_session` at each frame of the log (what its detections were placed
    /// with).
    planner_history: Vec<Isometry3<f64>>,
    /// Rocks known beforehand, world frame: centre (x, y) and radius
    /// ([`SessionSim::set_known_rocks_world`]).
    known_rocks_world: Vec<(Point2<f64>, f64)>,
    /// Boulders (and odometry, when set there) from rendered images instead of the sensor
    /// models, when set ([`SessionSim::with_rendered_sensors`]).
    rendered: Option<&'a mut RenderedSensors>,
    log: SessionLog,
    total_ticks: usize,
    wall: f64,
}

/// The planar part (x, y, yaw) of a pose.
fn planar_part(pose: &Isometry3<f64>) -> Isometry3<f64> {
    let (_, _, yaw) = pose.rotation.euler_angles();
    let t = pose.translation.vector;
    Isometry3::from_parts(
        Translation3::new(t.x, t.y, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
    )
}

pub use crate::localizer::frame_log::roll_pitch_from_gravity;

impl<'a> SessionSim<'a> {
    /// Set up a session on `moon` (tick 0 logged: the rover at its start, one camera frame).
    pub fn new(moon: &'a Moon, config: &SessionConfig, seed: u64) -> Result<Self, SessionError> {
        Self::with_rendered_sensors(moon, config, seed, None)
    }

    /// [`SessionSim::new`], the boulders of every camera frame detected by `rendered` (its
    /// front end on rendered stereo pairs) instead of the sensor model when given, and the
    /// odometry measured by its image odometry when it has one; ground and lander points
    /// still come from the sensor model, which draws its random numbers as without it.
    pub fn with_rendered_sensors(
        moon: &'a Moon,
        config: &SessionConfig,
        seed: u64,
        mut rendered: Option<&'a mut RenderedSensors>,
    ) -> Result<Self, SessionError> {
        config.validate()?;
        let started = Instant::now();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let vo = VisualOdometry::new(&config.vo, rng.random());
        let state = RoverState::at_rest(config.start[0], config.start[1], config.start[2]);
        let guess = config.initial_guess.unwrap_or(config.start);
        let plan = waypoints(&config.waypoints, Vector2::new(guess[0], guess[1]));
        let navigator = Navigator::new(&config.navigator, plan);
        let world_from_rover = state.pose(moon);
        let bias = gravity_bias(config.sensors.gravity_bias_rad, seed);
        let gravity_rover = bias
            * gravity_in_rover(
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
        if let Some(r) = rendered.as_deref_mut() {
            r.begin_session(seed, 0.0, &world_from_rover, Some(gravity_rover))
                .map_err(|e| SessionError::InvalidConfig(format!("image odometry: {e}")))?;
        }
        let mut sim = Self {
            moon,
            config: config.clone(),
            state,
            vo,
            rng,
            far_rng: ChaCha8Rng::seed_from_u64(seed ^ FAR_STREAM),
            gravity_bias: bias,
            navigator,
            obstacles: ObstacleMemory::new(&config.obstacles),
            seen: SeenGrid::with_min_views(0.25, config.seen_ground_min_views),
            planner_from_session: Isometry3::identity(),
            planner_history: Vec::new(),
            known_rocks_world: Vec::new(),
            rendered,
            log: SessionLog {
                seed,
                config: config.clone(),
                ticks: Vec::with_capacity(total_ticks + 1),
                frames: Vec::new(),
                navigation_counts: (0, 0, 0),
                wall_time_s: 0.0,
                image_odometry: None,
                odometry_bias: None,
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
        // the rover is set down on clear ground
        let start = Pose2::from_isometry3(&session_from_rover);
        let clear_m = config.start_clear_radius_m.max(config.collision_radius_m);
        sim.seen.mark_disc(start.x, start.y, clear_m);
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
    /// The rocks known beforehand ([`SessionSim::set_known_rocks_world`]) move with it.
    pub fn set_world_from_session_estimate(&mut self, world_from_session: &Isometry3<f64>) {
        let (_, _, yaw) = world_from_session.rotation.euler_angles();
        let t = world_from_session.translation.vector;
        self.navigator
            .set_nav_from_session(Isometry2::new(Vector2::new(t.x, t.y), yaw));
        if !self.known_rocks_world.is_empty() {
            let planner_from_world =
                planar_part(&(self.planner_from_session * world_from_session.inverse()));
            let placed: Vec<(Point2<f64>, f64)> = self
                .known_rocks_world
                .iter()
                .map(|(p, r)| {
                    let q = planner_from_world * Point3::new(p.x, p.y, 0.0);
                    (Point2::new(q.x, q.y), *r)
                })
                .collect();
            self.obstacles.set_known_rocks(&placed);
        }
    }

    /// Rocks known beforehand, in the world frame (centre x, y and radius, metres): a prior
    /// session's boulder map. The planner avoids them, whether or not its cameras see them,
    /// from the first [`SessionSim::set_world_from_session_estimate`] on (until then the
    /// session does not know where the world is), each time placed with the latest
    /// estimate.
    pub fn set_known_rocks_world(&mut self, rocks: Vec<(Point2<f64>, f64)>) {
        self.known_rocks_world = rocks;
    }

    /// Correct the planner's frame after a loop closure: `planner_from_session` holds, for
    /// each frame of the log so far, the optimised pose composed with the inverse of its
    /// odometry pose (only the planar part, x, y and yaw, is used).
    ///
    /// Every remembered obstacle moves as the frame that last detected it did, and from
    /// now on the navigator, the obstacle memory and the seen-ground grid place the rover
    /// with the latest correction instead of the bare odometry (the log keeps the
    /// odometry). A rock passed again after a loop then lands on its first sighting instead
    /// of 30–50 cm beside it, and the two copies do not fence the rover in.
    pub fn reanchor_planner(&mut self, planner_from_session: &[Isometry3<f64>]) {
        let planar: Vec<Isometry3<f64>> = planner_from_session.iter().map(planar_part).collect();
        let Some(latest) = planar.last().copied() else {
            return;
        };
        let (history, corrected) = (&self.planner_history, &planar);
        self.obstacles.reanchor(|memory_frame, p| {
            // memory frame f is log frame f − 1 (the memory counts from 1)
            let f = memory_frame.saturating_sub(1) as usize;
            match (history.get(f), corrected.get(f)) {
                (Some(old), Some(new)) => {
                    let q = new * old.inverse() * Point3::new(p.x, p.y, 0.0);
                    Point2::new(q.x, q.y)
                }
                _ => p,
            }
        });
        for (old, new) in self.planner_history.iter_mut().zip(&planar) {
            *old = *new;
        }
        self.planner_from_session = latest;
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
            .for_each_rock_near(x, y, r + self.moon.max_rock_radius_m(), |i, _| {
                if self.moon.rock_size_radius_m(i) >= self.config.collision_min_rock_radius_m
                    && hit.is_none()
                    && self.moon.distance_to_rock_m(i, x, y) < r
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
        let mut obs = observe(
            self.moon,
            &tick.world_from_rover,
            &self.config.sensors,
            &mut self.rng,
        );
        if let Some(rendered) = self.rendered.as_deref_mut() {
            let tick_index = self.log.ticks.len() - 1;
            obs.boulders =
                rendered.observe_boulders(&tick.world_from_rover, tick_index, &self.config.sensors);
        }
        let est = self.planner_from_session * tick.session_from_rover;
        self.planner_history.push(self.planner_from_session);
        self.obstacles.start_frame();
        self.seen.start_frame();
        for b in &obs.boulders {
            let p = est * b.p_rover;
            self.obstacles.add_rock_at(p, b.radius_m);
        }
        // unconfirmed rocks in view that were not detected again count a miss; the ground
        // the cameras saw (session frame)
        let seen_radius_m = self.config.seen_ground_point_radius_m;
        for camera in cameras() {
            let session_from_camera = est * camera.rover_from_camera;
            let cam = Pose2::from_isometry3(&session_from_camera);
            let half_fov = (CX_PX / FOCAL_PX).atan();
            let half_vertical_fov = (CY_PX / FOCAL_PX).atan();
            let c = &self.config.sensors;
            self.obstacles.record_camera_view(
                &session_from_camera,
                half_fov,
                half_vertical_fov,
                c.min_range_m,
            );
            if seen_radius_m <= 0.0 {
                self.seen.mark_view(
                    cam,
                    half_fov,
                    c.min_range_m,
                    c.max_range_m.min(c.ground_max_range_m),
                );
            }
        }
        if seen_radius_m > 0.0 {
            let toward = self.config.seen_ground_toward_camera_m;
            // each camera's position once per frame, not once per ground point
            let camera_at = cameras().map(|c| {
                let p = est * Point3::from(c.rover_from_camera.translation.vector);
                (c.id, p.x, p.y)
            });
            for g in &obs.ground {
                let p = est * g.p_rover;
                let from = toward.and_then(|t| {
                    camera_at
                        .iter()
                        .find(|(id, _, _)| *id == g.camera)
                        .map(|&(_, x, y)| (x, y, t))
                });
                self.seen.mark_disc_seen_from(p.x, p.y, seen_radius_m, from);
            }
        }
        for q in &obs.lander_points_rover {
            let p = est * q;
            self.obstacles.add_point(Point2::new(p.x, p.y));
        }
        // the far measurements feed the maps and the lander fit only: the planner's seen
        // ground is the near ground, where a small rock would have been detected, and the
        // lander is an obstacle only where it is near
        let far = observe_far(
            self.moon,
            &tick.world_from_rover,
            &self.config.sensors,
            &mut self.far_rng,
        );
        let (mut ground, mut lander_points_rover) = (obs.ground, obs.lander_points_rover);
        ground.extend(far.ground);
        lander_points_rover.extend(far.lander_points_rover);
        self.log.frames.push(FrameRecord {
            tick: self.log.ticks.len() - 1,
            time_s: tick.time_s,
            boulders: obs.boulders,
            ground,
            lander_points_rover,
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
        let pose = Pose2::from_isometry3(&(self.planner_from_session * prev.session_from_rover));
        // the rover stands on its own footprint: that ground is clear
        self.seen
            .mark_disc(pose.x, pose.y, self.config.collision_radius_m);
        self.obstacles
            .set_rover_position(Point2::new(pose.x, pose.y));
        let command = self
            .navigator
            .command(prev.time_s, pose, &self.obstacles, Some(&self.seen));
        self.state.step(command, &self.config.rover, TICK_S);
        let world_from_rover = self.state.pose(self.moon);
        let true_step = prev.world_from_rover.inverse() * world_from_rover;
        let gravity_rover = self.gravity_bias
            * gravity_in_rover(
                &world_from_rover,
                LUNAR_GRAVITY_MPS2,
                self.config.sensors.gravity_sigma_rad,
                &mut self.rng,
            );
        let from_images = self
            .rendered
            .as_deref_mut()
            .and_then(|r| r.measure_step(k, time_s, &world_from_rover, Some(gravity_rover)));
        let vo_prev_from_cur = from_images.unwrap_or_else(|| self.vo.measure(&true_step));
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
        self.log.image_odometry = self.rendered.as_ref().and_then(|r| r.odometry_stats());
        self.log.odometry_bias = self.log.image_odometry.is_none().then(|| self.vo.biases());
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
    use nalgebra::Vector3;

    #[test]
    fn gravity_gives_roll_and_pitch() {
        let r = UnitQuaternion::from_euler_angles(0.1, -0.2, 1.0);
        let g = r.inverse() * Vector3::new(0.0, 0.0, -1.622);
        let (roll, pitch) = roll_pitch_from_gravity(&g);
        assert!((roll - 0.1).abs() < 1e-12 && (pitch + 0.2).abs() < 1e-12);
    }

    #[test]
    fn gravity_bias_is_a_constant_seeded_tilt() {
        let a = gravity_bias(0.005, 4);
        assert!((a.angle() - 0.005).abs() < 1e-12);
        assert!(a.axis().unwrap().z.abs() < 1e-12, "horizontal axis");
        assert_eq!(a, gravity_bias(0.005, 4));
        assert!(
            a.angle_to(&gravity_bias(0.005, 5)) > 1e-6,
            "direction from the seed"
        );
        assert_eq!(gravity_bias(0.0, 4), UnitQuaternion::identity());

        let moon = Moon::generate(&MoonConfig::default(), 3).unwrap();
        let (x, y) = moon.nearest_clear_position(4.5, 0.0, 1.0, 0.08);
        let mut config = SessionConfig {
            duration_s: 5.0,
            start: [x, y, 1.5],
            ..SessionConfig::default()
        };
        config.sensors.gravity_sigma_rad = 0.0;
        config.sensors.gravity_bias_rad = 0.005;
        let log = run_session(&moon, &config, 4).unwrap();
        for tick in &log.ticks {
            let truth = tick.world_from_rover.rotation.inverse() * Vector3::new(0.0, 0.0, -1.0);
            let measured = tick.gravity_rover.normalize();
            assert!((measured - a * truth).norm() < 1e-9, "tick {}", tick.time_s);
            assert!(measured.angle(&truth) > 0.004, "tick {}", tick.time_s);
        }
        config.sensors.gravity_bias_rad = 0.2;
        assert!(run_session(&moon, &config, 4).is_err(), "validated");
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
    fn reanchoring_moves_remembered_rocks_and_the_planner() {
        let moon = Moon::generate(&MoonConfig::default(), 3).unwrap();
        let (x, y) = moon.nearest_clear_position(4.5, 0.0, 1.0, 0.08);
        let config = SessionConfig {
            duration_s: 20.0,
            start: [x, y, 1.5],
            ..SessionConfig::default()
        };
        let mut sim = SessionSim::new(&moon, &config, 1).unwrap();
        while sim.step() {}
        let before: Vec<Point2<f64>> = sim.obstacles.obstacles().iter().map(|o| o.p).collect();
        assert!(!before.is_empty());
        assert_eq!(sim.planner_history.len(), sim.log().frames.len());
        // every frame's pose corrected by 1 m along x (and a tilt the planner ignores)
        let shift = Isometry3::from_parts(
            Translation3::new(1.0, 0.0, 0.3),
            UnitQuaternion::from_euler_angles(0.01, 0.0, 0.0),
        );
        let corrections = vec![shift; sim.log().frames.len()];
        sim.reanchor_planner(&corrections);
        for (o, b) in sim.obstacles.obstacles().iter().zip(&before) {
            assert!((o.p - b - Vector2::new(1.0, 0.0)).norm() < 1e-9);
        }
        let t = sim.planner_from_session.translation.vector;
        assert!((t - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
        assert!(sim.planner_from_session.rotation.angle() < 1e-12);
        // a second correction composes with the first, not with the odometry
        sim.reanchor_planner(&corrections);
        for (o, b) in sim.obstacles.obstacles().iter().zip(&before) {
            assert!((o.p - b - Vector2::new(1.0, 0.0)).norm() < 1e-9);
        }
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
