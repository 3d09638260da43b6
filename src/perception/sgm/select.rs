//! Winner-takes-all for one row of aggregated costs, with the uniqueness test, the
//! left–right check against the right image's disparities (taken from the same sums) and
//! the parabolic sub-pixel offset.

use super::StereoConfig;

/// A sum and its disparity as one key: the smaller sum wins, ties go to the smaller
/// disparity (as a strict `<` scan in increasing disparity does).
#[inline(always)]
fn key(sum: u16, d: u32) -> u32 {
    ((sum as u32) << 16) | d
}

/// Disparities of one row. `sum[x nd + d]` are the summed path costs of all paths;
/// `textured` marks the pixels worth matching; `out` (NaN-filled) gets the disparities.
/// `best_rev` is scratch space. Call only from code compiled for the instruction set in
/// use (see `matcher.rs`).
#[inline(always)]
pub(super) fn select_row(
    sum: &[u16],
    nd: usize,
    config: &StereoConfig,
    textured: &[bool],
    out: &mut [f32],
    best_rev: &mut Vec<u32>,
) {
    let w = out.len();
    // Right image disparity dR(xr) = argmin_d S(xr + d, d), stored at w − 1 − xr so that
    // the slots one left pixel updates are contiguous in increasing d.
    best_rev.clear();
    best_rev.resize(w, u32::MAX);
    for x in 0..w {
        let dmax = nd.min(x + 1);
        let base = w - 1 - x;
        let s = &sum[x * nd..x * nd + dmax];
        for ((slot, &v), d) in best_rev[base..base + dmax].iter_mut().zip(s).zip(0u32..) {
            *slot = (*slot).min(key(v, d));
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
            .zip(0u32..)
            .map(|(&v, d)| key(v, d))
            .fold(u32::MAX, u32::min);
        let (best, bd) = ((winner >> 16) as u16, (winner & 0xFFFF) as usize);
        if bd == 0 || bd + 1 >= dmax {
            continue; // at the edge of the search range: no parabola, likely out of range
        }
        // uniqueness against every cost not adjacent to the winner
        let second = slice_min(&s[..bd - 1]).min(slice_min(&s[bd + 2..]));
        if second != u16::MAX && (best as f32) > keep * second as f32 {
            continue;
        }
        // left–right consistency
        let right_d = best_rev[w - 1 - (x - bd)] & 0xFFFF;
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
