//! Consistency edges when only a few associations are loose (covariance-driven thresholds,
//! see [`crate::tolerance`]).
//!
//! Pairs of two tight associations keep the plain build's decision and weight. Every pair
//! with a loose association `u = (i, j)` is found from `u`'s side: for each other prior
//! point `k`, the query points `l` whose distance to `j` lies within the widest threshold
//! of `|a_i − a_k|` are read off `j`'s sorted distance list, and the association `(k, l)`,
//! if it exists, is tested with the pair's own thresholds. The work is proportional to the
//! loose associations times the prior points, not to the square of the associations.

use nalgebra::Point3;

use crate::tolerance::PairThresholds;
use crate::{Association, ClipperError, ConsistencyGraph, Invariant};

/// An undirected edge `(u, v, weight)`.
pub(crate) type WeightedEdge = (u32, u32, f32);

/// Largest dense (prior × query) association lookup, in entries.
const LOOKUP_LIMIT: usize = 1 << 24;

/// The edges (each once, `u < v`), or `None` when the maps are too large for the dense
/// lookup (the caller then builds with the widest thresholds and filters).
pub(crate) fn edges(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
    invariant: &Invariant,
    pair: &PairThresholds,
    loose: &[bool],
) -> Result<Option<Vec<WeightedEdge>>, ClipperError> {
    let (n_p, n_q) = (prior.len(), query.len());
    if n_p.saturating_mul(n_q) > LOOKUP_LIMIT {
        return Ok(None);
    }
    let plain = ConsistencyGraph::build(prior, query, associations, invariant)?;
    let mut out = Vec::with_capacity(plain.num_edges());
    for u in (0..plain.num_vertices()).filter(|&u| !loose[u]) {
        for (&v, &w) in plain.neighbors(u).iter().zip(plain.weights(u)) {
            if v as usize > u && !loose[v as usize] {
                out.push((u as u32, v, w));
            }
        }
    }
    let mut lookup = vec![u32::MAX; n_p * n_q];
    for (id, a) in associations.iter().enumerate() {
        lookup[a.prior as usize * n_q + a.query as usize] = id as u32;
    }
    let mut sorted: Vec<Option<Vec<(f64, u32)>>> = vec![None; n_q];
    let t = &pair.test;
    for u in (0..associations.len()).filter(|&u| loose[u]) {
        let Association { prior: i, query: j } = associations[u];
        let by_distance = sorted[j as usize].get_or_insert_with(|| {
            let mut list: Vec<(f64, u32)> = (0..n_q as u32)
                .filter(|&l| l != j)
                .map(|l| (t.measure(&query[j as usize], &query[l as usize]).dist, l))
                .collect();
            list.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            list
        });
        for k in (0..n_p as u32).filter(|&k| k != i) {
            let d = t.measure(&prior[i as usize], &prior[k as usize]).dist;
            let lo = by_distance.partition_point(|e| e.0 < d - pair.epsilon_max);
            for &(dq, l) in &by_distance[lo..] {
                if dq > d + pair.epsilon_max {
                    break;
                }
                let v = lookup[k as usize * n_q + l as usize];
                if v == u32::MAX || (loose[v as usize] && (v as usize) < u) {
                    continue;
                }
                if let Some(w) = pair.edge(u, v as usize, prior, query, associations) {
                    let (a, b) = if (v as usize) < u {
                        (v, u as u32)
                    } else {
                        (u as u32, v)
                    };
                    out.push((a, b, w));
                }
            }
        }
    }
    Ok(Some(out))
}

#[cfg(test)]
mod tests {
    use crate::{Association, ConsistencyGraph, Invariant, PointVariances};
    use nalgebra::Point3;

    /// The sorted-distance path (few loose associations) finds exactly the pairs that pass
    /// their own thresholds, checked pair by pair.
    #[test]
    fn loose_partner_edges_are_the_pairs_within_their_own_thresholds() {
        let mut rng = crate::rng::SplitMix64::new(11);
        let mut coord = |scale: f64| (rng.below(1_000_000) as f64 / 1e6 - 0.5) * scale;
        let prior: Vec<Point3<f64>> = (0..40)
            .map(|_| Point3::new(coord(10.0), coord(10.0), coord(0.5)))
            .collect();
        let query: Vec<Point3<f64>> = prior
            .iter()
            .take(30)
            .map(|p| Point3::new(p.y + 3.0 + coord(0.02), -p.x + coord(0.02), p.z))
            .collect();
        let assoc: Vec<Association> = (0..40)
            .flat_map(|i| (0..30).map(move |j| Association::new(i, j)))
            .collect();
        let inv = Invariant::GravityAligned {
            epsilon: 0.08,
            sigma: 0.04,
            epsilon_z: 0.06,
            sigma_z: 0.03,
        };
        // two loose prior points: 60 of 1,200 associations
        let mut var_p = vec![1e-4; 40];
        var_p[3] = 0.003;
        var_p[17] = 0.002;
        let var_q = vec![1e-4; 30];
        let variances = PointVariances {
            prior: &var_p,
            query: &var_q,
            prior_z: &var_p,
            query_z: &var_q,
            multiplier: 2.0,
            max_epsilon: 0.5,
            max_epsilon_z: 0.25,
        };
        let few = ConsistencyGraph::build_with_variances(&prior, &query, &assoc, &inv, &variances)
            .unwrap()
            .0;
        let (_, summary) =
            ConsistencyGraph::build_with_variances(&prior, &query, &assoc, &inv, &variances)
                .unwrap();
        assert!(summary.widened);
        let pair = crate::tolerance::PairThresholds::for_tests(&inv, &assoc, &variances, 40, 30);
        let mut expected = 0;
        for u in 0..assoc.len() {
            for w in (u + 1)..assoc.len() {
                let e = pair.edge(u, w, &prior, &query, &assoc);
                assert_eq!(e.is_some(), few.has_edge(u, w), "pair ({u}, {w})");
                expected += e.is_some() as usize;
            }
        }
        assert_eq!(few.num_edges(), expected);
    }
}
