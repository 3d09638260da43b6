//! Covariance-driven consistency tolerances.
//!
//! With one fixed threshold ε, a pair of associations between well-known landmarks (1 cm)
//! and a pair between landmarks known to a grid cell (15 cm) are held to the same test:
//! either the first is too loose or the second refuses true pairs. Here each pair's
//! threshold follows the position variances of its four points: the invariant's residual
//! (a difference of two distances, or of two height differences) has variance
//! `var(a_i) + var(a_k) + var(b_j) + var(b_l)` along the pair's direction, and the pair is
//! consistent when the residual is below `max(ε, k·√that)`, its weight's width scaled by the
//! same factor. The floor ε keeps well-known landmarks exactly where they were: when no pair
//! can exceed the floor, the graph is the plain [`ConsistencyGraph::build`]'s, bit for bit.

use nalgebra::Point3;

use crate::association::{exp_neg, validate_input, PairTest};
use crate::build::{build_checked, choose_checked, join_deciding};
use crate::{Association, BuildStrategy, ClipperError, ConsistencyGraph, Invariant};

/// Per-point position variances (m²) of both maps, and the multiplier of the standard
/// deviation.
#[derive(Clone, Copy, Debug)]
pub struct PointVariances<'a> {
    /// Variance of each prior point along one horizontal direction (4-DOF) or any
    /// direction (6-DOF).
    pub prior: &'a [f64],
    /// Same for each query point.
    pub query: &'a [f64],
    /// Height variance of each prior point (4-DOF only; may be empty for 6-DOF).
    pub prior_z: &'a [f64],
    /// Same for each query point.
    pub query_z: &'a [f64],
    /// A pair's threshold is this many standard deviations of its residual (at least the
    /// invariant's own threshold).
    pub multiplier: f64,
    /// Largest threshold (distance / horizontal distance) any pair gets: a few very
    /// uncertain points must not make the whole graph dense.
    pub max_epsilon: f64,
    /// Largest height threshold any pair gets (4-DOF).
    pub max_epsilon_z: f64,
}

/// The thresholds a covariance-driven build used.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ToleranceSummary {
    /// Whether any pair's threshold exceeded the invariant's floor (false: the plain build).
    pub widened: bool,
    /// Largest threshold any pair could get (distance / horizontal distance).
    pub epsilon_max: f64,
    /// Largest height threshold any pair could get (4-DOF; 0 for 6-DOF).
    pub epsilon_z_max: f64,
    /// Median over associations of the threshold a pair of two such associations gets.
    pub epsilon_median: f64,
}

impl ConsistencyGraph {
    /// [`ConsistencyGraph::build`] with each pair's thresholds from the points' variances
    /// (see the module docs), and what thresholds were used.
    ///
    /// Pairs of two *tight* associations (each of whose variances, doubled, stays within
    /// the floor) are decided by the plain build. When only a few associations are loose,
    /// their pairs are found from each loose association's sorted distances
    /// (`loose_partners`); when most are (a grid map), the graph is built with the
    /// widest thresholds and every edge re-tested with its own.
    pub fn build_with_variances(
        prior: &[Point3<f64>],
        query: &[Point3<f64>],
        associations: &[Association],
        invariant: &Invariant,
        variances: &PointVariances<'_>,
    ) -> Result<(Self, ToleranceSummary), ClipperError> {
        let base = PairTest::new(invariant)?;
        let pair = PairThresholds::new(&base, associations, variances, prior.len(), query.len())?;
        let summary = pair.summary();
        let loose: Vec<bool> = (0..associations.len()).map(|u| pair.is_loose(u)).collect();
        let loose_count = loose.iter().filter(|&&l| l).count();
        if loose_count == 0 {
            let graph = Self::build(prior, query, associations, invariant)?;
            return Ok((graph, summary));
        }
        if loose_count * 4 <= associations.len() {
            if let Some(graph) = crate::loose_partners::graph(
                prior,
                query,
                associations,
                invariant,
                &pair,
                variances,
                &loose,
            )? {
                return Ok((graph, summary));
            }
        }
        let wide = PairTest::new(&widened(invariant, pair.epsilon_max, pair.epsilon_z_max))?;
        validate_input(prior, query, associations)?;
        let graph = match choose_checked(prior, query, associations, &wide) {
            // the join finds the candidates within the widest thresholds and decides each
            // with its own in the same pass
            BuildStrategy::Join => join_deciding(prior, query, associations, &wide, &pair),
            strategy => {
                let candidates = build_checked(prior, query, associations, &wide, strategy);
                pair.filter(&candidates, prior, query, associations)
            }
        };
        Ok((graph, summary))
    }
}

impl crate::build::PairDecision for PairThresholds {
    #[inline]
    fn decide(&self, u: u32, v: u32, c: f64, cz: f64, _x: f32) -> Option<f32> {
        self.exponent(u as usize, v as usize, c, cz)
    }
}

fn check_variances(map: &'static str, v: &[f64], n: usize) -> Result<(), ClipperError> {
    if v.len() != n {
        return Err(ClipperError::InvalidVariances {
            map,
            reason: format!("{} variances for {n} points", v.len()),
        });
    }
    if let Some(k) = v.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
        return Err(ClipperError::InvalidVariances {
            map,
            reason: format!(
                "point {k}'s variance {} is not a finite non-negative number",
                v[k]
            ),
        });
    }
    Ok(())
}

/// A pair's threshold: `multiplier` standard deviations of its residual (variance `var`),
/// at least the invariant's `floor` and at most `cap` (never below the floor).
fn pair_threshold(floor: f64, multiplier: f64, var: f64, cap: f64) -> f64 {
    floor.max(multiplier * var.sqrt()).min(cap.max(floor))
}

/// The invariant with its thresholds raised to the largest any pair can get (the widths
/// are left as they are: the filter recomputes every weight).
fn widened(invariant: &Invariant, epsilon: f64, epsilon_z: f64) -> Invariant {
    match *invariant {
        Invariant::Distance { sigma, .. } => Invariant::Distance { epsilon, sigma },
        Invariant::GravityAligned { sigma, sigma_z, .. } => Invariant::GravityAligned {
            epsilon,
            sigma,
            epsilon_z,
            sigma_z,
        },
    }
}

/// Each pair's own thresholds and weight.
pub(crate) struct PairThresholds {
    pub test: PairTest,
    /// Variance of each association's residual contribution (prior + query point).
    var: Vec<f64>,
    /// Same for the height (4-DOF; zeros otherwise).
    var_z: Vec<f64>,
    multiplier: f64,
    /// Largest threshold any pair can get (capped).
    pub epsilon_max: f64,
    /// Largest height threshold any pair can get (capped; 0 for 6-DOF).
    pub epsilon_z_max: f64,
}

impl PairThresholds {
    fn new(
        base: &PairTest,
        associations: &[Association],
        variances: &PointVariances<'_>,
        n_prior: usize,
        n_query: usize,
    ) -> Result<Self, ClipperError> {
        check_variances("prior", variances.prior, n_prior)?;
        check_variances("query", variances.query, n_query)?;
        if base.gravity {
            check_variances("prior", variances.prior_z, n_prior)?;
            check_variances("query", variances.query_z, n_query)?;
        }
        let k = variances.multiplier;
        for (name, value) in [
            ("multiplier", k),
            ("max_epsilon", variances.max_epsilon),
            ("max_epsilon_z", variances.max_epsilon_z),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ClipperError::InvalidParameter { name, value });
            }
        }
        let of = |a: &[f64], b: &[f64]| -> Vec<f64> {
            associations
                .iter()
                .map(|u| a[u.prior as usize] + b[u.query as usize])
                .collect()
        };
        let var = of(variances.prior, variances.query);
        let var_z = if base.gravity {
            of(variances.prior_z, variances.query_z)
        } else {
            vec![0.0; associations.len()]
        };
        let max_of = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        // the widest pair: the loosest association with itself
        let widest = |floor: f64, cap: f64, var: f64| pair_threshold(floor, k, 2.0 * var, cap);
        Ok(Self {
            test: *base,
            epsilon_max: widest(base.epsilon, variances.max_epsilon, max_of(&var)),
            epsilon_z_max: if base.gravity {
                widest(base.epsilon_z, variances.max_epsilon_z, max_of(&var_z))
            } else {
                0.0
            },
            var,
            var_z,
            multiplier: k,
        })
    }

    /// [`Self::new`] from an invariant, for tests.
    #[cfg(test)]
    pub fn for_tests(
        invariant: &Invariant,
        associations: &[Association],
        variances: &PointVariances<'_>,
        n_prior: usize,
        n_query: usize,
    ) -> Self {
        let base = PairTest::new(invariant).unwrap();
        Self::new(&base, associations, variances, n_prior, n_query).unwrap()
    }

    /// Whether a pair of association `u` with itself would exceed a floor: only pairs with
    /// a loose association can.
    fn is_loose(&self, u: usize) -> bool {
        !self.at_floor(u, u)
    }

    /// The residual variance of association `u` (prior point + query point).
    pub fn var(&self, u: usize) -> f64 {
        self.var[u]
    }

    /// Whether the pair `(u, v)`'s thresholds stay at the floor (the plain build decides
    /// it and weighs it).
    pub fn at_floor(&self, u: usize, v: usize) -> bool {
        let (t, k2) = (&self.test, self.multiplier * self.multiplier);
        k2 * (self.var[u] + self.var[v]) <= t.epsilon * t.epsilon
            && (!t.gravity || k2 * (self.var_z[u] + self.var_z[v]) <= t.epsilon_z * t.epsilon_z)
    }

    /// A point's variance over the floor's budget `(ε / multiplier)²`, the larger of the
    /// horizontal (or 3D) and the height one.
    pub fn looseness(&self, var: f64, var_z: Option<f64>) -> f64 {
        let (t, k2) = (&self.test, self.multiplier * self.multiplier);
        let xy = k2 * var / (t.epsilon * t.epsilon);
        match var_z {
            Some(z) if t.gravity => xy.max(k2 * z / (t.epsilon_z * t.epsilon_z)),
            _ => xy,
        }
    }

    /// The looseness a query point must exceed to widen a pair of association `u` with an
    /// association of a prior point of variances `var_k`, `var_z_k` (negative: any).
    pub fn looseness_to_widen(&self, u: usize, var_k: f64, var_z_k: Option<f64>) -> f64 {
        let (t, k2) = (&self.test, self.multiplier * self.multiplier);
        let xy = 1.0 - k2 * (self.var[u] + var_k) / (t.epsilon * t.epsilon);
        match var_z_k {
            Some(z) if t.gravity => {
                xy.min(1.0 - k2 * (self.var_z[u] + z) / (t.epsilon_z * t.epsilon_z))
            }
            _ => xy,
        }
    }

    /// The (distance / horizontal distance) threshold of a pair of association `u` with an
    /// association of residual variance `var_v`.
    pub fn threshold(&self, u: usize, var_v: f64) -> f64 {
        let t = &self.test;
        pair_threshold(
            t.epsilon,
            self.multiplier,
            self.var[u] + var_v,
            self.epsilon_max,
        )
    }

    /// The height threshold of a pair of association `u` with an association of height
    /// variance `var_z_v` (4-DOF).
    fn threshold_z(&self, u: usize, var_z_v: f64) -> f64 {
        let t = &self.test;
        pair_threshold(
            t.epsilon_z,
            self.multiplier,
            self.var_z[u] + var_z_v,
            self.epsilon_z_max,
        )
    }

    fn summary(&self) -> ToleranceSummary {
        let t = &self.test;
        let mut sorted = self.var.clone();
        let half = sorted.len() / 2;
        let median = if sorted.is_empty() {
            0.0
        } else {
            *sorted.select_nth_unstable_by(half, f64::total_cmp).1
        };
        let widened =
            self.epsilon_max > t.epsilon || (t.gravity && self.epsilon_z_max > t.epsilon_z);
        ToleranceSummary {
            widened,
            epsilon_max: self.epsilon_max,
            epsilon_z_max: self.epsilon_z_max,
            epsilon_median: pair_threshold(
                t.epsilon,
                self.multiplier,
                2.0 * median,
                self.epsilon_max,
            ),
        }
    }

    /// The edge weight of associations `u` and `v` under their own thresholds, or `None`
    /// (also when they share a point).
    pub fn edge(
        &self,
        u: usize,
        v: usize,
        prior: &[Point3<f64>],
        query: &[Point3<f64>],
        associations: &[Association],
    ) -> Option<f32> {
        let t = &self.test;
        let (a, b) = (associations[u], associations[v]);
        if a.prior == b.prior || a.query == b.query {
            return None;
        }
        let (a, b) = if a.prior < b.prior { (a, b) } else { (b, a) };
        let mp = t.measure(&prior[a.prior as usize], &prior[b.prior as usize]);
        let mq = t.measure(&query[a.query as usize], &query[b.query as usize]);
        let c = (mp.dist - mq.dist).abs();
        let cz = (mp.dz - mq.dz).abs();
        self.exponent(u, v, c, cz).map(exp_neg)
    }

    /// The weight exponent of associations `u` and `v` whose invariants differ by `c`
    /// (distance / horizontal distance) and `cz` (height), under their own thresholds:
    /// each threshold is the floor scaled by `s`, and the weight's width scales with it.
    #[inline]
    fn exponent(&self, u: usize, v: usize, c: f64, cz: f64) -> Option<f32> {
        let t = &self.test;
        let threshold = self.threshold(u, self.var[v]);
        if c >= threshold {
            return None;
        }
        let s = threshold / t.epsilon;
        let mut x = c * c * t.inv_two_sigma_sq / (s * s);
        if t.gravity {
            let threshold_z = self.threshold_z(u, self.var_z[v]);
            if cz >= threshold_z {
                return None;
            }
            let sz = threshold_z / t.epsilon_z;
            x += cz * cz * t.inv_two_sigma_z_sq / (sz * sz);
        }
        Some(x as f32)
    }

    /// The edges of `candidates` (built with the widest thresholds) that pass their own
    /// pair's thresholds, with their own weights. Each row is filtered in place (both
    /// directions of an edge are tested; the test is symmetric bit for bit), so the rows
    /// stay sorted and no transposition is needed: a 2,000-rock prior's million edges are
    /// scattered through memory by a transposition, which cost more than the second test.
    fn filter(
        &self,
        candidates: &ConsistencyGraph,
        prior: &[Point3<f64>],
        query: &[Point3<f64>],
        associations: &[Association],
    ) -> ConsistencyGraph {
        let n = candidates.num_vertices();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0usize);
        let mut neighbors = Vec::with_capacity(candidates.all_neighbors().len());
        let mut weights = Vec::with_capacity(candidates.all_neighbors().len());
        for u in 0..n {
            for &v in candidates.neighbors(u) {
                if let Some(w) = self.edge(u, v as usize, prior, query, associations) {
                    neighbors.push(v);
                    weights.push(w);
                }
            }
            offsets.push(neighbors.len());
        }
        ConsistencyGraph::from_csr_parts(offsets, neighbors, weights)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two associations whose horizontal distances differ by 12 cm.
    fn pair() -> (Vec<Point3<f64>>, Vec<Point3<f64>>, Vec<Association>) {
        let prior = vec![Point3::new(0.0, 0.0, 0.0), Point3::new(2.0, 0.0, 0.0)];
        let query = vec![Point3::new(5.0, 5.0, 0.0), Point3::new(5.0, 7.12, 0.0)];
        (
            prior,
            query,
            vec![Association::new(0, 0), Association::new(1, 1)],
        )
    }

    fn inv() -> Invariant {
        Invariant::GravityAligned {
            epsilon: 0.08,
            sigma: 0.04,
            epsilon_z: 0.06,
            sigma_z: 0.03,
        }
    }

    fn build(sigma_m: f64) -> (ConsistencyGraph, ToleranceSummary) {
        let (prior, query, assoc) = pair();
        let v = vec![sigma_m * sigma_m; 2];
        let variances = PointVariances {
            prior: &v,
            query: &v,
            prior_z: &v,
            query_z: &v,
            multiplier: 2.5,
            max_epsilon: 0.5,
            max_epsilon_z: 0.25,
        };
        ConsistencyGraph::build_with_variances(&prior, &query, &assoc, &inv(), &variances).unwrap()
    }

    #[test]
    fn the_same_pair_is_consistent_at_15_cm_and_not_at_1_cm() {
        let (loose, summary) = build(0.15 / 12f64.sqrt());
        assert_eq!(loose.num_edges(), 1, "{summary:?}");
        assert!(summary.widened);
        assert!(summary.epsilon_max > 0.2);
        let (tight, summary) = build(0.01);
        assert_eq!(tight.num_edges(), 0);
        assert!(!summary.widened);
        assert_eq!(summary.epsilon_max, 0.08);
    }

    #[test]
    fn at_the_floor_the_graph_is_the_plain_one() {
        let (prior, query, assoc) = pair();
        let (g, _) = build(0.005);
        assert_eq!(
            g,
            ConsistencyGraph::build(&prior, &query, &assoc, &inv()).unwrap()
        );
    }

    #[test]
    fn a_grid_graph_is_every_pair_under_its_own_thresholds() {
        // most associations loose (the wide build, filtered row by row): the same graph as
        // testing every pair with its own thresholds
        let mut rng = crate::rng::SplitMix64::new(3);
        let prior: Vec<_> = (0..40)
            .map(|_| Point3::new(8.0 * rng.next_open01(), 8.0 * rng.next_open01(), 0.0))
            .collect();
        let query: Vec<_> = prior[..12]
            .iter()
            .map(|p| Point3::new(p.y + 0.03 * rng.next_open01(), -p.x, 0.05))
            .collect();
        let assoc: Vec<_> = (0..40)
            .flat_map(|i| (0..12).map(move |j| Association::new(i, j)))
            .collect();
        let prior_var: Vec<_> = (0..40).map(|k| 0.0019 + 1e-4 * (k % 3) as f64).collect();
        let query_var: Vec<_> = (0..12).map(|k| 1e-4 * (k % 4) as f64).collect();
        let variances = PointVariances {
            prior: &prior_var,
            query: &query_var,
            prior_z: &prior_var,
            query_z: &query_var,
            multiplier: 2.0,
            max_epsilon: 0.5,
            max_epsilon_z: 0.25,
        };
        let (graph, summary) =
            ConsistencyGraph::build_with_variances(&prior, &query, &assoc, &inv(), &variances)
                .unwrap();
        assert!(summary.widened && graph.num_edges() > 0);
        let base = PairTest::new(&inv()).unwrap();
        let pair = PairThresholds::new(&base, &assoc, &variances, 40, 12).unwrap();
        let mut edges = Vec::new();
        for u in 0..assoc.len() {
            for v in u + 1..assoc.len() {
                if let Some(w) = pair.edge(u, v, &prior, &query, &assoc) {
                    edges.push((u as u32, v as u32, w));
                }
            }
        }
        assert_eq!(graph, ConsistencyGraph::from_edge_list(assoc.len(), &edges));
        // both builders: the join deciding each pair in one pass, the scan then the filter
        let wide = widened(&inv(), pair.epsilon_max, pair.epsilon_z_max);
        let joined = join_deciding(
            &prior,
            &query,
            &assoc,
            &PairTest::new(&wide).unwrap(),
            &pair,
        );
        let scanned = ConsistencyGraph::build_with(
            &prior,
            &query,
            &assoc,
            &wide,
            BuildStrategy::PairwiseScan,
        )
        .unwrap();
        assert_eq!(joined, graph);
        assert_eq!(pair.filter(&scanned, &prior, &query, &assoc), graph);
    }

    #[test]
    fn bad_variances_are_errors() {
        let (prior, query, assoc) = pair();
        let short = [0.0];
        let v = [0.0, 0.0];
        let variances = PointVariances {
            prior: &short,
            query: &v,
            prior_z: &v,
            query_z: &v,
            multiplier: 2.5,
            max_epsilon: 0.5,
            max_epsilon_z: 0.25,
        };
        let err =
            ConsistencyGraph::build_with_variances(&prior, &query, &assoc, &inv(), &variances);
        assert!(matches!(
            err,
            Err(ClipperError::InvalidVariances { map: "prior", .. })
        ));
    }
}
