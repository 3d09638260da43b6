//! Exact maximum clique: branch and bound with greedy-colouring bounds on bitsets
//! (Tomita's MCQ/MCS with San Segundo's bit-parallel colouring, BBMC).

use crate::core::core_decomposition;
use crate::densest::polish;
use crate::front::{greedy_front, k_core};
use crate::greedy::greedy_colouring_bound;
use crate::{ClipperError, CliqueSolution, ConsistencyGraph, DensestCliqueConfig};

/// Limits of [`max_clique`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MaxCliqueLimits {
    /// Largest graph (after core pruning) the search accepts; its bitset adjacency takes
    /// `max_vertices² / 8` bytes.
    pub max_vertices: usize,
    /// Branch-and-bound nodes after which the search gives up.
    pub max_nodes: u64,
}

impl Default for MaxCliqueLimits {
    fn default() -> Self {
        Self {
            max_vertices: 10_000,
            max_nodes: 5_000_000,
        }
    }
}

/// Finds a maximum clique and proves it maximum.
///
/// Among maximum cliques that differ by swapping one or two members, the heavier is
/// preferred (the weighted polish of [`crate::densest_clique`]); otherwise any maximum clique
/// may be returned.
///
/// A greedy clique (by degeneracy order) gives a lower bound; if it meets max core + 1 it is
/// returned at once. Otherwise vertices whose core number + 1 does not exceed it are pruned and
/// the rest is searched by branch and bound. Errors with [`ClipperError::TooLarge`] when the
/// pruned graph has more than `limits.max_vertices` vertices and with
/// [`ClipperError::BudgetExceeded`] after `limits.max_nodes` search nodes.
///
/// ```
/// use segloc_clipper::{max_clique, ConsistencyGraph, MaxCliqueLimits};
/// let g = ConsistencyGraph::from_edges(4, &[(0, 1, 1.0), (1, 2, 1.0), (0, 2, 1.0), (2, 3, 1.0)]).unwrap();
/// let s = max_clique(&g, &MaxCliqueLimits::default()).unwrap();
/// assert_eq!(s.vertices, vec![0, 1, 2]);
/// assert!(s.certified_maximum);
/// ```
pub fn max_clique(
    graph: &ConsistencyGraph,
    limits: &MaxCliqueLimits,
) -> Result<CliqueSolution, ClipperError> {
    let n = graph.num_vertices();
    if n == 0 {
        return Ok(CliqueSolution {
            certified_maximum: true,
            ..CliqueSolution::default()
        });
    }
    let front = greedy_front(graph, 0);
    let lb = front.clique.len();
    let greedy = front.clique;
    let certified = |vertices: Vec<u32>, pruned: usize, nodes: u64| {
        let mut s = CliqueSolution::new(graph, vertices);
        s.certified_maximum = true;
        s.upper_bound = s.vertices.len();
        s.pruned_vertices = pruned;
        s.search_nodes = nodes;
        // among maximum cliques, prefer a heavier one that swaps one or two members
        polish(graph, s, &DensestCliqueConfig::default())
    };
    if front.certified {
        return Ok(certified(greedy, 0, 0));
    }
    // Only a strictly larger clique can improve on the greedy one: search the lb-core.
    let keep = k_core(graph, lb);
    let (sub, old_of_new) = graph.induced_subgraph(&keep);
    let pruned = n - sub.num_vertices();
    if sub.num_vertices() <= lb {
        return Ok(certified(greedy, pruned, 0));
    }
    let sub_cd = core_decomposition(&sub);
    if greedy_colouring_bound(&sub, &sub_cd.order) <= lb {
        return Ok(certified(greedy, pruned, 0));
    }
    if sub.num_vertices() > limits.max_vertices {
        return Err(ClipperError::TooLarge {
            what: "vertices after core pruning",
            size: sub.num_vertices(),
            limit: limits.max_vertices,
        });
    }
    let mut search = Search::new(&sub, &sub_cd.order, lb, limits.max_nodes);
    search.run();
    if search.exceeded {
        return Err(ClipperError::BudgetExceeded {
            max_nodes: limits.max_nodes,
            best_size: lb.max(search.best.len()),
        });
    }
    let nodes = search.nodes;
    if search.best.len() > lb {
        let vertices = search
            .best
            .iter()
            .map(|&r| old_of_new[search.vertex_of_rank[r as usize] as usize])
            .collect();
        Ok(certified(vertices, pruned, nodes))
    } else {
        Ok(certified(greedy, pruned, nodes))
    }
}

/// Bitset branch-and-bound state. Vertices are renumbered by rank: rank 0 is the last vertex
/// of the degeneracy order (in the densest core).
struct Search {
    words: usize,
    /// Row `r` (length `words`): neighbours of rank `r`.
    adj: Vec<u64>,
    vertex_of_rank: Vec<u32>,
    /// Best clique (ranks); only a clique larger than `best_len` is recorded.
    best: Vec<u32>,
    best_len: usize,
    current: Vec<u32>,
    nodes: u64,
    max_nodes: u64,
    exceeded: bool,
}

impl Search {
    fn new(graph: &ConsistencyGraph, order: &[u32], lower_bound: usize, max_nodes: u64) -> Self {
        let n = graph.num_vertices();
        let words = n.div_ceil(64);
        let vertex_of_rank: Vec<u32> = order.iter().rev().copied().collect();
        let mut rank = vec![0u32; n];
        for (r, &v) in vertex_of_rank.iter().enumerate() {
            rank[v as usize] = r as u32;
        }
        let mut adj = vec![0u64; n * words];
        for (r, &v) in vertex_of_rank.iter().enumerate() {
            let row = &mut adj[r * words..(r + 1) * words];
            for &u in graph.neighbors(v as usize) {
                let ru = rank[u as usize] as usize;
                row[ru / 64] |= 1 << (ru % 64);
            }
        }
        Self {
            words,
            adj,
            vertex_of_rank,
            best: Vec::new(),
            best_len: lower_bound,
            current: Vec::new(),
            nodes: 0,
            max_nodes,
            exceeded: false,
        }
    }

    fn run(&mut self) {
        let n = self.vertex_of_rank.len();
        let mut p = vec![0u64; self.words];
        for r in 0..n {
            p[r / 64] |= 1 << (r % 64);
        }
        self.expand(p);
    }

    /// Explores cliques `current ∪ S`, `S ⊆ p`.
    fn expand(&mut self, mut p: Vec<u64>) {
        if self.exceeded {
            return;
        }
        self.nodes += 1;
        if self.nodes > self.max_nodes {
            self.exceeded = true;
            return;
        }
        let (order, colours) = self.colour_sort(&p);
        for idx in (0..order.len()).rev() {
            if self.current.len() + colours[idx] as usize <= self.best_len {
                return;
            }
            let v = order[idx] as usize;
            let row = &self.adj[v * self.words..(v + 1) * self.words];
            let new_p: Vec<u64> = p.iter().zip(row).map(|(a, b)| a & b).collect();
            self.current.push(v as u32);
            if new_p.iter().all(|&w| w == 0) {
                if self.current.len() > self.best_len {
                    self.best_len = self.current.len();
                    self.best.clone_from(&self.current);
                }
            } else {
                self.expand(new_p);
            }
            self.current.pop();
            if self.exceeded {
                return;
            }
            p[v / 64] &= !(1u64 << (v % 64));
        }
    }

    /// Greedy sequential colouring of `p` by rank; returns the vertices whose colour could
    /// still improve on the best clique, in increasing colour, with their colours.
    fn colour_sort(&self, p: &[u64]) -> (Vec<u32>, Vec<u32>) {
        let kmin = (self.best_len + 1)
            .saturating_sub(self.current.len())
            .max(1) as u32;
        let mut uncoloured = p.to_vec();
        let mut q = vec![0u64; self.words];
        let mut order = Vec::new();
        let mut colours = Vec::new();
        let mut k = 0u32;
        let mut remaining: usize = uncoloured.iter().map(|w| w.count_ones() as usize).sum();
        while remaining > 0 {
            k += 1;
            q.copy_from_slice(&uncoloured);
            let mut start_word = 0;
            loop {
                while start_word < self.words && q[start_word] == 0 {
                    start_word += 1;
                }
                if start_word == self.words {
                    break;
                }
                let bit = q[start_word].trailing_zeros() as usize;
                let v = start_word * 64 + bit;
                uncoloured[start_word] &= !(1u64 << bit);
                remaining -= 1;
                let row = &self.adj[v * self.words..(v + 1) * self.words];
                for w in start_word..self.words {
                    q[w] &= !row[w];
                }
                q[start_word] &= !(1u64 << bit);
                if k >= kmin {
                    order.push(v as u32);
                    colours.push(k);
                }
            }
        }
        (order, colours)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    fn random_graph(n: usize, p: f64, rng: &mut SplitMix64) -> ConsistencyGraph {
        let mut e = Vec::new();
        for u in 0..n as u32 {
            for v in u + 1..n as u32 {
                if rng.next_open01() < p {
                    e.push((u, v, 0.5 + 0.5 * rng.next_open01()));
                }
            }
        }
        ConsistencyGraph::from_edges(n, &e).unwrap()
    }

    fn brute_force_clique_number(g: &ConsistencyGraph) -> usize {
        let n = g.num_vertices();
        assert!(n <= 20);
        let mut adj = vec![0u32; n];
        for (v, row) in adj.iter_mut().enumerate() {
            for &u in g.neighbors(v) {
                *row |= 1 << u;
            }
        }
        let mut best = 0;
        for mask in 0u32..(1 << n) {
            let k = mask.count_ones() as usize;
            if k <= best {
                continue;
            }
            let ok = (0..n).all(|v| mask & (1 << v) == 0 || (adj[v] | (1 << v)) & mask == mask);
            if ok {
                best = k;
            }
        }
        best
    }

    #[test]
    fn agrees_with_brute_force() {
        let mut rng = SplitMix64::new(11);
        for trial in 0..120 {
            let n = 1 + trial % 18;
            let p = [0.2, 0.5, 0.8, 0.95][trial % 4];
            let g = random_graph(n, p, &mut rng);
            let s = max_clique(&g, &MaxCliqueLimits::default()).unwrap();
            assert!(s.certified_maximum);
            assert!(g.is_clique(&s.vertices));
            assert_eq!(
                s.vertices.len(),
                brute_force_clique_number(&g),
                "trial {trial}"
            );
            assert_eq!(s.upper_bound, s.vertices.len());
        }
    }

    #[test]
    fn refuses_beyond_limits() {
        let mut rng = SplitMix64::new(5);
        let g = random_graph(120, 0.5, &mut rng);
        let tiny = MaxCliqueLimits {
            max_vertices: 10,
            max_nodes: 1_000_000,
        };
        assert!(matches!(
            max_clique(&g, &tiny),
            Err(ClipperError::TooLarge { .. })
        ));
        let budget = MaxCliqueLimits {
            max_vertices: 1000,
            max_nodes: 3,
        };
        assert!(matches!(
            max_clique(&g, &budget),
            Err(ClipperError::BudgetExceeded { .. })
        ));
        let s = max_clique(&g, &MaxCliqueLimits::default()).unwrap();
        assert!(s.certified_maximum && g.is_clique(&s.vertices));
    }

    #[test]
    fn empty_and_edgeless() {
        let g = ConsistencyGraph::from_edges(0, &[]).unwrap();
        let s = max_clique(&g, &MaxCliqueLimits::default()).unwrap();
        assert!(s.vertices.is_empty() && s.certified_maximum);
        let g = ConsistencyGraph::from_edges(4, &[]).unwrap();
        let s = max_clique(&g, &MaxCliqueLimits::default()).unwrap();
        assert_eq!(s.vertices.len(), 1);
    }
}
