//! Arun / Umeyama: the weighted least-squares rigid motion between two point sets.
//!
//! Minimises Σ wᵢ ‖pᵢ − (R qᵢ + t)‖² over rotations R and translations t in closed form:
//! the rotation comes from the SVD of the weighted cross-covariance of the centred sets
//! (Arun, Huang and Blostein 1987), with Umeyama's sign correction so that R is a proper
//! rotation even for nearly planar sets.

use super::{weighted_centroids, WeightedPair};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};

/// The weighted rigid motion `prior_from_query`, or `None` with fewer than 3 pairs,
/// non-positive total weight, or a degenerate (collinear) configuration.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use segloc::align::{align_rigid, WeightedPair};
/// let truth = Isometry3::new(Vector3::new(1.0, 2.0, 0.5), Vector3::new(0.1, -0.2, 0.7));
/// let pts = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.2], [0.0, 4.0, 0.1], [2.0, 2.0, 1.0]];
/// let pairs: Vec<_> = pts.iter().map(|p| {
///     let q = Point3::new(p[0], p[1], p[2]);
///     WeightedPair { p_prior: truth * q, p_query: q, weight: 1.0 }
/// }).collect();
/// let est = align_rigid(&pairs).unwrap();
/// assert!((est.to_homogeneous() - truth.to_homogeneous()).norm() < 1e-9);
/// ```
pub fn align_rigid(pairs: &[WeightedPair]) -> Option<Isometry3<f64>> {
    if pairs.len() < 3 {
        return None;
    }
    let (c_prior, c_query, _) = weighted_centroids(pairs)?;
    let mut cross = Matrix3::zeros();
    for pair in pairs {
        let a = pair.p_prior - c_prior;
        let b = pair.p_query - c_query;
        cross += pair.weight * a * b.transpose();
    }
    let svd = cross.svd(true, true);
    let u = svd.u?;
    let v_t = svd.v_t?;
    // Two vanishing singular values mean the points are collinear: the rotation about
    // their line is not determined.
    let mut singular = svd.singular_values;
    singular
        .as_mut_slice()
        .sort_by(|a, b| b.partial_cmp(a).unwrap_or(std::cmp::Ordering::Equal));
    if singular[1].is_nan() || singular[1] <= 1e-12 * singular[0].max(1e-300) {
        return None;
    }
    let sign = (u * v_t).determinant().signum();
    let correction = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, sign));
    let rotation = Rotation3::from_matrix_unchecked(u * correction * v_t);
    let translation = c_prior.coords - rotation * c_query.coords;
    Some(Isometry3::from_parts(
        Translation3::from(translation),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::test_util::*;
    use nalgebra::{Point3, Vector3};

    #[test]
    fn recovers_a_known_motion_exactly() {
        let truth = Isometry3::new(Vector3::new(-4.0, 7.0, 1.0), Vector3::new(0.3, -0.1, 2.5));
        let pairs = pairs_for(&scatter(30, 1), &truth);
        let est = align_rigid(&pairs).unwrap();
        assert!((est.to_homogeneous() - truth.to_homogeneous()).norm() < 1e-9);
    }

    #[test]
    fn weights_pull_towards_heavy_pairs() {
        let truth = Isometry3::new(Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.4));
        let mut pairs = pairs_for(&scatter(10, 2), &truth);
        // Corrupt one pair but give it almost no weight.
        pairs[0].p_prior += Vector3::new(5.0, 0.0, 0.0);
        pairs[0].weight = 1e-12;
        let est = align_rigid(&pairs).unwrap();
        assert!((est.translation.vector - truth.translation.vector).norm() < 1e-6);
    }

    #[test]
    fn refuses_collinear_and_too_few_points() {
        let line: Vec<_> = (0..5)
            .map(|i| WeightedPair {
                p_prior: Point3::new(i as f64, 0.0, 0.0),
                p_query: Point3::new(i as f64, 0.0, 0.0),
                weight: 1.0,
            })
            .collect();
        assert!(align_rigid(&line).is_none());
        assert!(align_rigid(&line[..2]).is_none());
    }

    #[test]
    fn planar_points_give_a_proper_rotation() {
        let truth = Isometry3::new(Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 3.0));
        let flat: Vec<_> = scatter(12, 3)
            .into_iter()
            .map(|p| Point3::new(p.x, p.y, 0.0))
            .collect();
        let est = align_rigid(&pairs_for(&flat, &truth)).unwrap();
        assert!((est.rotation.to_rotation_matrix().matrix().determinant() - 1.0).abs() < 1e-12);
        assert!((est.to_homogeneous() - truth.to_homogeneous()).norm() < 1e-9);
    }
}
