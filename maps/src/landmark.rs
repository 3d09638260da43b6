//! One boulder landmark of an object map.

use nalgebra::{Matrix3, Matrix6, Point3};
use serde::{Deserialize, Serialize};

/// A boulder landmark: a 3D centroid with its uncertainty and provenance.
///
/// ```
/// use segloc_maps::Landmark;
/// use nalgebra::{Matrix3, Point3};
/// let lm = Landmark::new(4, Point3::new(1.0, 2.0, 0.5), Matrix3::identity() * 0.01);
/// assert_eq!(lm.observations, 1);
/// assert!(lm.check().is_ok());
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Landmark {
    /// Identifier, unique within its map.
    pub id: u32,
    /// Centroid in the map's frame, metres.
    pub position: Point3<f64>,
    /// Position covariance, m² (symmetric positive semi-definite).
    pub covariance: Matrix3<f64>,
    /// Boulder diameter in metres, when known.
    pub size_m: Option<f64>,
    /// Number of detections fused into this landmark.
    pub observations: u32,
    /// Sessions / agents that observed it (empty means: the map's own session).
    pub sessions: Vec<String>,
}

/// Relative tolerance for the symmetry and positive-semi-definiteness checks.
const COV_REL_TOL: f64 = 1e-6;

impl Landmark {
    /// A landmark seen once, with no size and no extra provenance.
    pub fn new(id: u32, position: Point3<f64>, covariance: Matrix3<f64>) -> Self {
        Landmark {
            id,
            position,
            covariance,
            size_m: None,
            observations: 1,
            sessions: Vec::new(),
        }
    }

    /// Check this landmark on its own: finite position, finite symmetric PSD covariance
    /// (within a small relative tolerance), finite non-negative size.
    ///
    /// The message does not name the landmark; [`crate::ObjectMap::validate`] adds that.
    pub fn check(&self) -> Result<(), LandmarkError> {
        let p = &self.position;
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(LandmarkError::Position([p.x, p.y, p.z]));
        }
        check_covariance(&self.covariance)?;
        if let Some(s) = self.size_m {
            if !(s.is_finite() && s >= 0.0) {
                return Err(LandmarkError::Size(s));
            }
        }
        Ok(())
    }
}

/// What is wrong with one landmark ([`Landmark::check`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LandmarkError {
    /// A coordinate is not finite.
    #[error("position ({}, {}, {}) is not finite", .0[0], .0[1], .0[2])]
    Position([f64; 3]),
    /// The covariance is not a covariance.
    #[error(transparent)]
    Covariance(#[from] CovarianceError),
    /// The size is negative or not finite.
    #[error("size_m {0} is not a finite non-negative number")]
    Size(f64),
}

/// What is wrong with a 3 × 3 covariance ([`check_covariance`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CovarianceError {
    /// An entry is NaN or infinite.
    #[error("covariance has a non-finite entry")]
    NonFinite,
    /// A diagonal entry is negative.
    #[error("covariance has a negative variance {axis}{axis} = {value}")]
    NegativeVariance {
        /// `x`, `y` or `z`.
        axis: &'static str,
        /// The variance.
        value: f64,
    },
    /// Entries `(row, col)` and `(col, row)` differ beyond the tolerance.
    #[error(
        "covariance is not symmetric: entry ({row},{col}) = {upper} but ({col},{row}) = {lower}"
    )]
    Asymmetric {
        /// Row of the upper entry.
        row: usize,
        /// Column of the upper entry.
        col: usize,
        /// The upper entry.
        upper: f64,
        /// The lower entry.
        lower: f64,
    },
    /// The smallest eigenvalue is clearly negative.
    #[error("covariance is not positive semi-definite (smallest eigenvalue {0:e})")]
    NotPositiveSemidefinite(f64),
}

/// Check a 3×3 covariance: finite, symmetric, non-negative diagonal, no clearly negative
/// eigenvalue (tolerance relative to the trace).
pub fn check_covariance(c: &Matrix3<f64>) -> Result<(), CovarianceError> {
    if c.iter().any(|v| !v.is_finite()) {
        return Err(CovarianceError::NonFinite);
    }
    for k in 0..3 {
        if c[(k, k)] < 0.0 {
            return Err(CovarianceError::NegativeVariance {
                axis: ["x", "y", "z"][k],
                value: c[(k, k)],
            });
        }
    }
    let scale = c.trace().max(f64::MIN_POSITIVE);
    for (r, col) in [(0, 1), (0, 2), (1, 2)] {
        if (c[(r, col)] - c[(col, r)]).abs() > COV_REL_TOL * scale {
            return Err(CovarianceError::Asymmetric {
                row: r,
                col,
                upper: c[(r, col)],
                lower: c[(col, r)],
            });
        }
    }
    let min_eig = c.symmetric_eigenvalues().min();
    if min_eig < -COV_REL_TOL * scale {
        return Err(CovarianceError::NotPositiveSemidefinite(min_eig));
    }
    Ok(())
}

/// The upper triangle of a symmetric 3 × 3 matrix, `[xx, xy, xz, yy, yz, zz]`: how the file
/// formats write a covariance.
pub fn upper_triangle(c: &Matrix3<f64>) -> [f64; 6] {
    [
        c[(0, 0)],
        c[(0, 1)],
        c[(0, 2)],
        c[(1, 1)],
        c[(1, 2)],
        c[(2, 2)],
    ]
}

/// The symmetric 3 × 3 matrix of an upper triangle `[xx, xy, xz, yy, yz, zz]`
/// ([`upper_triangle`]'s inverse).
pub fn from_upper_triangle([xx, xy, xz, yy, yz, zz]: [f64; 6]) -> Matrix3<f64> {
    Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
}

/// The upper triangle of a symmetric 6 × 6 matrix, row by row (21 numbers).
pub fn upper_triangle6(c: &Matrix6<f64>) -> [f64; 21] {
    let mut out = [0.0; 21];
    let mut k = 0;
    for r in 0..6 {
        for col in r..6 {
            out[k] = c[(r, col)];
            k += 1;
        }
    }
    out
}

/// The symmetric 6 × 6 matrix of an upper triangle written row by row
/// ([`upper_triangle6`]'s inverse).
pub fn from_upper_triangle6(values: &[f64; 21]) -> Matrix6<f64> {
    let mut c = Matrix6::zeros();
    let mut k = 0;
    for r in 0..6 {
        for col in r..6 {
            c[(r, col)] = values[k];
            c[(col, r)] = values[k];
            k += 1;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lm() -> Landmark {
        Landmark::new(1, Point3::new(1.0, 2.0, 3.0), Matrix3::identity() * 0.04)
    }

    #[test]
    fn good_landmark_passes() {
        assert!(lm().check().is_ok());
        let mut l = lm();
        l.covariance = Matrix3::zeros();
        assert!(l.check().is_ok(), "zero covariance is PSD");
    }

    #[test]
    fn nan_position_fails() {
        let mut l = lm();
        l.position.y = f64::NAN;
        assert!(l.check().unwrap_err().to_string().contains("not finite"));
    }

    #[test]
    fn negative_variance_fails() {
        let mut l = lm();
        l.covariance[(2, 2)] = -0.1;
        assert!(l.check().unwrap_err().to_string().contains("zz"));
    }

    #[test]
    fn asymmetric_or_indefinite_fails() {
        let mut l = lm();
        l.covariance[(0, 1)] = 0.01;
        assert!(l.check().unwrap_err().to_string().contains("symmetric"));
        l.covariance[(1, 0)] = 0.01;
        assert!(l.check().is_ok());
        // |xy| > sqrt(xx yy): indefinite
        l.covariance[(0, 1)] = 0.1;
        l.covariance[(1, 0)] = 0.1;
        assert!(l.check().unwrap_err().to_string().contains("semi-definite"));
    }

    #[test]
    fn bad_size_fails() {
        let mut l = lm();
        l.size_m = Some(-1.0);
        assert!(l.check().is_err());
        l.size_m = Some(f64::INFINITY);
        assert!(l.check().is_err());
        l.size_m = Some(0.3);
        assert!(l.check().is_ok());
    }
}
