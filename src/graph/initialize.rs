//! Chordal initialisation of a pose graph (Martinec & Pajdla 2007; Carlone et al. 2015).
//!
//! Rotations first: every relative factor asks `R_b = R_a Z_R`, which is linear in the
//! entries of the rotation matrices once their orthogonality is relaxed. The three rows of
//! the rotations decouple into three least-squares problems that share one sparse 3×3-block
//! matrix, so one factorisation gives all of them; each result is projected back onto
//! SO(3). Translations follow from the linear least squares with those rotations held. Both
//! systems have 3×3 blocks, so the whole initialisation costs about a quarter of one
//! Gauss–Newton factorisation, and it usually saves several of them.

use super::factors::Factor;
use super::structure::NormalEquations;
use super::GraphError;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// Replaces the estimates of the variables that are not `held` by the chordal solution.
///
/// Held variables anchor the problem (as do prior factors). `order` is the elimination
/// order of the free variables if already known (see [`NormalEquations::analyse_with_order`]).
/// Returns `Ok(false)` and leaves the estimates untouched if a system is singular.
pub(crate) fn chordal_initialize(
    poses: &mut [Isometry3<f64>],
    factors: &[Factor],
    held: &[bool],
    order: Option<&[usize]>,
) -> Result<bool, GraphError> {
    let mut system = NormalEquations::<3>::analyse_with_order(held, factors, order)?;
    if system.dim() == 0 {
        return Ok(true);
    }
    let rotation_matrix = |p: &Isometry3<f64>| p.rotation.to_rotation_matrix().into_inner();
    let rotations: Vec<Matrix3<f64>> = poses.iter().map(rotation_matrix).collect();
    let identity = Matrix3::identity();

    // Rotations, one row k at a time: x_v = (row k of R_v)ᵀ, residual x_b − Zᵀ x_a.
    let mut rows = vec![Matrix3::zeros(); system.var_of.len()];
    for k in 0..3 {
        if k == 0 {
            system.clear();
        } else {
            system.clear_gradient();
        }
        for (i, f) in factors.iter().enumerate() {
            let z = f.measured().rotation.to_rotation_matrix().into_inner();
            let info = f.information();
            let w = (info[(0, 0)] + info[(1, 1)] + info[(2, 2)]) / 3.0;
            let weight = identity * w;
            let [a, b] = f.vars();
            let xa: Vector3<f64> = rotations[a].row(k).transpose();
            let (jac_a, jac_b, residual) = if f.is_unary() {
                let zk: Vector3<f64> = z.row(k).transpose();
                (identity, identity, xa - zk)
            } else {
                let xb: Vector3<f64> = rotations[b].row(k).transpose();
                (-z.transpose(), identity, xb - z.transpose() * xa)
            };
            if k == 0 {
                system.add_factor(i, &jac_a, &jac_b, &weight, &residual);
            } else {
                system.add_factor_gradient(i, &jac_a, &jac_b, &weight, &residual);
            }
        }
        if k == 0 && !system.factorize_damped(|_, _| 0.0) {
            return Ok(false);
        }
        let mut step = vec![0.0; system.dim()];
        if !system.solve(&mut step) {
            return Ok(false);
        }
        for (blk, &v) in system.var_of.iter().enumerate() {
            for c in 0..3 {
                rows[blk][(k, c)] = rotations[v][(k, c)] + step[3 * blk + c];
            }
        }
    }
    let mut new_rotations = rotations.clone();
    for (blk, &v) in system.var_of.iter().enumerate() {
        new_rotations[v] = project_to_so3(&rows[blk]);
    }

    // Translations with the rotations held: residual R_zᵀ (R_aᵀ (t_b − t_a) − t_z).
    system.clear();
    for (i, f) in factors.iter().enumerate() {
        let z = f.measured();
        let rz_t = z.rotation.to_rotation_matrix().into_inner().transpose();
        let info = f.information();
        let weight: Matrix3<f64> = info.fixed_view::<3, 3>(3, 3).into_owned();
        let [a, b] = f.vars();
        let ta = poses[a].translation.vector;
        let tz = z.translation.vector;
        let (jac_a, jac_b, residual) = if f.is_unary() {
            (rz_t, rz_t, rz_t * (ta - tz))
        } else {
            let j = rz_t * new_rotations[a].transpose();
            let tb = poses[b].translation.vector;
            (-j, j, j * (tb - ta) - rz_t * tz)
        };
        system.add_factor(i, &jac_a, &jac_b, &weight, &residual);
    }
    if !system.factorize_damped(|_, _| 0.0) {
        return Ok(false);
    }
    let mut step = vec![0.0; system.dim()];
    if !system.solve(&mut step) {
        return Ok(false);
    }
    for (blk, &v) in system.var_of.iter().enumerate() {
        let t = poses[v].translation.vector
            + Vector3::new(step[3 * blk], step[3 * blk + 1], step[3 * blk + 2]);
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
            new_rotations[v],
        ));
        poses[v] = Isometry3::from_parts(Translation3::from(t), q);
    }
    Ok(true)
}

/// Nearest rotation in the Frobenius norm.
fn project_to_so3(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => {
            let mut d = Matrix3::identity();
            if (u * v_t).determinant() < 0.0 {
                d[(2, 2)] = -1.0;
            }
            u * d * v_t
        }
        _ => Matrix3::identity(),
    }
}
