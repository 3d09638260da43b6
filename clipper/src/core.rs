//! Core numbers (k-core decomposition) by the Batagelj–Zaversnik bucket algorithm.

use crate::ConsistencyGraph;

/// Core number of every vertex: the largest `k` such that the vertex belongs to a subgraph
/// in which every vertex has degree at least `k`. A vertex in a clique of size `s` has core
/// number at least `s - 1`. Runs in O(V + E) (Batagelj & Zaversnik 2003).
///
/// ```
/// use segloc_clipper::{core_numbers, ConsistencyGraph};
/// // triangle 0-1-2 with a pendant vertex 3
/// let g = ConsistencyGraph::from_edges(4, &[(0, 1, 1.0), (1, 2, 1.0), (0, 2, 1.0), (2, 3, 1.0)]).unwrap();
/// assert_eq!(core_numbers(&g), vec![2, 2, 2, 1]);
/// ```
pub fn core_numbers(graph: &ConsistencyGraph) -> Vec<u32> {
    core_decomposition(graph).core
}

/// Core numbers together with the degeneracy (removal) order.
pub(crate) struct CoreDecomposition {
    /// Core number of each vertex.
    pub core: Vec<u32>,
    /// Vertices in the order the peeling removed them (non-decreasing core number);
    /// the last vertex lies in the maximum core.
    pub order: Vec<u32>,
}

pub(crate) fn core_decomposition(graph: &ConsistencyGraph) -> CoreDecomposition {
    let n = graph.num_vertices();
    let mut deg: Vec<u32> = (0..n).map(|v| graph.degree(v) as u32).collect();
    let max_deg = deg.iter().copied().max().unwrap_or(0) as usize;
    // bin[d] = start of the block of vertices with current degree d in `vert`.
    let mut bin = vec![0u32; max_deg + 2];
    for &d in &deg {
        bin[d as usize + 1] += 1;
    }
    for d in 0..=max_deg {
        bin[d + 1] += bin[d];
    }
    let mut vert = vec![0u32; n];
    let mut pos = vec![0u32; n];
    {
        let mut next = bin.clone();
        for v in 0..n {
            let d = deg[v] as usize;
            pos[v] = next[d];
            vert[next[d] as usize] = v as u32;
            next[d] += 1;
        }
    }
    for i in 0..n {
        let v = vert[i] as usize;
        let dv = deg[v];
        for &u in graph.neighbors(v) {
            let u = u as usize;
            let du = deg[u];
            if du > dv {
                // move u to the front of its block, shrink the block, lower its degree
                let pu = pos[u];
                let pw = bin[du as usize];
                let w = vert[pw as usize] as usize;
                if u != w {
                    vert[pu as usize] = w as u32;
                    pos[w] = pu;
                    vert[pw as usize] = u as u32;
                    pos[u] = pw;
                }
                bin[du as usize] += 1;
                deg[u] = du - 1;
            }
        }
    }
    CoreDecomposition {
        core: deg,
        order: vert,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// Reference: repeatedly delete vertices of degree < k.
    fn brute_cores(g: &ConsistencyGraph) -> Vec<u32> {
        let n = g.num_vertices();
        let mut core = vec![0u32; n];
        for k in 1..=n as u32 {
            let mut alive = vec![true; n];
            loop {
                let mut changed = false;
                for v in 0..n {
                    if alive[v] {
                        let d = g
                            .neighbors(v)
                            .iter()
                            .filter(|&&u| alive[u as usize])
                            .count() as u32;
                        if d < k {
                            alive[v] = false;
                            changed = true;
                        }
                    }
                }
                if !changed {
                    break;
                }
            }
            for v in 0..n {
                if alive[v] {
                    core[v] = k;
                }
            }
        }
        core
    }

    #[test]
    fn matches_brute_force_on_random_graphs() {
        let mut rng = SplitMix64::new(3);
        for trial in 0..30 {
            let n = 5 + trial;
            let p = 0.1 + 0.02 * trial as f64;
            let mut edges = Vec::new();
            for u in 0..n as u32 {
                for v in u + 1..n as u32 {
                    if rng.next_open01() < p {
                        edges.push((u, v, 1.0));
                    }
                }
            }
            let g = ConsistencyGraph::from_edges(n, &edges).unwrap();
            let cd = core_decomposition(&g);
            assert_eq!(cd.core, brute_cores(&g));
            // removal order has non-decreasing core numbers and is a permutation
            let mut seen = vec![false; n];
            for w in cd.order.windows(2) {
                assert!(cd.core[w[0] as usize] <= cd.core[w[1] as usize]);
            }
            for &v in &cd.order {
                assert!(!seen[v as usize]);
                seen[v as usize] = true;
            }
        }
    }

    #[test]
    fn empty_graph() {
        let g = ConsistencyGraph::from_edges(0, &[]).unwrap();
        assert!(core_numbers(&g).is_empty());
        let g = ConsistencyGraph::from_edges(3, &[]).unwrap();
        assert_eq!(core_numbers(&g), vec![0, 0, 0]);
    }
}
