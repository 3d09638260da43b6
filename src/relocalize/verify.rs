//! Acceptance: decide from the evidence whether the best hypothesis is the answer.
//!
//! The worst failure is a wrong transform accepted, so every test must pass: enough
//! inliers, small residuals, inliers spread in two horizontal directions (collinear or
//! clustered inliers leave the yaw free), and a clear margin over the runner-up — the best
//! hypothesis whose transform differs from the winner's.

use super::config::VerificationConfig;
use super::result::{Hypothesis, Refusal};
use crate::align::{information_matrix, WeightedPair};
use nalgebra::{Isometry3, Matrix4};

/// Sort `hypotheses` best first and decide; `Ok` means the first one is accepted.
pub fn decide(hypotheses: &mut [Hypothesis], config: &VerificationConfig) -> Result<(), Refusal> {
    sort_best_first(hypotheses);
    let Some(best) = hypotheses.first() else {
        return Err(Refusal::TooFewInliers {
            inliers: 0,
            required: config.min_inliers,
        });
    };
    let required = best.min_inliers.unwrap_or(config.min_inliers);
    if best.inlier_count < required {
        return Err(Refusal::TooFewInliers {
            inliers: best.inlier_count,
            required,
        });
    }
    if best.rmse_m > best.max_rmse_m {
        return Err(Refusal::ResidualTooLarge {
            rmse_m: best.rmse_m,
            max_rmse_m: best.max_rmse_m,
        });
    }
    if best.spread_m < config.min_spread_m {
        return Err(Refusal::DegenerateGeometry {
            spread_m: best.spread_m,
            min_spread_m: config.min_spread_m,
        });
    }
    if let Some(yaw_sigma_deg) = best.yaw_sigma_deg {
        if yaw_sigma_deg.is_nan() || yaw_sigma_deg > config.max_yaw_sigma_deg {
            return Err(Refusal::YawUncertain {
                yaw_sigma_deg,
                max_yaw_sigma_deg: config.max_yaw_sigma_deg,
            });
        }
    }
    let runner_up = hypotheses[1..]
        .iter()
        .filter(|h| {
            max_displacement(&best.prior_from_query, &h.prior_from_query, best)
                > config.same_hypothesis_m
        })
        // a rival with fewer inliers than a wrong transform collects by chance (grid priors)
        .filter(|h| h.min_inliers.is_none_or(|m| h.inlier_count >= m))
        .map(|h| h.inlier_count)
        .max()
        .unwrap_or(0);
    if is_rival(runner_up, best.inlier_count, config) {
        return Err(Refusal::Ambiguous {
            best_inliers: best.inlier_count,
            runner_up_inliers: runner_up,
        });
    }
    Ok(())
}

/// Whether a different hypothesis with `inliers` makes the best one (`best_inliers`)
/// ambiguous: above `max_runner_up_ratio` of it, or within `min_runner_up_margin` of it.
pub fn is_rival(inliers: usize, best_inliers: usize, config: &VerificationConfig) -> bool {
    let ratio_ok = (inliers as f64) <= config.max_runner_up_ratio * best_inliers as f64;
    let margin_ok = best_inliers >= inliers + config.min_runner_up_margin;
    !(ratio_ok && margin_ok)
}

/// Most inliers first, then the smallest residual: the order [`decide`] judges in.
pub fn sort_best_first(hypotheses: &mut [Hypothesis]) {
    hypotheses.sort_by(|a, b| {
        b.inlier_count
            .cmp(&a.inlier_count)
            .then(a.rmse_m.total_cmp(&b.rmse_m))
    });
}

/// Radius (m) over which [`local_chance_inliers`] measures the prior's density around each
/// query landmark: about ten rocks of the LAC site.
pub const LOCAL_DENSITY_RADIUS_M: f64 = 2.0;

/// Refined inliers a wrong transform collects by chance where `prior_from_query` puts the
/// query, bounded: `λ + k·√λ`, `λ = Σᵢ nᵢ·(r/R)²` with `nᵢ` the prior landmarks within
/// `R =` [`LOCAL_DENSITY_RADIUS_M`] (horizontally) of query landmark `i` moved into the
/// prior, r the inlier threshold, `k = CHANCE_SIGMAS`. A query landmark that lands where
/// the prior has no rocks (off the site, around the lander) cannot be a chance inlier and
/// adds nothing; where it lands on the prior, λ is the uniform density's (query landmarks ×
/// density × πr²) measured there. Against a grid the inlier threshold is wide and a large
/// query meets many rocks anywhere (mirrored traverse 13, 532 landmarks, 0.15 m grid: 9
/// inliers; docs/design/grid-coarse-cells.md).
pub fn local_chance_inliers(
    prior: &[nalgebra::Point3<f64>],
    query: &[nalgebra::Point3<f64>],
    prior_from_query: &Isometry3<f64>,
    r_m: f64,
) -> usize {
    let radius_sq = LOCAL_DENSITY_RADIUS_M * LOCAL_DENSITY_RADIUS_M;
    let near: usize = query
        .iter()
        .map(|q| {
            let p = prior_from_query * q;
            prior
                .iter()
                .filter(|o| (o.x - p.x).powi(2) + (o.y - p.y).powi(2) <= radius_sq)
                .count()
        })
        .sum();
    let lambda = near as f64 * r_m * r_m / radius_sq;
    (lambda + CHANCE_SIGMAS * lambda.sqrt()).ceil() as usize
}

/// Standard deviations of the chance inlier count (Poisson) a survey-prior hypothesis must
/// clear (see [`local_chance_inliers`]).
pub const CHANCE_SIGMAS: f64 = 4.0;

/// Standard deviation (degrees) of the yaw of `prior_from_query` fitted to `pairs`: the yaw
/// entry of the inverse of the information matrix's yaw-and-translation block (the tilt
/// held, as gravity fixes it), the matrix scaled down when the residuals exceed what the
/// weights predict ([`information_matrix`]). Infinite when the pairs leave it free.
pub fn yaw_sigma_deg(pairs: &[WeightedPair], prior_from_query: &Isometry3<f64>) -> f64 {
    let info = information_matrix(pairs, prior_from_query);
    // rotation (x, y, z) first, then translation: yaw and translation are 2, 3, 4, 5
    let block = Matrix4::from_fn(|r, c| info[(r + 2, c + 2)]);
    match block.try_inverse() {
        Some(cov) if cov[(0, 0)].is_finite() && cov[(0, 0)] >= 0.0 => {
            cov[(0, 0)].sqrt().to_degrees()
        }
        _ => f64::INFINITY,
    }
}

/// Largest distance (m) between where two transforms put the best hypothesis' inliers.
fn max_displacement(a: &Isometry3<f64>, b: &Isometry3<f64>, best: &Hypothesis) -> f64 {
    best.support_query
        .iter()
        .map(|q| (a * q - b * q).norm())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Vector3};

    fn hyp(inliers: usize, rmse: f64, spread: f64, x: f64) -> Hypothesis {
        Hypothesis {
            clique_size: inliers,
            prior_from_query: Isometry3::translation(x, 0.0, 0.0),
            inliers: vec![],
            support_query: vec![
                nalgebra::Point3::origin(),
                nalgebra::Point3::new(3.0, 2.0, 0.0),
            ],
            inlier_count: inliers,
            rmse_m: rmse,
            spread_m: spread,
            tilt: None,
            max_rmse_m: 0.03,
            yaw_sigma_deg: None,
            min_inliers: None,
        }
    }

    #[test]
    fn accepts_a_clear_winner() {
        let mut h = vec![hyp(4, 0.02, 1.0, 5.0), hyp(15, 0.01, 1.0, 0.0)];
        assert!(decide(&mut h, &VerificationConfig::default()).is_ok());
        assert_eq!(h[0].inlier_count, 15);
    }

    #[test]
    fn refuses_each_kind_of_weak_evidence() {
        let cfg = VerificationConfig::default();
        let few = decide(&mut [hyp(4, 0.01, 1.0, 0.0)], &cfg);
        assert!(matches!(few, Err(Refusal::TooFewInliers { .. })));
        let loose = decide(&mut [hyp(12, 0.05, 1.0, 0.0)], &cfg);
        assert!(matches!(loose, Err(Refusal::ResidualTooLarge { .. })));
        let line = decide(&mut [hyp(12, 0.01, 0.05, 0.0)], &cfg);
        assert!(matches!(line, Err(Refusal::DegenerateGeometry { .. })));
        let tie = decide(
            &mut [hyp(12, 0.01, 1.0, 0.0), hyp(10, 0.01, 1.0, 3.0)],
            &cfg,
        );
        assert!(matches!(tie, Err(Refusal::Ambiguous { .. })));
    }

    #[test]
    fn local_chance_inliers_count_only_where_the_query_lands_on_the_prior() {
        // 1 rock per m² over 10 m × 10 m
        let prior: Vec<_> = (0..100)
            .map(|k| nalgebra::Point3::new((k % 10) as f64 + 0.5, (k / 10) as f64 + 0.5, 0.0))
            .collect();
        let query: Vec<_> = (0..100)
            .map(|k| {
                nalgebra::Point3::new(
                    4.0 + (k % 10) as f64 * 0.2,
                    4.0 + (k / 10) as f64 * 0.2,
                    0.0,
                )
            })
            .collect();
        let on_site = local_chance_inliers(&prior, &query, &Isometry3::identity(), 0.1);
        // about π·R² = 12.6 rocks near each of 100 landmarks: λ ≈ π, as the global bound's
        assert!((10..=12).contains(&on_site), "{on_site}");
        let off_site = Isometry3::translation(50.0, 0.0, 0.0);
        assert_eq!(local_chance_inliers(&prior, &query, &off_site, 0.1), 0);
        let mut best = hyp(9, 0.01, 1.0, 0.0);
        best.min_inliers = Some(on_site);
        let refused = decide(&mut [best.clone()], &VerificationConfig::default());
        assert!(
            matches!(refused, Err(Refusal::TooFewInliers { required, .. }) if required == on_site)
        );
        best.inlier_count = on_site;
        assert!(decide(&mut [best.clone()], &VerificationConfig::default()).is_ok());
        // a rival under its own chance count does not make the answer ambiguous
        let mut rival = hyp(on_site - 1, 0.01, 1.0, 5.0);
        let refused = decide(
            &mut [best.clone(), rival.clone()],
            &VerificationConfig::default(),
        );
        assert!(matches!(refused, Err(Refusal::Ambiguous { .. })));
        rival.min_inliers = Some(on_site);
        assert!(decide(&mut [best, rival], &VerificationConfig::default()).is_ok());
    }

    #[test]
    fn an_uncertain_yaw_is_refused_only_when_tested() {
        let cfg = VerificationConfig::default();
        let mut loose = hyp(12, 0.01, 1.0, 0.0);
        loose.yaw_sigma_deg = Some(0.8);
        let refused = decide(&mut [loose.clone()], &cfg);
        assert!(matches!(refused, Err(Refusal::YawUncertain { .. })));
        loose.yaw_sigma_deg = Some(0.3);
        assert!(decide(&mut [loose.clone()], &cfg).is_ok());
        loose.yaw_sigma_deg = None;
        assert!(decide(&mut [loose], &cfg).is_ok());
    }

    #[test]
    fn yaw_sigma_shrinks_with_the_spread_of_the_pairs() {
        // 8 pairs with 6 cm per axis, on a circle of radius r: σ_yaw = σ / (r √8)
        let sigma_of = |r: f64| {
            let pairs: Vec<WeightedPair> = (0..8)
                .map(|k| {
                    let a = k as f64 * std::f64::consts::TAU / 8.0;
                    let p = nalgebra::Point3::new(r * a.cos(), r * a.sin(), 0.0);
                    WeightedPair {
                        p_prior: p,
                        p_query: p,
                        weight: 1.0 / 0.06f64.powi(2),
                    }
                })
                .collect();
            yaw_sigma_deg(&pairs, &Isometry3::identity())
        };
        let expected = (0.06 / 8.0f64.sqrt()).to_degrees();
        assert!((sigma_of(1.0) - expected).abs() < 1e-9 * expected.max(1.0));
        assert!(sigma_of(3.0) < sigma_of(1.0) / 2.9);
    }

    #[test]
    fn a_near_duplicate_of_the_winner_is_not_a_rival() {
        let mut h = vec![hyp(12, 0.01, 1.0, 0.0), hyp(11, 0.01, 1.0, 0.01)];
        assert!(decide(&mut h, &VerificationConfig::default()).is_ok());
        let _ = Vector3::<f64>::zeros();
    }
}
