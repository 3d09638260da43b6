//! Building the consistency graph from points and associations.
//!
//! Two builders give identical graphs; [`BuildStrategy::Auto`] picks the cheaper one from
//! an estimate of their work:
//! - [`join`]: sorts each map's point pairs by their invariant and joins the two lists
//!   within epsilon: work proportional to the matching quads (all-to-all lists).
//! - [`scan`]: tests every association pair with a vectorised prefilter (sparse lists).

mod join;
pub(crate) use join::{build_deciding as join_deciding, PairDecision, UsedPoints};
mod scan;
#[cfg(target_arch = "x86_64")]
mod scan_avx2;

use nalgebra::Point3;

use crate::association::{validate_input, PairMeasure, PairTest};
use crate::rng::SplitMix64;
use crate::{Association, ClipperError, ConsistencyGraph, Invariant};

/// Which graph builder to use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildStrategy {
    /// Pick the cheaper builder from a cost estimate (see [`choose_strategy`]).
    #[default]
    Auto,
    /// Join the two maps' sorted pair lists (best for dense / all-to-all association lists).
    Join,
    /// Test every association pair (best for sparse association lists).
    PairwiseScan,
}

impl ConsistencyGraph {
    /// Builds the consistency graph of `associations`: vertex `k` is `associations[k]`, and
    /// two associations are adjacent when they share no point and preserve `invariant`.
    /// Edge weights are the invariant's Gaussian scores.
    ///
    /// The result does not depend on the number of threads.
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use segloc_clipper::{Association, ConsistencyGraph, Invariant};
    /// let prior = [Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 2.0, 0.0)];
    /// // the query map is the prior map shifted by (5, 0, 0)
    /// let query: Vec<_> = prior.iter().map(|p| p + nalgebra::Vector3::new(5.0, 0.0, 0.0)).collect();
    /// let assoc: Vec<_> = (0..3).map(|k| Association::new(k, k)).collect();
    /// let inv = Invariant::Distance { epsilon: 0.1, sigma: 0.05 };
    /// let g = ConsistencyGraph::build(&prior, &query, &assoc, &inv).unwrap();
    /// assert_eq!(g.num_edges(), 3);
    /// ```
    pub fn build(
        prior: &[Point3<f64>],
        query: &[Point3<f64>],
        associations: &[Association],
        invariant: &Invariant,
    ) -> Result<Self, ClipperError> {
        Self::build_with(prior, query, associations, invariant, BuildStrategy::Auto)
    }

    /// [`Self::build`] with an explicit builder choice (both builders give identical graphs).
    pub fn build_with(
        prior: &[Point3<f64>],
        query: &[Point3<f64>],
        associations: &[Association],
        invariant: &Invariant,
        strategy: BuildStrategy,
    ) -> Result<Self, ClipperError> {
        let test = PairTest::new(invariant)?;
        validate_input(prior, query, associations)?;
        Ok(build_checked(prior, query, associations, &test, strategy))
    }
}

/// [`ConsistencyGraph::build_with`] on input already validated, with the pair test made.
pub(crate) fn build_checked(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
    test: &PairTest,
    strategy: BuildStrategy,
) -> ConsistencyGraph {
    match strategy {
        BuildStrategy::Auto => {
            let chosen = choose_checked(prior, query, associations, test);
            build_checked(prior, query, associations, test, chosen)
        }
        BuildStrategy::Join => join::build(prior, query, associations, test),
        BuildStrategy::PairwiseScan => {
            scan::build(prior, query, associations, test, scan::Kernel::detect())
        }
    }
}

/// The builder [`BuildStrategy::Auto`] would use for this problem (never `Auto`).
///
/// The estimate compares the scan's `m(m-1)/2` vectorised pair tests with the join's pair
/// lists plus its candidate quads, whose count is estimated from a fixed-seed sample of
/// pairs. Errors as [`ConsistencyGraph::build`] on invalid input.
pub fn choose_strategy(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
    invariant: &Invariant,
) -> Result<BuildStrategy, ClipperError> {
    let test = PairTest::new(invariant)?;
    validate_input(prior, query, associations)?;
    Ok(choose_checked(prior, query, associations, &test))
}

/// Estimated costs (ns, one thread; measured on the benchmark problems): one scan pair
/// (prefilter and share of the row assembly), one scan candidate that reaches the exact
/// stage and becomes an edge, one pair-list entry (measure and sort), and one join
/// candidate (an association pair found from both ends, looked up, tested and placed).
const SCAN_PAIR_NS: f64 = 0.6;
const EXACT_TEST_NS: f64 = 15.0;
const LIST_ENTRY_NS: f64 = 40.0;
const JOIN_CANDIDATE_NS: f64 = 45.0;

pub(crate) fn choose_checked(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
    test: &PairTest,
) -> BuildStrategy {
    let m = associations.len() as f64;
    let used_p = join::UsedPoints::new(prior.len(), associations.iter().map(|a| a.prior));
    let used_q = join::UsedPoints::new(query.len(), associations.iter().map(|a| a.query));
    let (np, nq) = (used_p.len() as f64, used_q.len() as f64);
    let prior_pairs = np * (np - 1.0) / 2.0;
    let query_ordered = nq * (nq - 1.0);
    let scan_pairs = m * (m - 1.0) / 2.0;
    let list_ns = (prior_pairs + query_ordered) * LIST_ENTRY_NS;
    let scan_floor_ns = scan_pairs * SCAN_PAIR_NS;
    if list_ns >= scan_floor_ns || np < 2.0 || nq < 2.0 {
        return BuildStrategy::PairwiseScan;
    }
    let p_match = match_fraction(prior, query, &used_p, &used_q, test);
    let scan_ns = scan_floor_ns + scan_pairs * p_match * EXACT_TEST_NS;
    let join_ns = list_ns + prior_pairs * query_ordered * p_match * JOIN_CANDIDATE_NS;
    if join_ns < scan_ns {
        BuildStrategy::Join
    } else {
        BuildStrategy::PairwiseScan
    }
}

/// Fraction of (prior pair, query pair) combinations that pass the invariant, estimated on
/// a fixed-seed sample (at least one match is assumed, to stay conservative).
fn match_fraction(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    used_p: &join::UsedPoints,
    used_q: &join::UsedPoints,
    test: &PairTest,
) -> f64 {
    const SAMPLE: usize = 256;
    let mut rng = SplitMix64::new(0x05EE_D0FA_550C);
    let mut draw = |points: &[Point3<f64>], used: &join::UsedPoints| -> Vec<PairMeasure> {
        let n = used.len();
        (0..SAMPLE)
            .map(|_| {
                let a = rng.below(n);
                let mut b = rng.below(n - 1);
                if b >= a {
                    b += 1;
                }
                test.measure(
                    &points[used.original[a] as usize],
                    &points[used.original[b] as usize],
                )
            })
            .collect()
    };
    let sp = draw(prior, used_p);
    let sq = draw(query, used_q);
    let mut hits = 0usize;
    for a in &sp {
        for b in &sq {
            hits += test.exponent(*a, *b).is_some() as usize;
        }
    }
    (hits.max(1)) as f64 / (SAMPLE * SAMPLE) as f64
}

/// Splits rows `0..n` of an upper-triangular pair table (row `u` has `n - 1 - u` pairs)
/// into contiguous chunks of about equal work, several per thread.
pub(crate) fn balanced_row_chunks(n: usize) -> Vec<(usize, usize)> {
    if n == 0 {
        return Vec::new();
    }
    let total = (n as f64) * (n as f64 - 1.0) / 2.0 + n as f64;
    let n_chunks = (rayon::current_num_threads() * 8).clamp(1, n);
    let per = (total / n_chunks as f64).max(1.0);
    let mut out = Vec::with_capacity(n_chunks + 1);
    let (mut start, mut acc) = (0, 0.0);
    for u in 0..n {
        acc += (n - 1 - u) as f64 + 1.0;
        if acc >= per || u + 1 == n {
            out.push((start, u + 1));
            start = u + 1;
            acc = 0.0;
        }
    }
    out
}

#[cfg(test)]
mod tests;
