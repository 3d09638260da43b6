//! The graph-theoretic front of both clique solvers: a greedy clique (lower bound) and
//! k-core peeling that proves it maximum or prunes what cannot beat it.
//!
//! The greedy clique grows from high-degree start vertices, taking candidates by their degree
//! inside the start's neighbourhood. After every improvement to a clique of size `s`, the
//! graph is peeled to its `s`-core, the only vertices that can lie in a clique of size
//! `s + 1`; when that core is empty the clique is certified maximum. Peeling only touches the
//! rows of removed vertices, which is much cheaper than a full core decomposition on graphs
//! where almost everything is removed.

use crate::greedy::extend_to_maximal;
use crate::ConsistencyGraph;

/// Outcome of [`greedy_front`].
pub(crate) struct Front {
    /// A maximal clique, sorted.
    pub clique: Vec<u32>,
    /// True when no clique larger than `clique` exists (its `|clique|`-core is empty).
    pub certified: bool,
    /// Membership mask of the `|clique|`-core: the only vertices that can lie in a larger
    /// clique (all false when certified).
    pub larger_core: Vec<bool>,
}

/// Peeling state: which vertices survive and their degrees among survivors.
pub(crate) struct Peel {
    pub alive: Vec<bool>,
    deg: Vec<u32>,
    alive_count: usize,
    stack: Vec<u32>,
}

impl Peel {
    pub fn new(graph: &ConsistencyGraph) -> Self {
        let n = graph.num_vertices();
        Self {
            alive: vec![true; n],
            deg: (0..n).map(|v| graph.degree(v) as u32).collect(),
            alive_count: n,
            stack: Vec::new(),
        }
    }

    /// Number of surviving vertices.
    pub fn alive_count(&self) -> usize {
        self.alive_count
    }

    /// Removes vertices until every survivor has at least `k` surviving neighbours: the
    /// survivors are the `k`-core (of the current survivors).
    pub fn peel(&mut self, graph: &ConsistencyGraph, k: usize) {
        // A non-empty k-core has more than k vertices of degree >= k: when there are not
        // that many candidates, it is empty and nothing needs peeling.
        let candidates = self
            .alive
            .iter()
            .zip(&self.deg)
            .filter(|&(&a, &d)| a && d as usize >= k)
            .count();
        if candidates <= k {
            self.alive.fill(false);
            self.alive_count = 0;
            return;
        }
        let k = k as u32;
        self.stack.clear();
        let mut removed_work = 0usize;
        for v in 0..self.alive.len() {
            if self.alive[v] && self.deg[v] < k {
                self.alive[v] = false;
                self.stack.push(v as u32);
                removed_work += graph.degree(v);
            }
        }
        // When the survivors' rows are shorter than the removed ones, recount the survivors'
        // degrees instead of decrementing through the removed rows.
        let survivors = self.alive_count - self.stack.len();
        let survivor_work: usize = (0..self.alive.len())
            .filter(|&v| self.alive[v])
            .map(|v| graph.degree(v))
            .sum();
        if survivor_work < removed_work {
            self.alive_count = survivors;
            self.stack.clear();
            for v in 0..self.alive.len() {
                if self.alive[v] {
                    self.deg[v] = graph
                        .neighbors(v)
                        .iter()
                        .filter(|&&u| self.alive[u as usize])
                        .count() as u32;
                }
            }
            for v in 0..self.alive.len() {
                if self.alive[v] && self.deg[v] < k {
                    self.alive[v] = false;
                    self.stack.push(v as u32);
                }
            }
            // the rows of vertices removed now are decremented below as usual; deg of the
            // vertices removed in the first batch is no longer needed
        }
        while let Some(v) = self.stack.pop() {
            self.alive_count -= 1;
            for &u in graph.neighbors(v as usize) {
                let u = u as usize;
                if self.alive[u] {
                    self.deg[u] -= 1;
                    if self.deg[u] < k {
                        self.alive[u] = false;
                        self.stack.push(u as u32);
                    }
                }
            }
        }
    }
}

/// The `k`-core of `graph` as a membership mask.
pub(crate) fn k_core(graph: &ConsistencyGraph, k: usize) -> Vec<bool> {
    let mut p = Peel::new(graph);
    p.peel(graph, k);
    p.alive
}

/// Greedy clique plus certification by peeling (see the module docs). Tries at most
/// `max_starts` start vertices (0: no limit) and stops early once its work exceeds about one
/// pass over the graph.
pub(crate) fn greedy_front(graph: &ConsistencyGraph, max_starts: usize) -> Front {
    let n = graph.num_vertices();
    if n == 0 {
        return Front {
            clique: Vec::new(),
            certified: true,
            larger_core: Vec::new(),
        };
    }
    let mut starts: Vec<u32> = (0..n as u32).collect();
    starts.sort_unstable_by(|&a, &b| {
        graph
            .degree(b as usize)
            .cmp(&graph.degree(a as usize))
            .then(a.cmp(&b))
    });
    let budget = (graph.all_neighbors().len() + n) as u64;
    let mut spent = 0u64;
    let mut peel = Peel::new(graph);
    let mut best: Vec<u32> = Vec::new();
    let mut grower = Grower::new(n);
    for (tried, &v) in starts.iter().enumerate() {
        if graph.degree(v as usize) < best.len() {
            break; // no larger clique through v or any later start
        }
        if (max_starts > 0 && tried >= max_starts) || (spent > budget && !best.is_empty()) {
            break;
        }
        if !peel.alive[v as usize] {
            continue;
        }
        let clique = grower.grow(graph, v, &peel.alive, best.len(), &mut spent);
        if clique.len() > best.len() {
            // A grown clique that beats the best is maximal: `grow` passed over every
            // candidate, and the candidates it dropped cannot lie in a clique this large.
            best = clique;
            best.sort_unstable();
            peel.peel(graph, best.len());
            if peel.alive_count() == 0 {
                return Front {
                    clique: best,
                    certified: true,
                    larger_core: peel.alive,
                };
            }
        }
    }
    if best.is_empty() {
        best = extend_to_maximal(graph, &[]);
    }
    // the loop may have stopped before peeling for the final size
    peel.peel(graph, best.len());
    let certified = peel.alive_count() == 0;
    Front {
        clique: best,
        certified,
        larger_core: peel.alive,
    }
}

/// Scratch space for growing cliques from start vertices.
struct Grower {
    stamp: Vec<u32>,
    current: u32,
    pdeg: Vec<u32>,
    count: Vec<u32>,
    cand: Vec<u32>,
}

impl Grower {
    fn new(n: usize) -> Self {
        Self {
            stamp: vec![0; n],
            current: 0,
            pdeg: vec![0; n],
            count: vec![0; n],
            cand: Vec::new(),
        }
    }

    /// Greedy clique through `v` among alive neighbours, candidates ordered by their degree
    /// inside the candidate set. Returns an empty clique when it cannot beat `best_len`.
    fn grow(
        &mut self,
        graph: &ConsistencyGraph,
        v: u32,
        alive: &[bool],
        best_len: usize,
        spent: &mut u64,
    ) -> Vec<u32> {
        self.current = self.current.wrapping_add(1);
        if self.current == 0 {
            self.stamp.fill(0);
            self.current = 1;
        }
        let cur = self.current;
        self.cand.clear();
        self.cand.extend(
            graph
                .neighbors(v as usize)
                .iter()
                .copied()
                .filter(|&u| alive[u as usize]),
        );
        if self.cand.len() < best_len {
            return Vec::new();
        }
        for &u in &self.cand {
            self.stamp[u as usize] = cur;
        }
        for &u in &self.cand {
            let row = graph.neighbors(u as usize);
            *spent += row.len() as u64;
            self.pdeg[u as usize] = row
                .iter()
                .map(|&w| u32::from(self.stamp[w as usize] == cur))
                .sum();
            self.count[u as usize] = 0;
        }
        // u can only be in a clique {v, u, ...} of size pdeg(u) + 2
        let pdeg = &self.pdeg;
        self.cand
            .retain(|&u| pdeg[u as usize] as usize + 2 > best_len);
        self.cand.sort_unstable_by(|&a, &b| {
            pdeg[b as usize]
                .cmp(&pdeg[a as usize])
                .then(graph.degree(b as usize).cmp(&graph.degree(a as usize)))
                .then(a.cmp(&b))
        });
        let mut clique = vec![v];
        for (idx, &u) in self.cand.iter().enumerate() {
            if clique.len() + (self.cand.len() - idx) <= best_len {
                break;
            }
            if self.count[u as usize] as usize == clique.len() - 1 {
                clique.push(u);
                let row = graph.neighbors(u as usize);
                *spent += row.len() as u64;
                for &w in row {
                    // branch-free; counts of vertices outside the candidate set are unused
                    self.count[w as usize] += u32::from(self.stamp[w as usize] == cur);
                }
            }
        }
        clique
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::core_numbers;
    use crate::rng::SplitMix64;

    #[test]
    fn peel_matches_core_numbers() {
        let mut rng = SplitMix64::new(8);
        let mut e = Vec::new();
        for u in 0..60u32 {
            for v in u + 1..60 {
                if rng.next_open01() < 0.2 {
                    e.push((u, v, 1.0));
                }
            }
        }
        let g = ConsistencyGraph::from_edges(60, &e).unwrap();
        let core = core_numbers(&g);
        for k in 0..15 {
            let alive = k_core(&g, k);
            for v in 0..60 {
                assert_eq!(alive[v], core[v] as usize >= k);
            }
        }
    }

    #[test]
    fn certifies_planted_clique() {
        // clique {0..6} plus a path through the rest
        let mut e = Vec::new();
        for u in 0..7u32 {
            for v in u + 1..7 {
                e.push((u, v, 1.0));
            }
        }
        for u in 6..15u32 {
            e.push((u, u + 1, 1.0));
        }
        let g = ConsistencyGraph::from_edges(16, &e).unwrap();
        let f = greedy_front(&g, 0);
        assert_eq!(f.clique, (0..7).collect::<Vec<_>>());
        assert!(f.certified);
    }

    #[test]
    fn not_certified_when_cores_exceed_clique() {
        // 5-cycle: clique number 2, every vertex has core 2
        let e: Vec<_> = (0..5u32).map(|u| (u, (u + 1) % 5, 1.0)).collect();
        let g = ConsistencyGraph::from_edges(5, &e).unwrap();
        let f = greedy_front(&g, 0);
        assert_eq!(f.clique.len(), 2);
        assert!(!f.certified);
        let empty = ConsistencyGraph::from_edges(3, &[]).unwrap();
        let f = greedy_front(&empty, 0);
        assert_eq!(f.clique.len(), 1);
        assert!(f.certified);
    }
}
