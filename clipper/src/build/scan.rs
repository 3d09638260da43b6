//! Pairwise-scan graph build: every association pair is tested, with a vectorised
//! single-precision prefilter and an exact double-precision decision.
//!
//! The prefilter avoids square roots: for distances `da = sqrt(A)`, `db = sqrt(B)`,
//! `|da - db| < e` implies `(A - B)^2 = (da - db)^2 (da + db)^2 < e^2 (da + db)^2 <= 2 e^2 (A + B)`.
//! It runs on map-centred `f32` coordinates with a widened threshold that covers their
//! rounding, so it never rejects a consistent pair; the survivors (a few percent) are then
//! decided in `f64` on the original points with exactly the arithmetic of
//! [`PairTest::test_associations`] (the function the join uses), so both builders give
//! identical graphs. On x86-64 with AVX2 and FMA both stages run in explicit SIMD
//! ([`super::scan_avx2`]; an AVX-512 prefilter measured no faster); elsewhere a portable
//! version runs.

use nalgebra::Point3;
use rayon::prelude::*;

use crate::association::{exponents_to_weights, PairTest};
use crate::graph::UpperRows;
use crate::{Association, ConsistencyGraph};

/// Lanes of one portable prefilter block.
const LANES: usize = 8;

/// Everything one row of the scan needs.
pub(crate) struct ScanData<'a> {
    /// Map-centred `f32` coordinates of each association's prior point (x, y, z) and query
    /// point (x, y, z), structure of arrays.
    pub px: Vec<f32>,
    pub py: Vec<f32>,
    pub pz: Vec<f32>,
    pub qx: Vec<f32>,
    pub qy: Vec<f32>,
    pub qz: Vec<f32>,
    /// Original `f64` coordinates, same layout.
    pub px64: Vec<f64>,
    pub py64: Vec<f64>,
    pub pz64: Vec<f64>,
    pub qx64: Vec<f64>,
    pub qy64: Vec<f64>,
    pub qz64: Vec<f64>,
    pub prior: &'a [Point3<f64>],
    pub query: &'a [Point3<f64>],
    pub associations: &'a [Association],
    pub pre: Prefilter,
    /// False when coordinates or thresholds are too large for the `f32` prefilter; then
    /// every pair goes to the exact stage.
    pub prefilter_usable: bool,
    pub test: PairTest,
}

/// Thresholds of the prefilter (already widened).
#[derive(Clone, Copy)]
pub(crate) struct Prefilter {
    /// `2 e'^2`.
    pub k: f32,
    /// `e'^4`: keeps pairs of coincident points.
    pub k_abs: f32,
    /// Height threshold `e_z'` (4-DOF only).
    pub eps_z: f32,
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

/// Which kernels a build uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kernel {
    Portable,
    #[cfg(target_arch = "x86_64")]
    Avx2,
}

impl Kernel {
    /// The fastest kernel this CPU supports.
    pub fn detect() -> Self {
        Self::available().pop().unwrap_or(Kernel::Portable)
    }

    /// Every kernel this CPU supports, slowest first (the portable one is always there).
    pub fn available() -> Vec<Self> {
        #[allow(unused_mut)]
        let mut kernels = vec![Kernel::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            if has!("avx2") && has!("fma") && has!("popcnt") && has!("bmi1") {
                kernels.push(Kernel::Avx2);
            }
        }
        kernels
    }
}

/// Builds the consistency graph by testing every pair of associations.
pub(crate) fn build(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
    test: &PairTest,
    kernel: Kernel,
) -> ConsistencyGraph {
    let m = associations.len();
    let data = ScanData::new(prior, query, associations, test);
    let chunks = super::balanced_row_chunks(m);
    let rows: Vec<UpperRows> = chunks
        .par_iter()
        .map(|&(r0, r1)| {
            let mut out = UpperRows {
                counts: Vec::with_capacity(r1 - r0),
                ..UpperRows::default()
            };
            let mut cand = vec![0u32; m + 16];
            for u in r0..r1 {
                let before = out.neighbors.len();
                data.scan_row(kernel, u, &mut cand, &mut out.neighbors, &mut out.weights);
                out.counts.push((out.neighbors.len() - before) as u32);
            }
            exponents_to_weights(&mut out.weights);
            out
        })
        .collect();
    ConsistencyGraph::from_upper_chunks(m, &rows)
}

impl<'a> ScanData<'a> {
    fn new(
        prior: &'a [Point3<f64>],
        query: &'a [Point3<f64>],
        associations: &'a [Association],
        test: &PairTest,
    ) -> Self {
        let m = associations.len();
        let cp = centre(prior);
        let cq = centre(query);
        let mut scale = 0.0f64;
        let mut d = ScanData {
            px: Vec::with_capacity(m),
            py: Vec::with_capacity(m),
            pz: Vec::with_capacity(m),
            qx: Vec::with_capacity(m),
            qy: Vec::with_capacity(m),
            qz: Vec::with_capacity(m),
            px64: Vec::with_capacity(m),
            py64: Vec::with_capacity(m),
            pz64: Vec::with_capacity(m),
            qx64: Vec::with_capacity(m),
            qy64: Vec::with_capacity(m),
            qz64: Vec::with_capacity(m),
            prior,
            query,
            associations,
            pre: Prefilter {
                k: 0.0,
                k_abs: 0.0,
                eps_z: 0.0,
            },
            prefilter_usable: true,
            test: *test,
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
            d.px.push(c[0] as f32);
            d.py.push(c[1] as f32);
            d.pz.push(c[2] as f32);
            d.qx.push(c[3] as f32);
            d.qy.push(c[4] as f32);
            d.qz.push(c[5] as f32);
            d.px64.push(p.x);
            d.py64.push(p.y);
            d.pz64.push(p.z);
            d.qx64.push(q.x);
            d.qy64.push(q.y);
            d.qz64.push(q.z);
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
        d.pre = Prefilter {
            k: (2.0 * eps * eps) as f32,
            k_abs: (eps * eps * eps * eps) as f32,
            eps_z: eps_z as f32,
        };
        // squared lengths (up to ~12 scale^2) and e'^4 must stay finite in f32
        d.prefilter_usable = scale < 1e15 && d.pre.k_abs.is_finite() && d.pre.k.is_finite();
        d
    }

    /// Appends row `u`'s neighbours `v > u` and their weight exponents. `cand` is scratch of
    /// length at least `m + 16`.
    fn scan_row(
        &self,
        kernel: Kernel,
        u: usize,
        cand: &mut [u32],
        nbrs: &mut Vec<u32>,
        xs: &mut Vec<f32>,
    ) {
        if !self.prefilter_usable {
            let au = self.associations[u];
            for v in u + 1..self.associations.len() {
                if let Some(x) =
                    self.test
                        .test_associations(self.prior, self.query, au, self.associations[v])
                {
                    nbrs.push(v as u32);
                    xs.push(x);
                }
            }
            return;
        }
        match kernel {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => {
                // SAFETY: `Kernel::Avx2` is only chosen when the CPU has AVX2, FMA, POPCNT and BMI1.
                unsafe {
                    if self.test.gravity {
                        super::scan_avx2::scan_row::<true>(self, u, cand, nbrs, xs)
                    } else {
                        super::scan_avx2::scan_row::<false>(self, u, cand, nbrs, xs)
                    }
                }
            }
            Kernel::Portable => {
                let n = if self.test.gravity {
                    prefilter_row_generic::<true>(self, u, cand)
                } else {
                    prefilter_row_generic::<false>(self, u, cand)
                };
                let au = self.associations[u];
                for &v in &cand[..n] {
                    if let Some(x) = self.test.test_associations(
                        self.prior,
                        self.query,
                        au,
                        self.associations[v as usize],
                    ) {
                        nbrs.push(v);
                        xs.push(x);
                    }
                }
            }
        }
    }
}

/// Portable prefilter: writes every `v > u` that passes into `cand`, returns how many.
/// Blocks of [`LANES`] lanes are written branch-free so that they vectorise.
fn prefilter_row_generic<const GRAVITY: bool>(d: &ScanData, u: usize, cand: &mut [u32]) -> usize {
    let m = d.px.len();
    let pre = d.pre;
    let (ax, ay, az) = (d.px[u], d.py[u], d.pz[u]);
    let (bx, by, bz) = (d.qx[u], d.qy[u], d.qz[u]);
    let lane_pass = |px: f32, py: f32, pz: f32, qx: f32, qy: f32, qz: f32| -> bool {
        let dx = ax - px;
        let dy = ay - py;
        let dza = az - pz;
        let ex = bx - qx;
        let ey = by - qy;
        let dzb = bz - qz;
        let mut a = dx * dx + dy * dy;
        let mut b = ex * ex + ey * ey;
        if !GRAVITY {
            a += dza * dza;
            b += dzb * dzb;
        }
        let diff = a - b;
        let ok_d = diff * diff <= pre.k * (a + b) + pre.k_abs;
        let ok_z = !GRAVITY || (dza - dzb).abs() <= pre.eps_z;
        ok_d & ok_z
    };
    let mut n = 0;
    let mut v0 = u + 1;
    while v0 + LANES <= m {
        let px = &d.px[v0..v0 + LANES];
        let py = &d.py[v0..v0 + LANES];
        let pz = &d.pz[v0..v0 + LANES];
        let qx = &d.qx[v0..v0 + LANES];
        let qy = &d.qy[v0..v0 + LANES];
        let qz = &d.qz[v0..v0 + LANES];
        let mut pass = [0u8; LANES];
        for l in 0..LANES {
            pass[l] = lane_pass(px[l], py[l], pz[l], qx[l], qy[l], qz[l]) as u8;
        }
        if u64::from_ne_bytes(pass) != 0 {
            for (l, &p) in pass.iter().enumerate() {
                if p != 0 {
                    cand[n] = (v0 + l) as u32;
                    n += 1;
                }
            }
        }
        v0 += LANES;
    }
    for v in v0..m {
        if lane_pass(d.px[v], d.py[v], d.pz[v], d.qx[v], d.qy[v], d.qz[v]) {
            cand[n] = v as u32;
            n += 1;
        }
    }
    n
}
