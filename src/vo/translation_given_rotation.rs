//! The frame's translation when its rotation is known (from the gyro): every stereo-matched
//! correspondence proposes one translation (`p_curr − R · p_prev`), the one with the most
//! reprojection inliers wins, and a Gauss–Newton refinement with a Huber kernel adjusts the
//! three translation coordinates alone. Five inliers are asked where the full motion needs
//! six (one determines it, but three were seen to agree on a wrong one), so a frame with
//! few features (a dark slope filling the view) still moves.

use super::motion::{
    huber_weight, inliers_of, reprojection_jacobian, residual, Correspondence, MotionConfig,
    MotionEstimate,
};
use crate::graph::StereoCalibration;
use nalgebra::{Isometry3, Matrix3, Matrix6, Translation3, UnitQuaternion, Vector3};

/// Fewest inliers for a translation-only motion.
const MIN_INLIERS: usize = 5;

/// `curr_from_prev` with the given rotation and the translation the correspondences agree
/// on; `None` when fewer than five agree.
pub fn translation_given_rotation(
    camera: &StereoCalibration,
    cs: &[Correspondence],
    rotation: &UnitQuaternion<f64>,
    config: &MotionConfig,
) -> Option<MotionEstimate> {
    let mut best: Option<(usize, Vec<bool>, Isometry3<f64>)> = None;
    for c in cs.iter().filter(|c| !c.uv.y.is_nan()) {
        let Some(p_curr) = camera.backproject(&c.uv) else {
            continue;
        };
        let t = p_curr - rotation * c.p_prev.coords;
        let hypothesis = Isometry3::from_parts(Translation3::from(t), *rotation);
        let inliers = inliers_of(camera, &hypothesis, cs, config.inlier_px);
        let count = inliers.iter().filter(|&&b| b).count();
        if best.as_ref().is_none_or(|(n, _, _)| count > *n) {
            best = Some((count, inliers, hypothesis));
        }
    }
    let (count, inliers, start) = best?;
    if count < MIN_INLIERS {
        return None;
    }
    let curr_from_prev = refine_translation(camera, cs, &inliers, start, config);
    let inliers = inliers_of(camera, &curr_from_prev, cs, config.inlier_px);
    if inliers.iter().filter(|&&b| b).count() < MIN_INLIERS {
        return None;
    }
    let information = information_at(camera, cs, &inliers, &curr_from_prev);
    Some(MotionEstimate {
        curr_from_prev,
        inliers,
        information,
    })
}

/// Gauss–Newton with a Huber kernel on the translation alone.
fn refine_translation(
    camera: &StereoCalibration,
    cs: &[Correspondence],
    inliers: &[bool],
    mut t: Isometry3<f64>,
    config: &MotionConfig,
) -> Isometry3<f64> {
    for _ in 0..config.refine_iterations {
        let mut h = Matrix3::zeros();
        let mut g = Vector3::zeros();
        for (c, _) in cs.iter().zip(inliers).filter(|(_, &k)| k) {
            let Some((e, q)) = residual(camera, &t, c) else {
                continue;
            };
            let j = reprojection_jacobian(camera, &q, c)
                .fixed_view::<3, 3>(0, 3)
                .into_owned();
            let w = huber_weight(e.norm(), config.huber_px);
            h += j.transpose() * j * w;
            g += j.transpose() * e * w;
        }
        let Some(chol) = h.cholesky() else { break };
        let delta = -chol.solve(&g);
        t.translation.vector += delta;
        if delta.amax() < 1e-10 {
            break;
        }
    }
    t
}

/// `JᵀJ` of the reprojection of the inliers at `t` ((rotation, translation) order, px⁻², left
/// perturbation, as the full motion's refinement reports it).
fn information_at(
    camera: &StereoCalibration,
    cs: &[Correspondence],
    inliers: &[bool],
    t: &Isometry3<f64>,
) -> Matrix6<f64> {
    let mut h = Matrix6::zeros();
    for (c, _) in cs.iter().zip(inliers).filter(|(_, &k)| k) {
        let Some((_, q)) = residual(camera, t, c) else {
            continue;
        };
        let j = reprojection_jacobian(camera, &q, c);
        h += j.transpose() * j;
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::se3;
    use nalgebra::{Point3, Vector6};

    #[test]
    fn five_points_and_the_true_rotation_give_the_true_translation() {
        let camera = StereoCalibration {
            fx: 900.0,
            fy: 900.0,
            skew: 0.0,
            cx: 640.0,
            cy: 360.0,
            baseline_m: 0.162,
        };
        let truth = se3::exp(&Vector6::new(0.01, -0.3, 0.002, 0.04, -0.01, 0.08));
        let points = [
            Point3::new(-0.5, 0.3, 3.0),
            Point3::new(0.4, 0.5, 4.0),
            Point3::new(0.1, 0.2, 2.5),
            Point3::new(-1.0, -0.2, 5.0),
            Point3::new(1.5, 0.1, 6.0),
            Point3::new(5.0, -1.0, 9.0), // an outlier below
        ];
        let mut cs: Vec<Correspondence> = points
            .iter()
            .map(|p| Correspondence {
                p_prev: *p,
                uv: camera.project(&(truth * p).coords).unwrap(),
            })
            .collect();
        cs[5].uv.x += 40.0;
        cs[5].uv.y += 40.0;
        let m = translation_given_rotation(&camera, &cs, &truth.rotation, &MotionConfig::default())
            .unwrap();
        assert!((m.curr_from_prev.translation.vector - truth.translation.vector).norm() < 1e-9);
        assert_eq!(m.inliers, [true, true, true, true, true, false]);
        // four points are not enough
        assert!(translation_given_rotation(
            &camera,
            &cs[..4],
            &truth.rotation,
            &MotionConfig::default()
        )
        .is_none());
    }
}
