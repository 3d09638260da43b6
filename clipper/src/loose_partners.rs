//! Consistency edges when only a few associations are loose (covariance-driven thresholds,
//! see [`crate::tolerance`]).
//!
//! A pair whose thresholds stay at the floor (the sum of its two variances is small) keeps
//! the plain build's decision and weight; only a pair with a loose association can be
//! widened. Such pairs are found from the loose association `u = (i, j)`'s side: for each
//! other prior point `k`, the query points `l` whose distance to `j` lies within the
//! pair's widest threshold of `|a_i − a_k|` are read off `j`'s sorted distance list (or off
//! a shorter list of its looser query points, when only those can widen the pair), and
//! the association `(k, l)`, if it exists, is tested with the pair's own thresholds. The
//! work is proportional to the loose associations times the prior points, not to the
//! square of the associations.

use nalgebra::Point3;
use rayon::prelude::*;

use crate::build::UsedPoints;
use crate::tolerance::PairThresholds;
use crate::{Association, ClipperError, ConsistencyGraph, Invariant, PointVariances};

/// An undirected edge `(u, v, weight)`.
pub(crate) type WeightedEdge = (u32, u32, f32);

/// Largest dense (prior × query) association lookup, in entries.
const LOOKUP_LIMIT: usize = 1 << 24;

/// Looseness levels (a query point's variance over the floor's budget) of the shorter
/// partner lists, loosest first.
const LEVELS: [f64; 3] = [0.4, 0.2, 0.1];

/// The graph, or `None` when the maps are too large for the dense lookup (the caller then
/// builds with the widest thresholds and filters).
pub(crate) fn graph(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
    invariant: &Invariant,
    pair: &PairThresholds,
    variances: &PointVariances<'_>,
    loose: &[bool],
) -> Result<Option<ConsistencyGraph>, ClipperError> {
    if prior.len().saturating_mul(query.len()) > LOOKUP_LIMIT {
        return Ok(None);
    }
    let plain = ConsistencyGraph::build(prior, query, associations, invariant)?;
    let search = PartnerSearch::new(prior, query, associations, pair, variances, loose);
    let extra = ConsistencyGraph::from_edge_list(associations.len(), &search.edges());
    Ok(Some(merge(&plain, &extra, pair, loose)))
}

/// What the partner search of one loose association reads.
struct PartnerSearch<'a> {
    prior: &'a [Point3<f64>],
    query: &'a [Point3<f64>],
    associations: &'a [Association],
    pair: &'a PairThresholds,
    loose: &'a [bool],
    /// Association id of (prior, query), `u32::MAX` if none.
    lookup: Vec<u32>,
    /// The largest residual variance of any association of each prior point: it bounds the
    /// threshold of every pair with that point.
    max_var_of_prior: Vec<f64>,
    /// Prior points with an association (only they can be partners).
    prior_active: Vec<u32>,
    /// Per-point variances of both maps.
    variances: &'a PointVariances<'a>,
    /// For each query point of a loose association, the other query points with an
    /// association, by distance (`(distance, point)`; empty for the others): all of them,
    /// then those at least as loose as each of [`LEVELS`].
    by_distance: Vec<[Vec<(f64, u32)>; 4]>,
}

impl<'a> PartnerSearch<'a> {
    fn new(
        prior: &'a [Point3<f64>],
        query: &'a [Point3<f64>],
        associations: &'a [Association],
        pair: &'a PairThresholds,
        variances: &'a PointVariances<'a>,
        loose: &'a [bool],
    ) -> Self {
        let (n_p, n_q) = (prior.len(), query.len());
        let mut lookup = vec![u32::MAX; n_p * n_q];
        let mut max_var_of_prior = vec![0.0_f64; n_p];
        let mut query_of_loose = vec![false; n_q];
        for (id, a) in associations.iter().enumerate() {
            let (i, j) = (a.prior as usize, a.query as usize);
            lookup[i * n_q + j] = id as u32;
            max_var_of_prior[i] = max_var_of_prior[i].max(pair.var(id));
            query_of_loose[j] |= loose[id];
        }
        let used = |n: usize, point: fn(&Association) -> u32| {
            UsedPoints::new(n, associations.iter().map(point)).original
        };
        let query_active = used(n_q, |a| a.query);
        let t = &pair.test;
        let looseness: Vec<f64> = (0..n_q)
            .map(|l| pair.looseness(variances.query[l], variances.query_z.get(l).copied()))
            .collect();
        let by_distance = (0..n_q)
            .into_par_iter()
            .map(|j| {
                if !query_of_loose[j] {
                    return Default::default();
                }
                let mut all: Vec<(f64, u32)> = query_active
                    .iter()
                    .filter(|&&l| l as usize != j)
                    .map(|&l| (t.measure(&query[j], &query[l as usize]).dist, l))
                    .collect();
                all.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
                let at_least = |level: f64| -> Vec<(f64, u32)> {
                    all.iter()
                        .copied()
                        .filter(|e| looseness[e.1 as usize] >= level)
                        .collect()
                };
                let [a, b, c] = LEVELS.map(at_least);
                [all, a, b, c]
            })
            .collect();
        Self {
            prior,
            query,
            associations,
            pair,
            loose,
            lookup,
            max_var_of_prior,
            prior_active: used(n_p, |a| a.prior),
            variances,
            by_distance,
        }
    }

    /// Every widened edge, each once (`u < v`), searched in parallel over the loose
    /// associations.
    fn edges(&self) -> Vec<WeightedEdge> {
        let loose_ids: Vec<usize> = (0..self.loose.len()).filter(|&u| self.loose[u]).collect();
        loose_ids
            .par_chunks(64)
            .flat_map_iter(|chunk| {
                let mut out = Vec::new();
                chunk.iter().for_each(|&u| self.partners(u, &mut out));
                out
            })
            .collect()
    }

    /// The shortest of `j`'s partner lists that holds every query point that can widen a
    /// pair of `u` with an association of prior point `k`.
    fn partner_list(&self, u: usize, j: u32, k: u32) -> &[(f64, u32)] {
        let v = self.variances;
        let need = self.pair.looseness_to_widen(
            u,
            v.prior[k as usize],
            v.prior_z.get(k as usize).copied(),
        );
        let lists = &self.by_distance[j as usize];
        match LEVELS.iter().position(|&level| need >= level) {
            Some(p) => &lists[p + 1],
            None => &lists[0],
        }
    }

    /// Appends the edges of loose association `u` (those with a loose `v < u` are found
    /// from `v`).
    fn partners(&self, u: usize, out: &mut Vec<WeightedEdge>) {
        let (pair, n_q) = (self.pair, self.query.len());
        let Association { prior: i, query: j } = self.associations[u];
        for &k in self.prior_active.iter().filter(|&&k| k != i) {
            let by_distance = self.partner_list(u, j, k);
            let d = pair
                .test
                .measure(&self.prior[i as usize], &self.prior[k as usize])
                .dist;
            let reach = pair.threshold(u, self.max_var_of_prior[k as usize]);
            let lo = by_distance.partition_point(|e| e.0 <= d - reach);
            for &(dq, l) in &by_distance[lo..] {
                if dq >= d + reach {
                    break;
                }
                let v = self.lookup[k as usize * n_q + l as usize];
                if v == u32::MAX
                    || (self.loose[v as usize] && (v as usize) < u)
                    || pair.at_floor(u, v as usize)
                {
                    continue;
                }
                if (d - dq).abs() >= pair.threshold(u, pair.var(v as usize)) {
                    continue;
                }
                if let Some(w) = pair.edge(u, v as usize, self.prior, self.query, self.associations)
                {
                    out.push(((u as u32).min(v), (u as u32).max(v), w));
                }
            }
        }
    }
}

/// The plain graph's edges whose thresholds stay at the floor, and every edge of `extra`
/// (the widened ones), row by row in sorted order.
fn merge(
    plain: &ConsistencyGraph,
    extra: &ConsistencyGraph,
    pair: &PairThresholds,
    loose: &[bool],
) -> ConsistencyGraph {
    // two tight associations are always at the floor
    let at_floor = |u: usize, v: usize| (!loose[u] && !loose[v]) || pair.at_floor(u, v);
    let n = plain.num_vertices();
    let mut offsets = Vec::with_capacity(n + 1);
    offsets.push(0);
    let mut neighbors = Vec::with_capacity(plain.num_edges() * 2 + extra.num_edges() * 2);
    let mut weights = Vec::with_capacity(neighbors.capacity());
    for u in 0..n {
        let (plain_row, plain_w) = (plain.neighbors(u), plain.weights(u));
        let (extra_row, extra_w) = (extra.neighbors(u), extra.weights(u));
        let (mut a, mut b) = (0, 0);
        loop {
            while a < plain_row.len() && !at_floor(u, plain_row[a] as usize) {
                a += 1;
            }
            let take_plain = match (a < plain_row.len(), b < extra_row.len()) {
                (false, false) => break,
                (true, false) => true,
                (false, true) => false,
                (true, true) => plain_row[a] < extra_row[b],
            };
            if take_plain {
                neighbors.push(plain_row[a]);
                weights.push(plain_w[a]);
                a += 1;
            } else {
                neighbors.push(extra_row[b]);
                weights.push(extra_w[b]);
                b += 1;
            }
        }
        offsets.push(neighbors.len());
    }
    ConsistencyGraph::from_csr_parts(offsets, neighbors, weights)
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
