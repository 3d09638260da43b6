//! Pair-join graph build for dense association lists (all-to-all and the like).
//!
//! Each map's point pairs are listed with their invariant (distance, or horizontal distance
//! and signed height difference). The query list holds both orientations of every pair and
//! is sorted; every prior pair `(i, k)`, `i < k`, looks up the query pairs `(j, l)` whose
//! invariant lies within the thresholds. Each match is the association pair
//! `((i, j), (k, l))` if both associations exist. The work is proportional to the matching
//! quads, not to the square of the association count.

use std::collections::HashMap;

use nalgebra::Point3;
use rayon::prelude::*;

use crate::association::{PairMeasure, PairTest};
use crate::{Association, ConsistencyGraph};

/// Largest dense (prior x query) lookup table, in entries.
const DENSE_TABLE_LIMIT: usize = 1 << 24;

/// Association id of a (compact prior, compact query) pair.
enum Lookup {
    Dense { n_query: usize, ids: Vec<u32> },
    Sparse(HashMap<(u32, u32), u32>),
}

impl Lookup {
    #[inline]
    fn get(&self, p: u32, q: u32) -> Option<u32> {
        match self {
            Lookup::Dense { n_query, ids } => {
                let id = ids[p as usize * n_query + q as usize];
                (id != u32::MAX).then_some(id)
            }
            Lookup::Sparse(map) => map.get(&(p, q)).copied(),
        }
    }
}

/// One ordered query pair with its measure.
#[derive(Clone, Copy)]
struct QueryPair {
    m: PairMeasure,
    /// Sort key: distance (6-DOF) or distance cell (4-DOF).
    cell: i64,
    j: u32,
    l: u32,
}

/// Points of one map that some association uses, in ascending original index.
pub(crate) struct UsedPoints {
    /// Original index of each compact index.
    pub original: Vec<u32>,
    /// Compact index of each original index (`u32::MAX` if unused).
    pub compact: Vec<u32>,
}

impl UsedPoints {
    pub fn new(n: usize, indices: impl Iterator<Item = u32>) -> Self {
        let mut used = vec![false; n];
        for i in indices {
            used[i as usize] = true;
        }
        let mut original = Vec::new();
        let mut compact = vec![u32::MAX; n];
        for (i, &u) in used.iter().enumerate() {
            if u {
                compact[i] = original.len() as u32;
                original.push(i as u32);
            }
        }
        Self { original, compact }
    }

    pub fn len(&self) -> usize {
        self.original.len()
    }
}

/// Builds the consistency graph by joining the two maps' sorted pair lists.
pub(crate) fn build(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
    test: &PairTest,
) -> ConsistencyGraph {
    let m = associations.len();
    let used_p = UsedPoints::new(prior.len(), associations.iter().map(|a| a.prior));
    let used_q = UsedPoints::new(query.len(), associations.iter().map(|a| a.query));
    let (np, nq) = (used_p.len(), used_q.len());

    let lookup = if np.saturating_mul(nq) <= DENSE_TABLE_LIMIT {
        let mut ids = vec![u32::MAX; np * nq];
        for (id, a) in associations.iter().enumerate() {
            let p = used_p.compact[a.prior as usize] as usize;
            let q = used_q.compact[a.query as usize] as usize;
            ids[p * nq + q] = id as u32;
        }
        Lookup::Dense { n_query: nq, ids }
    } else {
        let mut map = HashMap::with_capacity(m);
        for (id, a) in associations.iter().enumerate() {
            map.insert(
                (
                    used_p.compact[a.prior as usize],
                    used_q.compact[a.query as usize],
                ),
                id as u32,
            );
        }
        Lookup::Sparse(map)
    };

    let query_pairs = sorted_query_pairs(query, &used_q, test);

    // Prior pairs row by row (row a: pairs (a, b), b > a), rows chunked for balance.
    let rows = super::balanced_row_chunks(np);
    let edges: Vec<Vec<(u32, u32, f32)>> = rows
        .par_iter()
        .map(|&(r0, r1)| {
            let mut out = Vec::new();
            for a in r0..r1 {
                let pa = &prior[used_p.original[a] as usize];
                for b in a + 1..np {
                    let ma = test.measure(pa, &prior[used_p.original[b] as usize]);
                    join_one(
                        ma,
                        a as u32,
                        b as u32,
                        &query_pairs,
                        test,
                        &lookup,
                        &mut out,
                    );
                }
            }
            out
        })
        .collect();
    let all: Vec<(u32, u32, f32)> = edges.into_iter().flatten().collect();
    ConsistencyGraph::from_edge_list(m, &all)
}

/// All ordered pairs `(j, l)`, `j != l`, of used query points, sorted by (cell, dz) for
/// 4-DOF or by distance for 6-DOF.
fn sorted_query_pairs(query: &[Point3<f64>], used: &UsedPoints, test: &PairTest) -> Vec<QueryPair> {
    let nq = used.len();
    let mut list: Vec<QueryPair> = (0..nq)
        .into_par_iter()
        .flat_map_iter(|j| {
            let qj = &query[used.original[j] as usize];
            (j + 1..nq).flat_map(move |l| {
                let ms = test.measure(qj, &query[used.original[l] as usize]);
                let cell = if test.gravity {
                    cell_of(ms.dist, test.epsilon)
                } else {
                    0
                };
                let rev = PairMeasure {
                    dist: ms.dist,
                    dz: -ms.dz,
                };
                [
                    QueryPair {
                        m: ms,
                        cell,
                        j: j as u32,
                        l: l as u32,
                    },
                    QueryPair {
                        m: rev,
                        cell,
                        j: l as u32,
                        l: j as u32,
                    },
                ]
            })
        })
        .collect();
    if test.gravity {
        list.par_sort_unstable_by(|x, y| {
            x.cell
                .cmp(&y.cell)
                .then(x.m.dz.total_cmp(&y.m.dz))
                .then((x.j, x.l).cmp(&(y.j, y.l)))
        });
    } else {
        list.par_sort_unstable_by(|x, y| {
            x.m.dist
                .total_cmp(&y.m.dist)
                .then((x.j, x.l).cmp(&(y.j, y.l)))
        });
    }
    list
}

#[inline]
fn cell_of(dist: f64, width: f64) -> i64 {
    (dist / width).floor() as i64
}

/// Emits every edge of prior pair `(a, b)` (compact, `a < b`, measure `ma`).
#[inline]
fn join_one(
    ma: PairMeasure,
    a: u32,
    b: u32,
    query_pairs: &[QueryPair],
    test: &PairTest,
    lookup: &Lookup,
    out: &mut Vec<(u32, u32, f32)>,
) {
    // Search windows slightly wider than the thresholds (rounding of the window ends); the
    // exact test decides.
    let slack = 1e-9 * test.epsilon + 1e-12 * ma.dist.abs();
    let lo = ma.dist - test.epsilon - slack;
    let hi = ma.dist + test.epsilon + slack;
    let mut emit = |qp: &QueryPair| {
        if let (Some(u), Some(v)) = (lookup.get(a, qp.j), lookup.get(b, qp.l)) {
            if let Some(w) = test.weight(ma, qp.m) {
                out.push((u, v, w));
            }
        }
    };
    if test.gravity {
        let slack_z = 1e-9 * test.epsilon_z + 1e-12 * ma.dz.abs();
        let zlo = ma.dz - test.epsilon_z - slack_z;
        let zhi = ma.dz + test.epsilon_z + slack_z;
        for cell in cell_of(lo, test.epsilon)..=cell_of(hi, test.epsilon) {
            let start = query_pairs.partition_point(|q| (q.cell, q.m.dz) < (cell, zlo));
            for qp in &query_pairs[start..] {
                if qp.cell != cell || qp.m.dz > zhi {
                    break;
                }
                emit(qp);
            }
        }
    } else {
        let start = query_pairs.partition_point(|q| q.m.dist < lo);
        for qp in &query_pairs[start..] {
            if qp.m.dist > hi {
                break;
            }
            emit(qp);
        }
    }
}
