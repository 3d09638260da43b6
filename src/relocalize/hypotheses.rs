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
use crate::align::{align, refine, Dof, WeightedPair};
use segloc_clipper::{
    densest_clique, max_clique, Association, CliqueSolution, ConsistencyGraph, DensestCliqueConfig,
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

/// Extract up to `config.clique.hypotheses` hypotheses from `graph`.
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
    let mut keep = vec![true; associations.len()];
    for round in 0..config.clique.hypotheses.max(1) {
        let started = Instant::now();
        let (subgraph, to_original) = if round == 0 {
            (graph.clone(), (0..associations.len() as u32).collect())
        } else {
            graph.induced_subgraph(&keep)
        };
        if subgraph.num_vertices() == 0 {
            break;
        }
        let clique: Vec<usize> = solve_clique(&subgraph, config)
            .vertices
            .iter()
            .map(|&v| to_original[v as usize] as usize)
            .collect();
        set.clique_ms += started.elapsed().as_secs_f64() * 1e3;
        set.largest_clique = set.largest_clique.max(clique.len());
        if clique.len() < config.clique.min_clique {
            break;
        }

        let started = Instant::now();
        let pairs: Vec<WeightedPair> = clique
            .iter()
            .map(|&k| pair_of(&associations[k], prior, query))
            .collect();
        for &k in &clique {
            keep[k] = false;
        }
        let Some(initial) = align(&pairs, dof) else {
            set.alignment_ms += started.elapsed().as_secs_f64() * 1e3;
            continue;
        };
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
        // Everything this transform explains is spent: the next round looks elsewhere.
        for (k, a) in associations.iter().enumerate() {
            let residual = (prior.points[a.prior as usize]
                - transform * query.points[a.query as usize])
                .norm();
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
            (refined.residuals_m.iter().map(|r| r * r).sum::<f64>()
                / refined.residuals_m.len() as f64)
                .sqrt()
        };
        set.hypotheses.push(Hypothesis {
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
        });
        set.alignment_ms += started.elapsed().as_secs_f64() * 1e3;
    }
    set
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

/// The best clique the solvers find: the exact maximum clique when the graph is small
/// enough to certify, else the densest-clique relaxation.
fn solve_clique(graph: &ConsistencyGraph, config: &RelocalizeConfig) -> CliqueSolution {
    let relaxation = DensestCliqueConfig {
        seed: config.clique.seed,
        max_outer_iterations: config.clique.max_outer_iterations,
        max_inner_iterations: config.clique.max_inner_iterations,
        ..DensestCliqueConfig::default()
    };
    let mut heuristic = densest_clique(graph, &relaxation);
    if heuristic.certified_maximum {
        return heuristic;
    }
    if config.clique.seeded_samples > 0 {
        let seeded = super::seeded::edge_seeded_clique(
            graph,
            config.clique.seeded_samples,
            config.clique.seed,
        );
        if seeded.len() > heuristic.vertices.len() {
            heuristic.vertices = seeded;
        }
    }
    if config.clique.exact_max_vertices == 0 {
        return heuristic;
    }
    let limits = MaxCliqueLimits {
        max_vertices: config.clique.exact_max_vertices,
        ..MaxCliqueLimits::default()
    };
    match max_clique(graph, &limits) {
        Ok(exact) if exact.vertices.len() > heuristic.vertices.len() => exact,
        _ => heuristic,
    }
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
