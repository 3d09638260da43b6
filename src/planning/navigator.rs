//! The navigator: follows the waypoint list with the arc planner, turning on the spot when
//! the waypoint is far off the heading, and backing up (then turning away) when no arc is
//! free or the rover stops making progress. Waypoints it cannot reach in time, or that sit
//! inside an obstacle's clearance, are skipped; when the list runs out it is driven again in
//! reverse (revisiting mapped ground). When the arc fan is stuck (no arc free, or no
//! progress), the navigator plans a route to the waypoint over the whole neighbourhood
//! ([`crate::planning::route`]) and steers along it; a waypoint without a route is skipped.

use crate::planning::arc_planner::{ArcPlannerConfig, LanderBox, Scene};
use crate::planning::kinematics::{wrap_angle, Command};
use crate::planning::lander_glance::{GlanceConfig, GlanceStep, LanderGlance};
use crate::planning::obstacles::ObstacleMemory;
use crate::planning::route::{plan_route, Route, RouteConfig};
use crate::planning::visibility::SeenGrid;
use crate::planning::Pose2;
use nalgebra::{Isometry2, Point2, Vector2};
use serde::{Deserialize, Serialize};

/// Parameters of the navigator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NavigatorConfig {
    /// The arc fan.
    pub arcs: ArcPlannerConfig,
    /// A waypoint is reached within this distance, metres.
    pub waypoint_reached_m: f64,
    /// … or passed, when the rover is this close and beyond it along the path, metres.
    pub waypoint_passed_m: f64,
    /// Steer for the first waypoint at least this far ahead (pure pursuit), metres.
    pub lookahead_m: f64,
    /// … looking at most this many waypoints ahead.
    pub lookahead_waypoints: usize,
    /// Turn on the spot when the waypoint's bearing is off by more than this, radians.
    pub point_turn_threshold_rad: f64,
    /// Yaw rate of a point turn, rad/s.
    pub point_turn_rate_rps: f64,
    /// Progress is checked over this window, seconds.
    pub stall_window_s: f64,
    /// Less progress toward the waypoint than this over the window is a stall, metres.
    pub stall_progress_m: f64,
    /// Reverse speed of the backup manoeuvre, m/s.
    pub backup_speed_mps: f64,
    /// How long to reverse, seconds.
    pub backup_duration_s: f64,
    /// After a scan found a free arc, keep driving arcs (no point turn toward the goal) for
    /// this long, seconds.
    pub commit_after_scan_s: f64,
    /// Treat ground the cameras have not seen as blocked.
    pub require_seen_ground: bool,
    /// Skip the waypoint after this many backups on the way to it.
    pub backups_per_waypoint: usize,
    /// Give up on a waypoint after this long, seconds.
    pub waypoint_timeout_s: f64,
    /// Half-width of the lander box, metres.
    pub lander_half_extent_m: f64,
    /// The route planner used when the arcs are stuck.
    pub route: RouteConfig,
    /// Glances at the lander for absolute fixes.
    pub glance: GlanceConfig,
}

impl Default for NavigatorConfig {
    fn default() -> Self {
        Self {
            arcs: ArcPlannerConfig::default(),
            waypoint_reached_m: 1.0,
            waypoint_passed_m: 0.0,
            lookahead_m: 0.0,
            lookahead_waypoints: 1,
            point_turn_threshold_rad: 1.6,
            point_turn_rate_rps: 0.7,
            stall_window_s: 8.0,
            stall_progress_m: 0.2,
            backup_speed_mps: 0.2,
            backup_duration_s: 2.0,
            backups_per_waypoint: 3,
            require_seen_ground: true,
            commit_after_scan_s: 4.0,
            waypoint_timeout_s: 30.0,
            lander_half_extent_m: crate::ipex::LANDER_HALF_EXTENT_M,
            route: RouteConfig::default(),
            glance: GlanceConfig::default(),
        }
    }
}

/// What the navigator is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum NavMode {
    /// Following an arc.
    Drive,
    /// Turning on the spot toward the waypoint.
    PointTurn,
    /// Reversing out of a dead end.
    Backup,
    /// Turning on the spot to look around (at the start, and when no arc is free), until
    /// an arc is free or a full turn is done.
    Scan,
    /// Turning on the spot to look at the lander, then holding still for a frame.
    Glance,
}

/// Waypoint follower with the arc planner.
#[derive(Clone, Debug)]
pub struct Navigator {
    config: NavigatorConfig,
    waypoints: Vec<Point2<f64>>,
    next: usize,
    nav_from_session: Isometry2<f64>,
    mode: NavMode,
    mode_until_s: f64,
    turn_sign: f64,
    initial_scan: bool,
    in_initial_scan: bool,
    commit_until_s: f64,
    waypoint_since_s: f64,
    waypoint_backups: usize,
    progress: Vec<(f64, f64)>,
    /// The route being followed to the current waypoint, and when it was planned.
    route: Option<(Route, f64)>,
    glance: LanderGlance,
    reached: usize,
    skipped: usize,
    backups: usize,
}

impl Navigator {
    /// A navigator for `waypoints` (nav frame), with the session frame taken to be the nav
    /// frame until told otherwise.
    pub fn new(config: &NavigatorConfig, waypoints: Vec<Vector2<f64>>) -> Self {
        Self {
            config: config.clone(),
            waypoints: waypoints.into_iter().map(Point2::from).collect(),
            next: 0,
            nav_from_session: Isometry2::identity(),
            mode: NavMode::Scan,
            mode_until_s: 0.0,
            turn_sign: 1.0,
            initial_scan: true,
            in_initial_scan: false,
            commit_until_s: 0.0,
            waypoint_since_s: 0.0,
            waypoint_backups: 0,
            progress: Vec::new(),
            route: None,
            glance: LanderGlance::new(&config.glance),
            reached: 0,
            skipped: 0,
            backups: 0,
        }
    }

    /// Update the believed nav-from-session transform (e.g. after a relocalization).
    pub fn set_nav_from_session(&mut self, nav_from_session: Isometry2<f64>) {
        self.nav_from_session = nav_from_session;
    }

    /// The current mode.
    pub fn mode(&self) -> NavMode {
        self.mode
    }

    /// (waypoints reached, waypoints skipped, backup manoeuvres) so far.
    pub fn counts(&self) -> (usize, usize, usize) {
        (self.reached, self.skipped, self.backups)
    }

    /// Glances at the lander started so far.
    pub fn glances(&self) -> usize {
        self.glance.count()
    }

    /// The waypoint being driven to, nav frame.
    pub fn current_waypoint(&self) -> Option<Point2<f64>> {
        self.waypoints.get(self.next).copied()
    }

    fn advance(&mut self, time_s: f64, reached: bool) {
        if reached {
            self.reached += 1;
        } else {
            self.skipped += 1;
        }
        self.next += 1;
        if self.next >= self.waypoints.len() {
            // drive the pattern again, backwards: revisit mapped ground
            self.waypoints.reverse();
            self.next = 1.min(self.waypoints.len().saturating_sub(1));
        }
        self.waypoint_since_s = time_s;
        self.waypoint_backups = 0;
        self.progress.clear();
        self.route = None;
    }

    /// Plan a route from `here` to the current waypoint: followed from now on if there is
    /// one, the waypoint skipped if there is none. Returns whether a route was found.
    fn plan_route_or_skip(&mut self, time_s: f64, here: Point2<f64>, scene: &Scene) -> bool {
        if !self.config.route.enabled || self.waypoints.is_empty() {
            return false;
        }
        let goal = self.waypoint_session(self.next);
        match plan_route(here, goal, &self.config.arcs, scene, &self.config.route) {
            Some(route) => {
                self.route = Some((route, time_s));
                self.progress.clear();
                true
            }
            None => {
                self.advance(time_s, false);
                false
            }
        }
    }

    /// Waypoint `k` (wrapping) in the session frame.
    fn waypoint_session(&self, k: usize) -> Point2<f64> {
        let n = self.waypoints.len().max(1);
        self.nav_from_session.inverse() * self.waypoints[k % n]
    }

    /// Whether a session-frame point lies within an obstacle's clearance or the lander's.
    fn blocked(&self, p: Point2<f64>, obstacles: &ObstacleMemory) -> bool {
        let arcs = &self.config.arcs;
        let mut blocked = false;
        obstacles.for_each_near(p, arcs.required_m(obstacles.max_radius_m()), |o| {
            blocked |= (o.p - p).norm() < arcs.required_m(o.radius_m);
        });
        let q = self.nav_from_session * p;
        let h = self.config.lander_half_extent_m + arcs.clearance_m;
        blocked || (q.x.abs() < h && q.y.abs() < h)
    }

    /// Move on past waypoints that are reached, passed (the rover is beyond them along the
    /// path and near), blocked, or took too long.
    fn update_progress(&mut self, time_s: f64, here: Point2<f64>, obstacles: &ObstacleMemory) {
        if self
            .route
            .as_ref()
            .is_some_and(|(_, since)| time_s - since > self.config.route.replan_after_s)
        {
            self.route = None;
        }
        for _ in 0..self.waypoints.len() {
            let a = self.waypoint_session(self.next);
            let b = self.waypoint_session(self.next + 1);
            let dist = (a - here).norm();
            if dist < self.config.waypoint_reached_m
                || (dist < self.config.waypoint_passed_m && (here - a).dot(&(b - a)) > 0.0)
            {
                self.advance(time_s, true);
                continue;
            }
            if self.blocked(a, obstacles)
                || time_s - self.waypoint_since_s > self.config.waypoint_timeout_s
                || self.waypoint_backups >= self.config.backups_per_waypoint
            {
                self.advance(time_s, false);
                continue;
            }
            break;
        }
    }

    /// The point to steer for (session frame): the first unblocked waypoint from the next one
    /// on that is at least `lookahead_m` away (pure pursuit along the waypoint path), within
    /// `lookahead_waypoints`; the next waypoint when none is.
    fn carrot(&self, here: Point2<f64>, obstacles: &ObstacleMemory) -> Point2<f64> {
        let first = self.waypoint_session(self.next);
        if let Some(p) = self
            .route
            .as_ref()
            .and_then(|(r, _)| r.carrot(here, self.config.route.lookahead_m))
        {
            return p;
        }
        let mut goal = first;
        let n = self.waypoints.len();
        for k in self.next..self.next + self.config.lookahead_waypoints.min(n) {
            if k >= n && self.next + 1 < n {
                break;
            }
            let p = self.waypoint_session(k);
            if self.blocked(p, obstacles) {
                continue;
            }
            goal = p;
            if (p - here).norm() >= self.config.lookahead_m {
                break;
            }
        }
        goal
    }

    /// Progress along the path: waypoints passed (each worth its spacing, taken as 100 m so
    /// that passing one always counts) minus the distance to the next, metres.
    fn path_progress(&self, here: Point2<f64>) -> f64 {
        let passed = (self.reached + self.skipped) as f64;
        let left = match &self.route {
            Some((route, _)) => route.remaining_m(here),
            None => (self.waypoint_session(self.next) - here).norm(),
        };
        100.0 * passed - left
    }

    /// The command for this control cycle, from the estimated pose (session frame) and the
    /// remembered obstacles.
    /// Unseen ground counts as blocked when `seen` is given.
    pub fn command(
        &mut self,
        time_s: f64,
        pose: Pose2,
        obstacles: &ObstacleMemory,
        seen: Option<&SeenGrid>,
    ) -> Command {
        let stop = Command::default();
        if self.waypoints.is_empty() || !pose.x.is_finite() || !pose.y.is_finite() {
            return stop;
        }
        let session_from_nav = self.nav_from_session.inverse();
        let lander = LanderBox {
            session_from_lander: session_from_nav,
            half_extent_m: self.config.lander_half_extent_m,
        };
        let scene = Scene {
            obstacles,
            lander: Some(lander),
            nav_from_session: self.nav_from_session,
            seen: seen.filter(|_| self.config.require_seen_ground),
        };
        let here = Point2::new(pose.x, pose.y);
        self.update_progress(time_s, here, obstacles);
        let goal = self.carrot(here, obstacles);
        let to_goal = goal - here;
        let bearing = wrap_angle(to_goal.y.atan2(to_goal.x) - pose.yaw);
        let progress = self.path_progress(here);
        let full_turn_s = 2.0 * std::f64::consts::PI / self.config.point_turn_rate_rps.max(0.05);
        if self.initial_scan {
            // look all around before the first move
            self.initial_scan = false;
            self.in_initial_scan = true;
            self.start_scan(time_s + full_turn_s, bearing);
        }
        if let Some(command) = self.manoeuvre(time_s, pose, goal, &scene, full_turn_s) {
            return command;
        }
        if let Some(command) = self.glance_step(time_s, pose, session_from_nav * Point2::origin()) {
            return command;
        }
        if let Some(command) = self.stall_check(time_s, here, progress, &scene) {
            return command;
        }
        self.steer(time_s, pose, (goal, bearing), &scene, full_turn_s)
    }

    /// Enters the scan mode until `until_s`, turning towards the goal's side.
    fn start_scan(&mut self, until_s: f64, bearing: f64) {
        self.mode = NavMode::Scan;
        self.mode_until_s = until_s;
        self.turn_sign = if bearing >= 0.0 { 1.0 } else { -1.0 };
    }

    /// The manoeuvres in progress: backing up (then scanning), and scanning for a free arc;
    /// `None` when none is (or the initial look around just ended).
    fn manoeuvre(
        &mut self,
        time_s: f64,
        pose: Pose2,
        goal: Point2<f64>,
        scene: &Scene<'_>,
        full_turn_s: f64,
    ) -> Option<Command> {
        if self.mode == NavMode::Backup {
            let back = Pose2::new(pose.x, pose.y, pose.yaw + std::f64::consts::PI);
            let speed = self.config.backup_speed_mps;
            let check = ArcPlannerConfig {
                horizon_s: 2.0,
                ..self.config.arcs.clone()
            };
            let back_scene = Scene {
                seen: None,
                ..*scene
            };
            if time_s < self.mode_until_s && check.arc_is_free(back, speed, 0.0, &back_scene) {
                return Some(Command {
                    speed_mps: -speed,
                    yaw_rate_rps: 0.0,
                });
            }
            self.mode = NavMode::Scan;
            self.mode_until_s = time_s + full_turn_s;
        }
        if self.mode == NavMode::Scan {
            return self.scan(time_s, pose, goal, scene);
        }
        None
    }

    /// One cycle of the scan: turn in place until an arc is free (except during the first
    /// look around), back up when the scan ends without one; `None` when the initial look
    /// around ends (the rover drives on).
    fn scan(
        &mut self,
        time_s: f64,
        pose: Pose2,
        goal: Point2<f64>,
        scene: &Scene<'_>,
    ) -> Option<Command> {
        let initial = self.in_initial_scan;
        if time_s < self.mode_until_s {
            // leave as soon as an arc is free (except during the first look around)
            if !initial || time_s + 1e-9 >= self.mode_until_s {
                if let Some(arc) = self.config.arcs.choose(pose, goal, scene) {
                    self.mode = NavMode::Drive;
                    self.in_initial_scan = false;
                    // follow the way out for a while before turning back to the goal
                    self.commit_until_s = time_s + self.config.commit_after_scan_s;
                    self.progress.clear();
                    return Some(Command {
                        speed_mps: arc.speed_mps,
                        yaw_rate_rps: arc.yaw_rate_rps,
                    });
                }
            }
            return Some(Command {
                speed_mps: 0.0,
                yaw_rate_rps: self.turn_sign * self.config.point_turn_rate_rps,
            });
        }
        if !initial {
            return Some(self.start_backup(time_s));
        }
        self.in_initial_scan = false;
        self.mode = NavMode::Drive;
        self.progress.clear();
        None
    }

    /// A glance at the lander (at `lander_centre`, session frame) while driving: its
    /// command while it lasts.
    fn glance_step(
        &mut self,
        time_s: f64,
        pose: Pose2,
        lander_centre: Point2<f64>,
    ) -> Option<Command> {
        let may_glance = matches!(self.mode, NavMode::Drive | NavMode::Glance);
        match self.glance.step(time_s, pose, lander_centre, may_glance) {
            GlanceStep::Active(command) => {
                self.mode = NavMode::Glance;
                return Some(command);
            }
            GlanceStep::Finished { duration_s } => {
                // the glance's time counts neither against the waypoint nor as a stall
                self.mode = NavMode::Drive;
                self.waypoint_since_s += duration_s;
                self.progress.clear();
            }
            GlanceStep::Idle => {}
        }
        None
    }

    /// A stall (no `progress` over the window): a route around on the first one for this
    /// waypoint, else a backup (its command).
    fn stall_check(
        &mut self,
        time_s: f64,
        here: Point2<f64>,
        progress: f64,
        scene: &Scene<'_>,
    ) -> Option<Command> {
        self.progress.push((time_s, progress));
        let window = self.config.stall_window_s;
        self.progress.retain(|&(t, _)| time_s - t <= window);
        if let Some(&(t0, p0)) = self.progress.first() {
            if time_s - t0 >= window * 0.95 && progress - p0 < self.config.stall_progress_m {
                // a first stall on the way to this waypoint: look for a route around
                if self.route.is_some() || !self.plan_route_or_skip(time_s, here, scene) {
                    return Some(self.start_backup(time_s));
                }
            }
        }
        None
    }

    /// Towards the goal (at `bearing` from the heading): a point turn when it lies too far
    /// aside (and no way out is being followed), else the best free arc, else a scan.
    fn steer(
        &mut self,
        time_s: f64,
        pose: Pose2,
        (goal, bearing): (Point2<f64>, f64),
        scene: &Scene<'_>,
        full_turn_s: f64,
    ) -> Command {
        let committed = time_s < self.commit_until_s;
        if !committed
            && (bearing.abs() > self.config.point_turn_threshold_rad
                || (self.mode == NavMode::PointTurn && bearing.abs() > 0.3))
        {
            self.mode = NavMode::PointTurn;
            return Command {
                speed_mps: 0.0,
                yaw_rate_rps: bearing.signum() * self.config.point_turn_rate_rps,
            };
        }
        match self.config.arcs.choose(pose, goal, scene) {
            Some(arc) => {
                self.mode = NavMode::Drive;
                Command {
                    speed_mps: arc.speed_mps,
                    yaw_rate_rps: arc.yaw_rate_rps,
                }
            }
            None => {
                // nothing free ahead: a route to steer along, and look around for a way
                if self.route.is_none() {
                    self.plan_route_or_skip(time_s, Point2::new(pose.x, pose.y), scene);
                }
                self.start_scan(time_s + full_turn_s, bearing);
                Command {
                    speed_mps: 0.0,
                    yaw_rate_rps: self.turn_sign * self.config.point_turn_rate_rps,
                }
            }
        }
    }

    fn start_backup(&mut self, time_s: f64) -> Command {
        self.backups += 1;
        self.waypoint_backups += 1;
        self.progress.clear();
        self.mode = NavMode::Backup;
        self.mode_until_s = time_s + self.config.backup_duration_s;
        // alternate the turn direction so repeated backups explore both sides
        self.turn_sign = -self.turn_sign;
        Command::default()
    }
}

#[cfg(test)]
mod tests {
    //! Tests of the navigator.

    use super::*;
    use crate::planning::kinematics::{RoverConfig, RoverState};
    use crate::planning::obstacles::ObstacleConfig;

    fn drive(
        nav: &mut Navigator,
        obstacles: &ObstacleMemory,
        start: RoverState,
        seconds: f64,
    ) -> RoverState {
        let mut s = start;
        let config = RoverConfig::default();
        let mut t = 0.0;
        while t < seconds {
            let cmd = nav.command(t, Pose2::new(s.x, s.y, s.yaw), obstacles, None);
            s.step(cmd, &config, 0.05);
            t += 0.05;
        }
        s
    }

    #[test]
    fn reaches_waypoints_around_a_rock() {
        let mut obstacles = ObstacleMemory::new(&ObstacleConfig::default());
        obstacles.add_rock(Point2::new(6.0, 0.0), 0.3);
        obstacles.add_rock(Point2::new(6.0, 0.0), 0.3);
        let mut nav = Navigator::new(
            &NavigatorConfig::default(),
            vec![Vector2::new(9.0, 0.0), Vector2::new(9.0, 4.0)],
        );
        let start = RoverState::at_rest(3.0, 0.0, 0.0);
        let mut s = start;
        let config = RoverConfig::default();
        let mut t = 0.0;
        let mut min_d = f64::INFINITY;
        while t < 40.0 {
            let cmd = nav.command(t, Pose2::new(s.x, s.y, s.yaw), &obstacles, None);
            s.step(cmd, &config, 0.05);
            min_d = min_d.min((s.x - 6.0).hypot(s.y));
            t += 0.05;
        }
        assert!(nav.counts().0 >= 2, "{:?}", nav.counts());
        assert!(min_d > 0.65 + 0.3 - 0.05, "{min_d}");
    }

    #[test]
    fn passes_waypoints_beyond_and_skips_blocked_ones_for_the_carrot() {
        let config = NavigatorConfig {
            waypoint_passed_m: 2.5,
            lookahead_m: 2.0,
            lookahead_waypoints: 4,
            ..NavigatorConfig::default()
        };
        let mut obstacles = ObstacleMemory::new(&ObstacleConfig::default());
        let path = vec![
            Vector2::new(4.0, 0.0),
            Vector2::new(6.0, 0.0),
            Vector2::new(8.0, 0.0),
            Vector2::new(10.0, 0.0),
        ];
        let mut nav = Navigator::new(&config, path);
        // 1.56 m from the first waypoint but beyond it along the path: passed
        let here = Point2::new(5.0, 1.2);
        nav.update_progress(0.0, here, &obstacles);
        assert_eq!(nav.counts(), (1, 0, 0));
        assert_eq!(nav.current_waypoint(), Some(Point2::new(6.0, 0.0)));
        // the carrot is the first waypoint at least 2 m ahead, skipping a blocked one
        assert_eq!(nav.carrot(here, &obstacles), Point2::new(8.0, 0.0));
        obstacles.add_rock(Point2::new(8.0, 0.2), 0.2);
        obstacles.add_rock(Point2::new(8.0, 0.2), 0.2);
        assert_eq!(nav.carrot(here, &obstacles), Point2::new(10.0, 0.0));
    }

    #[test]
    fn turns_on_the_spot_for_a_waypoint_behind() {
        let obstacles = ObstacleMemory::new(&ObstacleConfig::default());
        let mut nav = Navigator::new(&NavigatorConfig::default(), vec![Vector2::new(-5.0, 3.0)]);
        let c = nav.command(0.0, Pose2::new(0.0, 3.0, 0.0), &obstacles, None);
        assert_eq!(c.speed_mps, 0.0);
        assert!(c.yaw_rate_rps.abs() > 0.0);
        assert_eq!(nav.mode(), NavMode::Scan);
        let s = drive(
            &mut nav,
            &obstacles,
            RoverState::at_rest(0.0, 3.0, 0.0),
            40.0,
        );
        assert!(nav.counts().0 >= 1, "{s:?}");
    }

    #[test]
    fn backs_up_when_boxed_in() {
        let mut obstacles = ObstacleMemory::new(&ObstacleConfig::default());
        for k in 0..13 {
            let a = -1.2 + 0.2 * k as f64;
            obstacles.add_rock(Point2::new(1.0 * a.cos(), 1.0 * a.sin()), 0.1);
            obstacles.add_rock(Point2::new(1.0 * a.cos(), 1.0 * a.sin()), 0.1);
        }
        let mut nav = Navigator::new(&NavigatorConfig::default(), vec![Vector2::new(8.0, 0.0)]);
        // the first look around, then a second full turn finds nothing free: back up
        let mut t = 0.0;
        while nav.mode() != NavMode::Backup && t < 30.0 {
            let _ = nav.command(t, Pose2::new(0.0, 0.0, 0.0), &obstacles, None);
            t += 0.05;
        }
        assert_eq!(nav.mode(), NavMode::Backup);
        let c = nav.command(t, Pose2::new(0.0, 0.0, 0.0), &obstacles, None);
        assert!(c.speed_mps < 0.0);
    }

    /// A U of rocks open to the west, the waypoint east of it: the arcs alone turn back
    /// into the U after every way out; the route leads around it.
    fn escape_from_a_pocket(route: bool) -> (usize, f64) {
        let mut obstacles = ObstacleMemory::new(&ObstacleConfig::default());
        // 8 m north-east of the lander
        let mut rock = |x: f64, y: f64| {
            obstacles.add_rock(Point2::new(x + 8.0, y + 8.0), 0.1);
            obstacles.add_rock(Point2::new(x + 8.0, y + 8.0), 0.1);
        };
        for k in 0..=12 {
            let t = -3.0 + 0.5 * k as f64;
            rock(2.0, t); // the east wall
        }
        for k in 0..=8 {
            let x = -2.0 + 0.5 * k as f64;
            rock(x, 3.0);
            rock(x, -3.0);
        }
        let config = NavigatorConfig {
            route: RouteConfig {
                enabled: route,
                ..RouteConfig::default()
            },
            waypoint_timeout_s: 200.0,
            backups_per_waypoint: 100,
            ..NavigatorConfig::default()
        };
        let mut nav = Navigator::new(&config, vec![Vector2::new(14.0, 8.0)]);
        let mut s = RoverState::at_rest(8.0, 8.0, 0.0);
        let rover = RoverConfig::default();
        let (mut t, mut closest) = (0.0, f64::INFINITY);
        while t < 150.0 && nav.counts().0 == 0 {
            let cmd = nav.command(t, Pose2::new(s.x, s.y, s.yaw), &obstacles, None);
            s.step(cmd, &rover, 0.05);
            for o in obstacles.obstacles() {
                closest = closest.min((o.p - Point2::new(s.x, s.y)).norm());
            }
            t += 0.05;
        }
        (nav.counts().0, closest)
    }

    #[test]
    fn a_route_leads_out_of_a_pocket() {
        let (reached, closest) = escape_from_a_pocket(true);
        assert_eq!(reached, 1);
        assert!(closest > 0.7, "{closest}");
        let (reached, _) = escape_from_a_pocket(false);
        assert_eq!(reached, 0, "the arcs alone stay in the pocket");
    }

    #[test]
    fn glances_at_the_lander_on_an_outer_loop_and_drives_on() {
        // a square loop of half-side 9 m round the lander, driven tangentially: the lander
        // stays beside the rover, out of both cameras' views, unless it glances
        let loop_waypoints: Vec<Vector2<f64>> = (0..16)
            .map(|k| {
                let a = k as f64 / 16.0 * std::f64::consts::TAU;
                Vector2::new(9.0 * a.cos(), 9.0 * a.sin())
            })
            .collect();
        let obstacles = ObstacleMemory::new(&ObstacleConfig::default());
        let run = |glance: bool| {
            let mut config = NavigatorConfig::default();
            config.glance.enabled = glance;
            let mut nav = Navigator::new(&config, loop_waypoints.clone());
            let start = RoverState::at_rest(9.0, 0.0, std::f64::consts::FRAC_PI_2);
            drive(&mut nav, &obstacles, start, 90.0);
            (nav.glances(), nav.counts().0)
        };
        let (glances_off, reached_off) = run(false);
        let (glances, reached) = run(true);
        assert_eq!(glances_off, 0);
        // a glance every 20 s out of view, a few seconds each
        assert!((2..=5).contains(&glances), "{glances} glances");
        assert!(
            reached + 3 >= reached_off && reached >= 8,
            "{reached} vs {reached_off}"
        );
    }
}
