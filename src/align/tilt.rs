//! Tilt-aware alignment of gravity-aligned maps that are not quite aligned.
//!
//! Two maps made with an IMU each are gravity-aligned only to the IMUs' accuracy (a few
//! tenths of a degree): the query may be tilted by a small residual roll and pitch. A
//! 0.5° tilt moves a boulder 10 m away by 9 cm vertically, far above the centimetre
//! residuals of a right answer, so the yaw-only closed form ([`super::yaw_only`]) is
//! biased. This stage starts from that closed form and solves the full rigid motion by
//! Gauss–Newton with a Gaussian prior on the tilt (the gravity prior, `gravity_sigma_deg`
//! per axis): the maximum a posteriori estimate.
//!
//! The tilt is estimated only when the pairs determine it: the conditioning test is on
//! the Schur complement `S` of the tilt block in the data's normal equations (tilt given
//! yaw and translation, i.e. with yaw and translation free). Its smallest eigenvalue,
//! scaled down by the a posteriori variance factor when the residuals exceed what the
//! weights predict, gives the worst-direction tilt σ = 1/√λ_min(S). Pairs spread widely in
//! plan (vertical residuals grow with the horizontal lever arm) and in height (horizontal
//! residuals grow with the height) make it small; pairs on a line or in a small patch
//! leave it large, and the answer stays the yaw-only one (tilt zero, known from gravity).
//!
//! A determined tilt is applied only when it differs from level by at least
//! `level_within_sigmas` of its σ (Mahalanobis, `√(θᵀSθ)`): a tilt indistinguishable from
//! zero is zero, so maps that are truly level get the yaw-only answer, not its noise.
//!
//! Perturbations here are on the left, in the prior frame: `Exp(ξ) · prior_from_query`
//! with `ξ = (ω, v)`, so that `ω_x, ω_y` are rotations about the gravity-aligned prior's
//! horizontal axes: the tilt.

use super::{align_yaw, WeightedPair};
use crate::field_error::FieldError;
use nalgebra::{
    Isometry3, Matrix2, Matrix3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3, Vector6,
};
use serde::{Deserialize, Serialize};

/// Parameters of the tilt-aware alignment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TiltConfig {
    /// The gravity prior: standard deviation (degrees, per horizontal axis) of the relative
    /// tilt between two maps that claim to be gravity-aligned (both IMUs' errors).
    pub gravity_sigma_deg: f64,
    /// The tilt is estimated only when the pairs fix it to this standard deviation
    /// (degrees, worst horizontal axis) or better; otherwise the alignment is yaw-only.
    pub max_tilt_sigma_deg: f64,
    /// A determined tilt closer to level than this many of its standard deviations
    /// (Mahalanobis) is taken as level: the answer is yaw-only.
    pub level_within_sigmas: f64,
    /// Largest plausible tilt (degrees) between two maps that claim to be gravity-aligned:
    /// a larger estimate (say, a mirror image fitted by a steep rotation) is not a tilt the
    /// IMUs could have made, and the answer stays yaw-only.
    pub max_tilt_deg: f64,
    /// Most Gauss–Newton iterations.
    pub iterations: usize,
}

impl Default for TiltConfig {
    fn default() -> Self {
        Self {
            gravity_sigma_deg: 1.0,
            max_tilt_sigma_deg: 0.5,
            level_within_sigmas: 0.5,
            max_tilt_deg: 2.0,
            iterations: 8,
        }
    }
}

impl TiltConfig {
    /// Check the values; the error names the field (`tilt.…`).
    pub fn validate(&self) -> Result<(), FieldError> {
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(FieldError::new(
                    format!("tilt.{name}"),
                    format!("must be a positive number, got {v}"),
                ))
            }
        };
        positive("gravity_sigma_deg", self.gravity_sigma_deg)?;
        positive("max_tilt_sigma_deg", self.max_tilt_sigma_deg)?;
        positive("max_tilt_deg", self.max_tilt_deg)?;
        if !(self.level_within_sigmas.is_finite() && self.level_within_sigmas >= 0.0) {
            return Err(FieldError::new(
                "tilt.level_within_sigmas",
                format!(
                    "must be a non-negative number, got {}",
                    self.level_within_sigmas
                ),
            ));
        }
        if self.iterations == 0 || self.iterations > 100 {
            return Err(FieldError::new(
                "tilt.iterations",
                format!("must be within 1..=100, got {}", self.iterations),
            ));
        }
        Ok(())
    }
}

/// A tilt-aware alignment and what decided it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TiltAlignment {
    /// The answer: `tilted` when `tilt_applied`, else `yaw_only`.
    pub prior_from_query: Isometry3<f64>,
    /// The maximum a posteriori rigid motion (tilt included, held by the gravity prior).
    pub tilted: Isometry3<f64>,
    /// The yaw-only closed form.
    pub yaw_only: Isometry3<f64>,
    /// Whether the pairs determined the tilt (the conditioning test passed) at a plausible
    /// value (within `max_tilt_deg`).
    pub tilt_determined: bool,
    /// Whether the answer includes the tilt: determined, and not indistinguishable from
    /// level.
    pub tilt_applied: bool,
    /// The estimated tilt (radians) about the prior frame's x and y axes, whether applied
    /// or not.
    pub tilt_rad: [f64; 2],
    /// Worst-direction standard deviation (radians) of the tilt from the pairs alone (the
    /// conditioning test); infinite when they do not determine it at all.
    pub tilt_sigma_rad: f64,
}

/// The tilt-aware `prior_from_query`, or `None` when even the yaw-only alignment is
/// degenerate (see [`align_yaw`]).
pub fn align_tilt(pairs: &[WeightedPair], config: &TiltConfig) -> Option<TiltAlignment> {
    let yaw_only = align_yaw(pairs)?;
    let fallback = TiltAlignment {
        prior_from_query: yaw_only,
        tilted: yaw_only,
        yaw_only,
        tilt_determined: false,
        tilt_applied: false,
        tilt_rad: [0.0; 2],
        tilt_sigma_rad: f64::INFINITY,
    };
    if pairs.len() < 3 {
        return Some(fallback);
    }
    let prior_info = 1.0 / config.gravity_sigma_deg.to_radians().powi(2);
    let mut transform = yaw_only;
    for _ in 0..config.iterations.max(1) {
        let (h, g) = normal_equations(pairs, &transform);
        let tilt = tilt_of(&transform);
        let mut h_map = h;
        let mut rhs = g;
        for k in 0..2 {
            h_map[(k, k)] += prior_info;
            rhs[k] -= prior_info * tilt[k];
        }
        let Some(step) = h_map.cholesky().map(|c| c.solve(&rhs)) else {
            return Some(fallback);
        };
        transform = apply_left(&step, &transform);
        if step.norm() < 1e-12 {
            break;
        }
    }
    let tilt = tilt_of(&transform);
    let schur = tilt_information(pairs, &transform);
    let sigma = sigma_of(&schur);
    let plausible = tilt[0].hypot(tilt[1]) <= config.max_tilt_deg.to_radians();
    let determined = plausible && sigma <= config.max_tilt_sigma_deg.to_radians();
    let theta = nalgebra::Vector2::new(tilt[0], tilt[1]);
    let sigmas_from_level = theta.dot(&(schur * theta)).max(0.0).sqrt();
    let applied = determined && sigmas_from_level >= config.level_within_sigmas;
    Some(TiltAlignment {
        prior_from_query: if applied { transform } else { yaw_only },
        tilted: transform,
        yaw_only,
        tilt_determined: determined,
        tilt_applied: applied,
        tilt_rad: tilt,
        tilt_sigma_rad: sigma,
    })
}

/// The data's normal equations `(H, g)` at `prior_from_query` for a left step ξ: `H = Σ w
/// JᵀJ`, `g = −Σ w Jᵀ r` with `r = p_prior − T p_query` and `J = [[T p_query]×, −I]`.
pub fn normal_equations(
    pairs: &[WeightedPair],
    prior_from_query: &Isometry3<f64>,
) -> (Matrix6<f64>, Vector6<f64>) {
    let mut h = Matrix6::zeros();
    let mut g = Vector6::zeros();
    for pair in pairs {
        let moved = prior_from_query * pair.p_query;
        let r = pair.p_prior - moved;
        let jac = jacobian(&moved);
        h += pair.weight * jac.transpose() * jac;
        g -= pair.weight * jac.transpose() * r;
    }
    (h, g)
}

fn jacobian(moved: &Point3<f64>) -> nalgebra::Matrix3x6<f64> {
    let mut jac = nalgebra::Matrix3x6::zeros();
    jac.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&moved.coords.cross_matrix());
    jac.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-Matrix3::identity()));
    jac
}

/// `Exp(ξ) · T` with the retraction (rotation exp, plain translation), first-order equal
/// to the SE(3) exponential and consistent with [`normal_equations`].
fn apply_left(step: &Vector6<f64>, transform: &Isometry3<f64>) -> Isometry3<f64> {
    let omega = Vector3::new(step[0], step[1], step[2]);
    let v = Vector3::new(step[3], step[4], step[5]);
    let delta = Isometry3::from_parts(
        Translation3::from(v),
        UnitQuaternion::from_scaled_axis(omega),
    );
    delta * transform
}

/// The tilt (radians, about the prior frame's x and y axes) of a transform's rotation: the
/// rotation that takes the prior's up axis onto the query's up axis, to first order.
pub fn tilt_of(prior_from_query: &Isometry3<f64>) -> [f64; 2] {
    let up = prior_from_query.rotation * Vector3::z();
    [-up.y, up.x]
}

/// Worst-direction standard deviation (radians) of the tilt from the pairs alone, with yaw
/// and translation free: `1/√λ_min` of [`tilt_information`]; infinite when the pairs do
/// not determine the tilt at all.
pub fn tilt_sigma(pairs: &[WeightedPair], prior_from_query: &Isometry3<f64>) -> f64 {
    sigma_of(&tilt_information(pairs, prior_from_query))
}

fn sigma_of(schur: &Matrix2<f64>) -> f64 {
    let eigen = schur.symmetric_eigenvalues();
    let lambda_min = eigen[0].min(eigen[1]);
    if lambda_min.is_nan() || lambda_min <= 0.0 {
        return f64::INFINITY;
    }
    1.0 / lambda_min.sqrt()
}

/// The information (1/rad²) of the tilt from the pairs alone, with yaw and translation
/// free: the Schur complement of the tilt block of the normal equations, divided by the a
/// posteriori variance factor when the residuals exceed what the weights predict.
pub fn tilt_information(pairs: &[WeightedPair], prior_from_query: &Isometry3<f64>) -> Matrix2<f64> {
    let (h, _) = normal_equations(pairs, prior_from_query);
    let chi2: f64 = pairs
        .iter()
        .map(|p| p.weight * (p.p_prior - prior_from_query * p.p_query).norm_squared())
        .sum();
    let redundancy = 3.0 * pairs.len() as f64 - 6.0;
    let factor = if redundancy > 0.0 {
        (chi2 / redundancy).max(1.0)
    } else {
        1.0
    };
    tilt_schur_complement(&h) / factor
}

/// The Schur complement `H_tt − H_to H_oo⁻¹ H_ot` of the tilt block (indices 0, 1) over
/// yaw and translation (2..6); zero when those are not determined.
pub fn tilt_schur_complement(h: &Matrix6<f64>) -> Matrix2<f64> {
    let h_tt: Matrix2<f64> = h.fixed_view::<2, 2>(0, 0).into();
    let h_to: nalgebra::Matrix2x4<f64> = h.fixed_view::<2, 4>(0, 2).into();
    let h_oo: nalgebra::Matrix4<f64> = h.fixed_view::<4, 4>(2, 2).into();
    match h_oo.cholesky() {
        Some(c) => {
            let s = h_tt - h_to * c.solve(&h_to.transpose());
            (s + s.transpose()) * 0.5
        }
        None => Matrix2::zeros(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::test_util::*;

    fn tilted(roll: f64, pitch: f64, yaw: f64, t: Vector3<f64>) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(t),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        )
    }

    fn weighted(mut pairs: Vec<WeightedPair>, w: f64) -> Vec<WeightedPair> {
        for p in pairs.iter_mut() {
            p.weight = w;
        }
        pairs
    }

    /// Deterministic noise in [-a, a] per axis.
    fn jitter(pairs: &mut [WeightedPair], a: f64, seed: u64) {
        let noise = scatter(pairs.len(), seed);
        for (p, n) in pairs.iter_mut().zip(noise) {
            p.p_prior += Vector3::new(n.x / 10.0, n.y / 10.0, 2.0 * n.z - 1.0) * a;
        }
    }

    #[test]
    fn recovers_a_known_tilt_on_a_wide_map() {
        for (k, (roll_deg, pitch_deg)) in [(0.5, -0.3), (-1.0, 0.8), (0.2, 0.0), (-0.4, -0.9)]
            .into_iter()
            .enumerate()
        {
            let truth = tilted(
                f64::to_radians(roll_deg),
                f64::to_radians(pitch_deg),
                0.7 + k as f64,
                Vector3::new(4.0, -2.0, 0.3),
            );
            let mut pairs = weighted(pairs_for(&scatter(30, 20 + k as u64), &truth), 1e4);
            jitter(&mut pairs, 0.005, 40 + k as u64);
            let est = align_tilt(&pairs, &TiltConfig::default()).unwrap();
            assert!(est.tilt_applied, "sigma {}", est.tilt_sigma_rad);
            let error = est.prior_from_query * truth.inverse();
            assert!(error.rotation.angle().to_degrees() < 0.03, "{error:?}");
            assert!(error.translation.vector.norm() < 0.005);
            let yaw_only = align_yaw(&pairs).unwrap() * truth.inverse();
            assert!(yaw_only.rotation.angle() > 5.0 * error.rotation.angle());
        }
    }

    #[test]
    fn exact_pairs_give_the_exact_tilt() {
        let truth = tilted(0.006, -0.011, -2.0, Vector3::new(-7.0, 3.0, 1.0));
        let pairs = weighted(pairs_for(&scatter(12, 3), &truth), 1e4);
        let est = align_tilt(&pairs, &TiltConfig::default()).unwrap();
        // The prior pulls the tilt towards zero only as far as the data let it: with exact
        // data and σ_data ≪ σ_prior the bias is a few microradians.
        let error = est.prior_from_query * truth.inverse();
        assert!(error.rotation.angle() < 3e-5, "{}", error.rotation.angle());
        let [tx, ty] = est.tilt_rad;
        let up = truth.rotation * Vector3::z();
        assert!((tx + up.y).abs() < 3e-5 && (ty - up.x).abs() < 3e-5);
    }

    #[test]
    fn keeps_yaw_only_when_the_pairs_do_not_fix_the_tilt() {
        let truth = tilted(0.0, 0.0, 1.0, Vector3::new(1.0, 2.0, 0.0));
        // A narrow strip: 3 m long, 5 cm wide, noisy by 1 cm: roll about the strip's axis
        // is not determined.
        let strip: Vec<_> = scatter(10, 8)
            .into_iter()
            .map(|p| Point3::new(p.x * 0.15, p.y * 0.0025, 0.1 * p.z))
            .collect();
        let mut pairs = weighted(pairs_for(&strip, &truth), 1e4);
        jitter(&mut pairs, 0.01, 9);
        let est = align_tilt(&pairs, &TiltConfig::default()).unwrap();
        assert!(!est.tilt_determined, "sigma {}", est.tilt_sigma_rad);
        assert_eq!(est.prior_from_query, align_yaw(&pairs).unwrap());
    }

    #[test]
    fn a_level_query_keeps_the_yaw_only_answer() {
        // Level and exact, with weights of σ 5 cm: the tilt is determined (σ ≈ 0.1°) and
        // found level, so the answer is the yaw-only one, not a tilt of rounding noise.
        let truth = tilted(0.0, 0.0, 0.3, Vector3::new(2.0, 1.0, 0.0));
        let pairs = weighted(pairs_for(&scatter(25, 12), &truth), 400.0);
        let est = align_tilt(&pairs, &TiltConfig::default()).unwrap();
        assert!(est.tilt_determined && !est.tilt_applied, "{est:?}");
        assert_eq!(est.prior_from_query, align_yaw(&pairs).unwrap());
    }

    #[test]
    fn an_implausible_tilt_is_not_applied() {
        let truth = tilted(0.08, 0.0, 0.3, Vector3::new(2.0, 1.0, 0.0));
        let pairs = weighted(pairs_for(&scatter(25, 12), &truth), 1e4);
        let est = align_tilt(&pairs, &TiltConfig::default()).unwrap();
        assert!(!est.tilt_determined && !est.tilt_applied, "{est:?}");
        assert_eq!(est.prior_from_query, est.yaw_only);
    }

    #[test]
    fn schur_complement_is_the_inverse_of_the_tilt_block_of_the_covariance() {
        let truth = tilted(0.01, 0.02, 0.5, Vector3::new(1.0, 2.0, 0.5));
        let pairs = weighted(pairs_for(&scatter(9, 6), &truth), 100.0);
        let (h, _) = normal_equations(&pairs, &truth);
        let cov = h.try_inverse().unwrap();
        let block: Matrix2<f64> = cov.fixed_view::<2, 2>(0, 0).into();
        let s = tilt_schur_complement(&h);
        assert!((s * block - Matrix2::identity()).norm() < 1e-8);
    }

    #[test]
    fn rejects_bad_config_values_by_name() {
        let mut c = TiltConfig::default();
        assert!(c.validate().is_ok());
        c.max_tilt_sigma_deg = f64::NAN;
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("tilt.max_tilt_sigma_deg"));
    }
}
