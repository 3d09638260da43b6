//! Information matrices that are not positive definite, as some public pose-graph files
//! hold (GTSAM and g2o load such files): the nearest positive-definite matrix.
//!
//! The repair symmetrises the matrix, takes its symmetric eigen-decomposition `V Λ Vᵀ`
//! and raises every eigenvalue below `floor · λmax` to that value: `V max(Λ, floor · λmax) Vᵀ`
//! is the symmetric matrix nearest to the input in the Frobenius norm whose eigenvalues
//! are all at least `floor · λmax` (Higham 1988). Directions the file gave no (or a
//! negative) weight keep almost none: with [`REPAIR_EIGENVALUE_FLOOR`] = 1e-9 they weigh a
//! billionth of the edge's best-measured direction, which leaves the problem's optimum
//! essentially as the file's positive part defines it while the matrix has a Cholesky
//! factor (condition number 1e9, far inside double precision).

use nalgebra::Matrix6;

/// Eigenvalue floor of [`nearest_positive_definite`] used when reading files, relative to
/// the largest eigenvalue.
pub const REPAIR_EIGENVALUE_FLOOR: f64 = 1e-9;

/// Why an information matrix could not be repaired.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum RepairError {
    /// An entry is NaN or infinite.
    #[error("information matrix has NaN or infinite entries")]
    NonFinite,
    /// No eigenvalue is positive, so there is no scale to floor the others at.
    #[error("information matrix has no positive eigenvalue (largest {largest:e}); it cannot be repaired")]
    NoPositiveEigenvalue {
        /// The largest eigenvalue of the symmetrised matrix.
        largest: f64,
    },
    /// `floor` is not in (0, 1].
    #[error("eigenvalue floor {0} is not in (0, 1]")]
    BadFloor(f64),
}

/// True when `m` is finite, symmetric and has a Cholesky factor (what a factor accepts).
pub fn is_positive_definite(m: &Matrix6<f64>) -> bool {
    super::factors::check_information(m).is_ok()
}

/// The nearest symmetric matrix to `m` (Frobenius norm) whose eigenvalues are all at least
/// `floor` times its largest eigenvalue; `floor` in (0, 1].
///
/// Eigenvalues already above the floor are kept, so a positive-definite matrix whose
/// condition number is below `1 / floor` comes back unchanged up to rounding.
pub fn nearest_positive_definite(
    m: &Matrix6<f64>,
    floor: f64,
) -> Result<Matrix6<f64>, RepairError> {
    if !(floor > 0.0 && floor <= 1.0) {
        return Err(RepairError::BadFloor(floor));
    }
    if !m.iter().all(|v| v.is_finite()) {
        return Err(RepairError::NonFinite);
    }
    let symmetric = (m + m.transpose()) * 0.5;
    let eigen = symmetric.symmetric_eigen();
    let largest = eigen.eigenvalues.max();
    if largest.is_nan() || largest <= 0.0 {
        return Err(RepairError::NoPositiveEigenvalue { largest });
    }
    let lowest = floor * largest;
    let clamped = eigen.eigenvalues.map(|l| l.max(lowest));
    let v = eigen.eigenvectors;
    let repaired = v * Matrix6::from_diagonal(&clamped) * v.transpose();
    // Exactly symmetric, as the factors require.
    Ok((repaired + repaired.transpose()) * 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector6;

    #[test]
    fn indefinite_matrix_becomes_the_nearest_positive_definite_one() {
        // Known eigen-decomposition: a rotation of diag(4, 3, 2, 1, -1, -2).
        let q = Matrix6::from_fn(|i, j| ((i * 7 + j * 3) as f64).sin())
            .qr()
            .q();
        let lambda = Vector6::new(4.0, 3.0, 2.0, 1.0, -1.0, -2.0);
        let m = q * Matrix6::from_diagonal(&lambda) * q.transpose();
        assert!(!is_positive_definite(&m));
        let floor = 1e-3;
        let r = nearest_positive_definite(&m, floor).unwrap();
        assert!(is_positive_definite(&r));
        let expected = Vector6::new(4.0, 3.0, 2.0, 1.0, 4e-3, 4e-3);
        let want = q * Matrix6::from_diagonal(&expected) * q.transpose();
        assert!((r - want).abs().max() < 1e-12, "{r} vs {want}");
        // Nearest: the Frobenius distance is that of the raised eigenvalues alone.
        let d = (r - m).norm();
        assert!((d - ((1.004f64).powi(2) + (2.004f64).powi(2)).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn well_conditioned_matrix_is_unchanged() {
        let mut m = Matrix6::identity() * 10.0;
        m[(0, 1)] = 1.0;
        m[(1, 0)] = 1.0;
        let r = nearest_positive_definite(&m, REPAIR_EIGENVALUE_FLOOR).unwrap();
        assert!((r - m).abs().max() < 1e-13);
    }

    #[test]
    fn singular_matrix_gets_the_relative_floor() {
        let mut m = Matrix6::zeros();
        m[(0, 0)] = 100.0;
        let r = nearest_positive_definite(&m, REPAIR_EIGENVALUE_FLOOR).unwrap();
        assert!(is_positive_definite(&r));
        let e = r.symmetric_eigen().eigenvalues;
        assert!((e.min() - 100.0 * REPAIR_EIGENVALUE_FLOOR).abs() < 1e-15);
        assert!((e.max() - 100.0).abs() < 1e-12);
    }

    #[test]
    fn hopeless_matrices_are_refused() {
        let m = -Matrix6::identity();
        assert!(matches!(
            nearest_positive_definite(&m, 1e-9),
            Err(RepairError::NoPositiveEigenvalue { .. })
        ));
        let mut m = Matrix6::identity();
        m[(2, 3)] = f64::NAN;
        assert_eq!(
            nearest_positive_definite(&m, 1e-9),
            Err(RepairError::NonFinite)
        );
        assert_eq!(
            nearest_positive_definite(&Matrix6::identity(), 0.0),
            Err(RepairError::BadFloor(0.0))
        );
    }
}
