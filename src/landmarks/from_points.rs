//! A map from bare boulder centroids, for callers that have points but no detections
//! (another tool's boulder positions, a numpy array).

use nalgebra::{Matrix3, Point3};
use segloc_maps::{Landmark, MapError, ObjectMap};

/// The landmarks' values that bare points do not carry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointsMapOptions {
    /// Whether z is up (4-DOF relocalization possible).
    pub gravity_aligned: bool,
    /// Standard deviation (m) of every landmark's position when no covariance is given:
    /// the fusion's repeatability floor ([`super::FusionConfig::repeatability_m`]), what a
    /// landmark fused from detections gets at best.
    pub position_sigma_m: f64,
}

impl Default for PointsMapOptions {
    fn default() -> Self {
        Self {
            gravity_aligned: true,
            position_sigma_m: super::FusionConfig::default().repeatability_m,
        }
    }
}

/// A map of one landmark per point, ids `0..n` in order, each seen once: its size from
/// `sizes` (NaN: unknown), its covariance from `covariances`, else isotropic with
/// `options.position_sigma_m`. The map is validated: a wrong length, a non-finite
/// coordinate or a bad covariance is an error naming the landmark.
pub fn map_from_points(
    points: &[Point3<f64>],
    sizes: Option<&[f64]>,
    covariances: Option<&[Matrix3<f64>]>,
    options: &PointsMapOptions,
) -> Result<ObjectMap, MapError> {
    let invalid = |message: String| MapError::InvalidData {
        what: "map",
        message,
    };
    let n = points.len();
    if let Some(sizes) = sizes.filter(|s| s.len() != n) {
        return Err(invalid(format!("{n} points but {} sizes", sizes.len())));
    }
    if let Some(covs) = covariances.filter(|c| c.len() != n) {
        return Err(invalid(format!(
            "{n} points but {} covariances",
            covs.len()
        )));
    }
    let sigma = options.position_sigma_m;
    if !(sigma.is_finite() && sigma > 0.0) {
        return Err(invalid(format!(
            "position_sigma_m {sigma} must be positive"
        )));
    }
    let mut map = ObjectMap::new("points", "", options.gravity_aligned);
    map.landmarks = points
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let covariance = covariances.map_or(Matrix3::identity() * sigma * sigma, |c| c[k]);
            let mut landmark = Landmark::new(k as u32, *p, covariance);
            landmark.size_m = sizes.map(|s| s[k]).filter(|s| !s.is_nan());
            landmark
        })
        .collect();
    map.validate()?;
    Ok(map)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_landmark_per_point_with_the_floor_as_covariance() {
        let points = [Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 2.0, 0.1)];
        let options = PointsMapOptions::default();
        let map = map_from_points(&points, Some(&[0.3, f64::NAN]), None, &options).unwrap();
        assert_eq!(map.len(), 2);
        assert!(map.gravity_aligned);
        assert_eq!(map.landmarks[1].id, 1);
        assert_eq!(map.landmarks[0].size_m, Some(0.3));
        assert_eq!(map.landmarks[1].size_m, None);
        let s = options.position_sigma_m;
        assert_eq!(map.landmarks[1].covariance, Matrix3::identity() * s * s);
    }

    #[test]
    fn bad_input_names_the_problem() {
        let points = [Point3::new(0.0, 0.0, f64::NAN)];
        let options = PointsMapOptions::default();
        let e = map_from_points(&points, None, None, &options).unwrap_err();
        assert!(e.to_string().contains("landmark id 0 (index 0)"), "{e}");
        let e = map_from_points(&[Point3::origin()], Some(&[]), None, &options).unwrap_err();
        assert!(e.to_string().contains("1 points but 0 sizes"), "{e}");
        let bad = [Matrix3::identity() * -1.0];
        let e = map_from_points(&[Point3::origin()], None, Some(&bad), &options).unwrap_err();
        assert!(e.to_string().contains("negative variance"), "{e}");
    }
}
