//! Trajectory error of an estimate against ground truth.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// Absolute trajectory error over the poses present in both trajectories.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryError {
    /// Number of poses compared.
    pub matched: usize,
    /// Root-mean-square position error.
    pub position_rmse_m: f64,
    /// Largest position error.
    pub position_max_m: f64,
    /// Root-mean-square rotation error.
    pub rotation_rmse_rad: f64,
}

/// Compares `estimate` with `truth` pose by pose (matched by id).
///
/// With `align`, the estimate is first moved by the rigid transform that best fits its
/// positions onto the truth's (Kabsch/Horn, least squares); without, the two are compared
/// in their own frames (meaningful when both are anchored at the same first pose).
pub fn trajectory_error(
    estimate: &[(u64, Isometry3<f64>)],
    truth: &[(u64, Isometry3<f64>)],
    align: bool,
) -> TrajectoryError {
    let truth_by_id: HashMap<u64, &Isometry3<f64>> = truth.iter().map(|(i, p)| (*i, p)).collect();
    let pairs: Vec<(Isometry3<f64>, Isometry3<f64>)> = estimate
        .iter()
        .filter_map(|(i, p)| truth_by_id.get(i).map(|t| (*p, **t)))
        .collect();
    let truth_from_estimate = if align && pairs.len() >= 3 {
        rigid_fit(&pairs)
    } else {
        Isometry3::identity()
    };
    let mut sum_p = 0.0;
    let mut max_p: f64 = 0.0;
    let mut sum_r = 0.0;
    for (est, tru) in &pairs {
        let aligned = truth_from_estimate * est;
        let dp = (aligned.translation.vector - tru.translation.vector).norm();
        let dr = aligned.rotation.angle_to(&tru.rotation);
        sum_p += dp * dp;
        max_p = max_p.max(dp);
        sum_r += dr * dr;
    }
    let n = pairs.len().max(1) as f64;
    TrajectoryError {
        matched: pairs.len(),
        position_rmse_m: (sum_p / n).sqrt(),
        position_max_m: max_p,
        rotation_rmse_rad: (sum_r / n).sqrt(),
    }
}

/// Least-squares rigid transform taking the estimate positions onto the truth positions.
fn rigid_fit(pairs: &[(Isometry3<f64>, Isometry3<f64>)]) -> Isometry3<f64> {
    let n = pairs.len() as f64;
    let ce = pairs
        .iter()
        .map(|p| p.0.translation.vector)
        .sum::<Vector3<f64>>()
        / n;
    let ct = pairs
        .iter()
        .map(|p| p.1.translation.vector)
        .sum::<Vector3<f64>>()
        / n;
    let mut h = Matrix3::zeros();
    for (e, t) in pairs {
        h += (e.translation.vector - ce) * (t.translation.vector - ct).transpose();
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Isometry3::identity();
    };
    let mut d = Matrix3::identity();
    if (v_t.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = v_t.transpose() * d * u.transpose();
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = ct - rotation * ce;
    Isometry3::from_parts(Translation3::from(t), rotation)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_removes_a_rigid_offset() {
        let truth: Vec<(u64, Isometry3<f64>)> = (0..10)
            .map(|i| {
                let f = i as f64;
                (i, Isometry3::translation(f, (f * 0.7).sin(), 0.1 * f * f))
            })
            .collect();
        let offset = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.1, 0.2, -0.3));
        let estimate: Vec<_> = truth.iter().map(|(i, p)| (*i, offset * p)).collect();
        let raw = trajectory_error(&estimate, &truth, false);
        assert!(raw.position_rmse_m > 0.5);
        let aligned = trajectory_error(&estimate, &truth, true);
        assert_eq!(aligned.matched, 10);
        assert!(aligned.position_rmse_m < 1e-9);
        assert!(aligned.rotation_rmse_rad < 1e-9);
    }
}
