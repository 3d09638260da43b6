//! Winner-takes-all for one row of aggregated costs, with the uniqueness test, the
//! left–right check against the right image's disparities (taken from the same sums) and
//! the parabolic sub-pixel offset.

use super::StereoConfig;

/// A sum and its disparity as one key, `sum << shift | d`: the smaller sum wins, ties go to
/// the smaller disparity (as a strict `<` scan in increasing disparity does). 16-bit keys
/// (16 per AVX2 register) when the largest sum fits, as with the defaults (4 × 96 = 384
/// with 7 bits for 96 disparities); 32-bit keys otherwise.
trait Key: Copy + Ord {
    const MAX: Self;
    fn make(sum: u16, d: usize, shift: u32) -> Self;
    fn split(self, shift: u32) -> (u16, usize);
}

impl Key for u16 {
    const MAX: u16 = u16::MAX;
    #[inline(always)]
    fn make(sum: u16, d: usize, shift: u32) -> u16 {
        (sum << shift) | d as u16
    }
    #[inline(always)]
    fn split(self, shift: u32) -> (u16, usize) {
        (self >> shift, (self & ((1 << shift) - 1)) as usize)
    }
}

impl Key for u32 {
    const MAX: u32 = u32::MAX;
    #[inline(always)]
    fn make(sum: u16, d: usize, shift: u32) -> u32 {
        ((sum as u32) << shift) | d as u32
    }
    #[inline(always)]
    fn split(self, shift: u32) -> (u16, usize) {
        ((self >> shift) as u16, (self & ((1 << shift) - 1)) as usize)
    }
}

/// Scratch space of [`select_row`]: the right image's best keys.
#[derive(Clone, Debug, Default)]
pub(super) struct SelectScratch {
    narrow: Vec<u16>,
    wide: Vec<u32>,
}

/// Disparities of one row. `sum[x nd + d]` are the summed path costs of all paths, at most
/// `max_sum`; `textured` marks the pixels worth matching; `out` (NaN-filled) gets the
/// disparities. Call only from code compiled for the instruction set in use (see
/// `matcher.rs`).
#[inline(always)]
pub(super) fn select_row(
    sum: &[u16],
    nd: usize,
    max_sum: u32,
    config: &StereoConfig,
    textured: &[bool],
    out: &mut [f32],
    scratch: &mut SelectScratch,
) {
    let d_bits = usize::BITS - (nd - 1).leading_zeros();
    if ((max_sum as u64) << d_bits) + nd as u64 <= u16::MAX as u64 {
        select_keys(sum, nd, d_bits, config, textured, out, &mut scratch.narrow);
    } else {
        select_keys(sum, nd, 16, config, textured, out, &mut scratch.wide);
    }
}

#[inline(always)]
fn select_keys<K: Key>(
    sum: &[u16],
    nd: usize,
    shift: u32,
    config: &StereoConfig,
    textured: &[bool],
    out: &mut [f32],
    best_rev: &mut Vec<K>,
) {
    let w = out.len();
    // Right image disparity dR(xr) = argmin_d S(xr + d, d), stored at w − 1 − xr so that
    // the slots one left pixel updates are contiguous in increasing d.
    best_rev.clear();
    best_rev.resize(w, K::MAX);
    for x in 0..w {
        let dmax = nd.min(x + 1);
        let base = w - 1 - x;
        let s = &sum[x * nd..x * nd + dmax];
        for (d, (slot, &v)) in best_rev[base..base + dmax].iter_mut().zip(s).enumerate() {
            *slot = (*slot).min(K::make(v, d, shift));
        }
    }
    let keep = 1.0 - config.uniqueness;
    for x in 0..w {
        if !textured[x] {
            continue;
        }
        let dmax = nd.min(x + 1);
        let s = &sum[x * nd..x * nd + dmax];
        let winner = s
            .iter()
            .enumerate()
            .map(|(d, &v)| K::make(v, d, shift))
            .fold(K::MAX, K::min);
        let (best, bd) = winner.split(shift);
        if bd == 0 || bd + 1 >= dmax {
            continue; // at the edge of the search range: no parabola, likely out of range
        }
        // uniqueness against every cost not adjacent to the winner
        let second = slice_min(&s[..bd - 1]).min(slice_min(&s[bd + 2..]));
        if second != u16::MAX && (best as f32) > keep * second as f32 {
            continue;
        }
        // left–right consistency
        let (_, right_d) = best_rev[w - 1 - (x - bd)].split(shift);
        if (right_d as f32 - bd as f32).abs() > config.lr_tolerance {
            continue;
        }
        let (a, b, c) = (s[bd - 1] as f32, s[bd] as f32, s[bd + 1] as f32);
        let denom = a - 2.0 * b + c;
        let offset = if denom > 0.0 {
            0.5 * (a - c) / denom
        } else {
            0.0
        };
        out[x] = bd as f32 + offset.clamp(-0.5, 0.5);
    }
}

#[inline(always)]
fn slice_min(s: &[u16]) -> u16 {
    s.iter().copied().fold(u16::MAX, u16::min)
}
