//! From detections to landmarks: one landmark per boulder.
//!
//! A session yields many noisy detections of each boulder (one a second while it is in
//! view), a few spurious ones, and some boulders seen only once or twice.
//! [`fuse_detections`] clusters them ([`cluster`]) and turns each cluster into a landmark
//! with a robust centroid and a covariance ([`estimate`]), weighing each detection by the
//! stereo pair's noise model ([`stereo_noise`]).

pub mod cluster;
pub mod estimate;
pub mod from_grid;
pub mod from_points;
pub mod size_bias;
pub mod stereo_noise;
pub mod view_bias;

use crate::field_error::FieldError;
pub use estimate::CentroidEstimator;
pub use from_grid::{map_from_grid, map_from_raster, GridRocksConfig, RockCells};
pub use from_points::{map_from_points, PointsMapOptions};
use segloc_maps::{Detection, DetectionSet, ObjectMap};
use serde::{Deserialize, Serialize};
use stereo_noise::StereoNoiseConfig;

/// Parameters of the detection-to-landmark fusion stage.
///
/// The defaults were measured on the 17 real LunarLoc traverses (see BENCHMARKS.md):
/// stereo depth noise along the line of sight grows from 5 mm at 2 m to 3 cm at 6 m,
/// across it stays near 2–5 mm; detections closer than 1.5 m (boulders cut by the image
/// border) are an order of magnitude worse.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FusionConfig {
    /// Detections within this distance (m) of a cluster's centroid join it.
    pub cluster_radius_m: f64,
    /// Clusters with fewer detections are dropped as spurious.
    pub min_observations: u32,
    /// Detections closer than this to the rover (m) are ignored (needs rover positions).
    pub min_range_m: f64,
    /// Detections farther than this from the rover (m) are ignored (needs rover positions).
    pub max_range_m: f64,
    /// Floor (m) of a landmark's position standard deviation: how well the same boulder's
    /// centroid repeats between sessions seen from other viewpoints, however many
    /// detections it has.
    pub repeatability_m: f64,
    /// Viewpoint-bias correction (m): each detection is pushed this far away from the
    /// rover along its horizontal line of sight before clustering (needs rover positions;
    /// 0 = off, the default). A centroid from stereo points on the visible surface of a
    /// boulder sits nearer the camera than the boulder's centre; on the 17 LunarLoc
    /// traverses the offset, estimated from boulders seen from several directions
    /// ([`view_bias::estimate_view_bias`]), is about 1.4 cm at every range.
    pub view_bias_m: f64,
    /// Spread (m) of the viewpoint bias from boulder to boulder (0 = not modelled, the
    /// default). When positive, a landmark's covariance gains `σ² m mᵀ`, with `m` the mean
    /// horizontal line of sight of its detections: length 1 for a boulder seen from one
    /// direction (its centroid keeps its own bias), near 0 for one seen from all sides
    /// (the biases cancel). Needs rover positions.
    pub view_bias_sigma_m: f64,
    /// Viewpoint-bias correction proportional to the boulder's size: each detection with a
    /// size is pushed a further `view_bias_size_fraction × size_m` away from the rover
    /// (0 = off, the default). The visible face of a larger boulder lies farther in front
    /// of its centre.
    pub view_bias_size_fraction: f64,
    /// How each landmark's centroid is computed from its detections.
    pub centroid: CentroidEstimator,
    /// [`CentroidEstimator::StereoWeighted`]: the stereo pair's noise (depth error growing as
    /// the square of the range, lateral error as the range); the default is the IPEX
    /// pair's.
    pub stereo: StereoNoiseConfig,
    /// [`CentroidEstimator::StereoWeighted`]: standard deviation (m) of the rover position
    /// behind each detection, added to its stereo error in every direction, so that the
    /// nearest views weigh no more than the poses placing them can support (a session's
    /// trajectory is good to about a centimetre).
    pub pose_sigma_m: f64,
    /// [`CentroidEstimator::StereoWeighted`]: width of the Cauchy kernel that down-weights
    /// detections far from the centroid, in standard deviations.
    pub outlier_width_sigmas: f64,
}

impl FusionConfig {
    /// Checks that every distance, noise figure and width is finite and non-negative, the
    /// cluster radius positive and the range gate ordered; the message names the field.
    pub fn validate(&self) -> Result<(), FieldError> {
        let non_negative = [
            (self.min_range_m, "min_range_m"),
            (self.repeatability_m, "repeatability_m"),
            (self.view_bias_sigma_m, "view_bias_sigma_m"),
            (self.stereo.disparity_sigma_px, "stereo.disparity_sigma_px"),
            (self.stereo.pixel_sigma_px, "stereo.pixel_sigma_px"),
            (self.pose_sigma_m, "pose_sigma_m"),
            (self.outlier_width_sigmas, "outlier_width_sigmas"),
        ];
        if let Some((_, name)) = non_negative
            .iter()
            .find(|(v, _)| !(v.is_finite() && *v >= 0.0))
        {
            return Err(FieldError::new(*name, "must be finite and non-negative"));
        }
        if !(self.cluster_radius_m.is_finite() && self.cluster_radius_m > 0.0) {
            return Err(FieldError::new("cluster_radius_m", "must be positive"));
        }
        if self.max_range_m.is_nan() || self.max_range_m < self.min_range_m {
            return Err(FieldError::new(
                "max_range_m",
                "must not be below min_range_m",
            ));
        }
        if !(self.view_bias_m.is_finite() && self.view_bias_size_fraction.is_finite()) {
            let field = if self.view_bias_m.is_finite() {
                "view_bias_size_fraction"
            } else {
                "view_bias_m"
            };
            return Err(FieldError::new(field, "must be finite"));
        }
        let (focal, baseline) = (self.stereo.focal_px, self.stereo.baseline_m);
        if !(focal.is_finite() && focal > 0.0 && baseline.is_finite() && baseline > 0.0) {
            let field = if focal.is_finite() && focal > 0.0 {
                "stereo.baseline_m"
            } else {
                "stereo.focal_px"
            };
            return Err(FieldError::new(field, "must be positive"));
        }
        Ok(())
    }
}

impl Default for FusionConfig {
    fn default() -> Self {
        Self {
            cluster_radius_m: 0.2,
            min_observations: 2,
            min_range_m: 1.5,
            max_range_m: 8.0,
            repeatability_m: 0.01,
            view_bias_m: 0.0,
            view_bias_sigma_m: 0.0,
            view_bias_size_fraction: 0.0,
            centroid: CentroidEstimator::Median,
            stereo: StereoNoiseConfig::default(),
            pose_sigma_m: 0.01,
            outlier_width_sigmas: 3.0,
        }
    }
}

/// Fuse a session's detections into an object map (frame and session from the set).
///
/// ```
/// use nalgebra::Point3;
/// use segloc::landmarks::{fuse_detections, FusionConfig};
/// use segloc_maps::{Detection, DetectionSet};
/// let mut set = DetectionSet::new("demo", "world", true);
/// for k in 0..4 {
///     let jitter = 0.003 * k as f64;
///     set.detections.push(Detection { frame: k, p_world: Point3::new(3.0 + jitter, 1.0, 0.2),
///         rover_position: Some(Point3::new(0.0, 0.0, 0.3)), size_m: None, score: None });
/// }
/// let map = fuse_detections(&set, &FusionConfig::default());
/// assert_eq!(map.len(), 1);
/// assert_eq!(map.landmarks[0].observations, 4);
/// ```
pub fn fuse_detections(set: &DetectionSet, config: &FusionConfig) -> ObjectMap {
    let usable: Vec<_> = set
        .detections
        .iter()
        .filter(|d| match d.rover_position {
            Some(rover) => {
                let range = (d.p_world - rover).xy().norm();
                range >= config.min_range_m && range <= config.max_range_m
            }
            None => true,
        })
        .collect();
    let corrected: Vec<Detection>;
    let usable: Vec<&Detection> =
        if config.view_bias_m != 0.0 || config.view_bias_size_fraction != 0.0 {
            corrected = usable
                .iter()
                .map(|d| {
                    let size_m = d.size_m.unwrap_or(0.0);
                    view_bias::corrected(
                        d,
                        config.view_bias_m + config.view_bias_size_fraction * size_m,
                    )
                })
                .collect();
            corrected.iter().collect()
        } else {
            usable
        };
    let points: Vec<_> = usable.iter().map(|d| d.p_world).collect();
    let clusters = cluster::cluster_points(&points, config.cluster_radius_m);
    let mut map = ObjectMap::new(set.frame.clone(), set.session.clone(), set.gravity_aligned);
    for members in clusters {
        if (members.len() as u32) < config.min_observations {
            continue;
        }
        let detections: Vec<_> = members.iter().map(|&k| usable[k as usize]).collect();
        let id = map.landmarks.len() as u32;
        let mut landmark = estimate::landmark_from(&detections, id, config);
        landmark.sessions = vec![set.session.clone()];
        map.landmarks.push(landmark);
    }
    map.notes.insert("source".into(), "fused detections".into());
    map.notes.insert(
        "fusion".into(),
        serde_json::to_string(config).unwrap_or_default(),
    );
    map.notes
        .insert("detections".into(), set.detections.len().to_string());
    map
}

/// A detection of `p` from a rover at `rover`, without size or score (for tests).
#[cfg(test)]
pub(crate) fn detection_seen_from(
    p: nalgebra::Point3<f64>,
    rover: nalgebra::Point3<f64>,
) -> Detection {
    Detection {
        frame: 0,
        p_world: p,
        rover_position: Some(rover),
        size_m: None,
        score: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_names_the_bad_field() {
        assert!(FusionConfig::default().validate().is_ok());
        let bad = FusionConfig {
            pose_sigma_m: f64::NAN,
            ..FusionConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("pose_sigma_m"));
        let inverted = FusionConfig {
            min_range_m: 9.0,
            ..FusionConfig::default()
        };
        assert!(inverted
            .validate()
            .unwrap_err()
            .to_string()
            .contains("max_range_m"));
        let mut blind = FusionConfig::default();
        blind.stereo.focal_px = 0.0;
        assert!(blind
            .validate()
            .unwrap_err()
            .to_string()
            .contains("focal_px"));
    }
}
