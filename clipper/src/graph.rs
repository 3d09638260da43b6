//! The consistency graph in compressed sparse rows.

use crate::ClipperError;

/// A run of consecutive rows of an upper-triangular adjacency: row `k` of the run has
/// `counts[k]` neighbours (all larger than the row's vertex, ascending), stored one row after
/// the other in `neighbors` / `weights`.
#[derive(Default)]
pub(crate) struct UpperRows {
    pub counts: Vec<u32>,
    pub neighbors: Vec<u32>,
    pub weights: Vec<f32>,
}

/// An undirected weighted graph in compressed sparse rows (CSR).
///
/// Vertex `v`'s neighbours are `neighbors(v)`, sorted ascending, with the matching edge
/// weights in `weights(v)`. Every undirected edge is stored in both rows. For a graph built
/// from associations, vertex `v` is association `v` of the list it was built from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConsistencyGraph {
    offsets: Vec<usize>,
    neighbors: Vec<u32>,
    weights: Vec<f32>,
}

impl ConsistencyGraph {
    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Number of undirected edges.
    pub fn num_edges(&self) -> usize {
        self.neighbors.len() / 2
    }

    /// Sorted neighbours of `v`. Panics if `v >= num_vertices()` (like slice indexing).
    pub fn neighbors(&self, v: usize) -> &[u32] {
        &self.neighbors[self.offsets[v]..self.offsets[v + 1]]
    }

    /// Edge weights of `v`, aligned with [`Self::neighbors`].
    pub fn weights(&self, v: usize) -> &[f32] {
        &self.weights[self.offsets[v]..self.offsets[v + 1]]
    }

    /// Degree of `v`.
    pub fn degree(&self, v: usize) -> usize {
        self.offsets[v + 1] - self.offsets[v]
    }

    /// Weight of edge `{u, v}`, or `None` if absent (binary search in the shorter row).
    pub fn edge_weight(&self, u: usize, v: usize) -> Option<f32> {
        let (a, b) = if self.degree(u) <= self.degree(v) {
            (u, v)
        } else {
            (v, u)
        };
        let row = self.neighbors(a);
        row.binary_search(&(b as u32))
            .ok()
            .map(|k| self.weights(a)[k])
    }

    /// True if `{u, v}` is an edge.
    pub fn has_edge(&self, u: usize, v: usize) -> bool {
        self.edge_weight(u, v).is_some()
    }

    /// Row offsets (length `num_vertices() + 1`).
    pub fn offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// All neighbour entries, row after row.
    pub fn all_neighbors(&self) -> &[u32] {
        &self.neighbors
    }

    /// All weight entries, aligned with [`Self::all_neighbors`].
    pub fn all_weights(&self) -> &[f32] {
        &self.weights
    }

    /// Builds a graph with `n` vertices from undirected edges `(u, v, weight)`.
    ///
    /// Each edge must join two different vertices below `n`, appear once (in either
    /// orientation) and have a weight in (0, 1].
    ///
    /// ```
    /// use segloc_clipper::ConsistencyGraph;
    /// let g = ConsistencyGraph::from_edges(3, &[(0, 1, 1.0), (2, 1, 0.5)]).unwrap();
    /// assert_eq!(g.neighbors(1), &[0, 2]);
    /// assert_eq!(g.num_edges(), 2);
    /// ```
    pub fn from_edges(n: usize, edges: &[(u32, u32, f64)]) -> Result<Self, ClipperError> {
        if n >= u32::MAX as usize {
            return Err(ClipperError::TooLarge {
                what: "vertex count",
                size: n,
                limit: u32::MAX as usize - 1,
            });
        }
        let mut list = Vec::with_capacity(edges.len());
        for (index, &(u, v, w)) in edges.iter().enumerate() {
            let reason = if u as usize >= n || v as usize >= n {
                Some("endpoint out of range")
            } else if u == v {
                Some("self loop")
            } else if !(w > 0.0 && w <= 1.0) {
                Some("weight not in (0, 1]")
            } else {
                None
            };
            if let Some(reason) = reason {
                return Err(ClipperError::InvalidEdge {
                    index,
                    u,
                    v,
                    reason,
                });
            }
            list.push((u, v, w as f32));
        }
        let g = Self::from_edge_list(n, &list);
        for v in 0..n {
            if let Some(k) = g.neighbors(v).windows(2).position(|w| w[0] == w[1]) {
                let u = g.neighbors(v)[k];
                let index = edges
                    .iter()
                    .position(|&(a, b, _)| (a, b) == (u, v as u32) || (a, b) == (v as u32, u))
                    .unwrap_or(0);
                return Err(ClipperError::InvalidEdge {
                    index,
                    u,
                    v: v as u32,
                    reason: "duplicate edge",
                });
            }
        }
        Ok(g)
    }

    /// CSR from a list of undirected edges (unchecked: in range, no loops, no duplicates).
    ///
    /// Two scatter passes (a transpose of a transpose) leave every row sorted without a
    /// comparison sort, in time linear in the edge count; the result does not depend on the
    /// order of `edges`.
    pub(crate) fn from_edge_list(n: usize, edges: &[(u32, u32, f32)]) -> Self {
        let mut offsets = vec![0usize; n + 1];
        for &(u, v, _) in edges {
            offsets[u as usize + 1] += 1;
            offsets[v as usize + 1] += 1;
        }
        for k in 0..n {
            offsets[k + 1] += offsets[k];
        }
        let total = offsets[n];
        // Pass 1: row y of the transpose lists every x with a directed edge x -> y.
        let mut cursor = offsets[..n].to_vec();
        let mut t_src = vec![0u32; total];
        let mut t_w = vec![0f32; total];
        for &(u, v, w) in edges {
            let c = &mut cursor[v as usize];
            t_src[*c] = u;
            t_w[*c] = w;
            *c += 1;
            let c = &mut cursor[u as usize];
            t_src[*c] = v;
            t_w[*c] = w;
            *c += 1;
        }
        // Pass 2: visiting y in increasing order fills every row x sorted.
        cursor.copy_from_slice(&offsets[..n]);
        let mut neighbors = vec![0u32; total];
        let mut weights = vec![0f32; total];
        for y in 0..n {
            for idx in offsets[y]..offsets[y + 1] {
                let x = t_src[idx] as usize;
                let c = &mut cursor[x];
                neighbors[*c] = y as u32;
                weights[*c] = t_w[idx];
                *c += 1;
            }
        }
        Self {
            offsets,
            neighbors,
            weights,
        }
    }

    /// CSR from raw parts (unchecked: rows sorted, symmetric, no loops).
    pub(crate) fn from_csr_parts(
        offsets: Vec<usize>,
        neighbors: Vec<u32>,
        weights: Vec<f32>,
    ) -> Self {
        Self {
            offsets,
            neighbors,
            weights,
        }
    }

    /// The same graph with vertex `r` renamed `new_of_old[r]` (a permutation); rows re-sorted.
    pub(crate) fn relabelled(&self, new_of_old: &[u32]) -> Self {
        let n = self.num_vertices();
        let mut offsets = vec![0usize; n + 1];
        for r in 0..n {
            offsets[new_of_old[r] as usize + 1] = self.degree(r);
        }
        for v in 0..n {
            offsets[v + 1] += offsets[v];
        }
        let mut neighbors = vec![0u32; self.neighbors.len()];
        let mut weights = vec![0f32; self.weights.len()];
        let mut row: Vec<(u32, f32)> = Vec::new();
        for r in 0..n {
            row.clear();
            row.extend(
                self.neighbors(r)
                    .iter()
                    .zip(self.weights(r))
                    .map(|(&u, &w)| (new_of_old[u as usize], w)),
            );
            row.sort_unstable_by_key(|e| e.0);
            let start = offsets[new_of_old[r] as usize];
            for (k, &(u, w)) in row.iter().enumerate() {
                neighbors[start + k] = u;
                weights[start + k] = w;
            }
        }
        Self {
            offsets,
            neighbors,
            weights,
        }
    }

    /// CSR from the upper triangle given row by row: row `u` lists its neighbours `v > u`
    /// in increasing order (`upper_offsets` has length `n + 1`).
    #[cfg(test)]
    pub(crate) fn from_upper_rows(
        n: usize,
        upper_offsets: &[usize],
        upper_neighbors: &[u32],
        upper_weights: &[f32],
    ) -> Self {
        let chunk = UpperRows {
            counts: upper_offsets
                .windows(2)
                .map(|w| (w[1] - w[0]) as u32)
                .collect(),
            neighbors: upper_neighbors.to_vec(),
            weights: upper_weights.to_vec(),
        };
        Self::from_upper_chunks(n, &[chunk])
    }

    /// CSR from the upper triangle given as consecutive runs of rows (see [`UpperRows`]);
    /// the chunks' row counts must add up to `n`.
    ///
    /// Row `v` is `[lower part | upper part]`: the lower part (neighbours `u < v`) is the
    /// transpose of the upper triangle. To keep the scattered writes of the transpose in
    /// cache, the vertices are split into blocks whose rows fit in a few hundred KB: entries
    /// are first bucketed by the block of their target row (a few sequential streams), then
    /// each block's rows are assembled while they are cache-resident. Buckets keep the
    /// ascending source order, so every row comes out sorted.
    pub(crate) fn from_upper_chunks(n: usize, chunks: &[UpperRows]) -> Self {
        // where each row's upper part lives
        let mut row_chunk = Vec::with_capacity(n);
        let mut row_start = Vec::with_capacity(n);
        for (ci, c) in chunks.iter().enumerate() {
            let mut a = 0usize;
            for &cnt in &c.counts {
                row_chunk.push(ci as u32);
                row_start.push(a);
                a += cnt as usize;
            }
        }
        let mut upper_deg = Vec::with_capacity(n);
        for c in chunks {
            upper_deg.extend_from_slice(&c.counts);
        }
        let mut lower_deg = vec![0u32; n];
        for c in chunks {
            for &v in &c.neighbors {
                lower_deg[v as usize] += 1;
            }
        }
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0usize);
        for u in 0..n {
            offsets.push(offsets[u] + lower_deg[u] as usize + upper_deg[u] as usize);
        }
        let total = offsets[n];
        // ~256 KB of final rows per block
        const BLOCK_BYTES: usize = 256 * 1024;
        let n_blocks = (total * 8).div_ceil(BLOCK_BYTES).clamp(1, n.max(1));
        let block_len = n.div_ceil(n_blocks).max(1);
        let n_blocks = n.div_ceil(block_len).max(1);
        // bucket the transposed entries (target v, source u, weight) by target block
        let mut bucket_len = vec![0usize; n_blocks];
        for (v, &d) in lower_deg.iter().enumerate() {
            bucket_len[v / block_len] += d as usize;
        }
        let mut buckets: Vec<Vec<(u32, u32, f32)>> =
            bucket_len.iter().map(|&l| Vec::with_capacity(l)).collect();
        let mut u = 0usize;
        for c in chunks {
            let mut a = 0usize;
            for &cnt in &c.counts {
                let b = a + cnt as usize;
                for (&v, &w) in c.neighbors[a..b].iter().zip(&c.weights[a..b]) {
                    buckets[v as usize / block_len].push((v, u as u32, w));
                }
                a = b;
                u += 1;
            }
        }
        let mut neighbors = vec![0u32; total];
        let mut weights = vec![0f32; total];
        let mut lower_cursor = offsets[..n].to_vec();
        for (bi, bucket) in buckets.iter().enumerate() {
            let (r0, r1) = (bi * block_len, ((bi + 1) * block_len).min(n));
            for u in r0..r1 {
                let c = &chunks[row_chunk[u] as usize];
                let (a, len) = (row_start[u], upper_deg[u] as usize);
                let start = offsets[u] + lower_deg[u] as usize;
                neighbors[start..start + len].copy_from_slice(&c.neighbors[a..a + len]);
                weights[start..start + len].copy_from_slice(&c.weights[a..a + len]);
            }
            for &(v, u, w) in bucket {
                let pos = lower_cursor[v as usize];
                lower_cursor[v as usize] = pos + 1;
                neighbors[pos] = u;
                weights[pos] = w;
            }
        }
        Self {
            offsets,
            neighbors,
            weights,
        }
    }

    /// Subgraph induced by `keep` (`keep[v] == true`); returns it and the map new index -> old index.
    ///
    /// Vertices keep their relative order. Entries of `keep` past `num_vertices()` are
    /// ignored; missing entries count as `false`.
    pub fn induced_subgraph(&self, keep: &[bool]) -> (ConsistencyGraph, Vec<u32>) {
        let n = self.num_vertices();
        let kept = |v: usize| keep.get(v).copied().unwrap_or(false);
        let mut new_index = vec![u32::MAX; n];
        let mut old_of_new = Vec::new();
        for (v, slot) in new_index.iter_mut().enumerate() {
            if kept(v) {
                *slot = old_of_new.len() as u32;
                old_of_new.push(v as u32);
            }
        }
        // Branch-free compaction: every entry of a kept row is written, and the write
        // position only advances for kept neighbours.
        let bound: usize = old_of_new.iter().map(|&v| self.degree(v as usize)).sum();
        let mut offsets = Vec::with_capacity(old_of_new.len() + 1);
        offsets.push(0);
        let mut neighbors = vec![0u32; bound];
        let mut weights = vec![0f32; bound];
        let mut len = 0usize;
        for &v in &old_of_new {
            let v = v as usize;
            for (&u, &w) in self.neighbors(v).iter().zip(self.weights(v)) {
                let nu = new_index[u as usize];
                neighbors[len] = nu;
                weights[len] = w;
                len += usize::from(nu != u32::MAX);
            }
            offsets.push(len);
        }
        neighbors.truncate(len);
        weights.truncate(len);
        (
            ConsistencyGraph {
                offsets,
                neighbors,
                weights,
            },
            old_of_new,
        )
    }

    /// Subgraph induced by the sorted, distinct `vertices` (new index = position in the
    /// list), in time linear in their degrees. `index` is scratch of length
    /// `num_vertices()` holding `u32::MAX` everywhere; it is left that way.
    pub(crate) fn subgraph_on(&self, vertices: &[u32], index: &mut [u32]) -> ConsistencyGraph {
        for (k, &v) in vertices.iter().enumerate() {
            index[v as usize] = k as u32;
        }
        let mut offsets = Vec::with_capacity(vertices.len() + 1);
        offsets.push(0);
        let mut neighbors = Vec::new();
        let mut weights = Vec::new();
        for &v in vertices {
            for (&u, &w) in self
                .neighbors(v as usize)
                .iter()
                .zip(self.weights(v as usize))
            {
                let nu = index[u as usize];
                if nu != u32::MAX {
                    neighbors.push(nu);
                    weights.push(w);
                }
            }
            offsets.push(neighbors.len());
        }
        for &v in vertices {
            index[v as usize] = u32::MAX;
        }
        ConsistencyGraph {
            offsets,
            neighbors,
            weights,
        }
    }

    /// True if every pair of `vertices` is adjacent (and no vertex repeats). O(V + Σ degree).
    pub fn is_clique(&self, vertices: &[u32]) -> bool {
        let n = self.num_vertices();
        if vertices.iter().any(|&v| v as usize >= n) {
            return false;
        }
        let mut member = vec![false; n];
        for &v in vertices {
            if std::mem::replace(&mut member[v as usize], true) {
                return false;
            }
        }
        let k = vertices.len();
        vertices.iter().all(|&v| {
            self.neighbors(v as usize)
                .iter()
                .filter(|&&u| member[u as usize])
                .count()
                == k - 1
        })
    }

    /// `uᵀ M u` for the uniform unit vector on `vertices` (M: weights, unit diagonal), i.e.
    /// `1 + 2·(sum of edge weights inside) / k`; equals `1 + (k-1)·mean weight` on a clique.
    /// Zero for an empty set.
    pub fn uniform_objective(&self, vertices: &[u32]) -> f64 {
        if vertices.is_empty() {
            return 0.0;
        }
        let n = self.num_vertices();
        let mut member = vec![false; n];
        for &v in vertices {
            if let Some(m) = member.get_mut(v as usize) {
                *m = true;
            }
        }
        let mut sorted: Vec<u32> = vertices
            .iter()
            .copied()
            .filter(|&v| (v as usize) < n)
            .collect();
        sorted.sort_unstable();
        sorted.dedup();
        let mut sum = 0.0f64;
        for &u in &sorted {
            // branch-free: non-members contribute zero
            let row_sum: f64 = self
                .neighbors(u as usize)
                .iter()
                .zip(self.weights(u as usize))
                .map(|(&x, &w)| w as f64 * f64::from(u8::from(member[x as usize])))
                .sum();
            sum += row_sum;
        }
        let k = sorted.len() as f64;
        (k + sum) / k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn from_edges_sorts_rows_and_counts() {
        let g = ConsistencyGraph::from_edges(4, &[(3, 0, 0.5), (1, 0, 1.0), (2, 3, 0.25)]).unwrap();
        assert_eq!(g.num_vertices(), 4);
        assert_eq!(g.num_edges(), 3);
        assert_eq!(g.neighbors(0), &[1, 3]);
        assert_eq!(g.weights(0), &[1.0, 0.5]);
        assert_eq!(g.neighbors(3), &[0, 2]);
        assert_eq!(g.degree(2), 1);
        assert_eq!(g.edge_weight(2, 3), Some(0.25));
        assert!(!g.has_edge(1, 2));
    }

    #[test]
    fn from_edges_rejects_bad_edges() {
        assert!(ConsistencyGraph::from_edges(2, &[(0, 2, 1.0)]).is_err());
        assert!(ConsistencyGraph::from_edges(2, &[(1, 1, 1.0)]).is_err());
        assert!(ConsistencyGraph::from_edges(2, &[(0, 1, f64::NAN)]).is_err());
        assert!(matches!(
            ConsistencyGraph::from_edges(3, &[(0, 1, 1.0), (1, 2, 1.0), (1, 0, 1.0)]),
            Err(ClipperError::InvalidEdge {
                reason: "duplicate edge",
                ..
            })
        ));
    }

    #[test]
    fn upper_rows_match_edge_list() {
        let edges = [(0u32, 2u32, 0.5f32), (0, 3, 1.0), (1, 2, 0.75), (2, 3, 0.1)];
        let a = ConsistencyGraph::from_edge_list(4, &edges);
        let b = ConsistencyGraph::from_upper_rows(
            4,
            &[0, 2, 3, 4, 4],
            &[2, 3, 2, 3],
            &[0.5, 1.0, 0.75, 0.1],
        );
        assert_eq!(a, b);
    }

    #[test]
    fn relabelling_permutes_vertices() {
        let g = ConsistencyGraph::from_edges(3, &[(0, 1, 1.0), (1, 2, 0.5)]).unwrap();
        let h = g.relabelled(&[2, 0, 1]);
        let expected = ConsistencyGraph::from_edges(3, &[(2, 0, 1.0), (0, 1, 0.5)]).unwrap();
        assert_eq!(h, expected);
    }

    #[test]
    fn induced_subgraph_maps_back() {
        let g = ConsistencyGraph::from_edges(
            5,
            &[
                (0, 1, 1.0),
                (1, 2, 1.0),
                (2, 4, 0.5),
                (0, 4, 1.0),
                (3, 4, 1.0),
            ],
        )
        .unwrap();
        let (s, map) = g.induced_subgraph(&[true, false, true, false, true]);
        assert_eq!(map, vec![0, 2, 4]);
        assert_eq!(s.num_vertices(), 3);
        assert_eq!(s.num_edges(), 2);
        assert_eq!(s.neighbors(2), &[0, 1]);
        assert_eq!(s.weights(2), &[1.0, 0.5]);
    }

    #[test]
    fn clique_check_and_objective() {
        let g = ConsistencyGraph::from_edges(3, &[(0, 1, 1.0), (1, 2, 0.5), (0, 2, 0.5)]).unwrap();
        assert!(g.is_clique(&[2, 0, 1]));
        assert!(!g.is_clique(&[0, 0]));
        assert!((g.uniform_objective(&[0, 1, 2]) - (3.0 + 4.0) / 3.0).abs() < 1e-12);
        assert_eq!(g.uniform_objective(&[]), 0.0);
    }
}
