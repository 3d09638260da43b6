//! Joint refinement of the map frames against each other's landmarks.
//!
//! The frame graph combines pairwise answers, each fixed by the landmarks two maps share.
//! A map that overlaps several others is better fixed by all of them at once: each
//! non-reference frame is re-aligned (robust refinement over re-associated mutual nearest
//! neighbours, as in relocalization) to the landmarks of every other placed map, and the
//! sweep is repeated a few times so that corrections propagate. A landmark weighs by its
//! largest variance, so one whose covariance is stretched along a line of sight (seen
//! from one side only, see [`crate::landmarks::FusionConfig::view_bias_sigma_m`]) counts
//! less than one seen from all sides.

use crate::align::{refine, Dof, RefineConfig};
use nalgebra::{Isometry3, Point3};
use segloc_maps::ObjectMap;

/// Refine the placed frames in `reference_from_map` (the reference stays fixed) in `sweeps`
/// passes; a frame is only replaced when its refinement keeps at least `min_inliers`.
pub fn refine_frames(
    maps: &[ObjectMap],
    reference_from_map: &mut [Option<Isometry3<f64>>],
    reference: usize,
    dof: Dof,
    config: &RefineConfig,
    sweeps: usize,
    min_inliers: usize,
) {
    let weights: Vec<Vec<f64>> = maps
        .iter()
        .map(|m| {
            m.landmarks
                .iter()
                .map(|l| 1.0 / largest_variance(&l.covariance).max(1e-8))
                .collect()
        })
        .collect();
    let local: Vec<Vec<Point3<f64>>> = maps.iter().map(|m| m.positions()).collect();
    for _ in 0..sweeps {
        for k in 0..maps.len() {
            let Some(current) = reference_from_map[k] else {
                continue;
            };
            if k == reference {
                continue;
            }
            let (mut others, mut other_weights) = (Vec::new(), Vec::new());
            for (j, placed) in reference_from_map.iter().enumerate() {
                if let (Some(t), true) = (placed, j != k) {
                    others.extend(local[j].iter().map(|p| t * p));
                    other_weights.extend_from_slice(&weights[j]);
                }
            }
            if others.is_empty() {
                continue;
            }
            let refined = refine(
                &others,
                &other_weights,
                &local[k],
                &weights[k],
                &current,
                dof,
                config,
            );
            if refined.inliers.len() >= min_inliers {
                reference_from_map[k] = Some(refined.prior_from_query);
            }
        }
    }
}

/// The largest eigenvalue of a covariance (its trace / 3 if it is not finite).
fn largest_variance(covariance: &nalgebra::Matrix3<f64>) -> f64 {
    if !covariance.iter().all(|v| v.is_finite()) {
        return covariance.trace() / 3.0;
    }
    let symmetric = (covariance + covariance.transpose()) * 0.5;
    symmetric.symmetric_eigenvalues().max()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_covariance_stretched_along_a_line_of_sight_weighs_by_its_long_axis() {
        let round = nalgebra::Matrix3::identity() * 1e-4;
        let m = nalgebra::Vector3::new(0.6, 0.8, 0.0);
        let stretched = round + m * m.transpose() * 1e-4;
        assert!((largest_variance(&round) - 1e-4).abs() < 1e-12);
        assert!((largest_variance(&stretched) - 2e-4).abs() < 1e-12);
    }
}
