//! The log of one simulated session ([`crate::sim::session`]): per-tick poses, odometry and
//! gravity, per-frame observations, and the helpers the mission uses downstream (detection
//! sets for relocalization, odometry between ticks, ground points, a summary). Frames are
//! described in [`crate::sim::session`].

use crate::localizer::odometry_bias::OdometryBias;
use crate::planning::navigator::NavMode;
use crate::sim::ipex::SITE_HALF_EXTENT_M;
use crate::sim::rendered_odometry::ImageOdometryStats;
use crate::sim::rover::Command;
use crate::sim::sensors::{BoulderObservation, GroundObservation};
use crate::sim::session::SessionConfig;
use nalgebra::{Isometry3, Point3, Vector3};
use segloc_maps::{Detection, DetectionSet};
use serde::{Deserialize, Serialize};

/// What the rover collided with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Obstruction {
    /// The rock at this index in [`crate::sim::moon::Moon::rocks`].
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
    /// What the odometry from images did (`None`: the drift model measured the steps).
    pub image_odometry: Option<ImageOdometryStats>,
    /// The drift model's systematic errors as drawn for this session (`None`: the odometry
    /// came from images); what the localizer's calibration should find.
    pub odometry_bias: Option<OdometryBias>,
}

impl FrameRecord {
    /// This frame's boulder detections placed with `x_from_rover` (the rover's pose in the
    /// detection set's frame): each detection's `frame` is the tick, `size_m` the measured
    /// diameter.
    pub fn detections<'a>(
        &'a self,
        x_from_rover: &'a Isometry3<f64>,
    ) -> impl Iterator<Item = Detection> + 'a {
        let rover = Point3::from(x_from_rover.translation.vector);
        self.boulders.iter().map(move |b| Detection {
            frame: self.tick as u64,
            p_world: x_from_rover * b.p_rover,
            rover_position: Some(rover),
            size_m: Some(2.0 * b.radius_m),
            score: None,
        })
    }
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
    /// order: the index of the true rock in [`crate::sim::moon::Moon::rocks`], `None` for a spurious one.
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
            set.detections.extend(f.detections(&pose(t)));
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
