//! The information matrix of an alignment, for the pose graph.
//!
//! Convention (GTSAM's `Pose3`): the estimate is perturbed on the right,
//! `prior_from_query · Exp(ξ)` with `ξ = (ω, v)`, rotation first, then translation,
//! both in the query frame. Each inlier pair contributes `Jᵀ W J`, where
//! `J = ∂(p_prior − T·Exp(ξ)·p_query)/∂ξ = [R [p_query]×, −R]` and `W = w I₃` its weight.
//! When the residuals are larger than the weights predict (a posteriori variance factor
//! above 1), the matrix is scaled down by that factor, so the pose graph never trusts a
//! relocalization more than its own residuals justify.

use super::WeightedPair;
use nalgebra::{Isometry3, Matrix3, Matrix3x6, Matrix6};

/// The 6 × 6 information matrix (rotation, translation) of `prior_from_query` given the
/// inlier pairs and their weights (inverse variances, 1/m²).
pub fn information_matrix(
    pairs: &[WeightedPair],
    prior_from_query: &Isometry3<f64>,
) -> Matrix6<f64> {
    let rotation: Matrix3<f64> = *prior_from_query.rotation.to_rotation_matrix().matrix();
    let mut info = Matrix6::zeros();
    let mut chi2 = 0.0;
    for pair in pairs {
        let q = pair.p_query.coords;
        let mut jac = Matrix3x6::zeros();
        jac.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(rotation * q.cross_matrix()));
        jac.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-rotation));
        info += pair.weight * jac.transpose() * jac;
        chi2 += pair.weight * (pair.p_prior - prior_from_query * pair.p_query).norm_squared();
    }
    let redundancy = 3.0 * pairs.len() as f64 - 6.0;
    if redundancy > 0.0 {
        let variance_factor = chi2 / redundancy;
        if variance_factor > 1.0 {
            info /= variance_factor;
        }
    }
    (info + info.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::test_util::*;
    use nalgebra::{Vector3, Vector6};

    /// The information matrix must equal JᵀWJ of the exact residual, checked by finite
    /// differences of the residual under right perturbations.
    #[test]
    fn matches_finite_difference_jacobian() {
        let truth = Isometry3::new(Vector3::new(2.0, -1.0, 0.3), Vector3::new(0.1, 0.2, 0.9));
        let pairs: Vec<_> = pairs_for(&scatter(6, 4), &truth)
            .into_iter()
            .map(|mut p| {
                p.weight = 100.0;
                p
            })
            .collect();
        let mut expected = Matrix6::zeros();
        let h = 1e-6;
        for pair in &pairs {
            let mut jac = Matrix3x6::zeros();
            for k in 0..6 {
                let mut xi = Vector6::zeros();
                xi[k] = h;
                // Exp of (ω, v): nalgebra's Isometry3::new takes (translation, axis-angle);
                // for a small step the first-order terms match the SE(3) exponential.
                let step =
                    Isometry3::new(xi.fixed_rows::<3>(3).into(), xi.fixed_rows::<3>(0).into());
                let plus = pair.p_prior - (truth * step) * pair.p_query;
                let minus_step = Isometry3::new(-xi.fixed_rows::<3>(3), -xi.fixed_rows::<3>(0));
                let minus = pair.p_prior - (truth * minus_step) * pair.p_query;
                jac.set_column(k, &((plus - minus) / (2.0 * h)));
            }
            expected += pair.weight * jac.transpose() * jac;
        }
        let got = information_matrix(&pairs, &truth);
        assert!((got - expected).norm() / expected.norm() < 1e-6);
    }

    #[test]
    fn large_residuals_shrink_the_information() {
        let truth = Isometry3::identity();
        let mut pairs = pairs_for(&scatter(10, 5), &truth);
        for p in pairs.iter_mut() {
            p.weight = 1e4; // σ = 1 cm
        }
        let clean = information_matrix(&pairs, &truth);
        for (k, p) in pairs.iter_mut().enumerate() {
            p.p_prior.x += if k % 2 == 0 { 0.5 } else { -0.5 };
        }
        let noisy = information_matrix(&pairs, &truth);
        assert!(noisy.trace() < clean.trace());
    }
}
