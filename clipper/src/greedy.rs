//! Greedy clique extension and the greedy-colouring upper bound.

use crate::ConsistencyGraph;

/// Greedily extends a clique to a maximal one: repeatedly adds the vertex adjacent to all
/// members with the largest total edge weight to them (ties: lower index). An empty input
/// starts from the vertex of largest degree (lowest index among ties); an empty graph gives
/// an empty clique. Returns the clique sorted.
pub(crate) fn extend_to_maximal(graph: &ConsistencyGraph, clique: &[u32]) -> Vec<u32> {
    let n = graph.num_vertices();
    if n == 0 {
        return Vec::new();
    }
    let mut members: Vec<u32> = clique.to_vec();
    if members.is_empty() {
        let best = (0..n).max_by(|&a, &b| graph.degree(a).cmp(&graph.degree(b)).then(b.cmp(&a)));
        members.push(best.unwrap_or(0) as u32);
    }
    let mut count = vec![0u32; n];
    let mut wsum = vec![0f64; n];
    let mut in_clique = vec![false; n];
    for &c in &members {
        in_clique[c as usize] = true;
    }
    let add = |c: usize, count: &mut [u32], wsum: &mut [f64]| {
        for (&x, &w) in graph.neighbors(c).iter().zip(graph.weights(c)) {
            count[x as usize] += 1;
            wsum[x as usize] += w as f64;
        }
    };
    for &c in &members {
        add(c as usize, &mut count, &mut wsum);
    }
    let k = members.len() as u32;
    let mut cands: Vec<u32> = graph
        .neighbors(members[0] as usize)
        .iter()
        .copied()
        .filter(|&x| count[x as usize] == k && !in_clique[x as usize])
        .collect();
    while !cands.is_empty() {
        let mut best = cands[0];
        for &x in &cands[1..] {
            let (wx, wb) = (wsum[x as usize], wsum[best as usize]);
            if wx > wb || (wx == wb && x < best) {
                best = x;
            }
        }
        members.push(best);
        in_clique[best as usize] = true;
        add(best as usize, &mut count, &mut wsum);
        let k = members.len() as u32;
        cands.retain(|&x| count[x as usize] == k && !in_clique[x as usize]);
    }
    members.sort_unstable();
    members
}

/// Number of colours of a greedy colouring that visits vertices in `order` reversed
/// (largest core first; for the degeneracy order this uses at most max core + 1 colours).
/// Every clique needs distinct colours, so this bounds the clique number.
pub(crate) fn greedy_colouring_bound(graph: &ConsistencyGraph, order: &[u32]) -> usize {
    let n = graph.num_vertices();
    let mut colour = vec![u32::MAX; n];
    let mut used_stamp: Vec<u32> = Vec::new();
    let mut n_colours = 0usize;
    for (step, &v) in order.iter().rev().enumerate() {
        let stamp = step as u32 + 1;
        for &u in graph.neighbors(v as usize) {
            let c = colour[u as usize];
            if c != u32::MAX {
                used_stamp[c as usize] = stamp;
            }
        }
        let c = used_stamp
            .iter()
            .position(|&s| s != stamp)
            .unwrap_or(used_stamp.len());
        if c == used_stamp.len() {
            used_stamp.push(0);
            n_colours += 1;
        }
        colour[v as usize] = c as u32;
    }
    n_colours
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::core_decomposition;

    fn graph(n: usize, edges: &[(u32, u32)]) -> ConsistencyGraph {
        let e: Vec<_> = edges.iter().map(|&(u, v)| (u, v, 1.0)).collect();
        ConsistencyGraph::from_edges(n, &e).unwrap()
    }

    fn clique_edges(vs: &[u32]) -> Vec<(u32, u32)> {
        let mut e = Vec::new();
        for (a, &u) in vs.iter().enumerate() {
            for &v in &vs[a + 1..] {
                e.push((u, v));
            }
        }
        e
    }

    #[test]
    fn colouring_bounds_planted_clique() {
        let mut e = clique_edges(&[1, 4, 6, 8, 9]);
        e.extend([(0, 1), (2, 3), (3, 5), (5, 7), (0, 2), (7, 4)]);
        let g = graph(10, &e);
        let cd = core_decomposition(&g);
        let colours = greedy_colouring_bound(&g, &cd.order);
        assert_eq!(colours, 5);
    }

    #[test]
    fn extension_prefers_heavier_vertex() {
        // 0-1 edge; 2 and 3 both adjacent to 0 and 1 but not to each other; 3 heavier
        let e = [
            (0, 1, 1.0),
            (0, 2, 0.3),
            (1, 2, 0.3),
            (0, 3, 0.9),
            (1, 3, 0.9),
        ];
        let g = ConsistencyGraph::from_edges(4, &e).unwrap();
        assert_eq!(extend_to_maximal(&g, &[0, 1]), vec![0, 1, 3]);
        assert_eq!(extend_to_maximal(&g, &[]).len(), 3);
        let empty = ConsistencyGraph::from_edges(0, &[]).unwrap();
        assert!(extend_to_maximal(&empty, &[]).is_empty());
    }

    #[test]
    fn colouring_bounds_odd_cycle() {
        let g = graph(5, &[(0, 1), (1, 2), (2, 3), (3, 4), (4, 0)]);
        let cd = core_decomposition(&g);
        assert_eq!(greedy_colouring_bound(&g, &cd.order), 3);
    }
}
