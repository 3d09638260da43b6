//! Frame-to-frame motion from tracked stereo points: RANSAC on minimal sets of three 3D–3D
//! correspondences (Kabsch), inliers by the reprojection of the previous frame's points into
//! the current stereo pair (3D–2D), then a Gauss–Newton refinement of the reprojection error
//! with a Huber kernel (the PnP step).

use crate::graph::{se3, StereoCalibration};
use nalgebra::{
    Isometry3, Matrix3, Matrix6, Point3, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6,
};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Motion estimation settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MotionConfig {
    /// RANSAC hypotheses.
    pub ransac_iterations: usize,
    /// Inlier threshold on the reprojection error, pixels.
    pub inlier_px: f64,
    /// Points farther than this are not used for hypotheses (their depth is poor), metres.
    pub max_hypothesis_depth_m: f64,
    /// Huber threshold of the refinement, pixels.
    pub huber_px: f64,
    /// Gauss–Newton iterations of the refinement.
    pub refine_iterations: usize,
    /// Seed of the sampler.
    pub seed: u64,
}

impl Default for MotionConfig {
    fn default() -> Self {
        Self {
            ransac_iterations: 100,
            inlier_px: 2.0,
            max_hypothesis_depth_m: 40.0,
            huber_px: 1.5,
            refine_iterations: 10,
            seed: 1,
        }
    }
}

/// A correspondence: a point of the previous frame (its camera frame) and what the current
/// frame sees of it.
#[derive(Clone, Copy, Debug)]
pub struct Correspondence {
    /// The point in the previous left camera's frame.
    pub p_prev: Point3<f64>,
    /// `(u_left, u_right, v)` in the current pair; `u_right` is NaN when unmatched.
    pub uv: Vector3<f64>,
}

/// The motion found.
#[derive(Clone, Debug)]
pub struct MotionEstimate {
    /// `curr_from_prev`.
    pub curr_from_prev: Isometry3<f64>,
    /// Inlier flags by correspondence.
    pub inliers: Vec<bool>,
    /// `JᵀJ` of the refinement at the optimum ((rotation, translation) order, px⁻²).
    pub information: Matrix6<f64>,
}

/// Reprojection residual of one correspondence under `curr_from_prev` (2 or 3 entries).
pub(super) fn residual(
    camera: &StereoCalibration,
    t: &Isometry3<f64>,
    c: &Correspondence,
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let q = t * c.p_prev;
    let projected = camera.project(&q.coords)?;
    let mut e = projected - c.uv;
    if c.uv.y.is_nan() {
        e.y = 0.0;
    }
    Some((e, q.coords))
}

fn kabsch(a: &[Point3<f64>; 3], b: &[Point3<f64>; 3]) -> Option<Isometry3<f64>> {
    let ca = (a[0].coords + a[1].coords + a[2].coords) / 3.0;
    let cb = (b[0].coords + b[1].coords + b[2].coords) / 3.0;
    let mut h = Matrix3::zeros();
    for k in 0..3 {
        h += (a[k].coords - ca) * (b[k].coords - cb).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (v_t.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = v_t.transpose() * d * u.transpose();
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = cb - rotation * ca;
    Some(Isometry3::from_parts(Translation3::from(t), rotation))
}

/// One RANSAC hypothesis from the candidates `idx` (indices into `candidates`): its
/// inlier count and motion, `None` for a degenerate sample.
fn hypothesis(
    camera: &StereoCalibration,
    cs: &[Correspondence],
    candidates: &[usize],
    idx: &[usize; 3],
    inlier_px: f64,
) -> Option<(usize, Isometry3<f64>)> {
    if idx[0] == idx[1] || idx[1] == idx[2] || idx[0] == idx[2] {
        return None;
    }
    let pick = idx.map(|k| cs[candidates[k]]);
    let a = pick.map(|c| c.p_prev);
    let b = [0, 1, 2]
        .iter()
        .map(|&k| camera.backproject(&pick[k].uv).map(Point3::from))
        .collect::<Option<Vec<_>>>()?;
    let t = kabsch(&a, &[b[0], b[1], b[2]])?;
    let count = cs
        .iter()
        .filter(|c| residual(camera, &t, c).is_some_and(|(e, _)| e.amax() <= inlier_px))
        .count();
    Some((count, t))
}

pub(super) fn inliers_of(
    camera: &StereoCalibration,
    t: &Isometry3<f64>,
    cs: &[Correspondence],
    px: f64,
) -> Vec<bool> {
    cs.iter()
        .map(|c| residual(camera, t, c).is_some_and(|(e, _)| e.amax() <= px))
        .collect()
}

/// Estimates `curr_from_prev`; `None` when fewer than six correspondences agree.
pub fn estimate_motion(
    camera: &StereoCalibration,
    cs: &[Correspondence],
    guess: &Isometry3<f64>,
    config: &MotionConfig,
) -> Option<MotionEstimate> {
    let candidates: Vec<usize> = (0..cs.len())
        .filter(|&i| !cs[i].uv.y.is_nan() && cs[i].p_prev.z < config.max_hypothesis_depth_m)
        .collect();
    let mut best = inliers_of(camera, guess, cs, config.inlier_px);
    let mut best_count = best.iter().filter(|&&b| b).count();
    let mut best_t = *guess;
    let mut state = config.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    if candidates.len() >= 3 {
        // the samples are drawn in order, the hypotheses scored in parallel (rayon) and the
        // first of the best kept: the same winner for any number of threads
        let samples: Vec<[usize; 3]> = (0..config.ransac_iterations)
            .map(|_| {
                [
                    next(candidates.len()),
                    next(candidates.len()),
                    next(candidates.len()),
                ]
            })
            .collect();
        let scored: Vec<Option<(usize, Isometry3<f64>)>> = samples
            .par_iter()
            .map(|idx| hypothesis(camera, cs, &candidates, idx, config.inlier_px))
            .collect();
        let mut winner = None;
        for (count, t) in scored.into_iter().flatten() {
            if count > best_count {
                (best_count, best_t, winner) = (count, t, Some(t));
            }
        }
        if let Some(t) = winner {
            best = inliers_of(camera, &t, cs, config.inlier_px);
        }
    }
    if best_count < 6 {
        return None;
    }
    let (mut t, mut information) = refine(camera, cs, &best, &best_t, config);
    let inliers = inliers_of(camera, &t, cs, config.inlier_px);
    if inliers.iter().filter(|&&b| b).count() >= 6 {
        (t, information) = refine(camera, cs, &inliers, &t, config);
    }
    Some(MotionEstimate {
        curr_from_prev: t,
        inliers,
        information,
    })
}

/// The largest standard deviation of the rotation, radians, that a refinement's `JᵀJ`
/// (px⁻², (rotation, translation) order) gives for image noise of `pixel_sigma` px: the
/// rotation block's marginal covariance `σ² (H_rr − H_rt H_tt⁻¹ H_tr)⁻¹`, whose largest
/// eigenvalue is the worst-known direction. Infinite when the motion is not determined.
pub fn rotation_sigma_rad(information: &Matrix6<f64>, pixel_sigma: f64) -> f64 {
    let h_rr = information.fixed_view::<3, 3>(0, 0).into_owned();
    let h_rt = information.fixed_view::<3, 3>(0, 3).into_owned();
    let h_tt = information.fixed_view::<3, 3>(3, 3).into_owned();
    let Some(h_tt_inv) = h_tt.try_inverse() else {
        return f64::INFINITY;
    };
    let schur = h_rr - h_rt * h_tt_inv * h_rt.transpose();
    let smallest = schur.symmetric_eigenvalues().min();
    if smallest > 0.0 && smallest.is_finite() {
        pixel_sigma / smallest.sqrt()
    } else {
        f64::INFINITY
    }
}

/// The reprojection's Jacobian at the point `q` (current camera frame) for the left
/// perturbation `T ← Exp(δ) · T`, (rotation, translation) columns: `P · [−[q]×, I]`; the
/// right-image row is zero when the correspondence has no right match.
pub(super) fn reprojection_jacobian(
    camera: &StereoCalibration,
    q: &Vector3<f64>,
    c: &Correspondence,
) -> nalgebra::SMatrix<f64, 3, 6> {
    let p = camera.projection_jacobian(q);
    let mut j = nalgebra::SMatrix::<f64, 3, 6>::zeros();
    j.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-p * se3::hat(q)));
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(&p);
    if c.uv.y.is_nan() {
        j.row_mut(1).fill(0.0);
    }
    j
}

/// The Huber weight of a residual of norm `norm` for the threshold `huber`.
pub(super) fn huber_weight(norm: f64, huber: f64) -> f64 {
    if norm <= huber {
        1.0
    } else {
        huber / norm
    }
}

/// Gauss–Newton with a Huber kernel on the reprojection error of the inliers (left
/// perturbation `T ← Exp(δ) · T`); returns the pose and `JᵀJ` (right-perturbation order is
/// not needed by the callers: the matrix is a diagnostic).
fn refine(
    camera: &StereoCalibration,
    cs: &[Correspondence],
    inliers: &[bool],
    start: &Isometry3<f64>,
    config: &MotionConfig,
) -> (Isometry3<f64>, Matrix6<f64>) {
    let mut t = *start;
    let mut h = Matrix6::zeros();
    for _ in 0..config.refine_iterations {
        h = Matrix6::zeros();
        let mut g = Vector6::zeros();
        for (c, _) in cs.iter().zip(inliers).filter(|(_, &k)| k) {
            let Some((e, q)) = residual(camera, &t, c) else {
                continue;
            };
            let j = reprojection_jacobian(camera, &q, c);
            let w = huber_weight(e.norm(), config.huber_px);
            h += j.transpose() * j * w;
            g += j.transpose() * e * w;
        }
        let Some(chol) = h.cholesky() else { break };
        let delta = -chol.solve(&g);
        t = se3::exp(&delta) * t;
        if delta.amax() < 1e-10 {
            break;
        }
    }
    (t, h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_stereo_points_give_the_exact_motion() {
        let camera = StereoCalibration {
            fx: 700.0,
            fy: 700.0,
            skew: 0.0,
            cx: 600.0,
            cy: 180.0,
            baseline_m: 0.54,
        };
        let truth = se3::exp(&Vector6::new(0.01, -0.03, 0.002, 0.05, -0.02, -0.9));
        let mut cs = Vec::new();
        for k in 0..60 {
            let p = Point3::new(
                (k % 10) as f64 - 4.5,
                ((k / 10) % 3) as f64 - 1.5,
                6.0 + (k % 7) as f64 * 3.0,
            );
            let Some(uv) = camera.project(&(truth * p).coords) else {
                continue;
            };
            cs.push(Correspondence { p_prev: p, uv });
        }
        // a few outliers
        for c in cs.iter_mut().take(8) {
            c.uv.x += 40.0;
        }
        let m = estimate_motion(
            &camera,
            &cs,
            &Isometry3::identity(),
            &MotionConfig::default(),
        )
        .unwrap();
        let err = se3::log(&(m.curr_from_prev.inverse() * truth));
        assert!(
            err.fixed_rows::<3>(3).norm() < 1e-3,
            "translation error {err}"
        );
        assert!(
            err.fixed_rows::<3>(0).norm().to_degrees() < 0.01,
            "rotation error {err}"
        );
        assert_eq!(m.inliers.iter().filter(|&&b| !b).count(), 8);
    }
}
