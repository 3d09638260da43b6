//! Drift over segments of a fixed travelled length, the KITTI odometry metric: for every
//! start frame, the relative motion to the first frame at least `length_m` further along
//! the true path, compared with the estimate's relative motion over the same frames.

use nalgebra::Isometry3;
use serde::Serialize;

/// Drift of an estimated trajectory over segments of one length.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SegmentDrift {
    /// Segment length along the true path, metres.
    pub length_m: f64,
    /// Segments measured (one per start frame that has a segment end).
    pub segments: usize,
    /// Mean translation error as a percentage of the segment length.
    pub translation_percent: f64,
    /// 90th percentile of the per-segment translation error, percent.
    pub translation_percent_p90: f64,
    /// Mean rotation error, degrees per 10 m travelled.
    pub rotation_deg_per_10m: f64,
}

/// The drift of `estimate` against `truth` (both `first_from_camera`, frame by frame) over
/// segments of `length_m`; `None` when the path is shorter than one segment or the two
/// trajectories differ in length.
pub fn segment_drift(
    estimate: &[Isometry3<f64>],
    truth: &[Isometry3<f64>],
    length_m: f64,
) -> Option<SegmentDrift> {
    if estimate.len() != truth.len() || length_m.is_nan() || length_m <= 0.0 {
        return None;
    }
    let mut along = Vec::with_capacity(truth.len());
    let mut travelled = 0.0;
    for (k, pose) in truth.iter().enumerate() {
        if k > 0 {
            travelled += (pose.translation.vector - truth[k - 1].translation.vector).norm();
        }
        along.push(travelled);
    }
    let mut translation = Vec::new();
    let mut rotation_sum = 0.0;
    let mut end = 0;
    for start in 0..truth.len() {
        end = end.max(start);
        while end < truth.len() && along[end] - along[start] < length_m {
            end += 1;
        }
        if end == truth.len() {
            break;
        }
        let true_motion = truth[start].inverse() * truth[end];
        let estimated_motion = estimate[start].inverse() * estimate[end];
        let error = true_motion.inverse() * estimated_motion;
        translation.push(100.0 * error.translation.vector.norm() / length_m);
        rotation_sum += error.rotation.angle().to_degrees() * 10.0 / length_m;
    }
    if translation.is_empty() {
        return None;
    }
    let n = translation.len();
    let mean = translation.iter().sum::<f64>() / n as f64;
    translation.sort_by(f64::total_cmp);
    let p90 = translation[((n - 1) as f64 * 0.9).round() as usize];
    Some(SegmentDrift {
        length_m,
        segments: n,
        translation_percent: mean,
        translation_percent_p90: p90,
        rotation_deg_per_10m: rotation_sum / n as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn straight(n: usize, step_m: f64, scale: f64) -> Vec<Isometry3<f64>> {
        (0..n)
            .map(|k| {
                Isometry3::from_parts(
                    Translation3::new(k as f64 * step_m * scale, 0.0, 0.0),
                    UnitQuaternion::identity(),
                )
            })
            .collect()
    }

    #[test]
    fn a_one_percent_scale_error_is_one_percent() {
        // Steps of 1/8 m are exact in binary: every segment spans 80 frames.
        let truth = straight(300, 0.125, 1.0);
        let estimate = straight(300, 0.125, 1.01);
        let d = segment_drift(&estimate, &truth, 10.0).unwrap();
        assert_eq!(d.segments, 220);
        assert!((d.translation_percent - 1.0).abs() < 1e-9, "{d:?}");
        assert!(d.rotation_deg_per_10m.abs() < 1e-9);
    }

    #[test]
    fn a_constant_yaw_rate_error_is_measured_per_10_m() {
        let truth = straight(201, 0.125, 1.0);
        // 0.00125° of yaw error a frame: 0.1° over the 80 frames of a 10 m segment.
        let estimate: Vec<_> = truth
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let yaw = UnitQuaternion::from_axis_angle(
                    &Vector3::z_axis(),
                    (0.00125 * k as f64).to_radians(),
                );
                Isometry3::from_parts(t.translation, yaw)
            })
            .collect();
        let d = segment_drift(&estimate, &truth, 10.0).unwrap();
        assert!((d.rotation_deg_per_10m - 0.1).abs() < 1e-6, "{d:?}");
    }

    #[test]
    fn a_path_shorter_than_a_segment_has_no_drift() {
        let truth = straight(50, 0.1, 1.0);
        assert!(segment_drift(&truth, &truth, 10.0).is_none());
    }
}
