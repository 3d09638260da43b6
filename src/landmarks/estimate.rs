//! A landmark from the detections of one boulder: robust centroid and covariance.
//!
//! The centroid is the coordinate-wise median (a few detections of a boulder cut by the
//! image border or merged with its shadow would drag a mean). The covariance is the
//! robust scatter (1.4826 × median absolute deviation per axis, squared) divided by the
//! number of detections, plus the repeatability floor: detections of one session agree to
//! millimetres, but the same boulder seen from another side in another session moves by
//! about a centimetre.

use super::FusionConfig;
use nalgebra::{Matrix3, Point3};
use segloc_maps::{Detection, Landmark};

/// The landmark for a cluster of detections (at least one).
pub fn landmark_from(detections: &[&Detection], id: u32, config: &FusionConfig) -> Landmark {
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
        variance[k] = sigma * sigma / n as f64 + config.repeatability_m * config.repeatability_m;
    }
    let mut covariance = Matrix3::from_diagonal(&nalgebra::Vector3::from(variance));
    if config.view_bias_sigma_m > 0.0 {
        if let Some(m) = super::view_bias::mean_line_of_sight(detections) {
            covariance += m * m.transpose() * (config.view_bias_sigma_m * config.view_bias_sigma_m);
        }
    }
    let mut sizes: Vec<f64> = detections.iter().filter_map(|d| d.size_m).collect();
    let size_m = (!sizes.is_empty()).then(|| median(&mut sizes));
    let mut landmark = Landmark::new(id, position, covariance);
    landmark.size_m = size_m;
    landmark.observations = detections.len() as u32;
    landmark
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
