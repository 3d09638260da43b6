//! AVX2 + FMA (+ POPCNT, BMI1) kernels of the pairwise scan (x86-64 only).
//!
//! The prefilter compares eight pairs at a time and left-packs the survivors with a
//! permutation table, without branches. The exact stage gathers four candidates at a time
//! and evaluates the invariant in `f64` with the same operations, in the same order, as
//! [`crate::association::PairTest::test_associations`] (no fused multiply-adds), so its
//! decisions and exponents are bit-identical to the scalar code.

#![cfg(target_arch = "x86_64")]

use std::arch::x86_64::*;

use super::scan::ScanData;

/// `LEFT_PACK[mask]`: lane indices of the set bits of `mask`, packed to the front (the rest
/// of the row is don't-care).
static LEFT_PACK: [[u32; 8]; 256] = left_pack_table();

const fn left_pack_table() -> [[u32; 8]; 256] {
    let mut t = [[0u32; 8]; 256];
    let mut mask = 0;
    while mask < 256 {
        let mut n = 0;
        let mut lane = 0;
        while lane < 8 {
            if mask & (1 << lane) != 0 {
                t[mask][n] = lane as u32;
                n += 1;
            }
            lane += 1;
        }
        mask += 1;
    }
    t
}

/// Appends row `u`'s neighbours `v > u` and their weight exponents.
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT and BMI1. `cand.len() >= m + 16`.
#[target_feature(enable = "avx2,fma,popcnt,bmi1")]
pub(crate) unsafe fn scan_row<const GRAVITY: bool>(
    d: &ScanData,
    u: usize,
    cand: &mut [u32],
    nbrs: &mut Vec<u32>,
    xs: &mut Vec<f32>,
) {
    let n = prefilter::<GRAVITY>(d, u, cand);
    exact::<GRAVITY>(d, u, &cand[..n], nbrs, xs);
}

/// Broadcast per-row constants of the prefilter.
#[derive(Clone, Copy)]
struct RowConsts {
    ax: __m256,
    ay: __m256,
    az: __m256,
    bx: __m256,
    by: __m256,
    bz: __m256,
    k: __m256,
    k_abs: __m256,
    eps_z: __m256,
    abs_mask: __m256,
}

/// Pass mask (8 bits) of the block of lanes whose coordinates are loaded from `p*` / `q*`.
#[inline(always)]
unsafe fn block_mask<const GRAVITY: bool>(
    c: &RowConsts,
    lx: __m256,
    ly: __m256,
    lz: __m256,
    mx: __m256,
    my: __m256,
    mz: __m256,
) -> u32 {
    let dx = _mm256_sub_ps(c.ax, lx);
    let dy = _mm256_sub_ps(c.ay, ly);
    let dza = _mm256_sub_ps(c.az, lz);
    let ex = _mm256_sub_ps(c.bx, mx);
    let ey = _mm256_sub_ps(c.by, my);
    let dzb = _mm256_sub_ps(c.bz, mz);
    let mut a = _mm256_fmadd_ps(dy, dy, _mm256_mul_ps(dx, dx));
    let mut b = _mm256_fmadd_ps(ey, ey, _mm256_mul_ps(ex, ex));
    if !GRAVITY {
        a = _mm256_fmadd_ps(dza, dza, a);
        b = _mm256_fmadd_ps(dzb, dzb, b);
    }
    let diff = _mm256_sub_ps(a, b);
    let lhs = _mm256_mul_ps(diff, diff);
    let rhs = _mm256_fmadd_ps(c.k, _mm256_add_ps(a, b), c.k_abs);
    let mut pass = _mm256_cmp_ps::<_CMP_LE_OQ>(lhs, rhs);
    if GRAVITY {
        let cz = _mm256_and_ps(_mm256_sub_ps(dza, dzb), c.abs_mask);
        pass = _mm256_and_ps(pass, _mm256_cmp_ps::<_CMP_LE_OQ>(cz, c.eps_z));
    }
    _mm256_movemask_ps(pass) as u32
}

/// Writes the indices `base + lane` of the set bits of `bits` to `out` (8 slots written).
#[inline(always)]
unsafe fn left_pack(out: *mut u32, bits: u32, base: __m256i) -> usize {
    let lanes = _mm256_loadu_si256(LEFT_PACK[bits as usize].as_ptr() as *const __m256i);
    _mm256_storeu_si256(out as *mut __m256i, _mm256_add_epi32(lanes, base));
    bits.count_ones() as usize
}

#[inline(never)]
#[target_feature(enable = "avx2,fma,popcnt,bmi1")]
unsafe fn prefilter<const GRAVITY: bool>(d: &ScanData, u: usize, cand: &mut [u32]) -> usize {
    let m = d.px.len();
    assert!(cand.len() >= m + 8);
    let c = RowConsts {
        ax: _mm256_set1_ps(d.px[u]),
        ay: _mm256_set1_ps(d.py[u]),
        az: _mm256_set1_ps(d.pz[u]),
        bx: _mm256_set1_ps(d.qx[u]),
        by: _mm256_set1_ps(d.qy[u]),
        bz: _mm256_set1_ps(d.qz[u]),
        k: _mm256_set1_ps(d.pre.k),
        k_abs: _mm256_set1_ps(d.pre.k_abs),
        eps_z: _mm256_set1_ps(d.pre.eps_z),
        abs_mask: _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff)),
    };
    let (px, py, pz) = (d.px.as_ptr(), d.py.as_ptr(), d.pz.as_ptr());
    let (qx, qy, qz) = (d.qx.as_ptr(), d.qy.as_ptr(), d.qz.as_ptr());
    let out = cand.as_mut_ptr();
    let mut n = 0usize;
    let mut v0 = u + 1;
    let eight = _mm256_set1_epi32(8);
    let mut base = _mm256_set1_epi32(v0 as i32);
    // Full blocks; every store writes 8 slots at n <= v0 - u - 1, within `cand`.
    while v0 + 8 <= m {
        let bits = block_mask::<GRAVITY>(
            &c,
            _mm256_loadu_ps(px.add(v0)),
            _mm256_loadu_ps(py.add(v0)),
            _mm256_loadu_ps(pz.add(v0)),
            _mm256_loadu_ps(qx.add(v0)),
            _mm256_loadu_ps(qy.add(v0)),
            _mm256_loadu_ps(qz.add(v0)),
        );
        n += left_pack(out.add(n), bits, base);
        base = _mm256_add_epi32(base, eight);
        v0 += 8;
    }
    if v0 < m {
        // last partial block: copy the valid lanes, mask the rest
        let valid = m - v0;
        let mut lanes = [0f32; 6 * 8];
        for (slot, src) in [&d.px, &d.py, &d.pz, &d.qx, &d.qy, &d.qz]
            .iter()
            .enumerate()
        {
            lanes[8 * slot..8 * slot + valid].copy_from_slice(&src[v0..m]);
        }
        let p = lanes.as_ptr();
        let bits = block_mask::<GRAVITY>(
            &c,
            _mm256_loadu_ps(p),
            _mm256_loadu_ps(p.add(8)),
            _mm256_loadu_ps(p.add(16)),
            _mm256_loadu_ps(p.add(24)),
            _mm256_loadu_ps(p.add(32)),
            _mm256_loadu_ps(p.add(40)),
        ) & ((1u32 << valid) - 1);
        n += left_pack(out.add(n), bits, base);
    }
    n
}

/// `LEFT_PACK4[mask]`: the 4-lane version of [`LEFT_PACK`].
static LEFT_PACK4: [[u32; 4]; 16] = {
    let mut t = [[0u32; 4]; 16];
    let mut mask = 0;
    while mask < 16 {
        let mut n = 0;
        let mut lane = 0;
        while lane < 4 {
            if mask & (1 << lane) != 0 {
                t[mask][n] = lane as u32;
                n += 1;
            }
            lane += 1;
        }
        mask += 1;
    }
    t
};

/// Exact `f64` stage on the prefilter's candidates.
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT and BMI1.
#[inline(never)]
#[target_feature(enable = "avx2,fma,popcnt,bmi1")]
unsafe fn exact<const GRAVITY: bool>(
    d: &ScanData,
    u: usize,
    cand: &[u32],
    nbrs: &mut Vec<u32>,
    xs: &mut Vec<f32>,
) {
    let t = &d.test;
    let au = d.associations[u];
    let upx = _mm256_set1_pd(d.px64[u]);
    let upy = _mm256_set1_pd(d.py64[u]);
    let upz = _mm256_set1_pd(d.pz64[u]);
    let uqx = _mm256_set1_pd(d.qx64[u]);
    let uqy = _mm256_set1_pd(d.qy64[u]);
    let uqz = _mm256_set1_pd(d.qz64[u]);
    let eps = _mm256_set1_pd(t.epsilon);
    let eps_z = _mm256_set1_pd(t.epsilon_z);
    let inv = _mm256_set1_pd(t.inv_two_sigma_sq);
    let inv_z = _mm256_set1_pd(t.inv_two_sigma_z_sq);
    let zero = _mm256_setzero_pd();
    let abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fff_ffff_ffff_ffff));
    // Accepted lanes are left-packed into spare capacity: every step writes 4 slots at
    // `len`, and `len` grows by at most 4 per step, so `cand.len() + 4` slots suffice.
    nbrs.reserve(cand.len() + 4);
    xs.reserve(cand.len() + 4);
    let mut len = nbrs.len();
    debug_assert_eq!(len, xs.len());
    let nb_ptr = nbrs.as_mut_ptr();
    let x_ptr = xs.as_mut_ptr();
    let mut k = 0;
    while k < cand.len() {
        let valid = (cand.len() - k).min(4);
        let mut idx4 = [cand[k]; 4];
        idx4[..valid].copy_from_slice(&cand[k..k + valid]);
        let idx = _mm_loadu_si128(idx4.as_ptr() as *const __m128i);
        let g = |base: &[f64]| _mm256_i32gather_pd::<8>(base.as_ptr(), idx);
        let dxa = _mm256_sub_pd(upx, g(&d.px64));
        let dya = _mm256_sub_pd(upy, g(&d.py64));
        let dza = _mm256_sub_pd(upz, g(&d.pz64));
        let dxb = _mm256_sub_pd(uqx, g(&d.qx64));
        let dyb = _mm256_sub_pd(uqy, g(&d.qy64));
        let dzb = _mm256_sub_pd(uqz, g(&d.qz64));
        // (dx*dx + dy*dy) [+ dz*dz], exactly as PairTest::measure
        let mut sa = _mm256_add_pd(_mm256_mul_pd(dxa, dxa), _mm256_mul_pd(dya, dya));
        let mut sb = _mm256_add_pd(_mm256_mul_pd(dxb, dxb), _mm256_mul_pd(dyb, dyb));
        if !GRAVITY {
            sa = _mm256_add_pd(sa, _mm256_mul_pd(dza, dza));
            sb = _mm256_add_pd(sb, _mm256_mul_pd(dzb, dzb));
        }
        let c = _mm256_and_pd(
            _mm256_sub_pd(_mm256_sqrt_pd(sa), _mm256_sqrt_pd(sb)),
            abs_mask,
        );
        let mut ok = _mm256_cmp_pd::<_CMP_LT_OQ>(c, eps);
        let mut x = _mm256_mul_pd(_mm256_mul_pd(c, c), inv);
        if GRAVITY {
            let cz = _mm256_and_pd(_mm256_sub_pd(dza, dzb), abs_mask);
            ok = _mm256_and_pd(ok, _mm256_cmp_pd::<_CMP_LT_OQ>(cz, eps_z));
            x = _mm256_add_pd(x, _mm256_mul_pd(_mm256_mul_pd(cz, cz), inv_z));
        }
        let mut bits = (_mm256_movemask_pd(ok) as u32) & ((1u32 << valid) - 1);
        // One-to-one rule: a shared point makes one of the two lengths exactly zero, so
        // only those lanes need the index check.
        let zero_len = _mm256_or_pd(
            _mm256_cmp_pd::<_CMP_EQ_OQ>(sa, zero),
            _mm256_cmp_pd::<_CMP_EQ_OQ>(sb, zero),
        );
        let mut suspicious = bits & (_mm256_movemask_pd(zero_len) as u32);
        while suspicious != 0 {
            let lane = suspicious.trailing_zeros();
            suspicious &= suspicious - 1;
            let av = d.associations[idx4[lane as usize] as usize];
            if av.prior == au.prior || av.query == au.query {
                bits &= !(1 << lane);
            }
        }
        let perm = _mm_loadu_si128(LEFT_PACK4[bits as usize].as_ptr() as *const __m128i);
        let packed_idx = _mm_castps_si128(_mm_permutevar_ps(_mm_castsi128_ps(idx), perm));
        let packed_x = _mm_permutevar_ps(_mm256_cvtpd_ps(x), perm);
        // SAFETY: len + 4 <= old len + cand.len() + 4 <= capacity (reserved above).
        _mm_storeu_si128(nb_ptr.add(len) as *mut __m128i, packed_idx);
        _mm_storeu_ps(x_ptr.add(len), packed_x);
        len += bits.count_ones() as usize;
        k += 4;
    }
    // SAFETY: the first `len` slots are initialised (written above or before the call).
    nbrs.set_len(len);
    xs.set_len(len);
}
