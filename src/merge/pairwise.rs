//! Relocalize every pair of maps, in parallel.
//!
//! For each pair (a, b) with a < b, map a is the prior and b the query, so an accepted
//! answer is `a_from_b`. The cheap test: a map with fewer landmarks than the acceptance
//! test's minimum inliers can never yield an accepted transform, so its pairs are skipped.

use crate::relocalize::result::serialize_option_isometry;
use crate::relocalize::{RelocalizeConfig, Relocalizer};
use nalgebra::{Isometry3, Matrix6};
use rayon::prelude::*;
use segloc_maps::ObjectMap;
use serde::Serialize;

/// The outcome of relocalizing map `b` against map `a`.
#[derive(Clone, Debug, Serialize)]
pub struct PairOutcome {
    /// Prior map index.
    pub a: usize,
    /// Query map index.
    pub b: usize,
    /// Whether a transform was accepted.
    pub accepted: bool,
    /// `a_from_b`, when accepted.
    #[serde(serialize_with = "serialize_option_isometry")]
    pub a_from_b: Option<Isometry3<f64>>,
    /// Information matrix of `a_from_b` (rotation, translation).
    #[serde(skip)]
    pub information: Matrix6<f64>,
    /// Inliers of the best hypothesis.
    pub inliers: usize,
    /// Inlier residual RMSE (m) of the best hypothesis (0 when there is none).
    pub rmse_m: f64,
    /// Inliers of the runner-up hypothesis (0 when there is none).
    pub runner_up_inliers: usize,
    /// Why it was refused or skipped.
    pub reason: Option<String>,
    /// Skipped by the cheap test (not relocalized at all).
    pub skipped: bool,
    /// After the frame optimisation: disagreed with the consensus and was out-voted.
    pub outvoted: bool,
    /// Relocalization time (ms).
    pub time_ms: f64,
}

/// Relocalize every pair (a < b).
pub fn relocalize_pairs(
    maps: &[ObjectMap],
    config: &RelocalizeConfig,
) -> Result<Vec<PairOutcome>, crate::relocalize::RelocalizeError> {
    let min_landmarks = config
        .verification
        .min_inliers
        .max(crate::relocalize::MIN_LANDMARKS);
    let relocalizers: Vec<Option<Relocalizer>> = maps
        .iter()
        .map(|m| {
            if m.len() < min_landmarks {
                Ok(None)
            } else {
                Relocalizer::new(m.clone(), config.clone()).map(Some)
            }
        })
        .collect::<Result<_, _>>()?;
    let pairs: Vec<(usize, usize)> = (0..maps.len())
        .flat_map(|a| ((a + 1)..maps.len()).map(move |b| (a, b)))
        .collect();
    pairs
        .par_iter()
        .map(|&(a, b)| {
            let Some(relocalizer) = &relocalizers[a] else {
                return Ok(skipped(a, b, a, maps[a].len(), min_landmarks));
            };
            if maps[b].len() < min_landmarks {
                return Ok(skipped(a, b, b, maps[b].len(), min_landmarks));
            }
            let started = std::time::Instant::now();
            let answer = relocalizer.relocalize(&maps[b])?;
            Ok(PairOutcome {
                a,
                b,
                accepted: answer.is_accepted(),
                a_from_b: answer.prior_from_query(),
                information: answer
                    .accepted()
                    .map_or_else(nalgebra::Matrix6::zeros, |a| a.information),
                inliers: answer
                    .diagnostics
                    .hypotheses
                    .first()
                    .map_or(0, |h| h.inlier_count),
                rmse_m: answer
                    .diagnostics
                    .hypotheses
                    .first()
                    .map_or(0.0, |h| h.rmse_m),
                runner_up_inliers: answer
                    .diagnostics
                    .hypotheses
                    .get(1)
                    .map_or(0, |h| h.inlier_count),
                reason: answer.refusal().map(|r| r.to_string()),
                skipped: false,
                outvoted: false,
                time_ms: started.elapsed().as_secs_f64() * 1e3,
            })
        })
        .collect()
}

fn skipped(a: usize, b: usize, small: usize, count: usize, needed: usize) -> PairOutcome {
    PairOutcome {
        a,
        b,
        accepted: false,
        a_from_b: None,
        information: Matrix6::zeros(),
        inliers: 0,
        rmse_m: 0.0,
        runner_up_inliers: 0,
        reason: Some(format!(
            "skipped: map {small} has {count} landmarks, an accepted transform needs {needed} inliers"
        )),
        skipped: true,
        outvoted: false,
        time_ms: 0.0,
    }
}
