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
    let mut is_member = vec![false; n];
    let mut count = vec![0u32; n];
    let mut wsum = vec![0f64; n];
    let mut mark = vec![false; n];
    let mut touched: Vec<u32> = Vec::new();
    for _ in 0..max_rounds {
        let k = members.len() as u32;
        for &c in &members {
            is_member[c as usize] = true;
        }
        touched.clear();
        for &c in &members {
            for (&x, &w) in graph
                .neighbors(c as usize)
                .iter()
                .zip(graph.weights(c as usize))
            {
                if count[x as usize] == 0 {
                    touched.push(x);
                }
                count[x as usize] += 1;
                wsum[x as usize] += w as f64;
            }
        }
        touched.sort_unstable();
        // outside vertices missing one or two members, grouped by the missing set
        let mut miss1: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
        let mut miss2: BTreeMap<(u32, u32), Vec<u32>> = BTreeMap::new();
        for &x in &touched {
            let cx = count[x as usize];
            if is_member[x as usize] || cx + 2 < k {
                continue;
            }
            for &y in graph.neighbors(x as usize) {
                mark[y as usize] = true;
            }
            let missing: Vec<u32> = members
                .iter()
                .copied()
                .filter(|&c| !mark[c as usize])
                .take(3)
                .collect();
            for &y in graph.neighbors(x as usize) {
                mark[y as usize] = false;
            }
            match missing.as_slice() {
                [y] => miss1.entry(*y).or_default().push(x),
                [y1, y2] => miss2.entry((*y1, *y2)).or_default().push(x),
                _ => {} // adjacent to all (clique not maximal: extension handles it)
            }
        }
        let w_of = |a: u32, b: u32| graph.edge_weight(a as usize, b as usize).map(f64::from);
        // Best move: (size gain, weight gain, removed, added)
        let mut best: Option<(usize, f64, Vec<u32>, Vec<u32>)> = None;
        let mut consider = |size_gain: usize, gain: f64, rem: Vec<u32>, add: Vec<u32>| {
            let better = match &best {
                None => size_gain > 0 || gain > MIN_GAIN,
                Some((s, g, _, _)) => size_gain > *s || (size_gain == *s && gain > *g),
            };
            if better {
                best = Some((size_gain, gain, rem, add));
            }
        };
        for (&y, xs) in &miss1 {
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
        for (&(y1, y2), xs) in &miss2 {
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
        // reset scratch
        for &x in &touched {
            count[x as usize] = 0;
            wsum[x as usize] = 0.0;
        }
        for &c in &members {
            is_member[c as usize] = false;
        }
        let Some((_, _, removed, added)) = best else {
            break;
        };
        members.retain(|c| !removed.contains(c));
        members.extend(added);
        members.sort_unstable();
        swapped = true;
    }
    swapped.then(|| extend_to_maximal(graph, &members))
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
