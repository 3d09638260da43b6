//! The rover's differential drive as the planner reasons about it: a velocity [`Command`],
//! the drive limits ([`RoverConfig`], the LAC's by default) and the planar [`RoverState`]
//! integrated under a command, clamped and rate-limited, on the horizontal plane.
//!
//! The simulator drives the same model (`sim::rover` re-exports these types and adds the
//! pose on the terrain, `RoverState::pose`); the planner predicts with it and issues its
//! commands.

use crate::ipex::{MAX_SPEED_MPS, MAX_YAW_RATE_RPS};
use serde::{Deserialize, Serialize};

/// Drive limits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RoverConfig {
    /// Largest |speed|, m/s (LAC: 0.49).
    pub max_speed_mps: f64,
    /// Largest |yaw rate|, rad/s (LAC: 4.13).
    pub max_yaw_rate_rps: f64,
    /// Largest change of speed per second, m/s².
    pub max_accel_mps2: f64,
    /// Largest change of yaw rate per second, rad/s².
    pub max_yaw_accel_rps2: f64,
}

impl Default for RoverConfig {
    fn default() -> Self {
        Self {
            max_speed_mps: MAX_SPEED_MPS,
            max_yaw_rate_rps: MAX_YAW_RATE_RPS,
            max_accel_mps2: 1.0,
            max_yaw_accel_rps2: 8.0,
        }
    }
}

/// A velocity command: forward speed and yaw rate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Command {
    /// Forward speed, m/s (negative: reverse).
    pub speed_mps: f64,
    /// Yaw rate, rad/s, counter-clockwise.
    pub yaw_rate_rps: f64,
}

/// The rover's planar state (the terrain gives the rest of the pose: `RoverState::pose` in
/// `sim::rover`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RoverState {
    /// Position x, world frame, metres.
    pub x: f64,
    /// Position y, world frame, metres.
    pub y: f64,
    /// Heading, radians.
    pub yaw: f64,
    /// Current forward speed, m/s.
    pub speed_mps: f64,
    /// Current yaw rate, rad/s.
    pub yaw_rate_rps: f64,
}

impl RoverState {
    /// At rest at (x, y) heading `yaw`.
    pub fn at_rest(x: f64, y: f64, yaw: f64) -> Self {
        Self {
            x,
            y,
            yaw,
            ..Self::default()
        }
    }

    /// Advance by `dt_s` under `command`, clamped to the limits and rate-limited; a
    /// non-finite command stops the rover.
    pub fn step(&mut self, command: Command, config: &RoverConfig, dt_s: f64) {
        let clean = |v: f64| if v.is_finite() { v } else { 0.0 };
        let target_v = clean(command.speed_mps).clamp(-config.max_speed_mps, config.max_speed_mps);
        let target_w =
            clean(command.yaw_rate_rps).clamp(-config.max_yaw_rate_rps, config.max_yaw_rate_rps);
        let dv = config.max_accel_mps2 * dt_s;
        let dw = config.max_yaw_accel_rps2 * dt_s;
        self.speed_mps += (target_v - self.speed_mps).clamp(-dv, dv);
        self.yaw_rate_rps += (target_w - self.yaw_rate_rps).clamp(-dw, dw);
        // exact integration of a constant-curvature arc over the step
        let (v, w) = (self.speed_mps, self.yaw_rate_rps);
        if w.abs() < 1e-9 {
            self.x += v * dt_s * self.yaw.cos();
            self.y += v * dt_s * self.yaw.sin();
        } else {
            let yaw1 = self.yaw + w * dt_s;
            self.x += v / w * (yaw1.sin() - self.yaw.sin());
            self.y += v / w * (self.yaw.cos() - yaw1.cos());
        }
        self.yaw = wrap_angle(self.yaw + w * dt_s);
    }
}

/// Angle wrapped to (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    let w = (a + std::f64::consts::PI).rem_euclid(two_pi) - std::f64::consts::PI;
    if w <= -std::f64::consts::PI {
        w + two_pi
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_are_respected() {
        let config = RoverConfig::default();
        let mut s = RoverState::at_rest(0.0, 0.0, 0.0);
        for _ in 0..100 {
            s.step(
                Command {
                    speed_mps: 5.0,
                    yaw_rate_rps: -50.0,
                },
                &config,
                0.05,
            );
            assert!(s.speed_mps.abs() <= 0.49 + 1e-12);
            assert!(s.yaw_rate_rps.abs() <= 4.13 + 1e-12);
        }
        s.step(
            Command {
                speed_mps: f64::NAN,
                yaw_rate_rps: 0.0,
            },
            &config,
            0.05,
        );
        assert!(s.x.is_finite() && s.speed_mps.is_finite());
    }

    #[test]
    fn arc_integration_is_a_circle() {
        let config = RoverConfig {
            max_accel_mps2: 1e9,
            max_yaw_accel_rps2: 1e9,
            ..RoverConfig::default()
        };
        let mut s = RoverState::at_rest(1.0, 0.0, std::f64::consts::FRAC_PI_2);
        let cmd = Command {
            speed_mps: 0.4,
            yaw_rate_rps: 0.4,
        };
        let steps = (2.0 * std::f64::consts::PI / 0.4 / 0.05).round() as usize;
        for _ in 0..steps {
            s.step(cmd, &config, 0.05);
            assert!((s.x.hypot(s.y) - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn wraps_angles() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-12);
    }
}
