//! Candidate associations between the landmarks of two maps.
//!
//! Boulders carry no appearance descriptor, so every prior landmark may be every query
//! landmark (all-to-all); when both sizes are known, pairs of very different size are
//! left out. A large map contributes only its most observed landmarks (the consistency
//! graph grows with the square of the candidates; refinement and verification still use
//! every landmark). A survey prior (a rock grid: no detection counts) offers every
//! landmark, and the query its most observed few, within a budget of associations. The
//! consistency graph does the real work.

use super::config::AssociationConfig;
use super::prepared::PreparedMap;
use segloc_clipper::Association;

/// Candidate associations, prior-major order.
pub fn candidate_associations(
    prior: &PreparedMap,
    query: &PreparedMap,
    config: &AssociationConfig,
) -> Vec<Association> {
    let (prior_candidates, query_limit) = if prior.is_survey() {
        let per_prior = config.max_associations / prior.len().max(1);
        let limit = per_prior.clamp(config.min_query_landmarks, config.max_landmarks.max(1));
        ((0..prior.len()).collect(), limit)
    } else {
        (
            prior.best_observed(config.max_landmarks),
            config.max_landmarks,
        )
    };
    let query_candidates = query.best_observed(query_limit);
    let mut out = Vec::with_capacity(prior_candidates.len() * query_candidates.len());
    for &i in &prior_candidates {
        for &j in &query_candidates {
            if let (Some(a), Some(b)) = (&prior.sizes[i], &query.sizes[j]) {
                let (small, large) = if a < b { (*a, *b) } else { (*b, *a) };
                if small > 0.0 && large > config.max_size_ratio * small {
                    continue;
                }
            }
            out.push(Association {
                prior: i as u32,
                query: j as u32,
            });
        }
    }
    out
}
