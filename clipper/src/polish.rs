//! Local search among cliques of (at least) the same size: swaps that trade one or two
//! members for outside vertices.
//!
//! A maximum clique is often not unique: when two prior points lie close together, the two
//! "crossed" associations are consistent with nearly everything, and a clique can hold them
//! instead of the two right ones. Those alternatives differ by swapping one or two members,
//! and the right one is heavier (its residuals are smaller). Moves, in order of preference:
//! - (1, 2): drop one member, add two adjacent vertices that miss only it (size grows);
//! - (1, 1) and (2, 2): drop one or two members, add as many outside vertices that miss
//!   exactly those, when the total edge weight grows.

use std::collections::BTreeMap;

use crate::greedy::extend_to_maximal;
use crate::ConsistencyGraph;

/// Smallest weight gain that counts as an improvement.
const MIN_GAIN: f64 = 1e-9;
/// Largest group of outside vertices examined pairwise for one missing set.
const MAX_GROUP: usize = 64;

/// Improves `clique` by swaps until none helps or `max_rounds` swaps were made; returns the
/// improved maximal clique (sorted), or `None` when no swap helped.
pub(crate) fn polish_swaps(
    graph: &ConsistencyGraph,
    clique: &[u32],
    max_rounds: usize,
) -> Option<Vec<u32>> {
    let n = graph.num_vertices();
    let mut members: Vec<u32> = clique.to_vec();
    members.sort_unstable();
    if members.len() < 2 || n == 0 {
        return None;
    }
    let mut swapped = false;
    let mut scratch = Scratch::new(n);
    for _ in 0..max_rounds {
        let missing = scratch.missing_sets(graph, &members);
        let best = best_swap(graph, &scratch.wsum, &missing);
        scratch.reset(&members);
        let Some(Swap { removed, added, .. }) = best else {
            break;
        };
        members.retain(|c| !removed.contains(c));
        members.extend(added);
        members.sort_unstable();
        swapped = true;
    }
    swapped.then(|| extend_to_maximal(graph, &members))
}

/// Outside vertices adjacent to all members but one (`one`, by the missing member) or two
/// (`two`, by the missing pair).
struct MissingSets {
    one: BTreeMap<u32, Vec<u32>>,
    two: BTreeMap<(u32, u32), Vec<u32>>,
}

/// Per-vertex counters of one round, all zero (false) between rounds.
struct Scratch {
    is_member: Vec<bool>,
    /// Members adjacent to each vertex.
    count: Vec<u32>,
    /// Edge weight from each vertex to the members.
    wsum: Vec<f64>,
    mark: Vec<bool>,
    /// Vertices with a non-zero count.
    touched: Vec<u32>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Scratch {
            is_member: vec![false; n],
            count: vec![0u32; n],
            wsum: vec![0f64; n],
            mark: vec![false; n],
            touched: Vec::new(),
        }
    }

    /// Counts each vertex's member neighbours (and their weight), and groups the outside
    /// vertices missing one or two members by the missing set.
    fn missing_sets(&mut self, graph: &ConsistencyGraph, members: &[u32]) -> MissingSets {
        let k = members.len() as u32;
        for &c in members {
            self.is_member[c as usize] = true;
        }
        self.touched.clear();
        for &c in members {
            for (&x, &w) in graph
                .neighbors(c as usize)
                .iter()
                .zip(graph.weights(c as usize))
            {
                if self.count[x as usize] == 0 {
                    self.touched.push(x);
                }
                self.count[x as usize] += 1;
                self.wsum[x as usize] += w as f64;
            }
        }
        self.touched.sort_unstable();
        let mut sets = MissingSets {
            one: BTreeMap::new(),
            two: BTreeMap::new(),
        };
        for &x in &self.touched {
            let cx = self.count[x as usize];
            if self.is_member[x as usize] || cx + 2 < k {
                continue;
            }
            for &y in graph.neighbors(x as usize) {
                self.mark[y as usize] = true;
            }
            let missing: Vec<u32> = members
                .iter()
                .copied()
                .filter(|&c| !self.mark[c as usize])
                .take(3)
                .collect();
            for &y in graph.neighbors(x as usize) {
                self.mark[y as usize] = false;
            }
            match missing.as_slice() {
                [y] => sets.one.entry(*y).or_default().push(x),
                [y1, y2] => sets.two.entry((*y1, *y2)).or_default().push(x),
                _ => {} // adjacent to all (clique not maximal: extension handles it)
            }
        }
        sets
    }

    /// Zeroes the counters of this round.
    fn reset(&mut self, members: &[u32]) {
        for &x in &self.touched {
            self.count[x as usize] = 0;
            self.wsum[x as usize] = 0.0;
        }
        for &c in members {
            self.is_member[c as usize] = false;
        }
    }
}

/// A move: members `removed`, outside vertices `added`.
struct Swap {
    size_gain: usize,
    weight_gain: f64,
    removed: Vec<u32>,
    added: Vec<u32>,
}

/// The best move (largest size gain, then weight gain), if any improves the clique;
/// `wsum` is each vertex's edge weight to the members.
fn best_swap(graph: &ConsistencyGraph, wsum: &[f64], missing: &MissingSets) -> Option<Swap> {
    let w_of = |a: u32, b: u32| graph.edge_weight(a as usize, b as usize).map(f64::from);
    let mut best: Option<Swap> = None;
    let mut consider = |size_gain: usize, gain: f64, removed: Vec<u32>, added: Vec<u32>| {
        let better = match &best {
            None => size_gain > 0 || gain > MIN_GAIN,
            Some(b) => {
                size_gain > b.size_gain || (size_gain == b.size_gain && gain > b.weight_gain)
            }
        };
        if better {
            best = Some(Swap {
                size_gain,
                weight_gain: gain,
                removed,
                added,
            });
        }
    };
    for (&y, xs) in &missing.one {
        let wy = wsum[y as usize];
        for &x in xs {
            consider(0, wsum[x as usize] - wy, vec![y], vec![x]);
        }
        let xs = &xs[..xs.len().min(MAX_GROUP)];
        for (a, &x1) in xs.iter().enumerate() {
            for &x2 in &xs[a + 1..] {
                if let Some(w12) = w_of(x1, x2) {
                    let gain = wsum[x1 as usize] + wsum[x2 as usize] + w12 - wy;
                    consider(1, gain, vec![y], vec![x1, x2]);
                }
            }
        }
    }
    for (&(y1, y2), xs) in &missing.two {
        let w_removed = wsum[y1 as usize] + wsum[y2 as usize] - w_of(y1, y2).unwrap_or(0.0);
        let xs = &xs[..xs.len().min(MAX_GROUP)];
        for (a, &x1) in xs.iter().enumerate() {
            for &x2 in &xs[a + 1..] {
                if let Some(w12) = w_of(x1, x2) {
                    let gain = wsum[x1 as usize] + wsum[x2 as usize] + w12 - w_removed;
                    consider(0, gain, vec![y1, y2], vec![x1, x2]);
                }
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clique_edges(vs: &[u32], w: f64) -> Vec<(u32, u32, f64)> {
        let mut e = Vec::new();
        for (a, &u) in vs.iter().enumerate() {
            for &v in &vs[a + 1..] {
                e.push((u, v, w));
            }
        }
        e
    }

    #[test]
    fn one_for_one_swap_by_weight() {
        let mut e = clique_edges(&[0, 1, 2, 3, 4], 0.8);
        for b in 0..4 {
            e.push((b, 5, 0.95)); // 5 misses only 4, heavier than 4
        }
        let g = ConsistencyGraph::from_edges(6, &e).unwrap();
        assert_eq!(
            polish_swaps(&g, &[0, 1, 2, 3, 4], 8),
            Some(vec![0, 1, 2, 3, 5])
        );
    }

    #[test]
    fn two_for_two_swap_by_weight() {
        // members 4, 5 are light; outside 6, 7 miss exactly {4, 5} and are heavy
        let mut e = clique_edges(&[0, 1, 2, 3], 0.8);
        for b in 0..4 {
            e.extend([(b, 4, 0.3), (b, 5, 0.3), (b, 6, 0.9), (b, 7, 0.9)]);
        }
        e.extend([(4, 5, 0.3), (6, 7, 0.9)]);
        let g = ConsistencyGraph::from_edges(8, &e).unwrap();
        assert_eq!(
            polish_swaps(&g, &[0, 1, 2, 3, 4, 5], 8),
            Some(vec![0, 1, 2, 3, 6, 7])
        );
    }

    #[test]
    fn one_for_two_swap_grows_the_clique() {
        // clique {0,1,2,3}; 4 and 5 are adjacent, miss only 3
        let mut e = clique_edges(&[0, 1, 2, 3], 1.0);
        for b in 0..3 {
            e.extend([(b, 4, 0.5), (b, 5, 0.5)]);
        }
        e.push((4, 5, 0.5));
        let g = ConsistencyGraph::from_edges(6, &e).unwrap();
        assert_eq!(
            polish_swaps(&g, &[0, 1, 2, 3], 8),
            Some(vec![0, 1, 2, 4, 5])
        );
    }

    #[test]
    fn keeps_a_clique_without_better_moves() {
        let e = clique_edges(&[0, 1, 2], 1.0);
        let g = ConsistencyGraph::from_edges(4, &e).unwrap();
        assert_eq!(polish_swaps(&g, &[0, 1, 2], 8), None);
    }
}
