//! The IPEX rover as a differential drive on the terrain: commanded speed and yaw rate,
//! clamped to the LAC limits and rate-limited, integrated at 20 Hz on the horizontal plane;
//! height, roll and pitch follow the height field under the four wheels.

use crate::sim::ipex::{
    BODY_ABOVE_GROUND_M, MAX_SPEED_MPS, MAX_YAW_RATE_RPS, WHEEL_DIAMETER_M, WHEEL_X_M, WHEEL_Y_M,
};
use crate::sim::moon::Moon;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
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

/// The rover's planar state (the terrain gives the rest of the pose).
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

    /// The full pose on `moon`: `world_from_rover`.
    pub fn pose(&self, moon: &Moon) -> Isometry3<f64> {
        terrain_pose(moon, self.x, self.y, self.yaw)
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

/// `world_from_rover` for the rover at (x, y) heading `yaw` resting on the terrain: each
/// wheel stands on the highest ground under its contact patch (three samples along the
/// wheel), pitch and roll from the front–rear and left–right height differences, the body
/// origin 0.119 m above the mean contact height.
pub fn terrain_pose(moon: &Moon, x: f64, y: f64, yaw: f64) -> Isometry3<f64> {
    let (c, s) = (yaw.cos(), yaw.sin());
    let patch = WHEEL_DIAMETER_M / 4.0;
    let contact = |bx: f64, by: f64| {
        [-patch, 0.0, patch]
            .iter()
            .map(|&dx| {
                let (px, py) = (bx + dx, by);
                moon.height_at(x + c * px - s * py, y + s * px + c * py)
            })
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let fl = contact(WHEEL_X_M, WHEEL_Y_M);
    let fr = contact(WHEEL_X_M, -WHEEL_Y_M);
    let rl = contact(-WHEEL_X_M, WHEEL_Y_M);
    let rr = contact(-WHEEL_X_M, -WHEEL_Y_M);
    let slope_forward = ((fl + fr) - (rl + rr)) / 2.0 / (2.0 * WHEEL_X_M);
    let slope_left = ((fl + rl) - (fr + rr)) / 2.0 / (2.0 * WHEEL_Y_M);
    // R = Rz(yaw) Ry(pitch) Rx(roll): nose up is negative pitch, left side up positive roll
    let pitch = -slope_forward.atan();
    let roll = slope_left.atan();
    let z = (fl + fr + rl + rr) / 4.0 + BODY_ABOVE_GROUND_M;
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::moon::MoonConfig;
    use nalgebra::Vector3;

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
    fn pose_follows_terrain() {
        let m = Moon::generate(&MoonConfig::default(), 2).unwrap();
        let p = terrain_pose(&m, 6.0, -4.0, 0.7);
        let up = p.rotation * Vector3::z();
        // close to the terrain normal, body origin ~0.12 m over the ground
        assert!(up.dot(&m.normal_at(6.0, -4.0)) > 0.99);
        assert!((p.translation.z - m.height_at(6.0, -4.0) - 0.119).abs() < 0.05);
        let (_, _, yaw) = p.rotation.euler_angles();
        assert!((yaw - 0.7).abs() < 1e-9);
    }

    #[test]
    fn wraps_angles() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-12);
    }
}
