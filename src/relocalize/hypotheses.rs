//! Hypotheses: cliques of the consistency graph, each aligned and refined.
//!
//! One clique is not enough evidence: with few true common boulders among thousands of
//! candidates, a coincidental clique can be as large as the true one. So the search
//! extracts several: after each clique, every association consistent with its transform
//! is removed and the graph is solved again. Each clique's transform is then refined over
//! all landmarks, and the hypotheses compete on refined inliers.

use super::config::RelocalizeConfig;
use super::prepared::PreparedMap;
use super::result::Hypothesis;
use crate::align::{align_with, refine, Dof, WeightedPair};
use segloc_clipper::{
    core_numbers, densest_clique, max_clique, Association, ConsistencyGraph, DensestCliqueConfig,
    MaxCliqueLimits,
};
use std::time::Instant;

/// Hypotheses in extraction order, the largest clique seen, and time spent (ms) in the
/// clique solver and in alignment.
pub struct HypothesisSet {
    /// The hypotheses.
    pub hypotheses: Vec<Hypothesis>,
    /// Size of the largest clique found (also when below the hypothesis threshold).
    pub largest_clique: usize,
    /// Time in the clique solver (ms).
    pub clique_ms: f64,
    /// Time in alignment and refinement (ms).
    pub alignment_ms: f64,
}

/// Extract up to `config.clique.hypotheses` hypotheses from `graph`: the best clique the
/// solvers find, then its rivals — large cliques among the associations its transform
/// does not explain, from one pass of the edge-seeded search.
pub fn generate_hypotheses(
    graph: &ConsistencyGraph,
    associations: &[Association],
    prior: &PreparedMap,
    query: &PreparedMap,
    dof: Dof,
    config: &RelocalizeConfig,
) -> HypothesisSet {
    let mut set = HypothesisSet {
        hypotheses: Vec::new(),
        largest_clique: 0,
        clique_ms: 0.0,
        alignment_ms: 0.0,
    };
    let started = Instant::now();
    let (first, graph_cores) = solve_clique(graph, config, true);
    set.clique_ms += ms_since(started);
    set.largest_clique = first.len();
    if first.len() < config.clique.min_clique {
        return set;
    }
    let mut keep = vec![true; associations.len()];
    let examine_clique = |clique: Vec<usize>, keep: &mut [bool], set: &mut HypothesisSet| {
        let started = Instant::now();
        set.hypotheses.extend(examine(
            &clique,
            associations,
            prior,
            query,
            dof,
            config,
            keep,
        ));
        set.alignment_ms += ms_since(started);
    };
    examine_clique(
        first.iter().map(|&v| v as usize).collect(),
        &mut keep,
        &mut set,
    );
    if config.clique.hypotheses <= 1 {
        return set;
    }

    let started = Instant::now();
    // A rival with fewer than half the winner's associations cannot make the answer
    // ambiguous (see `VerificationConfig::max_runner_up_ratio`); only vertices whose core
    // number allows a clique that large can be in one.
    let min_size = config.clique.min_clique.max(first.len().div_ceil(2));
    // The (min_size − 1)-core of the unexplained associations lies within the graph's own
    // (min_size − 1)-core (removing vertices never raises a core number), so the graph's
    // core numbers, already known, cut the copy down before the rest's are computed: the
    // same vertices remain.
    let candidate: Vec<bool> = keep
        .iter()
        .zip(&graph_cores)
        .map(|(&unexplained, &core)| unexplained && core as usize + 1 >= min_size)
        .collect();
    let (rest, rest_to_graph) = graph.induced_subgraph(&candidate);
    let core_keep: Vec<bool> = core_numbers(&rest)
        .iter()
        .map(|&core| core as usize + 1 >= min_size)
        .collect();
    let (rest, to_rest) = rest.induced_subgraph(&core_keep);
    let to_original: Vec<u32> = to_rest.iter().map(|&v| rest_to_graph[v as usize]).collect();
    let search = segloc_clipper::SeededSearch {
        max_samples: config.clique.seeded_samples,
        miss_probability: 1e-3,
        seed: config.clique.seed ^ 0x5eed,
        min_size,
    };
    let rivals = segloc_clipper::edge_seeded_cliques(&rest, &search, config.clique.hypotheses - 1);
    set.clique_ms += ms_since(started);
    for rival in rivals
        .into_iter()
        .filter(|r| r.len() >= config.clique.min_clique)
    {
        let clique = rival
            .iter()
            .map(|&v| to_original[v as usize] as usize)
            .collect();
        examine_clique(clique, &mut keep, &mut set);
    }
    set
}

/// Align a clique, refine its transform over all landmarks, and mark in `keep` the
/// associations the transform explains.
fn examine(
    clique: &[usize],
    associations: &[Association],
    prior: &PreparedMap,
    query: &PreparedMap,
    dof: Dof,
    config: &RelocalizeConfig,
    keep: &mut [bool],
) -> Option<Hypothesis> {
    let pairs: Vec<WeightedPair> = clique
        .iter()
        .map(|&k| pair_of(&associations[k], prior, query))
        .collect();
    for &k in clique {
        keep[k] = false;
    }
    let initial = align_with(&pairs, dof, &config.refine.tilt)?;
    let refined = refine(
        &prior.points,
        &prior.weights,
        &query.points,
        &query.weights,
        &initial,
        dof,
        &config.refine,
    );
    let transform = refined.prior_from_query;
    for (k, a) in associations.iter().enumerate() {
        let residual =
            (prior.points[a.prior as usize] - transform * query.points[a.query as usize]).norm();
        if residual < config.verification.same_hypothesis_m {
            keep[k] = false;
        }
    }
    let inlier_prior: Vec<_> = refined
        .inliers
        .iter()
        .map(|&(i, _)| prior.points[i as usize])
        .collect();
    let rmse_m = if refined.residuals_m.is_empty() {
        f64::INFINITY
    } else {
        (refined.residuals_m.iter().map(|r| r * r).sum::<f64>() / refined.residuals_m.len() as f64)
            .sqrt()
    };
    let predicted_sq_m2 = refined
        .inliers
        .iter()
        .map(|&(i, j)| 3.0 * (prior.var_3d[i as usize] + query.var_3d[j as usize]))
        .sum::<f64>()
        / refined.inliers.len().max(1) as f64;
    let verification = &config.verification;
    Some(Hypothesis {
        max_rmse_m: verification
            .max_rmse_m
            .max(verification.rmse_multiplier * predicted_sq_m2.sqrt()),
        clique_size: clique.len(),
        prior_from_query: transform,
        support_query: refined
            .inliers
            .iter()
            .map(|&(_, j)| query.points[j as usize])
            .collect(),
        inlier_count: refined.inliers.len(),
        inliers: refined.inliers,
        rmse_m,
        spread_m: minor_axis_spread(&inlier_prior),
        tilt: refined.tilt.map(Into::into),
        yaw_sigma_deg: None,
        min_inliers: None,
    })
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The weighted point pair of an association.
pub fn pair_of(a: &Association, prior: &PreparedMap, query: &PreparedMap) -> WeightedPair {
    let (i, j) = (a.prior as usize, a.query as usize);
    WeightedPair {
        p_prior: prior.points[i],
        p_query: query.points[j],
        weight: 1.0 / (1.0 / prior.weights[i] + 1.0 / query.weights[j]),
    }
}

/// The largest clique the solvers find, as sorted vertex indices of `graph`.
///
/// The edge-seeded search ([`segloc_clipper::edge_seeded_clique`]) runs first; its clique is a lower bound, so
/// only vertices whose core number reaches it can be in a larger clique. The graph pruned
/// to them is usually tiny and searched exactly (which certifies the answer); when it is
/// too large for that and the seeded search found nothing worth a hypothesis, the
/// densest-clique relaxation has the last word.
///
/// Returns the clique and the graph's core numbers (the rival search reuses them).
fn solve_clique(
    graph: &ConsistencyGraph,
    config: &RelocalizeConfig,
    relax: bool,
) -> (Vec<u32>, Vec<u32>) {
    let limits = MaxCliqueLimits {
        max_vertices: config.clique.exact_max_vertices,
        max_nodes: config.clique.exact_max_nodes,
    };
    let search = segloc_clipper::SeededSearch {
        max_samples: config.clique.seeded_samples,
        miss_probability: 1e-3,
        seed: config.clique.seed,
        min_size: config.clique.min_clique,
    };
    let mut best = segloc_clipper::edge_seeded_clique(graph, &search);
    let lower_bound = best.len() as u32;
    let cores = core_numbers(graph);
    let keep: Vec<bool> = cores
        .iter()
        .map(|&core| core >= lower_bound.max(1))
        .collect();
    let (pruned, to_graph) = graph.induced_subgraph(&keep);
    if pruned.num_vertices() <= best.len() {
        return (best, cores);
    }
    let found = match max_clique(&pruned, &limits) {
        Ok(exact) => exact,
        // The relaxation is the last resort: when the seeded search found nothing worth a
        // hypothesis.
        Err(_) if !relax || best.len() >= config.clique.min_clique => return (best, cores),
        Err(_) => {
            let relaxation = DensestCliqueConfig {
                seed: config.clique.seed,
                max_outer_iterations: config.clique.max_outer_iterations,
                max_inner_iterations: config.clique.max_inner_iterations,
                ..DensestCliqueConfig::default()
            };
            densest_clique(&pruned, &relaxation)
        }
    };
    if found.vertices.len() > best.len() {
        best = found
            .vertices
            .iter()
            .map(|&v| to_graph[v as usize])
            .collect();
        best.sort_unstable();
    }
    (best, cores)
}

/// Standard deviation (m) of points along the minor axis of their horizontal scatter.
pub fn minor_axis_spread(points: &[nalgebra::Point3<f64>]) -> f64 {
    if points.len() < 2 {
        return 0.0;
    }
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p.x / n, y + p.y / n));
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p.x - mx, p.y - my);
        sxx += dx * dx / n;
        syy += dy * dy / n;
        sxy += dx * dy / n;
    }
    let half_trace = 0.5 * (sxx + syy);
    let det = sxx * syy - sxy * sxy;
    let minor = half_trace - (half_trace * half_trace - det).max(0.0).sqrt();
    minor.max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    #[test]
    fn spread_of_a_line_is_zero_and_of_a_square_is_not() {
        let line: Vec<_> = (0..5)
            .map(|i| Point3::new(i as f64, 2.0 * i as f64, 0.0))
            .collect();
        assert!(minor_axis_spread(&line) < 1e-9);
        let square = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(2.0, 0.0, 0.0),
            Point3::new(0.0, 2.0, 0.0),
            Point3::new(2.0, 2.0, 0.0),
        ];
        assert!((minor_axis_spread(&square) - 1.0).abs() < 1e-12);
    }
}
