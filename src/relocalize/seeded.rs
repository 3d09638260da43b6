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

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use segloc_clipper::ConsistencyGraph;

/// The largest clique found from `samples` random edges (sorted vertex indices), or an
/// empty vector for a graph without edges.
pub fn edge_seeded_clique(graph: &ConsistencyGraph, samples: usize, seed: u64) -> Vec<u32> {
    let offsets = graph.offsets();
    let ends = graph.all_neighbors();
    if ends.is_empty() {
        return Vec::new();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut best: Vec<u32> = Vec::new();
    let mut common = Vec::new();
    for _ in 0..samples {
        let slot = rng.random_range(0..ends.len());
        // The row holding `slot`: the last offset not above it.
        let u = offsets.partition_point(|&o| o <= slot) - 1;
        let v = ends[slot] as usize;
        intersect(graph.neighbors(u), graph.neighbors(v), &mut common);
        // Only a neighbourhood that could beat the best clique is worth growing.
        if common.len() + 2 <= best.len() {
            continue;
        }
        let clique = grow(graph, u as u32, v as u32, &common);
        if clique.len() > best.len() {
            best = clique;
        }
    }
    best.sort_unstable();
    best
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
        let found = edge_seeded_clique(&graph, 20_000, 1);
        assert!(graph.is_clique(&found));
        let mut expected = planted.clone();
        expected.sort_unstable();
        assert_eq!(found, expected);
    }
}
