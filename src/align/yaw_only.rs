//! Closed-form yaw + translation alignment for gravity-aligned maps (4 degrees of freedom).
//!
//! With z known to be up in both frames, the rotation is about z only. After removing the
//! weighted centroids, the optimal yaw is θ = atan2(Σ wᵢ (bᵢ × aᵢ)_z, Σ wᵢ (bᵢ · aᵢ)_xy)
//! with aᵢ the centred prior points and bᵢ the centred query points; the translation then
//! maps the query centroid onto the prior centroid (z included).

use super::{weighted_centroids, WeightedPair};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// The weighted yaw + translation `prior_from_query`, or `None` with fewer than 2 pairs,
/// non-positive total weight, or all points on one vertical line (yaw undetermined).
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use segloc::align::{align_yaw, WeightedPair};
/// let truth = Isometry3::new(Vector3::new(3.0, -1.0, 0.2), Vector3::new(0.0, 0.0, 1.2));
/// let pairs: Vec<_> = [[0.0, 0.0, 0.0], [2.0, 1.0, 0.1], [-1.0, 3.0, 0.0]].iter().map(|p| {
///     let q = Point3::new(p[0], p[1], p[2]);
///     WeightedPair { p_prior: truth * q, p_query: q, weight: 1.0 }
/// }).collect();
/// let est = align_yaw(&pairs).unwrap();
/// assert!((est.to_homogeneous() - truth.to_homogeneous()).norm() < 1e-9);
/// ```
pub fn align_yaw(pairs: &[WeightedPair]) -> Option<Isometry3<f64>> {
    if pairs.len() < 2 {
        return None;
    }
    let (c_prior, c_query, _) = weighted_centroids(pairs)?;
    let (mut sin_sum, mut cos_sum, mut scale) = (0.0, 0.0, 0.0);
    for pair in pairs {
        let a = pair.p_prior - c_prior;
        let b = pair.p_query - c_query;
        sin_sum += pair.weight * (b.x * a.y - b.y * a.x);
        cos_sum += pair.weight * (b.x * a.x + b.y * a.y);
        scale += pair.weight * (a.x * a.x + a.y * a.y + b.x * b.x + b.y * b.y);
    }
    let magnitude = sin_sum.hypot(cos_sum);
    if magnitude.is_nan() || magnitude <= 1e-12 * scale.max(1e-300) {
        return None;
    }
    let yaw = sin_sum.atan2(cos_sum);
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
    let translation = c_prior.coords - rotation * c_query.coords;
    Some(Isometry3::from_parts(
        Translation3::from(translation),
        rotation,
    ))
}

/// The yaw (rotation about z, radians in (−π, π]) of an isometry's rotation.
pub fn yaw_of(transform: &Isometry3<f64>) -> f64 {
    let m = transform.rotation.to_rotation_matrix();
    m[(1, 0)].atan2(m[(0, 0)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::test_util::*;
    use nalgebra::Point3;

    #[test]
    fn recovers_any_yaw() {
        for k in 0..16 {
            let yaw = -3.1 + 0.4 * k as f64;
            let truth = yaw_transform(yaw, Vector3::new(12.0, -7.5, 0.3));
            let est = align_yaw(&pairs_for(&scatter(8, k), &truth)).unwrap();
            assert!((est.to_homogeneous() - truth.to_homogeneous()).norm() < 1e-9);
            assert!((yaw_of(&est) - yaw).abs() < 1e-9);
        }
    }

    #[test]
    fn refuses_a_vertical_line() {
        let pairs: Vec<_> = (0..4)
            .map(|i| WeightedPair {
                p_prior: Point3::new(1.0, 1.0, i as f64),
                p_query: Point3::new(0.0, 0.0, i as f64),
                weight: 1.0,
            })
            .collect();
        assert!(align_yaw(&pairs).is_none());
    }
}
