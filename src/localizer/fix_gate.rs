//! The consistency gate of session 2's relocalizations.
//!
//! A relocalization can pass every test of the relocalizer and still be wrong by a degree:
//! the submap it aligned was bent by the odometry's yaw error, or it matched a part of the
//! prior map that is itself a little off. One result alone cannot tell; two independent ones
//! can. So a result enters the pose graph only when it agrees with an independent estimate of
//! the same pose: the graph's prediction (the earlier fixes carried forward by odometry) once
//! the session is localized, or else an earlier result awaiting confirmation (carried forward
//! by odometry). Results that disagree wait as the new candidate; two consecutive results
//! that agree with each other but not with the graph are accepted together (the graph was the
//! one off), so a wrong first fix cannot lock the session out.

use nalgebra::Isometry3;

/// The tolerance of the agreement between two estimates of the same pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// Horizontal distance, metres.
    pub position_m: f64,
    /// Yaw, radians.
    pub yaw_rad: f64,
}

impl Tolerance {
    /// The configured gate's bare tolerance.
    pub fn of_gate(config: &super::config::GateConfig) -> Self {
        Self {
            position_m: config.position_m,
            yaw_rad: config.yaw_deg.to_radians(),
        }
    }

    /// The tolerance widened by the odometry's uncertainty between the two estimates' frames
    /// (`sigma_m`, `sigma_yaw_rad`: one σ), at `n_sigma`.
    pub fn widened(&self, sigma_m: f64, sigma_yaw_rad: f64, n_sigma: f64) -> Self {
        Self {
            position_m: self.position_m + n_sigma * sigma_m,
            yaw_rad: self.yaw_rad + n_sigma * sigma_yaw_rad,
        }
    }
}

/// The difference of two estimates of the same pose: (horizontal distance m, |yaw| rad).
pub fn difference(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let d = a.inverse() * b;
    let yaw = d.rotation.euler_angles().2.abs();
    let position = (b.translation.vector - a.translation.vector).xy().norm();
    (position, yaw)
}

/// Whether two estimates of the same pose agree within `tolerance`.
pub fn agrees(a: &Isometry3<f64>, b: &Isometry3<f64>, tolerance: &Tolerance) -> bool {
    let (position, yaw) = difference(a, b);
    position <= tolerance.position_m && yaw <= tolerance.yaw_rad
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{UnitQuaternion, Vector3};

    fn pose(x: f64, y: f64, yaw_deg: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Vector3::new(x, y, 0.0).into(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians()),
        )
    }

    #[test]
    fn a_degree_of_yaw_disagrees_a_centimetre_does_not() {
        let t = Tolerance {
            position_m: 0.08,
            yaw_rad: 0.5f64.to_radians(),
        };
        let a = pose(1.0, 2.0, 30.0);
        assert!(agrees(&a, &pose(1.01, 2.0, 30.2), &t));
        assert!(!agrees(&a, &pose(1.0, 2.0, 31.1), &t));
        assert!(!agrees(&a, &pose(1.2, 2.0, 30.0), &t));
        // odometry uncertainty between the two widens the gate
        assert!(agrees(
            &a,
            &pose(1.0, 2.0, 31.1),
            &t.widened(0.0, 0.004, 3.0)
        ));
    }
}
