//! The IPEX rover on the terrain: the differential drive ([`RoverState`] under a
//! [`Command`], clamped to the [`RoverConfig`] limits, integrated at 20 Hz on the horizontal
//! plane) lives in [`crate::planning::kinematics`] with the planner that reasons about it and
//! is re-exported here; this module adds the third dimension: height, roll and pitch follow
//! the height field under the four wheels.

use crate::sim::ipex::{BODY_ABOVE_GROUND_M, WHEEL_DIAMETER_M, WHEEL_X_M, WHEEL_Y_M};
use crate::sim::moon::Moon;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

pub use crate::planning::kinematics::{wrap_angle, Command, RoverConfig, RoverState};

impl RoverState {
    /// The full pose on `moon`: `world_from_rover`.
    pub fn pose(&self, moon: &Moon) -> Isometry3<f64> {
        terrain_pose(moon, self.x, self.y, self.yaw)
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
}
