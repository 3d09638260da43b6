//! Edge-seeded clique search: finds a large clique that the relaxation can miss.
//!
//! In a dense consistency graph (the 6-DOF distance invariant between maps of a few
//! hundred boulders: ~10⁴ associations, ~10⁶ edges) coincidental cliques of 7–8 abound and
//! the relaxation can settle on one, while the true clique of 15 goes unseen; the graph
//! is too dense for core pruning to shrink it to a size an exact search can certify.
//!
//! Every edge inside the true clique, though, leads straight to it: the common neighbours
//! of its two ends are the rest of the clique and hardly anything else, while the common
//! neighbourhood of a coincidental edge is small and loose. So the search samples edges
//! (seeded, reproducible), grows a clique greedily inside each edge's common
//! neighbourhood (always adding the candidate adjacent to most other candidates), and
//! keeps the largest. With k clique members among E edges, s samples miss every one of
//! the k(k−1)/2 clique edges with probability (1 − k(k−1)/2E)^s.

use crate::ConsistencyGraph;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Sampling parameters of [`edge_seeded_clique`].
#[derive(Clone, Copy, Debug)]
pub struct SeededSearch {
    /// Most edges sampled.
    pub max_samples: usize,
    /// Probability of missing a larger clique that the stopping rule accepts.
    pub miss_probability: f64,
    /// Seed of the sampling.
    pub seed: u64,
    /// Cliques smaller than this are of no interest; the stopping rule aims at finding any
    /// clique of at least this size.
    pub min_size: usize,
}

/// The largest clique found from random edges (sorted vertex indices), or an empty vector
/// for a graph without edges.
///
/// Edges are drawn uniformly (a uniform slot of the adjacency). The search stops once so
/// many edges have been drawn since the last improvement that a clique one larger than
/// the best, if there were one, would have been hit with probability
/// `1 − miss_probability`: with k the best size and E edges, after
/// ln(1/δ) · E / (k(k+1)/2) fruitless draws.
pub fn edge_seeded_clique(graph: &ConsistencyGraph, search: &SeededSearch) -> Vec<u32> {
    edge_seeded_cliques(graph, search, 1)
        .pop()
        .unwrap_or_default()
}

/// Up to `count` large, pairwise vertex-disjoint cliques (each sorted), largest first, from
/// one sampling pass: the rivals of a hypothesis. The stopping rule watches the smallest
/// clique kept once `count` are kept.
pub fn edge_seeded_cliques(
    graph: &ConsistencyGraph,
    search: &SeededSearch,
    count: usize,
) -> Vec<Vec<u32>> {
    let offsets = graph.offsets();
    let ends = graph.all_neighbors();
    let n = graph.num_vertices();
    let count = count.max(1);
    if ends.is_empty() || n == 0 {
        return Vec::new();
    }
    // Row of every edge slot, so that a uniform slot gives a uniform edge.
    let mut row_of_slot = vec![0u32; ends.len()];
    for u in 0..n {
        row_of_slot[offsets[u]..offsets[u + 1]].fill(u as u32);
    }
    let edges = ends.len() as f64 / 2.0;
    let log_miss = (1.0 / search.miss_probability.clamp(1e-12, 0.5)).ln();
    let mut rng = ChaCha8Rng::seed_from_u64(search.seed);
    let mut kept: Vec<Vec<u32>> = Vec::new();
    let mut common = Vec::new();
    let mut stamp = vec![0u32; n];
    let mut epoch = 0u32;
    let mut since_improvement = 0usize;
    for _ in 0..search.max_samples {
        let floor = if kept.len() < count {
            search.min_size
        } else {
            kept.last().map_or(2, |c| c.len()).max(search.min_size)
        };
        let k = floor.max(2) as f64;
        if since_improvement as f64 > log_miss * edges / (k * (k + 1.0) / 2.0) {
            break;
        }
        since_improvement += 1;
        let slot = rng.random_range(0..ends.len());
        let (u, v) = (row_of_slot[slot] as usize, ends[slot] as usize);
        // Common neighbours by stamping u's row and scanning v's: branch-light, and the
        // stamps of a few thousand vertices stay in cache.
        epoch = epoch.wrapping_add(1);
        if epoch == 0 {
            stamp.fill(0);
            epoch = 1;
        }
        for &w in graph.neighbors(u) {
            stamp[w as usize] = epoch;
        }
        common.clear();
        common.extend(
            graph
                .neighbors(v)
                .iter()
                .copied()
                .filter(|&w| stamp[w as usize] == epoch),
        );
        // Only a neighbourhood that could beat the smallest kept clique is worth growing.
        if kept.len() == count && common.len() + 2 <= floor {
            continue;
        }
        if common.len() + 2 < search.min_size {
            continue;
        }
        let mut clique = grow(graph, u as u32, v as u32, &common);
        if clique.len() < search.min_size {
            continue;
        }
        clique.sort_unstable();
        if keep_clique(&mut kept, clique, count) {
            since_improvement = 0;
        }
    }
    kept
}

/// Insert `clique` among the kept ones (largest first, pairwise disjoint, at most `count`);
/// returns whether the kept set changed.
fn keep_clique(kept: &mut Vec<Vec<u32>>, clique: Vec<u32>, count: usize) -> bool {
    let overlaps = |other: &Vec<u32>| {
        let mut common = Vec::new();
        intersect(other, &clique, &mut common);
        !common.is_empty()
    };
    if kept.iter().any(|c| overlaps(c) && c.len() >= clique.len()) {
        return false;
    }
    if kept.len() == count && kept.last().is_some_and(|c| c.len() >= clique.len()) {
        return false;
    }
    kept.retain(|c| !overlaps(c));
    let at = kept.partition_point(|c| c.len() >= clique.len());
    kept.insert(at, clique);
    kept.truncate(count);
    true
}

/// Greedy clique from edge (u, v) inside their common neighbours `candidates`.
fn grow(graph: &ConsistencyGraph, u: u32, v: u32, candidates: &[u32]) -> Vec<u32> {
    let mut clique = vec![u, v];
    let mut candidates = candidates.to_vec();
    let mut scratch = Vec::new();
    while !candidates.is_empty() {
        let (pick, _) = candidates
            .iter()
            .map(|&w| {
                intersect(graph.neighbors(w as usize), &candidates, &mut scratch);
                (w, scratch.len())
            })
            .max_by_key(|&(w, count)| (count, std::cmp::Reverse(w)))
            .unwrap_or((candidates[0], 0));
        clique.push(pick);
        intersect(
            graph.neighbors(pick as usize),
            &candidates.clone(),
            &mut candidates,
        );
    }
    clique
}

/// `out` = the sorted intersection of two sorted slices.
fn intersect(a: &[u32], b: &[u32], out: &mut Vec<u32>) {
    out.clear();
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                out.push(a[i]);
                i += 1;
                j += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_planted_clique_in_a_noisy_graph() {
        let n = 400u32;
        let mut edges = Vec::new();
        let mut s = 12345u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        for u in 0..n {
            for v in (u + 1)..n {
                if next() % 20 == 0 {
                    edges.push((u, v, 1.0));
                }
            }
        }
        let planted: Vec<u32> = (0..12).map(|k| 7 + 31 * k).collect();
        for (a, &u) in planted.iter().enumerate() {
            for &v in &planted[a + 1..] {
                edges.push((u, v, 1.0));
            }
        }
        edges.sort_by_key(|e| (e.0, e.1));
        edges.dedup_by_key(|e| (e.0, e.1));
        let graph = ConsistencyGraph::from_edges(n as usize, &edges).unwrap();
        let search = SeededSearch {
            max_samples: 20_000,
            miss_probability: 1e-3,
            seed: 1,
            min_size: 2,
        };
        let found = edge_seeded_clique(&graph, &search);
        assert!(graph.is_clique(&found));
        let several = edge_seeded_cliques(&graph, &search, 3);
        assert_eq!(several[0], found);
        for (a, c) in several.iter().enumerate() {
            assert!(graph.is_clique(c));
            for d in &several[a + 1..] {
                assert!(c.iter().all(|v| !d.contains(v)), "rivals share a vertex");
                assert!(c.len() >= d.len());
            }
        }
        let mut expected = planted.clone();
        expected.sort_unstable();
        assert_eq!(found, expected);
    }
}
