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
