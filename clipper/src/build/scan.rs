//! Pairwise-scan graph build: every association pair is tested, with a vectorised
//! single-precision prefilter and an exact double-precision decision.
//!
//! The prefilter avoids square roots: for distances `da = sqrt(A)`, `db = sqrt(B)`,
//! `|da - db| < e` implies `(A - B)^2 = (da - db)^2 (da + db)^2 < e^2 (da + db)^2 <= 2 e^2 (A + B)`.
//! It runs on map-centred `f32` coordinates with a widened threshold that covers their
//! rounding, so it never rejects a consistent pair; the survivors (a few percent) are then
//! decided by [`PairTest::test_associations`] on the original `f64` points, the same function
//! the join uses, so both builders give identical graphs.

use nalgebra::Point3;
use rayon::prelude::*;

use crate::association::{exponents_to_weights, PairTest};
use crate::{Association, ConsistencyGraph};

/// Lanes of one prefilter block.
const LANES: usize = 8;

/// Association endpoints in structure-of-arrays `f32` form, map-centred.
struct Soa {
    px: Vec<f32>,
    py: Vec<f32>,
    pz: Vec<f32>,
    qx: Vec<f32>,
    qy: Vec<f32>,
    qz: Vec<f32>,
}

/// Thresholds of the prefilter (already widened).
#[derive(Clone, Copy)]
struct Prefilter {
    /// `2 e'^2`.
    k: f32,
    /// `e'^4`: keeps pairs of coincident points.
    k_abs: f32,
    /// Height threshold `e_z'` (4-DOF only).
    eps_z: f32,
    gravity: bool,
}

fn centre(points: &[Point3<f64>]) -> [f64; 3] {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let mut c = [0.0; 3];
    for d in 0..3 {
        if lo[d].is_finite() {
            c[d] = 0.5 * (lo[d] + hi[d]);
        }
    }
    c
}

/// Builds the consistency graph by testing every pair of associations.
pub(crate) fn build(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
    test: &PairTest,
) -> ConsistencyGraph {
    let m = associations.len();
    let cp = centre(prior);
    let cq = centre(query);
    let mut scale = 0.0f64;
    let mut soa = Soa {
        px: Vec::with_capacity(m),
        py: Vec::with_capacity(m),
        pz: Vec::with_capacity(m),
        qx: Vec::with_capacity(m),
        qy: Vec::with_capacity(m),
        qz: Vec::with_capacity(m),
    };
    for a in associations {
        let p = &prior[a.prior as usize];
        let q = &query[a.query as usize];
        let c = [
            p.x - cp[0],
            p.y - cp[1],
            p.z - cp[2],
            q.x - cq[0],
            q.y - cq[1],
            q.z - cq[2],
        ];
        for v in c {
            scale = scale.max(v.abs());
        }
        soa.px.push(c[0] as f32);
        soa.py.push(c[1] as f32);
        soa.pz.push(c[2] as f32);
        soa.qx.push(c[3] as f32);
        soa.qy.push(c[4] as f32);
        soa.qz.push(c[5] as f32);
    }
    // f32 rounding of centred coordinates and of the squared lengths stays far below
    // 3e-5 * scale on every distance; widen by that plus a relative 1e-4.
    let margin = 3e-5 * scale;
    let eps = test.epsilon * (1.0 + 1e-4) + margin;
    let eps_z = if test.gravity {
        test.epsilon_z * (1.0 + 1e-4) + margin
    } else {
        f64::INFINITY
    };
    let pre = Prefilter {
        k: (2.0 * eps * eps) as f32,
        k_abs: (eps * eps * eps * eps) as f32,
        eps_z: eps_z as f32,
        gravity: test.gravity,
    };

    let chunks = super::balanced_row_chunks(m);
    let results: Vec<(Vec<usize>, Vec<u32>, Vec<f32>)> = chunks
        .par_iter()
        .map(|&(r0, r1)| {
            let mut counts = Vec::with_capacity(r1 - r0);
            let mut nbrs = Vec::new();
            let mut wts = Vec::new();
            let mut cand = Vec::new();
            for u in r0..r1 {
                cand.clear();
                prefilter_row(&soa, u, &pre, &mut cand);
                let before = nbrs.len();
                let au = associations[u];
                for &v in &cand {
                    if let Some(w) =
                        test.test_associations(prior, query, au, associations[v as usize])
                    {
                        nbrs.push(v);
                        wts.push(w);
                    }
                }
                counts.push(nbrs.len() - before);
            }
            (counts, nbrs, wts)
        })
        .collect();

    let total: usize = results.iter().map(|r| r.1.len()).sum();
    let mut upper_offsets = Vec::with_capacity(m + 1);
    upper_offsets.push(0usize);
    let mut upper_neighbors = Vec::with_capacity(total);
    let mut upper_weights = Vec::with_capacity(total);
    for (counts, nbrs, wts) in results {
        for c in counts {
            let last = *upper_offsets.last().unwrap_or(&0);
            upper_offsets.push(last + c);
        }
        upper_neighbors.extend_from_slice(&nbrs);
        upper_weights.extend_from_slice(&wts);
    }
    exponents_to_weights(&mut upper_weights);
    ConsistencyGraph::from_upper_rows(m, &upper_offsets, &upper_neighbors, &upper_weights)
}

/// Appends to `out` every `v > u` that passes the prefilter.
fn prefilter_row(soa: &Soa, u: usize, pre: &Prefilter, out: &mut Vec<u32>) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above).
            unsafe { prefilter_row_avx2(soa, u, pre, out) };
            return;
        }
    }
    if pre.gravity {
        prefilter_row_generic::<true>(soa, u, pre, out);
    } else {
        prefilter_row_generic::<false>(soa, u, pre, out);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn prefilter_row_avx2(soa: &Soa, u: usize, pre: &Prefilter, out: &mut Vec<u32>) {
    if pre.gravity {
        prefilter_row_generic::<true>(soa, u, pre, out);
    } else {
        prefilter_row_generic::<false>(soa, u, pre, out);
    }
}

/// Portable kernel; compiled a second time with AVX2 enabled. Blocks of [`LANES`] lanes are
/// written branch-free so that they vectorise.
#[inline(always)]
fn prefilter_row_generic<const GRAVITY: bool>(
    soa: &Soa,
    u: usize,
    pre: &Prefilter,
    out: &mut Vec<u32>,
) {
    let m = soa.px.len();
    let (ax, ay, az) = (soa.px[u], soa.py[u], soa.pz[u]);
    let (bx, by, bz) = (soa.qx[u], soa.qy[u], soa.qz[u]);
    let mut v0 = u + 1;
    let lane_pass = |v: usize| -> bool {
        let dx = ax - soa.px[v];
        let dy = ay - soa.py[v];
        let dza = az - soa.pz[v];
        let ex = bx - soa.qx[v];
        let ey = by - soa.qy[v];
        let dzb = bz - soa.qz[v];
        let (a, b) = if GRAVITY {
            (dx * dx + dy * dy, ex * ex + ey * ey)
        } else {
            (dx * dx + dy * dy + dza * dza, ex * ex + ey * ey + dzb * dzb)
        };
        let d = a - b;
        d * d <= pre.k * (a + b) + pre.k_abs && (!GRAVITY || (dza - dzb).abs() <= pre.eps_z)
    };
    while v0 + LANES <= m {
        let px = &soa.px[v0..v0 + LANES];
        let py = &soa.py[v0..v0 + LANES];
        let pz = &soa.pz[v0..v0 + LANES];
        let qx = &soa.qx[v0..v0 + LANES];
        let qy = &soa.qy[v0..v0 + LANES];
        let qz = &soa.qz[v0..v0 + LANES];
        let mut pass = [0u8; LANES];
        for l in 0..LANES {
            let dx = ax - px[l];
            let dy = ay - py[l];
            let dza = az - pz[l];
            let ex = bx - qx[l];
            let ey = by - qy[l];
            let dzb = bz - qz[l];
            let mut a = dx * dx + dy * dy;
            let mut b = ex * ex + ey * ey;
            if !GRAVITY {
                a += dza * dza;
                b += dzb * dzb;
            }
            let d = a - b;
            let ok_d = d * d <= pre.k * (a + b) + pre.k_abs;
            let ok_z = !GRAVITY || (dza - dzb).abs() <= pre.eps_z;
            pass[l] = (ok_d & ok_z) as u8;
        }
        if u64::from_ne_bytes(pass) != 0 {
            for (l, &p) in pass.iter().enumerate() {
                if p != 0 {
                    out.push((v0 + l) as u32);
                }
            }
        }
        v0 += LANES;
    }
    for v in v0..m {
        if lane_pass(v) {
            out.push(v as u32);
        }
    }
}
