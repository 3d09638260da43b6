//! Gravity factors: the IMU's gravity direction holds every frame's roll and pitch in the
//! pose graph. Without them the tilt drifts with the odometry's relative factors (0.3–0.7°
//! rms over a 600 s session, 3–5 cm of height at 4 m range; docs/experiments.md).

use nalgebra::{Isometry3, Matrix6};

/// Information of a gravity factor on a pose whose measured attitude is `attitude`: only
/// the two rotations that tilt the body's up axis (`u`, body frame) are constrained,
/// `(I − u uᵀ) / σ²`, so that a yaw difference between the factor's target and the
/// estimate (a rotation about `u`) costs nothing; the rest is regularised to 1e-6.
pub fn gravity_information(attitude: &Isometry3<f64>, sigma_rad: f64) -> Matrix6<f64> {
    let u = attitude.rotation.inverse() * nalgebra::Vector3::z();
    let tilt = (nalgebra::Matrix3::identity() - u * u.transpose()) / (sigma_rad * sigma_rad);
    let mut info = Matrix6::identity() * 1e-6;
    let mut block = info.fixed_view_mut::<3, 3>(0, 0);
    block += tilt;
    info
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gravity_factor_costs_tilt_not_yaw() {
        use nalgebra::{UnitQuaternion, Vector3};
        let attitude = Isometry3::from_parts(
            Default::default(),
            UnitQuaternion::from_euler_angles(0.1, -0.15, 0.7),
        );
        let info = gravity_information(&attitude, 0.002);
        let cost = |r: Vector3<f64>| {
            let mut v = nalgebra::Vector6::zeros();
            v.fixed_rows_mut::<3>(0).copy_from(&r);
            (v.transpose() * info * v)[0]
        };
        // a yaw change is a rotation about the body's up axis: free
        let up = attitude.rotation.inverse() * Vector3::z();
        assert!(cost(up * 0.05) < 1e-6);
        // a tilt of 0.002 rad costs one σ²
        let tilt = up.cross(&Vector3::x()).normalize() * 0.002;
        assert!((cost(tilt) - 1.0).abs() < 1e-3);
    }
}
