//! A landmark from the detections of one boulder: robust centroid and covariance.
//!
//! Two centroids ([`CentroidEstimator`]):
//! - the coordinate-wise median (a few detections of a boulder cut by the image border or
//!   merged with its shadow would drag a mean), with the robust scatter (1.4826 × median
//!   absolute deviation per axis, squared) divided by the number of detections as its
//!   covariance;
//! - the stereo-weighted centroid ([`stereo_weighted`]), when the detections carry rover
//!   positions: each detection's error is mostly depth, along its line of sight, with a
//!   standard deviation growing as the square of the range (σ_z = z² σ_d / (f B)), so a
//!   view from 2 m is worth some 80 from 6 m. The centroid is the information-weighted
//!   mean, made robust by iteratively reweighting with a Cauchy kernel on each detection's
//!   Mahalanobis distance, starting from the median; its covariance is the inverse of the
//!   summed weighted information. Each detection's error also has the pose's in every
//!   direction ([`FusionConfig::pose_sigma_m`]), so the nearest views weigh no more than
//!   the poses that place them can support. The mission fuses with it
//!   ([`crate::mission::MissionConfig`]): on the synthetic mission it is worth +7 rock
//!   points at the median of seeds 1–10 (BENCHMARKS.md).
//!
//! Either way the covariance gains the repeatability floor: detections of one session
//! agree to millimetres, but the same boulder seen from another side in another session
//! moves by about a centimetre.

use super::FusionConfig;
use nalgebra::{Matrix3, Point3, Vector3};
use segloc_maps::{Detection, Landmark};
use serde::{Deserialize, Serialize};

/// How a landmark's centroid is computed from its detections.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CentroidEstimator {
    /// Coordinate-wise median, scatter-based covariance.
    Median,
    /// Information-weighted by the stereo noise model, robust (see the module's notes);
    /// the median for clusters without rover positions.
    StereoWeighted,
}

/// Reweighting rounds of [`stereo_weighted`].
const REWEIGHTING_ROUNDS: usize = 8;

/// The landmark for a cluster of detections (at least one).
pub fn landmark_from(detections: &[&Detection], id: u32, config: &FusionConfig) -> Landmark {
    let mut landmark = match config.centroid {
        CentroidEstimator::StereoWeighted => stereo_weighted(detections, config)
            .map(|(position, covariance)| Landmark::new(id, position, covariance)),
        CentroidEstimator::Median => None,
    }
    .unwrap_or_else(|| median_landmark(detections, id));
    let floor = config.repeatability_m * config.repeatability_m;
    landmark.covariance += Matrix3::identity() * floor;
    if config.view_bias_sigma_m > 0.0 {
        if let Some(m) = super::view_bias::mean_line_of_sight(detections) {
            landmark.covariance +=
                m * m.transpose() * (config.view_bias_sigma_m * config.view_bias_sigma_m);
        }
    }
    let mut sizes: Vec<f64> = detections.iter().filter_map(|d| d.size_m).collect();
    landmark.size_m = (!sizes.is_empty()).then(|| median(&mut sizes));
    landmark.observations = detections.len() as u32;
    landmark
}

/// Coordinate-wise median and scatter covariance (without the repeatability floor).
fn median_landmark(detections: &[&Detection], id: u32) -> Landmark {
    let n = detections.len().max(1);
    let axis = |k: usize| -> Vec<f64> { detections.iter().map(|d| d.p_world[k]).collect() };
    let mut position = Point3::origin();
    let mut variance = [0.0; 3];
    for k in 0..3 {
        let mut values = axis(k);
        let med = median(&mut values);
        position[k] = med;
        let mut deviations: Vec<f64> = values.iter().map(|v| (v - med).abs()).collect();
        let sigma = 1.4826 * median(&mut deviations);
        variance[k] = sigma * sigma / n as f64;
    }
    Landmark::new(
        id,
        position,
        Matrix3::from_diagonal(&Vector3::from(variance)),
    )
}

/// The information matrix of one detection seen from `rover` (m⁻²): depth along the line
/// of sight, the lateral error across it (`config.stereo`, with the range for the depth),
/// the pose error (`config.pose_sigma_m`) in every direction.
pub fn detection_information(
    p: &Point3<f64>,
    rover: &Point3<f64>,
    config: &FusionConfig,
) -> Matrix3<f64> {
    let sight = p - rover;
    let range = sight.norm();
    let pose2 = config.pose_sigma_m * config.pose_sigma_m + 1e-12;
    let depth2 = config.stereo.depth_sigma_m(range).powi(2) + pose2;
    let lateral2 = config.stereo.lateral_sigma_m(range).powi(2) + pose2;
    let u = if range > 1e-9 {
        sight / range
    } else {
        Vector3::x()
    };
    let along = u * u.transpose();
    along / depth2 + (Matrix3::identity() - along) / lateral2
}

/// The robust information-weighted centroid of detections with rover positions and its
/// covariance (without the repeatability floor), with `config`'s stereo noise, pose error
/// and Cauchy width (`outlier_width_sigmas`; 0: no kernel); `None` when a detection has no
/// rover position or the information is singular.
pub fn stereo_weighted(
    detections: &[&Detection],
    config: &FusionConfig,
) -> Option<(Point3<f64>, Matrix3<f64>)> {
    let information: Vec<Matrix3<f64>> = detections
        .iter()
        .map(|d| {
            Some(detection_information(
                &d.p_world,
                &d.rover_position?,
                config,
            ))
        })
        .collect::<Option<_>>()?;
    let start = median_landmark(detections, 0).position;
    let width2 = config.outlier_width_sigmas * config.outlier_width_sigmas;
    let mut centroid = start;
    let mut total = Matrix3::zeros();
    for _ in 0..REWEIGHTING_ROUNDS {
        total = Matrix3::zeros();
        let mut rhs = Vector3::zeros();
        for (d, info) in detections.iter().zip(&information) {
            let e = d.p_world - centroid;
            let m2 = (e.transpose() * info * e)[0];
            let w = if width2 > 0.0 {
                1.0 / (1.0 + m2 / width2)
            } else {
                1.0
            };
            total += info * w;
            rhs += info * d.p_world.coords * w;
        }
        let next = Point3::from(total.try_inverse()? * rhs);
        let moved = (next - centroid).norm();
        centroid = next;
        if moved < 1e-6 {
            break;
        }
    }
    let covariance = total.try_inverse()?;
    centroid
        .iter()
        .all(|v| v.is_finite())
        .then_some((centroid, covariance))
}

/// Median of a non-empty slice (reorders it); 0 for an empty one. NaN-free input.
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mid = values.len() / 2;
    let (_, upper, _) = values.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    let upper = *upper;
    if values.len() % 2 == 1 {
        upper
    } else {
        let lower = values[..mid]
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lower + upper)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
    }

    use crate::landmarks::detection_seen_from as seen_from;

    fn noise() -> FusionConfig {
        FusionConfig {
            pose_sigma_m: 0.0,
            ..FusionConfig::default()
        }
    }

    #[test]
    fn near_views_outweigh_far_ones_along_the_line_of_sight() {
        // a boulder at the origin seen along x: from 2 m, 3 cm short; from 6 m, 10 cm long
        let near = seen_from(Point3::new(0.03, 0.0, 0.0), Point3::new(2.0, 0.0, 0.0));
        let far = seen_from(Point3::new(-0.10, 0.0, 0.0), Point3::new(6.0, 0.0, 0.0));
        let (c, cov) = stereo_weighted(&[&near, &far], &noise()).unwrap();
        // σ 8 mm against 7.3 cm: the near view carries ~99 % of the weight
        assert!((c.x - 0.03).abs() < 0.005, "{c}");
        assert!(cov[(0, 0)] > 30.0 * cov[(1, 1)], "depth dominates: {cov}");
        // the median would sit halfway
        let m = landmark_from(&[&near, &far], 0, &FusionConfig::default());
        assert!((m.position.x + 0.035).abs() < 1e-9);
    }

    #[test]
    fn crossing_lines_of_sight_pin_the_centroid() {
        // two far views from orthogonal directions, each off along its own line of sight
        let a = seen_from(Point3::new(0.08, 0.0, 0.0), Point3::new(5.0, 0.0, 0.0));
        let b = seen_from(Point3::new(0.0, -0.08, 0.0), Point3::new(0.0, 5.0, 0.0));
        let (c, cov) = stereo_weighted(&[&a, &b], &noise()).unwrap();
        // each view fixes the coordinate across its own line of sight to millimetres
        assert!(c.x.abs() < 0.002 && c.y.abs() < 0.002, "{c}");
        assert!(cov[(0, 0)].sqrt() < 0.005 && cov[(1, 1)].sqrt() < 0.005);
    }

    #[test]
    fn a_wild_detection_is_down_weighted() {
        let rover = Point3::new(3.0, 0.0, 0.0);
        let mut dets: Vec<Detection> = (0..6)
            .map(|k| seen_from(Point3::new(0.002 * k as f64, 0.0, 0.0), rover))
            .collect();
        // cut by the image border: 15 cm across the line of sight
        dets.push(seen_from(Point3::new(0.0, 0.15, 0.0), rover));
        let refs: Vec<_> = dets.iter().collect();
        let (c, _) = stereo_weighted(&refs, &noise()).unwrap();
        assert!(c.y.abs() < 0.002, "{c}");
        let plain = FusionConfig {
            outlier_width_sigmas: 0.0,
            ..noise()
        };
        let (c, _) = stereo_weighted(&refs, &plain).unwrap();
        assert!(c.y > 0.02, "the plain weighted mean is dragged: {c}");
    }

    #[test]
    fn without_rover_positions_the_median_is_used() {
        let mut d = seen_from(Point3::new(1.0, 2.0, 0.0), Point3::origin());
        d.rover_position = None;
        assert!(stereo_weighted(&[&d], &noise()).is_none());
        let lm = landmark_from(&[&d, &d], 0, &FusionConfig::default());
        assert_eq!(lm.position, Point3::new(1.0, 2.0, 0.0));
    }

    #[test]
    fn one_wild_detection_does_not_move_the_centroid() {
        let mk = |x: f64| Detection {
            frame: 0,
            p_world: Point3::new(x, 0.0, 0.0),
            rover_position: None,
            size_m: Some(0.3),
            score: None,
        };
        let dets = [mk(1.0), mk(1.001), mk(0.999), mk(1.002), mk(1.15)];
        let refs: Vec<_> = dets.iter().collect();
        let lm = landmark_from(&refs, 3, &FusionConfig::default());
        assert!((lm.position.x - 1.001).abs() < 1e-9);
        assert_eq!(lm.observations, 5);
        assert_eq!(lm.size_m, Some(0.3));
        assert!(lm.covariance[(0, 0)] >= 1e-4);
    }
}
