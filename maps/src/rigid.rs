//! Rigid transforms given as 4 × 4 homogeneous matrices, as other tools (numpy, GTSAM's
//! `Pose3.matrix()`, evo) exchange them.

use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion};

/// Largest deviation of `RᵀR` from the identity, of `det R` from 1 and of the last row from
/// `[0, 0, 0, 1]` that [`isometry_from_matrix`] accepts (a matrix printed with 7
/// significant digits still passes).
pub const RIGID_TOLERANCE: f64 = 1e-6;

/// Why a 4 × 4 matrix is not a rigid transform.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RigidError {
    /// An entry is NaN or infinite.
    #[error("the matrix has a non-finite entry")]
    NonFinite,
    /// The last row is not `[0, 0, 0, 1]`.
    #[error("the last row is [{}, {}, {}, {}], not [0, 0, 0, 1]", row[0], row[1], row[2], row[3])]
    LastRow {
        /// The last row.
        row: [f64; 4],
    },
    /// The upper-left block is not a rotation.
    #[error("the upper-left 3 × 3 block is not a rotation (|RᵀR − I| = {off_orthonormal:.1e}, det = {det})")]
    NotRotation {
        /// Largest entry of `|RᵀR − I|`.
        off_orthonormal: f64,
        /// `det R`.
        det: f64,
    },
}

/// The rigid transform of a 4 × 4 homogeneous matrix `[R t; 0 0 0 1]`.
///
/// Refuses, with a message saying what is wrong, a non-finite entry, a last row other than
/// `[0, 0, 0, 1]`, or an `R` that is not a rotation (within [`RIGID_TOLERANCE`]); `R` is
/// then taken as the nearest unit quaternion.
///
/// ```
/// use segloc_maps::isometry_from_matrix;
/// use nalgebra::Matrix4;
/// let t = isometry_from_matrix(&Matrix4::new_translation(&[1.0, 2.0, 3.0].into())).unwrap();
/// assert_eq!(t.translation.vector.x, 1.0);
/// assert!(isometry_from_matrix(&Matrix4::zeros()).is_err());
/// ```
pub fn isometry_from_matrix(m: &Matrix4<f64>) -> Result<Isometry3<f64>, RigidError> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(RigidError::NonFinite);
    }
    let last_row = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)] - 1.0];
    if last_row.iter().any(|v| v.abs() > RIGID_TOLERANCE) {
        return Err(RigidError::LastRow {
            row: [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]],
        });
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let off_orthonormal = (r.transpose() * r - Matrix3::identity()).abs().max();
    let det = r.determinant();
    if off_orthonormal > RIGID_TOLERANCE || (det - 1.0).abs() > RIGID_TOLERANCE {
        return Err(RigidError::NotRotation {
            off_orthonormal,
            det,
        });
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Isometry3::from_parts(
        Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
        rotation,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn round_trips_a_rigid_transform() {
        let t = Isometry3::from_parts(
            Translation3::new(1.0, -2.0, 0.5),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 2.5),
        );
        let back = isometry_from_matrix(&t.to_homogeneous()).unwrap();
        assert!((back.to_homogeneous() - t.to_homogeneous()).abs().max() < 1e-15);
    }

    #[test]
    fn refuses_what_is_not_rigid() {
        let mut scaled = Matrix4::identity();
        scaled[(0, 0)] = 2.0;
        assert!(isometry_from_matrix(&scaled)
            .unwrap_err()
            .to_string()
            .contains("not a rotation"));
        let mirror = Matrix4::new_nonuniform_scaling(&Vector3::new(-1.0, 1.0, 1.0));
        assert!(isometry_from_matrix(&mirror)
            .unwrap_err()
            .to_string()
            .contains("det = -1"));
        let mut projective = Matrix4::identity();
        projective[(3, 0)] = 0.1;
        assert!(isometry_from_matrix(&projective)
            .unwrap_err()
            .to_string()
            .contains("last row"));
        let mut nan = Matrix4::identity();
        nan[(1, 3)] = f64::NAN;
        assert!(isometry_from_matrix(&nan)
            .unwrap_err()
            .to_string()
            .contains("non-finite"));
    }
}
