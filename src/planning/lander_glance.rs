//! Glances at the lander: on the outer loops the rover drives tangentially round the lander,
//! which then stays beside it, outside both cameras' views, and the odometry's drift grows
//! unchecked. Every `period_s` without the lander in a camera's view (while within
//! `max_range_m` of it) the rover stops, turns on the spot until the nearer camera looks at
//! the lander, holds still long enough for a camera frame, and drives on. The lander's sides
//! measured in that frame give the mission an absolute pose fix
//! ([`crate::localizer::lander_factor`]). Turning on the spot sweeps no new ground, so a glance
//! is always collision-free.

use crate::planning::kinematics::{wrap_angle, Command};
use crate::planning::Pose2;
use nalgebra::Point2;
use serde::{Deserialize, Serialize};

/// Parameters of the lander glances.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GlanceConfig {
    /// Glance at all.
    pub enabled: bool,
    /// Glance once the lander has been out of view this long, seconds.
    pub period_s: f64,
    /// … and only while the rover is at least this far from the lander's centre, metres
    /// (nearer, the lander comes into view on every turn anyway).
    pub min_range_m: f64,
    /// … and at most this far, metres (the range out to which its sides are measured).
    pub max_range_m: f64,
    /// The lander counts as in view when its centre's bearing is within this angle of a
    /// camera's axis, degrees (the cameras' half field of view is 35°).
    pub in_view_deg: f64,
    /// A glance turns until the bearing is within this angle of the nearer camera's axis,
    /// degrees.
    pub aim_deg: f64,
    /// Yaw rate of the turn, rad/s.
    pub turn_rate_rps: f64,
    /// Hold still this long once aimed, seconds (a camera frame comes once a second).
    pub hold_s: f64,
    /// Give a glance up after this long, seconds.
    pub timeout_s: f64,
}

impl Default for GlanceConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            period_s: 20.0,
            min_range_m: 6.0,
            max_range_m: 14.0,
            in_view_deg: 25.0,
            aim_deg: 8.0,
            turn_rate_rps: 0.7,
            hold_s: 1.05,
            timeout_s: 8.0,
        }
    }
}

impl GlanceConfig {
    /// True when the values are usable (checked whether or not glances are enabled).
    pub fn is_valid(&self) -> bool {
        let positive = [self.period_s, self.turn_rate_rps, self.timeout_s];
        let finite = [
            self.min_range_m,
            self.max_range_m,
            self.in_view_deg,
            self.aim_deg,
            self.hold_s,
        ];
        positive.iter().all(|v| v.is_finite() && *v > 0.0)
            && finite.iter().all(|v| v.is_finite())
            && self.hold_s >= 0.0
    }
}

/// What the glance wants this control cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GlanceStep {
    /// No glance under way: drive on.
    Idle,
    /// A glance is under way: send this command.
    Active(Command),
    /// A glance ended this cycle, after `duration_s` (the navigator's waypoint clock pauses
    /// for it).
    Finished {
        /// How long the glance took, seconds.
        duration_s: f64,
    },
}

/// The glance state machine of one session.
#[derive(Clone, Debug)]
pub struct LanderGlance {
    config: GlanceConfig,
    last_in_view_s: f64,
    /// Start of the glance under way, and when its hold ends once aimed.
    active: Option<(f64, Option<f64>)>,
    glances: usize,
}

impl LanderGlance {
    /// A glance state machine; the clock of the lander's last view starts at time 0.
    pub fn new(config: &GlanceConfig) -> Self {
        Self {
            config: config.clone(),
            last_in_view_s: 0.0,
            active: None,
            glances: 0,
        }
    }

    /// Glances started so far.
    pub fn count(&self) -> usize {
        self.glances
    }

    /// The step for this control cycle, from the estimated pose and the lander's centre
    /// (both in the session frame). `may_start`: the navigator is driving normally, so a new
    /// glance may begin now.
    pub fn step(
        &mut self,
        time_s: f64,
        pose: Pose2,
        lander: Point2<f64>,
        may_start: bool,
    ) -> GlanceStep {
        let c = &self.config;
        if !c.enabled {
            return GlanceStep::Idle;
        }
        let to_lander = lander - Point2::new(pose.x, pose.y);
        let range = to_lander.norm();
        let front = wrap_angle(to_lander.y.atan2(to_lander.x) - pose.yaw);
        let back = wrap_angle(front - std::f64::consts::PI);
        // the turn that brings the nearer camera's axis onto the lander
        let turn = if front.abs() <= back.abs() {
            front
        } else {
            back
        };
        if range <= c.max_range_m && turn.abs() <= c.in_view_deg.to_radians() {
            self.last_in_view_s = time_s;
        }
        let Some((start_s, hold_until)) = self.active else {
            let due = time_s - self.last_in_view_s > c.period_s;
            if !(may_start && due && (c.min_range_m..=c.max_range_m).contains(&range)) {
                return GlanceStep::Idle;
            }
            self.glances += 1;
            self.active = Some((time_s, None));
            return self.turn_toward(turn);
        };
        let finished = GlanceStep::Finished {
            duration_s: time_s - start_s,
        };
        if time_s - start_s > c.timeout_s {
            self.active = None;
            return finished;
        }
        match hold_until {
            Some(until) if time_s >= until => {
                self.active = None;
                self.last_in_view_s = time_s;
                finished
            }
            Some(_) => GlanceStep::Active(Command::default()),
            None if turn.abs() <= c.aim_deg.to_radians() => {
                self.active = Some((start_s, Some(time_s + c.hold_s)));
                GlanceStep::Active(Command::default())
            }
            None => self.turn_toward(turn),
        }
    }

    fn turn_toward(&self, turn: f64) -> GlanceStep {
        GlanceStep::Active(Command {
            speed_mps: 0.0,
            yaw_rate_rps: turn.signum() * self.config.turn_rate_rps,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn enabled() -> GlanceConfig {
        GlanceConfig {
            enabled: true,
            ..GlanceConfig::default()
        }
    }

    /// Runs the glance on a rover that only turns (as the navigator would let it), from
    /// `yaw`, until it ends; returns the final yaw and the duration.
    fn run(glance: &mut LanderGlance, t0: f64, pose: Pose2, lander: Point2<f64>) -> (f64, f64) {
        let mut yaw = pose.yaw;
        let mut t = t0;
        loop {
            let p = Pose2::new(pose.x, pose.y, yaw);
            match glance.step(t, p, lander, true) {
                GlanceStep::Active(cmd) => {
                    assert_eq!(cmd.speed_mps, 0.0);
                    yaw += cmd.yaw_rate_rps * 0.05;
                }
                GlanceStep::Finished { duration_s } => return (yaw, duration_s),
                GlanceStep::Idle => panic!("glance stopped without finishing"),
            }
            t += 0.05;
            assert!(t < t0 + 20.0);
        }
    }

    #[test]
    fn bad_values_are_invalid() {
        assert!(GlanceConfig::default().is_valid());
        for bad in [
            GlanceConfig {
                period_s: 0.0,
                ..GlanceConfig::default()
            },
            GlanceConfig {
                turn_rate_rps: f64::NAN,
                ..GlanceConfig::default()
            },
            GlanceConfig {
                hold_s: -1.0,
                ..GlanceConfig::default()
            },
            GlanceConfig {
                max_range_m: f64::INFINITY,
                ..GlanceConfig::default()
            },
        ] {
            assert!(!bad.is_valid(), "{bad:?}");
        }
    }

    #[test]
    fn turns_the_nearer_camera_onto_the_lander_and_holds() {
        let mut glance = LanderGlance::new(&enabled());
        let lander = Point2::origin();
        // on the outer loop, heading along it: the lander is 90° to the left
        let pose = Pose2::new(0.0, -12.0, 0.0);
        assert_eq!(glance.step(5.0, pose, lander, true), GlanceStep::Idle);
        let (yaw, duration) = run(&mut glance, 25.0, pose, lander);
        assert_eq!(glance.count(), 1);
        // front camera onto the lander (bearing +90°), within the aim tolerance
        assert!((yaw - std::f64::consts::FRAC_PI_2).abs() <= 8f64.to_radians() + 0.04);
        // the turn (about 2.2 s) and the hold
        assert!(duration > 3.0 && duration < 4.0, "{duration}");
        // just glanced: nothing due for a period
        let p = Pose2::new(0.0, -12.0, yaw);
        assert_eq!(glance.step(30.0, p, lander, true), GlanceStep::Idle);
    }

    #[test]
    fn uses_the_back_camera_when_it_is_nearer() {
        let mut glance = LanderGlance::new(&enabled());
        let lander = Point2::origin();
        // heading away from the lander, off by 40°: the back camera is nearer than the
        // front one (140°), but the lander is outside its view
        let pose = Pose2::new(10.0, 0.0, -40f64.to_radians());
        let (yaw, _) = run(&mut glance, 25.0, pose, lander);
        assert!(yaw.abs() < 9f64.to_radians(), "{}", yaw.to_degrees());
    }

    #[test]
    fn no_glance_when_near_far_disabled_or_the_lander_was_seen() {
        let lander = Point2::origin();
        let beside = |d: f64| Pose2::new(0.0, -d, 0.0);
        let mut glance = LanderGlance::new(&enabled());
        assert_eq!(
            glance.step(30.0, beside(4.0), lander, true),
            GlanceStep::Idle
        );
        assert_eq!(
            glance.step(30.0, beside(16.0), lander, true),
            GlanceStep::Idle
        );
        assert_eq!(
            glance.step(30.0, beside(10.0), lander, false),
            GlanceStep::Idle
        );
        let mut off = LanderGlance::new(&GlanceConfig::default());
        assert_eq!(off.step(30.0, beside(10.0), lander, true), GlanceStep::Idle);
        // facing the lander at 15 s: the clock restarts, nothing due at 30 s
        let mut seen = LanderGlance::new(&enabled());
        let facing = Pose2::new(0.0, -10.0, std::f64::consts::FRAC_PI_2);
        assert_eq!(seen.step(15.0, facing, lander, true), GlanceStep::Idle);
        assert_eq!(
            seen.step(30.0, beside(10.0), lander, true),
            GlanceStep::Idle
        );
        assert!(matches!(
            seen.step(36.0, beside(10.0), lander, true),
            GlanceStep::Active(_)
        ));
    }
}
