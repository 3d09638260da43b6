//! SE(3) exponential and logarithm maps, adjoint and right Jacobians.
//!
//! The tangent vector of a pose is ordered **(rotation, translation)**, exactly as in GTSAM:
//! `ξ = (ω, v)` with `ω` the rotation vector and `v` the translational part of the twist.
//! Poses are `nalgebra::Isometry3<f64>`; perturbations are applied on the right,
//! `X ⊞ δ = X · Exp(δ)`.

use nalgebra::{Isometry3, Matrix3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};

/// Angle below which series expansions replace the closed forms.
const SMALL_ANGLE: f64 = 1e-2;

/// Skew-symmetric matrix `[v]×` such that `[v]× u = v × u`.
pub fn hat(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Left Jacobian of SO(3) at rotation vector `omega`:
/// `J_l(ω) = I + (1 − cos θ)/θ² [ω]× + (θ − sin θ)/θ³ [ω]×²`.
pub fn so3_left_jacobian(omega: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = omega.norm_squared();
    let theta = theta2.sqrt();
    let (b, c) = if theta < SMALL_ANGLE {
        (
            0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0,
            1.0 / 6.0 - theta2 / 120.0 + theta2 * theta2 / 5040.0,
        )
    } else {
        (
            (1.0 - theta.cos()) / theta2,
            (theta - theta.sin()) / (theta2 * theta),
        )
    };
    let w = hat(omega);
    Matrix3::identity() + w * b + w * w * c
}

/// Inverse of the left Jacobian of SO(3):
/// `J_l⁻¹(ω) = I − ½[ω]× + (1/θ² − (1 + cos θ)/(2θ sin θ)) [ω]×²`.
pub fn so3_left_jacobian_inverse(omega: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = omega.norm_squared();
    let theta = theta2.sqrt();
    let c = if theta < SMALL_ANGLE {
        1.0 / 12.0 + theta2 / 720.0 + theta2 * theta2 / 30240.0
    } else {
        1.0 / theta2 - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    let w = hat(omega);
    Matrix3::identity() - w * 0.5 + w * w * c
}

/// The `Q(ω, v)` block of the SE(3) left Jacobian (Barfoot, eq. 7.86), so that
/// `J_l(ξ) = [[J_l(ω), 0], [Q(ω, v), J_l(ω)]]` in (rotation, translation) order.
fn se3_q(omega: &Vector3<f64>, v: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = omega.norm_squared();
    let theta = theta2.sqrt();
    let (a, b, c) = if theta < SMALL_ANGLE {
        let t4 = theta2 * theta2;
        (
            1.0 / 6.0 - theta2 / 120.0 + t4 / 5040.0,
            1.0 / 24.0 - theta2 / 720.0 + t4 / 40320.0,
            1.0 / 120.0 - theta2 / 2520.0 + t4 / 120960.0,
        )
    } else {
        let (s, co) = theta.sin_cos();
        let t4 = theta2 * theta2;
        (
            (theta - s) / (theta2 * theta),
            (theta2 + 2.0 * co - 2.0) / (2.0 * t4),
            (2.0 * theta - 3.0 * s + theta * co) / (2.0 * t4 * theta),
        )
    };
    let w = hat(omega);
    let p = hat(v);
    let wp = w * p;
    let pw = p * w;
    let wpw = wp * w;
    let ww = w * w;
    p * 0.5 + (wp + pw + wpw) * a + (ww * p + pw * w - wpw * 3.0) * b + (wpw * w + w * wpw) * c
}

/// Exponential map of SE(3): `ξ = (ω, v) ↦ (Exp(ω), J_l(ω) v)`.
pub fn exp(xi: &Vector6<f64>) -> Isometry3<f64> {
    let omega = xi.fixed_rows::<3>(0).into_owned();
    let v = xi.fixed_rows::<3>(3).into_owned();
    let rotation = UnitQuaternion::from_scaled_axis(omega);
    let t = so3_left_jacobian(&omega) * v;
    Isometry3::from_parts(Translation3::from(t), rotation)
}

/// Logarithm map of SE(3), the inverse of [`exp`]: `(R, t) ↦ (Log(R), J_l(Log R)⁻¹ t)`.
pub fn log(pose: &Isometry3<f64>) -> Vector6<f64> {
    let omega = pose.rotation.scaled_axis();
    let v = so3_left_jacobian_inverse(&omega) * pose.translation.vector;
    Vector6::new(omega.x, omega.y, omega.z, v.x, v.y, v.z)
}

/// Adjoint of a pose in (rotation, translation) order: `Ad(T) = [[R, 0], [[t]× R, R]]`,
/// so that `T · Exp(ξ) · T⁻¹ = Exp(Ad(T) ξ)`.
pub fn adjoint(pose: &Isometry3<f64>) -> Matrix6<f64> {
    let r = pose.rotation.to_rotation_matrix().into_inner();
    let tr = hat(&pose.translation.vector) * r;
    let mut ad = Matrix6::zeros();
    ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    ad.fixed_view_mut::<3, 3>(3, 0).copy_from(&tr);
    ad
}

/// Inverse of the SE(3) right Jacobian, `J_r⁻¹(ξ)`, which maps a right perturbation of a pose
/// to the change of its logarithm: `Log(Exp(ξ) Exp(δ)) ≈ ξ + J_r⁻¹(ξ) δ`.
pub fn right_jacobian_inverse(xi: &Vector6<f64>) -> Matrix6<f64> {
    // J_r(ξ) = J_l(−ξ); invert the block-triangular form.
    let omega = -xi.fixed_rows::<3>(0).into_owned();
    let v = -xi.fixed_rows::<3>(3).into_owned();
    let j_inv = so3_left_jacobian_inverse(&omega);
    let q = se3_q(&omega, &v);
    let lower = -(j_inv * q * j_inv);
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&j_inv);
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&j_inv);
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&lower);
    out
}

/// Right-retraction `X · Exp(δ)`, renormalising the rotation.
pub fn retract(pose: &Isometry3<f64>, delta: &Vector6<f64>) -> Isometry3<f64> {
    let mut out = pose * exp(delta);
    out.rotation.renormalize();
    out
}

/// Rotation from TORO/GTSAM roll, pitch, yaw: `R = Rz(yaw) · Ry(pitch) · Rx(roll)`.
pub fn rotation_from_rpy(roll: f64, pitch: f64, yaw: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(roll, pitch, yaw)
}

/// Roll, pitch, yaw of a rotation, the inverse of [`rotation_from_rpy`].
pub fn rpy_from_rotation(rotation: &UnitQuaternion<f64>) -> (f64, f64, f64) {
    rotation.euler_angles()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_twists() -> Vec<Vector6<f64>> {
        vec![
            Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            Vector6::new(1e-9, -2e-9, 3e-9, 0.1, 0.2, -0.3),
            Vector6::new(1e-4, 2e-3, -3e-3, 1.0, -2.0, 0.5),
            Vector6::new(0.3, -0.2, 0.1, 1.0, 2.0, 3.0),
            Vector6::new(-1.2, 0.7, 2.0, -4.0, 0.5, 1.5),
            Vector6::new(0.0, 0.0, 3.0, 1.0, 0.0, 0.0),
        ]
    }

    #[test]
    fn exp_log_round_trip() {
        for xi in sample_twists() {
            let back = log(&exp(&xi));
            assert!((back - xi).norm() < 1e-10, "{xi} -> {back}");
        }
    }

    #[test]
    fn adjoint_conjugates_exp() {
        let t = exp(&Vector6::new(0.4, -0.1, 0.9, 1.0, -2.0, 0.3));
        for xi in sample_twists() {
            let lhs = t * exp(&xi) * t.inverse();
            let rhs = exp(&(adjoint(&t) * xi));
            assert!(log(&(lhs.inverse() * rhs)).norm() < 1e-10);
        }
    }

    #[test]
    fn right_jacobian_inverse_matches_finite_differences() {
        let h = 1e-6;
        for xi in sample_twists() {
            let x = exp(&xi);
            let analytic = right_jacobian_inverse(&xi);
            let mut numeric = Matrix6::zeros();
            for k in 0..6 {
                let mut d = Vector6::zeros();
                d[k] = h;
                let plus = log(&(x * exp(&d)));
                let minus = log(&(x * exp(&(-d))));
                numeric.set_column(k, &((plus - minus) / (2.0 * h)));
            }
            let err = (analytic - numeric).abs().max();
            assert!(err < 1e-6, "xi = {xi}: error {err}\n{analytic}\n{numeric}");
        }
    }

    #[test]
    fn rpy_matches_rz_ry_rx() {
        let (r, p, y) = (0.1, -0.2, 0.3);
        let q = rotation_from_rpy(r, p, y);
        let rz = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), y);
        let ry = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), p);
        let rx = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), r);
        assert!(q.angle_to(&(rz * ry * rx)) < 1e-12);
        let (r2, p2, y2) = rpy_from_rotation(&q);
        assert!((r - r2).abs() + (p - p2).abs() + (y - y2).abs() < 1e-12);
    }
}
