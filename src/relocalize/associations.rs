//! Candidate associations between the landmarks of two maps.
//!
//! Boulders carry no appearance descriptor, so every prior landmark may be every query
//! landmark (all-to-all); when both sizes are known, pairs of very different size are
//! left out. The consistency graph does the real work.

use super::config::AssociationConfig;
use super::prepared::PreparedMap;
use segloc_clipper::Association;

/// Candidate associations, prior-major order.
pub fn candidate_associations(
    prior: &PreparedMap,
    query: &PreparedMap,
    config: &AssociationConfig,
) -> Vec<Association> {
    let mut out = Vec::with_capacity(prior.len() * query.len());
    for (i, size_prior) in prior.sizes.iter().enumerate() {
        for (j, size_query) in query.sizes.iter().enumerate() {
            if let (Some(a), Some(b)) = (size_prior, size_query) {
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
