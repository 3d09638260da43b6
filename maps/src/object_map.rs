//! An object map: a set of boulder landmarks in one frame, from one session.

use std::collections::{BTreeMap, HashMap};

use nalgebra::{Isometry3, Point3};

use crate::{Landmark, MapError};

/// A map of boulder landmarks expressed in one coordinate frame.
///
/// ```
/// use segloc_maps::{Landmark, ObjectMap};
/// use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
/// let mut map = ObjectMap::new("query", "traverse_3", true);
/// map.landmarks.push(Landmark::new(0, Point3::new(1.0, 0.0, 0.0), Matrix3::identity() * 0.01));
/// map.validate().unwrap();
/// let world_from_query = Isometry3::translation(0.0, 0.0, 2.0);
/// let in_world = map.transformed(&world_from_query, "world");
/// assert_eq!(in_world.frame, "world");
/// assert_eq!(in_world.positions()[0], Point3::new(1.0, 0.0, 2.0));
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectMap {
    /// Name of the frame the positions are expressed in, e.g. "world", "query", "traverse_3".
    pub frame: String,
    /// Session / agent that built the map.
    pub session: String,
    /// Whether z is up (gravity direction known), so that only yaw + translation are unknown.
    pub gravity_aligned: bool,
    /// The landmarks; ids are unique.
    pub landmarks: Vec<Landmark>,
    /// Free-form provenance (source file, fusion parameters, ...).
    pub notes: BTreeMap<String, String>,
}

impl ObjectMap {
    /// An empty map.
    pub fn new(
        frame: impl Into<String>,
        session: impl Into<String>,
        gravity_aligned: bool,
    ) -> Self {
        ObjectMap {
            frame: frame.into(),
            session: session.into(),
            gravity_aligned,
            landmarks: Vec::new(),
            notes: BTreeMap::new(),
        }
    }

    /// The landmark positions, in landmark order.
    pub fn positions(&self) -> Vec<Point3<f64>> {
        self.landmarks.iter().map(|l| l.position).collect()
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.landmarks.len()
    }

    /// Whether the map has no landmark.
    pub fn is_empty(&self) -> bool {
        self.landmarks.is_empty()
    }

    /// The landmark with a given id, if any (linear search).
    pub fn landmark(&self, id: u32) -> Option<&Landmark> {
        self.landmarks.iter().find(|l| l.id == id)
    }

    /// One more than the largest id (0 for an empty map): a fresh id for a new landmark.
    pub fn next_id(&self) -> u32 {
        self.landmarks
            .iter()
            .map(|l| l.id.saturating_add(1))
            .max()
            .unwrap_or(0)
    }

    /// Check the map: finite positions, symmetric PSD covariances with non-negative
    /// variances, finite sizes, unique ids. The error names the offending landmark by id
    /// and index.
    pub fn validate(&self) -> Result<(), MapError> {
        let mut seen: HashMap<u32, usize> = HashMap::with_capacity(self.landmarks.len());
        for (index, lm) in self.landmarks.iter().enumerate() {
            if let Err(message) = lm.check() {
                return Err(MapError::InvalidData {
                    what: "map",
                    message: format!("landmark id {} (index {index}): {message}", lm.id),
                });
            }
            if let Some(first) = seen.insert(lm.id, index) {
                return Err(MapError::InvalidData {
                    what: "map",
                    message: format!(
                        "duplicate landmark id {} (indices {first} and {index})",
                        lm.id
                    ),
                });
            }
        }
        Ok(())
    }

    /// The same map expressed in another frame: `a_from_b` maps points of this map's frame
    /// (b) into frame a, named `new_frame`. Positions are moved, covariances rotated
    /// (`R Σ Rᵀ`); everything else is kept.
    pub fn transformed(&self, a_from_b: &Isometry3<f64>, new_frame: &str) -> ObjectMap {
        let r = a_from_b.rotation.to_rotation_matrix();
        let r = r.matrix();
        let landmarks = self
            .landmarks
            .iter()
            .map(|l| {
                let cov = r * l.covariance * r.transpose();
                Landmark {
                    position: a_from_b * l.position,
                    // re-symmetrise against rounding
                    covariance: (cov + cov.transpose()) * 0.5,
                    ..l.clone()
                }
            })
            .collect();
        ObjectMap {
            frame: new_frame.to_string(),
            landmarks,
            ..self.clone_header()
        }
    }

    /// A copy without landmarks.
    fn clone_header(&self) -> ObjectMap {
        ObjectMap {
            frame: self.frame.clone(),
            session: self.session.clone(),
            gravity_aligned: self.gravity_aligned,
            landmarks: Vec::new(),
            notes: self.notes.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Translation3, UnitQuaternion, Vector3};
    use std::f64::consts::FRAC_PI_2;

    fn map() -> ObjectMap {
        let mut m = ObjectMap::new("query", "s1", true);
        m.landmarks.push(Landmark::new(
            0,
            Point3::new(1.0, 0.0, 0.0),
            Matrix3::from_diagonal(&Vector3::new(0.04, 0.01, 0.0025)),
        ));
        m.landmarks.push(Landmark::new(
            5,
            Point3::new(0.0, 2.0, 1.0),
            Matrix3::identity() * 0.01,
        ));
        m
    }

    #[test]
    fn basics() {
        let m = map();
        assert_eq!(m.len(), 2);
        assert!(!m.is_empty());
        assert_eq!(m.next_id(), 6);
        assert_eq!(m.landmark(5).unwrap().position.y, 2.0);
        assert!(m.landmark(3).is_none());
        assert!(ObjectMap::new("w", "s", false).is_empty());
        assert_eq!(ObjectMap::new("w", "s", false).next_id(), 0);
        m.validate().unwrap();
    }

    #[test]
    fn duplicate_ids_rejected_with_indices() {
        let mut m = map();
        m.landmarks[1].id = 0;
        let e = m.validate().unwrap_err().to_string();
        assert!(
            e.contains("duplicate landmark id 0 (indices 0 and 1)"),
            "{e}"
        );
    }

    #[test]
    fn nan_rejected_with_id_and_index() {
        let mut m = map();
        m.landmarks[1].position.x = f64::NAN;
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains("landmark id 5 (index 1)"), "{e}");
    }

    #[test]
    fn transform_moves_points_and_rotates_covariance() {
        let m = map();
        // 90° yaw then a translation
        let a_from_b = Isometry3::from_parts(
            Translation3::new(10.0, 0.0, 0.5),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), FRAC_PI_2),
        );
        let t = m.transformed(&a_from_b, "world");
        assert_eq!(t.frame, "world");
        assert_eq!(t.session, "s1");
        let p = t.landmarks[0].position;
        assert!((p - Point3::new(10.0, 1.0, 0.5)).norm() < 1e-12);
        // the x variance becomes the y variance
        let c = t.landmarks[0].covariance;
        assert!((c[(0, 0)] - 0.01).abs() < 1e-12);
        assert!((c[(1, 1)] - 0.04).abs() < 1e-12);
        assert!((c[(2, 2)] - 0.0025).abs() < 1e-12);
        assert!(c[(0, 1)].abs() < 1e-12);
        t.validate().unwrap();
        // round trip back
        let back = t.transformed(&a_from_b.inverse(), "query");
        for (a, b) in back.landmarks.iter().zip(&m.landmarks) {
            assert!((a.position - b.position).norm() < 1e-12);
            assert!((a.covariance - b.covariance).norm() < 1e-15);
        }
    }

    #[test]
    fn transform_of_general_covariance_is_r_sigma_rt() {
        let mut m = map();
        m.landmarks[0].covariance =
            Matrix3::new(0.04, 0.01, 0.0, 0.01, 0.02, 0.003, 0.0, 0.003, 0.01);
        let rot = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1);
        let iso = Isometry3::from_parts(Translation3::new(1.0, 2.0, 3.0), rot);
        let t = m.transformed(&iso, "a");
        let r = rot.to_rotation_matrix().into_inner();
        let expect = r * m.landmarks[0].covariance * r.transpose();
        assert!((t.landmarks[0].covariance - expect).norm() < 1e-15);
        // eigenvalues preserved
        let e0 = m.landmarks[0].covariance.symmetric_eigenvalues();
        let e1 = t.landmarks[0].covariance.symmetric_eigenvalues();
        let (mut a, mut b) = (e0.as_slice().to_vec(), e1.as_slice().to_vec());
        a.sort_by(f64::total_cmp);
        b.sort_by(f64::total_cmp);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-14);
        }
    }
}
