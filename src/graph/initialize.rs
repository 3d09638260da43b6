//! Chordal initialisation of a pose graph (Martinec & Pajdla 2007; Carlone et al. 2015).
//!
//! Rotations first: every relative factor asks `R_b = R_a Z_R`, which is linear in the
//! entries of the rotation matrices once their orthogonality is relaxed. The three rows of
//! the rotations decouple into three least-squares problems that share one sparse 3×3-block
//! matrix, so one factorisation gives all of them; each result is projected back onto
//! SO(3). Translations follow from the linear least squares with those rotations held and
//! isotropic translation weights, three scalar graph Laplacians sharing one factorisation.
//! The whole initialisation costs about a third of one Gauss–Newton iteration, and it
//! usually saves several of them.

use super::factors::Factor;
use super::structure::{NormalEquations, Precision};
use super::GraphError;
use nalgebra::{Isometry3, Matrix3, Rotation3, SMatrix, Translation3, UnitQuaternion, Vector3};

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
    let Some(rotations) = chordal_rotations(&mut system, poses, factors) else {
        return Ok(false);
    };
    let mut laplacian =
        NormalEquations::<1>::analyse_with_order(held, factors, Some(&system.order))?;
    let Some(translations) = chordal_translations(&mut laplacian, poses, factors, &rotations)
    else {
        return Ok(false);
    };
    for (blk, &v) in laplacian.var_of.iter().enumerate() {
        let q =
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotations[v]));
        poses[v] = Isometry3::from_parts(Translation3::from(translations[blk]), q);
    }
    Ok(true)
}

/// The chordal rotations: every pose's rotation (the held ones as they are), the free ones
/// solved one row k at a time as the relaxation `x_v = (row k of R_v)ᵀ`, residual
/// `x_b − Zᵀ x_a`, then projected onto SO(3); `None` if the system is singular. The three
/// right-hand sides are solved together, in one pass over the factor.
fn chordal_rotations(
    system: &mut NormalEquations<3>,
    poses: &[Isometry3<f64>],
    factors: &[Factor],
) -> Option<Vec<Matrix3<f64>>> {
    let rotation_matrix = |p: &Isometry3<f64>| p.rotation.to_rotation_matrix().into_inner();
    let rotations: Vec<Matrix3<f64>> = poses.iter().map(rotation_matrix).collect();
    let identity = Matrix3::identity();
    let n = system.dim();
    let mut steps = vec![0.0; 3 * n];
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
        for (s, g) in steps[k * n..(k + 1) * n].iter_mut().zip(&system.gradient) {
            *s = -g;
        }
    }
    // An initial estimate needs no more than a single-precision factor (its solves are
    // refined once in double precision) where that is cheaper.
    let precision = match system.single_precision_pays() {
        true => Precision::Single,
        false => Precision::Double,
    };
    if !system.factorize_damped_in(precision, |_, _| 0.0)
        || !system.solve_columns(&mut steps, 3, true)
    {
        return None;
    }
    let mut new_rotations = rotations.clone();
    for (blk, &v) in system.var_of.iter().enumerate() {
        let mut row = Matrix3::zeros();
        for k in 0..3 {
            for c in 0..3 {
                row[(k, c)] = rotations[v][(k, c)] + steps[k * n + 3 * blk + c];
            }
        }
        new_rotations[v] = project_to_so3(&row);
    }
    Some(new_rotations)
}

/// The chordal translations of the free variables (indexed by the Laplacian's blocks) with
/// the `rotations` held; `None` if the system is singular. With the translation
/// information replaced by its mean eigenvalue w, the residual `w‖t_b − t_a − R_a t_z‖²` is
/// one weighted graph Laplacian per coordinate: a scalar system, 27× cheaper than the
/// 3×3-block one.
fn chordal_translations(
    laplacian: &mut NormalEquations<1>,
    poses: &[Isometry3<f64>],
    factors: &[Factor],
    rotations: &[Matrix3<f64>],
) -> Option<Vec<Vector3<f64>>> {
    let m = laplacian.dim();
    let mut steps = vec![0.0; 3 * m];
    let one = SMatrix::<f64, 1, 1>::identity();
    for c in 0..3 {
        if c == 0 {
            laplacian.clear();
        } else {
            laplacian.clear_gradient();
        }
        for (i, f) in factors.iter().enumerate() {
            let z = f.measured();
            let info = f.information();
            let w = SMatrix::<f64, 1, 1>::new((info[(3, 3)] + info[(4, 4)] + info[(5, 5)]) / 3.0);
            let [a, b] = f.vars();
            let ta = poses[a].translation.vector;
            let (jac_a, residual) = if f.is_unary() {
                (one, ta[c] - z.translation.vector[c])
            } else {
                let d = rotations[a] * z.translation.vector;
                let tb = poses[b].translation.vector;
                (-one, tb[c] - ta[c] - d[c])
            };
            let r = SMatrix::<f64, 1, 1>::new(residual);
            if c == 0 {
                laplacian.add_factor(i, &jac_a, &one, &w, &r);
            } else {
                laplacian.add_factor_gradient(i, &jac_a, &one, &w, &r);
            }
        }
        for (s, g) in steps[c * m..(c + 1) * m]
            .iter_mut()
            .zip(&laplacian.gradient)
        {
            *s = -g;
        }
    }
    if !laplacian.factorize_damped(|_, _| 0.0) || !laplacian.solve_columns(&mut steps, 3, true) {
        return None;
    }
    let translations = laplacian
        .var_of
        .iter()
        .enumerate()
        .map(|(blk, &v)| {
            let t = poses[v].translation.vector;
            Vector3::from([0, 1, 2].map(|c| t[c] + steps[c * m + blk]))
        })
        .collect();
    Some(translations)
}

/// Nearest rotation in the Frobenius norm: the orthogonal polar factor by Newton's
/// iteration `X ← ½ (X + X⁻ᵀ)` (quadratic, a few 3×3 inverses), with an SVD fallback for
/// reflections and singular input.
fn project_to_so3(m: &Matrix3<f64>) -> Matrix3<f64> {
    if m.determinant() > 1e-12 {
        let mut x = *m;
        for _ in 0..30 {
            let Some(inv) = x.try_inverse() else { break };
            let next = (x + inv.transpose()) * 0.5;
            let delta = (next - x).abs().max();
            x = next;
            if delta < 1e-13 {
                return x;
            }
        }
    }
    project_to_so3_svd(m)
}

/// Nearest rotation in the Frobenius norm by SVD.
fn project_to_so3_svd(m: &Matrix3<f64>) -> Matrix3<f64> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_finds_the_nearest_rotation() {
        let r = Rotation3::new(Vector3::new(0.3, -1.2, 0.7)).into_inner();
        let noisy = r * 1.7 + Matrix3::new(0.01, -0.02, 0.0, 0.03, 0.0, 0.01, -0.01, 0.02, 0.0);
        let a = project_to_so3(&noisy);
        let b = project_to_so3_svd(&noisy);
        assert!((a - b).abs().max() < 1e-10);
        assert!((a.transpose() * a - Matrix3::identity()).abs().max() < 1e-12);
        assert!((a.determinant() - 1.0).abs() < 1e-12);
        // A reflection goes through the SVD path and still yields a rotation.
        let reflected = r * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        assert!((project_to_so3(&reflected).determinant() - 1.0).abs() < 1e-12);
    }
}
