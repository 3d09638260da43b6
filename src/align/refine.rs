//! Refinement of a rough alignment over all landmarks, robust to wrong pairs.
//!
//! The clique gives a handful of associations and a transform good to a few centimetres.
//! Refinement re-associates every query landmark with its mutual nearest prior landmark
//! under the current transform (within a gate), then solves a weighted least-squares
//! alignment whose weights combine each pair's uncertainty with a Cauchy kernel on its
//! residual (iteratively re-weighted least squares). A Cauchy kernel lets a few landmarks
//! whose centroids differ by several centimetres between sessions (seen from other sides)
//! fade out instead of dragging the answer.
//!
//! With [`Dof::Auto`] the re-association and re-weighting follow the tilt-aware alignment's
//! tilted estimate ([`super::tilt`]: a tilted query's far landmarks would otherwise fade
//! out as outliers, and with them what determines the tilt). At the end, if the inliers
//! do not determine the tilt, the answer is re-weighted once more yaw-only. Either way the
//! inliers and residuals the verification gates on are those of the answer.

use super::tilt::{align_tilt, TiltAlignment, TiltConfig};
use super::{align, Dof, WeightedPair};
use crate::spatial::GridIndex;
use nalgebra::{Isometry3, Point3};
use serde::{Deserialize, Serialize};

/// Parameters of the refinement stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefineConfig {
    /// Largest distance (m) between a moved query landmark and a prior landmark for the two
    /// to be re-associated.
    pub gate_m: f64,
    /// Scale (m) of the Cauchy kernel: a pair with this residual gets half weight.
    pub cauchy_scale_m: f64,
    /// Rounds of re-association.
    pub rounds: usize,
    /// Re-weighting iterations per round.
    pub iterations: usize,
    /// A pair is counted as an inlier when its residual is below this (m).
    pub inlier_threshold_m: f64,
    /// The tilt-aware alignment (motion model `auto` only).
    pub tilt: TiltConfig,
}

impl Default for RefineConfig {
    fn default() -> Self {
        Self {
            gate_m: 0.15,
            cauchy_scale_m: 0.008,
            rounds: 3,
            iterations: 15,
            inlier_threshold_m: 0.05,
            tilt: TiltConfig::default(),
        }
    }
}

/// A refined alignment and the pairs that support it.
#[derive(Clone, Debug)]
pub struct Refined {
    /// The refined transform.
    pub prior_from_query: Isometry3<f64>,
    /// Re-associated pairs `(prior index, query index)` whose residual is below the inlier
    /// threshold.
    pub inliers: Vec<(u32, u32)>,
    /// Residual (m) of each inlier pair under the refined transform.
    pub residuals_m: Vec<f64>,
    /// Final weight of each inlier pair (base weight × Cauchy weight).
    pub weights: Vec<f64>,
    /// `Dof::Auto` only: the last tilt-aware solve (whether the tilt was determined and
    /// applied, and how well the pairs fix it).
    pub tilt: Option<TiltAlignment>,
}

/// Refine `initial` over all landmarks. `prior_weights` / `query_weights` are per-landmark
/// inverse variances (1/m²); a pair's base weight is `1 / (1/w_p + 1/w_q)`.
pub fn refine(
    prior: &[Point3<f64>],
    prior_weights: &[f64],
    query: &[Point3<f64>],
    query_weights: &[f64],
    initial: &Isometry3<f64>,
    dof: Dof,
    config: &RefineConfig,
) -> Refined {
    let prior_index = GridIndex::from_points(prior, config.gate_m);
    let mut transform = *initial;
    let mut tilt: Option<TiltAlignment> = None;
    let mut pairs: Vec<(u32, u32, f64)> = Vec::new();
    let step_model = if dof == Dof::Auto {
        Step::Tilted
    } else {
        Step::Plain(dof)
    };
    for _ in 0..config.rounds.max(1) {
        pairs = mutual_nearest(prior, &prior_index, query, &transform, config.gate_m)
            .into_iter()
            .map(|(i, j)| {
                let base =
                    1.0 / (1.0 / prior_weights[i as usize] + 1.0 / query_weights[j as usize]);
                (i, j, base)
            })
            .collect();
        let ends = (prior, query, pairs.as_slice());
        transform = reweight(ends, transform, step_model, config, &mut tilt);
    }
    if let Some(last) = tilt.filter(|t| !t.tilt_applied) {
        // The inliers do not determine the tilt, or find it level: the answer is yaw-only,
        // re-weighted by its own residuals.
        let ends = (prior, query, pairs.as_slice());
        transform = reweight(
            ends,
            last.yaw_only,
            Step::Plain(Dof::Four),
            config,
            &mut None,
        );
    }
    let mut refined = Refined {
        prior_from_query: transform,
        inliers: Vec::new(),
        residuals_m: Vec::new(),
        weights: Vec::new(),
        tilt,
    };
    for (i, j, base) in pairs {
        let r = (prior[i as usize] - transform * query[j as usize]).norm();
        if r < config.inlier_threshold_m {
            let k = r / config.cauchy_scale_m;
            refined.inliers.push((i, j));
            refined.residuals_m.push(r);
            refined.weights.push(base / (1.0 + k * k));
        }
    }
    refined
}

/// One re-weighted solve's model: a plain one, or the tilt-aware alignment's tilted
/// estimate (whose decision is kept).
#[derive(Clone, Copy)]
enum Step {
    Plain(Dof),
    Tilted,
}

/// Prior points, query points and the pairs `(prior index, query index, base weight)`.
type PairSet<'a> = (&'a [Point3<f64>], &'a [Point3<f64>], &'a [(u32, u32, f64)]);

/// Iteratively re-weighted least squares over fixed pairs `(prior index, query index, base
/// weight)` from `transform`; records the last tilt-aware solve in `tilt`.
fn reweight(
    (prior, query, pairs): PairSet<'_>,
    mut transform: Isometry3<f64>,
    step: Step,
    config: &RefineConfig,
    tilt: &mut Option<TiltAlignment>,
) -> Isometry3<f64> {
    for _ in 0..config.iterations.max(1) {
        let weighted: Vec<WeightedPair> = pairs
            .iter()
            .map(|&(i, j, base)| {
                let p_prior = prior[i as usize];
                let p_query = query[j as usize];
                let r = (p_prior - transform * p_query).norm() / config.cauchy_scale_m;
                WeightedPair {
                    p_prior,
                    p_query,
                    weight: base / (1.0 + r * r),
                }
            })
            .collect();
        let next = match step {
            Step::Plain(dof) => align(&weighted, dof),
            Step::Tilted => align_tilt(&weighted, &config.tilt).map(|a| {
                *tilt = Some(a);
                a.tilted
            }),
        };
        match next {
            Some(next) => transform = next,
            None => break,
        }
    }
    transform
}

/// Mutual nearest neighbours between prior points and moved query points within `gate_m`.
pub fn mutual_nearest(
    prior: &[Point3<f64>],
    prior_index: &GridIndex,
    query: &[Point3<f64>],
    prior_from_query: &Isometry3<f64>,
    gate_m: f64,
) -> Vec<(u32, u32)> {
    let moved: Vec<Point3<f64>> = query.iter().map(|q| prior_from_query * q).collect();
    let mut best_for_prior: Vec<Option<(u32, f64)>> = vec![None; prior.len()];
    let mut best_for_query: Vec<Option<(u32, f64)>> = vec![None; query.len()];
    for (j, q) in moved.iter().enumerate() {
        if let Some((i, d)) = prior_index.nearest(prior, q, gate_m) {
            best_for_query[j] = Some((i, d));
            let slot = &mut best_for_prior[i as usize];
            if slot.is_none_or(|(_, bd)| d < bd) {
                *slot = Some((j as u32, d));
            }
        }
    }
    best_for_query
        .iter()
        .enumerate()
        .filter_map(|(j, best)| {
            let (i, _) = (*best)?;
            match best_for_prior[i as usize] {
                Some((jj, _)) if jj as usize == j => Some((i, j as u32)),
                _ => None,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::test_util::*;
    use nalgebra::Vector3;

    #[test]
    fn pulls_a_rough_guess_onto_the_truth_and_ignores_outliers() {
        let truth = yaw_transform(1.1, Vector3::new(5.0, -3.0, 0.2));
        let prior = scatter(60, 9);
        let query_from_prior = truth.inverse();
        let mut query: Vec<_> = prior.iter().map(|p| query_from_prior * p).collect();
        // A few landmarks seen elsewhere in the query session.
        for q in query.iter_mut().take(5) {
            *q += Vector3::new(0.04, 0.0, 0.0);
        }
        let rough = yaw_transform(1.1 + 0.004, Vector3::new(5.03, -2.97, 0.21));
        let w = vec![1e4; 60];
        let refined = refine(
            &prior,
            &w,
            &query,
            &w,
            &rough,
            Dof::Four,
            &RefineConfig::default(),
        );
        let err = (refined.prior_from_query.to_homogeneous() - truth.to_homogeneous()).norm();
        assert!(err < 1e-3, "error {err}");
        assert!(refined.inliers.len() >= 55);
    }
}
