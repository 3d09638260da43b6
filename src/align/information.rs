//! The information matrix of an alignment, for the pose graph.
//!
//! Convention (GTSAM's `Pose3`): the estimate is perturbed on the right,
//! `prior_from_query · Exp(ξ)` with `ξ = (ω, v)`, rotation first, then translation,
//! both in the query frame. Each inlier pair contributes `Jᵀ W J`, where
//! `J = ∂(p_prior − T·Exp(ξ)·p_query)/∂ξ = [R [p_query]×, −R]` and `W = w I₃` its weight.
//! When the residuals are larger than the weights predict (a posteriori variance factor
//! above 1), the matrix is scaled down by that factor, so the pose graph never trusts a
//! relocalization more than its own residuals justify.
//!
//! For the tilt-aware alignment ([`tilt_aware_information`]) the tilt rows say how well
//! the tilt is known: from the pairs and the gravity prior when the pairs determined it
//! (whether the answer applies it or found it level), from the gravity prior alone when
//! they did not (the answer is then yaw-only, and its yaw and translation information is
//! the data's with the tilt held).

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

/// The information matrix of a tilt-aware answer ([`super::tilt`]): the data's
/// [`information_matrix`], plus the gravity prior (σ `gravity_sigma_rad` per horizontal
/// axis of the prior frame) when the pairs determined the tilt; when they did not, the
/// tilt rows and columns hold the gravity prior alone.
pub fn tilt_aware_information(
    pairs: &[WeightedPair],
    prior_from_query: &Isometry3<f64>,
    tilt_determined: bool,
    gravity_sigma_rad: f64,
) -> Matrix6<f64> {
    let mut info = information_matrix(pairs, prior_from_query);
    let prior = gravity_sigma_rad.powi(-2);
    if !prior.is_finite() {
        return info;
    }
    // The prior is on the left rotation ω_l = R ω_r about the prior frame's x and y axes.
    let rotation: Matrix3<f64> = *prior_from_query.rotation.to_rotation_matrix().matrix();
    let horizontal = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, 0.0));
    let prior_right = rotation.transpose() * horizontal * rotation * prior;
    if !tilt_determined {
        // A yaw-only answer: the right perturbation's tilt axes are its x and y.
        for k in 0..2 {
            info.row_mut(k).fill(0.0);
            info.column_mut(k).fill(0.0);
        }
    }
    let mut rot_block = info.fixed_view_mut::<3, 3>(0, 0);
    rot_block += prior_right;
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

    /// The tilt rows of the tilt-aware information against finite differences: with exact
    /// pairs the Gauss–Newton matrix is the Hessian of the negative log posterior (the
    /// weighted squared residuals plus the gravity prior on the tilt), under right
    /// perturbations.
    #[test]
    fn tilt_rows_match_finite_differences_of_the_posterior() {
        use crate::align::tilt::tilt_of;
        let truth = Isometry3::from_parts(
            nalgebra::Translation3::new(3.0, -2.0, 0.4),
            nalgebra::UnitQuaternion::from_euler_angles(0.004, -0.007, 1.3),
        );
        let pairs: Vec<_> = pairs_for(&scatter(15, 11), &truth)
            .into_iter()
            .map(|mut p| {
                p.weight = 400.0; // σ = 5 cm
                p
            })
            .collect();
        let sigma = 0.5f64.to_radians();
        // At the truth the data residuals vanish; the prior's does not (the tilt is not
        // zero), so its gradient is constant and its Hessian is what the test checks.
        let cost = |xi: &Vector6<f64>| {
            let step = Isometry3::new(xi.fixed_rows::<3>(3).into(), xi.fixed_rows::<3>(0).into());
            let t = truth * step;
            let data: f64 = pairs
                .iter()
                .map(|p| p.weight * (p.p_prior - t * p.p_query).norm_squared())
                .sum();
            let [a, b] = tilt_of(&t);
            0.5 * data + 0.5 * (a * a + b * b) / (sigma * sigma)
        };
        let h = 1e-4;
        let mut hessian = Matrix6::zeros();
        for i in 0..6 {
            for j in 0..6 {
                let mut e_i = Vector6::zeros();
                let mut e_j = Vector6::zeros();
                e_i[i] = h;
                e_j[j] = h;
                hessian[(i, j)] = (cost(&(e_i + e_j)) - cost(&(e_i - e_j)) - cost(&(e_j - e_i))
                    + cost(&(-e_i - e_j)))
                    / (4.0 * h * h);
            }
        }
        let info = tilt_aware_information(&pairs, &truth, true, sigma);
        for k in 0..2 {
            let fd = hessian.row(k);
            let got = info.row(k);
            assert!(
                (got - fd).norm() < 2e-3 * fd.norm(),
                "row {k}: {got} vs {fd}"
            );
        }
        // The prior adds exactly 1/σ² of tilt information on top of the data's.
        let data = information_matrix(&pairs, &truth);
        let added = (info - data).fixed_view::<2, 2>(0, 0).trace();
        assert!((added - 2.0 / (sigma * sigma)).abs() < 1e-3 * added);
    }

    #[test]
    fn without_a_tilt_estimate_the_tilt_rows_are_the_gravity_prior() {
        let truth = yaw_transform(0.8, Vector3::new(1.0, 2.0, 0.1));
        let pairs = pairs_for(&scatter(12, 2), &truth);
        let sigma = 0.5f64.to_radians();
        let info = tilt_aware_information(&pairs, &truth, false, sigma);
        let data = information_matrix(&pairs, &truth);
        for k in 0..2 {
            for c in 0..6 {
                let expected = if c == k { sigma.powi(-2) } else { 0.0 };
                assert!((info[(k, c)] - expected).abs() < 1e-9 * expected.max(1.0));
            }
        }
        let rest = (info - data).fixed_view::<4, 4>(2, 2).norm();
        assert!(rest < 1e-9 * data.norm());
        let covariance = info.try_inverse().unwrap();
        assert!((covariance[(0, 0)].sqrt() - sigma).abs() < 1e-12);
    }
}
