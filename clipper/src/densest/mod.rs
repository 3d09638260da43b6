//! Densest-clique search: graph-theoretic front (core numbers, greedy clique, bounds,
//! pruning) followed by the CLIPPER-class relaxation on what is left.

use crate::core::core_decomposition;
use crate::front::{greedy_front, k_core};
use crate::greedy::{extend_to_maximal, greedy_colouring_bound};
use crate::polish::polish_swaps;
use crate::relaxation::relax;
use crate::ConsistencyGraph;

/// Settings of [`densest_clique`].
#[derive(Clone, Debug, PartialEq)]
pub struct DensestCliqueConfig {
    /// Seed of the random start (the result is a pure function of graph and config).
    pub seed: u64,
    /// Maximum number of penalty increases (outer iterations).
    pub max_outer_iterations: usize,
    /// Maximum gradient steps per outer iteration.
    pub max_inner_iterations: usize,
    /// Inner loop stops when the step moves `u` by less than this (2-norm).
    pub tolerance_u: f64,
    /// Inner loop stops when the objective changes by less than this.
    pub tolerance_f: f64,
    /// Use the graph-theoretic front: greedy clique, bounds, certification (skip the
    /// optimiser when the greedy clique meets the upper bound) and pruning of vertices whose
    /// core number + 1 is below the greedy clique size. When false, the relaxation runs on the
    /// whole graph like the original CLIPPER.
    pub prune_by_core: bool,
    /// First step length of each backtracking line search.
    pub initial_step: f64,
    /// Factor by which the line search shrinks the step.
    pub step_shrink: f64,
    /// Maximum step trials per line search.
    pub max_line_search_steps: usize,
    /// Entries of `u` at or below this are zero when reading the support (and for the
    /// penalty update); the support read this way is the clique.
    pub support_tolerance: f64,
    /// Maximum number of start vertices of the greedy clique heuristic (0: no limit).
    pub max_greedy_starts: usize,
    /// Polish the final clique by local search: swaps of one or two members for outside
    /// vertices that make it larger or heavier (resolves crossed associations among cliques
    /// of the same size).
    pub polish: bool,
    /// Maximum number of polish swaps.
    pub max_polish_swaps: usize,
}

impl Default for DensestCliqueConfig {
    fn default() -> Self {
        Self {
            seed: 0x00C1_1BBE_5EED,
            max_outer_iterations: 1000,
            max_inner_iterations: 200,
            tolerance_u: 1e-8,
            tolerance_f: 1e-9,
            prune_by_core: true,
            initial_step: 1.0,
            step_shrink: 0.25,
            max_line_search_steps: 40,
            support_tolerance: 1e-9,
            max_greedy_starts: 0,
            polish: true,
            max_polish_swaps: 32,
        }
    }
}

/// A clique found by [`densest_clique`] or [`crate::max_clique`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CliqueSolution {
    /// Clique vertices, sorted, as indices into the graph given.
    pub vertices: Vec<u32>,
    /// `uᵀMu` for the uniform unit vector on the clique: `1 + (k − 1)·mean edge weight`
    /// (0 for an empty clique).
    pub objective: f64,
    /// True when the clique is proven to be a maximum (largest) clique.
    pub certified_maximum: bool,
    /// Proven upper bound on the clique number (min of max core + 1 and the greedy-colouring
    /// bound when computed).
    pub upper_bound: usize,
    /// Vertices removed by core pruning before optimising or searching.
    pub pruned_vertices: usize,
    /// Outer (penalty) iterations of the relaxation, summed over the components it ran on.
    pub outer_iterations: usize,
    /// Inner (gradient) iterations of the relaxation, summed likewise.
    pub inner_iterations: usize,
    /// Branch-and-bound nodes visited by the exact search (0 for [`densest_clique`]).
    pub search_nodes: u64,
}

impl CliqueSolution {
    pub(crate) fn new(graph: &ConsistencyGraph, mut vertices: Vec<u32>) -> Self {
        vertices.sort_unstable();
        Self {
            objective: graph.uniform_objective(&vertices),
            vertices,
            ..Self::default()
        }
    }
}

/// Finds a dense (heavy, large) clique: the association set a CLIPPER-style solver selects.
///
/// 1. Core numbers; a greedy clique by degeneracy order (lower bound); upper bound
///    max core + 1. If they meet, the greedy clique is certified maximum and returned.
/// 2. Otherwise a greedy colouring of the greedy size's core (the only place a larger clique
///    can be) tightens the upper bound and may certify. Failing that, vertices with core
///    number + 1 below the greedy size are pruned.
/// 3. On each connected component of the pruned graph that could hold a clique at least as
///    large as the greedy one, the relaxation runs from a seeded random start; its support
///    is verified as a clique (repaired greedily if the outer loop ran out) and extended to a
///    maximal clique.
/// 4. The candidate (greedy or relaxation) with the largest objective wins (ties: larger,
///    then lexicographically smaller).
/// 5. Polish (see [`DensestCliqueConfig::polish`]): swaps of one or two members that make
///    the clique larger or heavier.
///
/// ```
/// use segloc_clipper::{densest_clique, ConsistencyGraph, DensestCliqueConfig};
/// // a 4-clique {0,1,2,3} and a triangle {3,4,5}
/// let mut e = vec![(3, 4, 1.0), (4, 5, 1.0), (3, 5, 1.0)];
/// for u in 0..4 { for v in u + 1..4 { e.push((u, v, 1.0)); } }
/// let g = ConsistencyGraph::from_edges(6, &e).unwrap();
/// let s = densest_clique(&g, &DensestCliqueConfig::default());
/// assert_eq!(s.vertices, vec![0, 1, 2, 3]);
/// assert!(s.certified_maximum);
/// ```
pub fn densest_clique(graph: &ConsistencyGraph, config: &DensestCliqueConfig) -> CliqueSolution {
    let n = graph.num_vertices();
    if n == 0 {
        return CliqueSolution {
            certified_maximum: true,
            ..CliqueSolution::default()
        };
    }
    if !config.prune_by_core {
        let cd = core_decomposition(graph);
        let ub_core = cd.core.iter().copied().max().unwrap_or(0) as usize + 1;
        let out = relax(graph, config, config.seed);
        let clique = extend_to_maximal(graph, &support_clique(graph, &out.u));
        let mut s = CliqueSolution::new(graph, clique);
        s.upper_bound = ub_core;
        s.certified_maximum = s.vertices.len() == ub_core;
        s.outer_iterations = out.outer_iterations;
        s.inner_iterations = out.inner_iterations;
        return polish(graph, s, config);
    }

    let front = greedy_front(graph, config.max_greedy_starts);
    let lb = front.clique.len();
    let mut best = CliqueSolution::new(graph, front.clique);
    if front.certified {
        best.upper_bound = lb;
        best.certified_maximum = true;
        return polish(graph, best, config);
    }
    // A larger clique lies in the lb-core: bound it by core number and greedy colouring.
    let (strict, _) = graph.induced_subgraph(&front.larger_core);
    let strict_cd = core_decomposition(&strict);
    let max_core = strict_cd.core.iter().copied().max().unwrap_or(0) as usize;
    let colours = greedy_colouring_bound(&strict, &strict_cd.order);
    best.pruned_vertices = n - strict.num_vertices();
    if colours <= lb {
        best.upper_bound = lb;
        best.certified_maximum = true;
        return polish(graph, best, config);
    }
    let ub = (max_core + 1).min(colours);
    best.upper_bound = ub;
    drop(strict);
    // Vertices that can lie in a clique of size >= lb: the (lb - 1)-core.
    let keep = k_core(graph, lb.saturating_sub(1));
    let (sub, old_of_new) = graph.induced_subgraph(&keep);
    best.pruned_vertices = n - sub.num_vertices();
    let sub_cd = core_decomposition(&sub);

    let (mut outer, mut inner) = (0, 0);
    let mut scratch = vec![u32::MAX; sub.num_vertices()];
    for (index, comp) in components(&sub).into_iter().enumerate() {
        let comp_max_core = comp
            .iter()
            .map(|&v| sub_cd.core[v as usize] as usize)
            .max()
            .unwrap_or(0);
        if comp.len() < lb || comp_max_core + 1 < lb {
            continue;
        }
        let cg = sub.subgraph_on(&comp, &mut scratch);
        let c_to_sub = &comp;
        let seed = config.seed ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let out = relax(&cg, config, seed);
        outer += out.outer_iterations;
        inner += out.inner_iterations;
        let local = support_clique(&cg, &out.u);
        let mapped: Vec<u32> = local
            .iter()
            .map(|&v| old_of_new[c_to_sub[v as usize] as usize])
            .collect();
        let candidate = CliqueSolution::new(graph, extend_to_maximal(graph, &mapped));
        if better(&candidate, &best) {
            best.vertices = candidate.vertices;
            best.objective = candidate.objective;
        }
    }
    best.outer_iterations = outer;
    best.inner_iterations = inner;
    best.certified_maximum = best.vertices.len() >= ub;
    polish(graph, best, config)
}

/// Swap polish (see [`crate::polish`]) of the solution's clique when enabled; the size never
/// drops, so certification stays valid.
pub(crate) fn polish(
    graph: &ConsistencyGraph,
    mut best: CliqueSolution,
    config: &DensestCliqueConfig,
) -> CliqueSolution {
    if !config.polish {
        return best;
    }
    let Some(polished) = polish_swaps(graph, &best.vertices, config.max_polish_swaps) else {
        return best;
    };
    let candidate = CliqueSolution::new(graph, polished);
    if candidate.vertices.len() > best.vertices.len()
        || (candidate.vertices.len() == best.vertices.len() && candidate.objective > best.objective)
    {
        best.vertices = candidate.vertices;
        best.objective = candidate.objective;
        best.certified_maximum &= best.vertices.len() <= best.upper_bound;
    }
    best
}

/// Candidate ordering: larger objective, then more vertices, then lexicographically smaller.
fn better(a: &CliqueSolution, b: &CliqueSolution) -> bool {
    a.objective > b.objective
        || (a.objective == b.objective
            && (a.vertices.len() > b.vertices.len()
                || (a.vertices.len() == b.vertices.len() && a.vertices < b.vertices)))
}

/// The support of `u` as a clique: the support itself when it is one (the converged case);
/// otherwise members are taken by decreasing `u` (ties: lower index) and kept when adjacent
/// to all kept so far.
fn support_clique(graph: &ConsistencyGraph, u: &[f64]) -> Vec<u32> {
    let mut support: Vec<u32> = (0..u.len() as u32)
        .filter(|&i| u[i as usize] > 0.0)
        .collect();
    if graph.is_clique(&support) {
        return support;
    }
    support.sort_by(|&a, &b| u[b as usize].total_cmp(&u[a as usize]).then(a.cmp(&b)));
    let mut clique: Vec<u32> = Vec::new();
    for &v in &support {
        if clique
            .iter()
            .all(|&c| graph.has_edge(c as usize, v as usize))
        {
            clique.push(v);
        }
    }
    clique.sort_unstable();
    clique
}

/// Connected components (each sorted), in order of their smallest vertex.
fn components(graph: &ConsistencyGraph) -> Vec<Vec<u32>> {
    let n = graph.num_vertices();
    let mut seen = vec![false; n];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for s in 0..n {
        if seen[s] {
            continue;
        }
        seen[s] = true;
        stack.push(s as u32);
        let mut comp = Vec::new();
        while let Some(v) = stack.pop() {
            comp.push(v);
            for &u in graph.neighbors(v as usize) {
                if !seen[u as usize] {
                    seen[u as usize] = true;
                    stack.push(u);
                }
            }
        }
        comp.sort_unstable();
        out.push(comp);
    }
    out
}

#[cfg(test)]
mod tests;
