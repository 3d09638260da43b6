//! Semi-global matching (Hirschmüller 2008) on census costs: dense disparity for a rectified
//! grayscale pair.
//!
//! Steps: optional reduction of both images by 2^levels; census transform; Hamming cost
//! volume; aggregation along 4 or 8 image paths with the penalties P1 (disparity steps of 1)
//! and P2 (larger jumps); winner-takes-all with a uniqueness test; a left–right consistency
//! check against the right image's disparities taken from the same aggregated volume;
//! parabolic sub-pixel refinement; removal of weakly textured pixels and small speckles.
//!
//! The two aggregation sweeps (top-down with left-to-right, bottom-up with right-to-left)
//! are independent and run on two threads.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::census::{census_bits, census_transform};
use super::{DisparityMap, GrayImage, PerceptionError, StereoCamera};

/// Semi-global matching settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StereoConfig {
    /// Work on images reduced by 2^levels (0 = full resolution; 1 = half, the default,
    /// which keeps a 1280 × 720 pair within the 100 ms budget on two cores).
    pub levels: u32,
    /// Disparities searched, at the working resolution (0 .. max_disparity − 1). At half
    /// resolution 96 reaches down to 0.77 m.
    pub max_disparity: usize,
    /// Census window radius (3 = 7 × 7, the maximum).
    pub census_radius: usize,
    /// Penalty for a disparity change of one pixel between neighbours.
    pub p1: u16,
    /// Penalty for larger disparity jumps.
    pub p2: u16,
    /// Aggregation paths: 4 (horizontal and vertical) or 8 (also the diagonals).
    pub paths: u8,
    /// Uniqueness margin: the best cost must beat every non-adjacent cost by this fraction.
    pub uniqueness: f32,
    /// Largest disagreement between left and right disparity, pixels.
    pub lr_tolerance: f32,
    /// Smallest local intensity standard deviation (7 × 7, gray levels) for a match to be
    /// trusted: the black sky and deep shadows have none.
    pub min_texture: f32,
    /// Connected patches of similar disparity smaller than this (pixels) are removed.
    pub speckle_max_area: usize,
    /// Disparity difference that still connects two neighbours in the speckle filter.
    pub speckle_max_diff: f32,
}

impl Default for StereoConfig {
    fn default() -> Self {
        StereoConfig {
            levels: 1,
            max_disparity: 96,
            census_radius: 3,
            p1: 6,
            p2: 48,
            paths: 4,
            uniqueness: 0.05,
            lr_tolerance: 1.0,
            min_texture: 2.0,
            speckle_max_area: 40,
            speckle_max_diff: 1.0,
        }
    }
}

impl StereoConfig {
    /// Check the values are usable.
    pub fn validate(&self) -> Result<(), PerceptionError> {
        let bad = |m: &str| Err(PerceptionError::Config(format!("stereo: {m}")));
        if !(4..=1024).contains(&self.max_disparity) {
            return bad("max_disparity must be within 4..=1024");
        }
        if self.census_radius == 0 || self.census_radius > 3 {
            return bad("census_radius must be 1, 2 or 3");
        }
        if self.paths != 4 && self.paths != 8 {
            return bad("paths must be 4 or 8");
        }
        if self.p1 == 0 || self.p2 < self.p1 || self.p2 > 1000 {
            return bad("need 0 < p1 <= p2 <= 1000");
        }
        if self.levels > 3 {
            return bad("levels must be at most 3");
        }
        if !(0.0..1.0).contains(&self.uniqueness)
            || self.lr_tolerance.is_nan()
            || self.lr_tolerance < 0.0
        {
            return bad("uniqueness must be in [0, 1) and lr_tolerance >= 0");
        }
        Ok(())
    }
}

/// Buffers reused from one pair to the next (the cost volume and the two sweep sums, about
/// 110 MB at half resolution with 96 disparities), so a stream of frames does not pay for
/// fresh memory every time.
#[derive(Clone, Debug, Default)]
pub struct StereoScratch {
    cost: Vec<u8>,
    down: Vec<u16>,
    up: Vec<u16>,
}

/// Dense disparity of the left image of a rectified pair (same size; the camera must match
/// the images). The result is at the working resolution (see [`StereoConfig::levels`]).
pub fn compute_disparity(
    left: &GrayImage,
    right: &GrayImage,
    camera: &StereoCamera,
    config: &StereoConfig,
) -> Result<DisparityMap, PerceptionError> {
    compute_disparity_with(left, right, camera, config, &mut StereoScratch::default())
}

/// [`compute_disparity`] reusing the buffers of `scratch`.
pub fn compute_disparity_with(
    left: &GrayImage,
    right: &GrayImage,
    camera: &StereoCamera,
    config: &StereoConfig,
    scratch: &mut StereoScratch,
) -> Result<DisparityMap, PerceptionError> {
    config.validate()?;
    if left.width != right.width || left.height != right.height {
        return Err(PerceptionError::ImageSize {
            path: "<stereo pair>".into(),
            message: format!(
                "left is {} × {} but right is {} × {}",
                left.width, left.height, right.width, right.height
            ),
        });
    }
    let camera = camera.for_size(left.width, left.height)?;
    let (l, r) = rayon::join(
        || left.reduced(config.levels),
        || right.reduced(config.levels),
    );
    let (w, h) = (l.width, l.height);
    if w < 2 * config.census_radius + 2 || h < 2 * config.census_radius + 2 {
        return Err(PerceptionError::ImageSize {
            path: "<stereo pair>".into(),
            message: format!("images too small for stereo at the working resolution ({w} × {h})"),
        });
    }
    let scale = 1usize << config.levels;
    let map_camera = camera.scaled(1.0 / scale as f64, w, h);
    let nd = config.max_disparity.min(w - 1).max(2);

    let (cl, cr) = rayon::join(
        || census_transform(&l, config.census_radius),
        || census_transform(&r, config.census_radius),
    );
    let StereoScratch { cost, down, up } = scratch;
    cost_volume(
        &cl,
        &cr,
        w,
        h,
        nd,
        census_bits(config.census_radius) as u8,
        cost,
    );
    drop((cl, cr));

    let diagonals = config.paths == 8;
    let (p1, p2) = (config.p1, config.p2);
    let cost: &[u8] = cost;
    rayon::join(
        || aggregate_sweep(cost, w, h, nd, true, diagonals, p1, p2, down),
        || aggregate_sweep(cost, w, h, nd, false, diagonals, p1, p2, up),
    );
    let (down, up): (&[u16], &[u16]) = (down, up);

    let texture = texture_mask(&l, config.min_texture);
    let mut data = vec![f32::NAN; w * h];
    data.par_chunks_mut(w).enumerate().for_each_with(
        (Vec::new(), Vec::new()),
        |(sum, best_right), (y, out)| {
            let a = &down[y * w * nd..(y + 1) * w * nd];
            let b = &up[y * w * nd..(y + 1) * w * nd];
            let textured = &texture[y * w..(y + 1) * w];
            select_row(a, b, w, nd, config, textured, out, sum, best_right);
        },
    );
    if config.speckle_max_area > 0 {
        remove_speckles(
            &mut data,
            w,
            h,
            config.speckle_max_area,
            config.speckle_max_diff,
        );
    }
    Ok(DisparityMap {
        width: w,
        height: h,
        data,
        scale,
        camera: map_camera,
    })
}

/// Hamming costs `cost[(y w + x) nd + d]` between left pixel x and right pixel x − d;
/// `max_cost` where x − d falls outside the image.
fn cost_volume(
    cl: &[u64],
    cr: &[u64],
    w: usize,
    h: usize,
    nd: usize,
    max_cost: u8,
    cost: &mut Vec<u8>,
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU supports AVX2 and POPCNT (checked just above).
        return unsafe { cost_volume_avx2(cl, cr, w, h, nd, max_cost, cost) };
    }
    cost_volume_generic(cl, cr, w, h, nd, max_cost, cost)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn cost_volume_avx2(
    cl: &[u64],
    cr: &[u64],
    w: usize,
    h: usize,
    nd: usize,
    max_cost: u8,
    cost: &mut Vec<u8>,
) {
    cost_volume_generic(cl, cr, w, h, nd, max_cost, cost)
}

#[inline(always)]
fn cost_volume_generic(
    cl: &[u64],
    cr: &[u64],
    w: usize,
    h: usize,
    nd: usize,
    max_cost: u8,
    cost: &mut Vec<u8>,
) {
    cost.clear();
    cost.resize(w * h * nd, max_cost);
    cost.par_chunks_mut(w * nd)
        .enumerate()
        .for_each(|(y, row)| {
            let l = &cl[y * w..(y + 1) * w];
            let r = &cr[y * w..(y + 1) * w];
            for (x, c) in row.chunks_exact_mut(nd).enumerate() {
                let lx = l[x];
                let dmax = nd.min(x + 1);
                for (d, c) in c[..dmax].iter_mut().enumerate() {
                    *c = (lx ^ r[x - d]).count_ones() as u8;
                }
            }
        });
}

/// One SGM path step: `out[d] = cost[d] + min(prev[d], prev[d±1] + p1, min(prev) + p2) −
/// min(prev)`. Returns `min(out)`.
#[inline(always)]
fn path_step(cost: &[u8], prev: &[u16], prev_min: u16, out: &mut [u16], p1: u16, p2: u16) -> u16 {
    let n = cost.len();
    let jump = prev_min + p2;
    out[0] = cost[0] as u16 + prev[0].min(prev[1] + p1).min(jump) - prev_min;
    out[n - 1] = cost[n - 1] as u16 + prev[n - 1].min(prev[n - 2] + p1).min(jump) - prev_min;
    let (lo, mid, hi) = (&prev[..n - 2], &prev[1..n - 1], &prev[2..]);
    for ((((o, &c), &a), &b), &z) in out[1..n - 1]
        .iter_mut()
        .zip(&cost[1..n - 1])
        .zip(lo)
        .zip(mid)
        .zip(hi)
    {
        *o = c as u16 + b.min(a + p1).min(z + p1).min(jump) - prev_min;
    }
    out.iter().copied().fold(u16::MAX, u16::min)
}

/// Start a path: `out = cost`, returns its minimum.
#[inline(always)]
fn path_start(cost: &[u8], out: &mut [u16]) -> u16 {
    for (o, &c) in out.iter_mut().zip(cost) {
        *o = c as u16;
    }
    out.iter().copied().fold(u16::MAX, u16::min)
}

#[inline(always)]
fn accumulate(sum: &mut [u16], l: &[u16]) {
    for (s, &v) in sum.iter_mut().zip(l) {
        *s += v;
    }
}

/// The aggregated cost of one sweep. `forward`: rows top to bottom with the left-to-right
/// horizontal path, the downward vertical path and (with `diagonals`) the two downward
/// diagonals; otherwise the mirror image (bottom to top, right to left, upward paths).
fn aggregate_sweep(
    cost: &[u8],
    w: usize,
    h: usize,
    nd: usize,
    forward: bool,
    diagonals: bool,
    p1: u16,
    p2: u16,
    sum: &mut Vec<u16>,
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { aggregate_sweep_avx2(cost, w, h, nd, forward, diagonals, p1, p2, sum) };
    }
    aggregate_sweep_generic(cost, w, h, nd, forward, diagonals, p1, p2, sum)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn aggregate_sweep_avx2(
    cost: &[u8],
    w: usize,
    h: usize,
    nd: usize,
    forward: bool,
    diagonals: bool,
    p1: u16,
    p2: u16,
    sum: &mut Vec<u16>,
) {
    aggregate_sweep_generic(cost, w, h, nd, forward, diagonals, p1, p2, sum)
}

#[inline(always)]
fn aggregate_sweep_generic(
    cost: &[u8],
    w: usize,
    h: usize,
    nd: usize,
    forward: bool,
    diagonals: bool,
    p1: u16,
    p2: u16,
    sum: &mut Vec<u16>,
) {
    sum.clear();
    sum.resize(w * h * nd, 0);
    let mut h_buf = [vec![0u16; nd], vec![0u16; nd]];
    let mut v_prev = vec![0u16; w * nd];
    let mut v_cur = vec![0u16; w * nd];
    let mut v_prev_min = vec![0u16; w];
    let mut v_cur_min = vec![0u16; w];
    let n_diag = if diagonals { 2 } else { 0 };
    let mut d_prev = vec![vec![0u16; w * nd]; n_diag];
    let mut d_cur = vec![vec![0u16; w * nd]; n_diag];
    let mut d_prev_min = vec![vec![0u16; w]; n_diag];
    let mut d_cur_min = vec![vec![0u16; w]; n_diag];

    for step in 0..h {
        let y = if forward { step } else { h - 1 - step };
        let row_cost = &cost[y * w * nd..(y + 1) * w * nd];
        let row_sum = &mut sum[y * w * nd..(y + 1) * w * nd];
        // horizontal path
        let mut h_min = 0u16;
        for i in 0..w {
            let x = if forward { i } else { w - 1 - i };
            let c = &row_cost[x * nd..(x + 1) * nd];
            let [prev, cur] = &mut h_buf;
            h_min = if i == 0 {
                path_start(c, cur)
            } else {
                path_step(c, prev, h_min, cur, p1, p2)
            };
            accumulate(&mut row_sum[x * nd..(x + 1) * nd], cur);
            h_buf.swap(0, 1);
        }
        // vertical path
        for x in 0..w {
            let c = &row_cost[x * nd..(x + 1) * nd];
            let cur = &mut v_cur[x * nd..(x + 1) * nd];
            v_cur_min[x] = if step == 0 {
                path_start(c, cur)
            } else {
                path_step(c, &v_prev[x * nd..(x + 1) * nd], v_prev_min[x], cur, p1, p2)
            };
            accumulate(&mut row_sum[x * nd..(x + 1) * nd], cur);
        }
        std::mem::swap(&mut v_prev, &mut v_cur);
        std::mem::swap(&mut v_prev_min, &mut v_cur_min);
        // diagonal paths: predecessor in the previous row at x − 1 and at x + 1
        for k in 0..n_diag {
            for x in 0..w {
                let c = &row_cost[x * nd..(x + 1) * nd];
                let px = if k == 0 {
                    x.checked_sub(1)
                } else {
                    Some(x + 1).filter(|&p| p < w)
                };
                let cur = &mut d_cur[k][x * nd..(x + 1) * nd];
                d_cur_min[k][x] = match px {
                    Some(px) if step > 0 => path_step(
                        c,
                        &d_prev[k][px * nd..(px + 1) * nd],
                        d_prev_min[k][px],
                        cur,
                        p1,
                        p2,
                    ),
                    _ => path_start(c, cur),
                };
                accumulate(&mut row_sum[x * nd..(x + 1) * nd], cur);
            }
        }
        for k in 0..n_diag {
            std::mem::swap(&mut d_prev[k], &mut d_cur[k]);
            std::mem::swap(&mut d_prev_min[k], &mut d_cur_min[k]);
        }
    }
}

/// Winner-takes-all for one row with uniqueness, left–right check and sub-pixel parabola.
/// `a` and `b` are the row's two sweep sums; `sum` and `best_right` are scratch space.
fn select_row(
    a: &[u16],
    b: &[u16],
    w: usize,
    nd: usize,
    config: &StereoConfig,
    textured: &[bool],
    out: &mut [f32],
    sum: &mut Vec<u16>,
    best_right: &mut Vec<(u16, u16)>,
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { select_row_avx2(a, b, w, nd, config, textured, out, sum, best_right) };
    }
    select_row_generic(a, b, w, nd, config, textured, out, sum, best_right)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn select_row_avx2(
    a: &[u16],
    b: &[u16],
    w: usize,
    nd: usize,
    config: &StereoConfig,
    textured: &[bool],
    out: &mut [f32],
    sum: &mut Vec<u16>,
    best_right: &mut Vec<(u16, u16)>,
) {
    select_row_generic(a, b, w, nd, config, textured, out, sum, best_right)
}

#[inline(always)]
fn slice_min(s: &[u16]) -> u16 {
    s.iter().copied().fold(u16::MAX, u16::min)
}

#[inline(always)]
fn select_row_generic(
    a: &[u16],
    b: &[u16],
    w: usize,
    nd: usize,
    config: &StereoConfig,
    textured: &[bool],
    out: &mut [f32],
    sum: &mut Vec<u16>,
    best_right: &mut Vec<(u16, u16)>,
) {
    sum.clear();
    sum.extend(a.iter().zip(b).map(|(x, y)| x + y));
    // right image disparities from the same volume: dR(xr) = argmin_d S(xr + d, d)
    best_right.clear();
    best_right.resize(w, (u16::MAX, 0));
    for x in 0..w {
        let s = &sum[x * nd..(x + 1) * nd];
        let dmax = nd.min(x + 1);
        for (d, &v) in s[..dmax].iter().enumerate() {
            let slot = &mut best_right[x - d];
            if v < slot.0 {
                *slot = (v, d as u16);
            }
        }
    }
    let keep = 1.0 - config.uniqueness;
    for x in 0..w {
        if !textured[x] {
            continue;
        }
        let s = &sum[x * nd..(x + 1) * nd];
        let dmax = nd.min(x + 1);
        let s = &s[..dmax];
        let best = slice_min(s);
        let Some(bd) = s.iter().position(|&v| v == best) else {
            continue;
        };
        if bd == 0 || bd + 1 >= dmax {
            continue; // at the edge of the search range: no parabola, likely out of range
        }
        // uniqueness against every cost not adjacent to the winner
        let second = slice_min(&s[..bd - 1]).min(slice_min(&s[(bd + 2).min(dmax)..]));
        if second != u16::MAX && (best as f32) > keep * second as f32 {
            continue;
        }
        // left-right consistency
        let xr = x - bd;
        if (best_right[xr].1 as f32 - bd as f32).abs() > config.lr_tolerance {
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

/// Pixels whose 7 × 7 intensity standard deviation is at least `min_std`.
fn texture_mask(image: &GrayImage, min_std: f32) -> Vec<bool> {
    let (w, h) = (image.width, image.height);
    let iw = w + 1;
    let mut s1 = vec![0u64; iw * (h + 1)];
    let mut s2 = vec![0u64; iw * (h + 1)];
    for y in 0..h {
        let (mut r1, mut r2) = (0u64, 0u64);
        for x in 0..w {
            let v = image.data[y * w + x] as u64;
            r1 += v;
            r2 += v * v;
            s1[(y + 1) * iw + x + 1] = s1[y * iw + x + 1] + r1;
            s2[(y + 1) * iw + x + 1] = s2[y * iw + x + 1] + r2;
        }
    }
    let min_var = (min_std * min_std) as f64;
    let mut out = vec![false; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(3), (y + 4).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(3), (x + 4).min(w));
            let n = ((y1 - y0) * (x1 - x0)) as f64;
            let rect = |s: &[u64]| {
                (s[y1 * iw + x1] + s[y0 * iw + x0]) as f64
                    - (s[y0 * iw + x1] + s[y1 * iw + x0]) as f64
            };
            let mean = rect(&s1) / n;
            let var = rect(&s2) / n - mean * mean;
            out[y * w + x] = var >= min_var;
        }
    }
    out
}

/// Invalidate connected patches (4-neighbours differing by at most `max_diff`) smaller than
/// `max_area` pixels.
fn remove_speckles(data: &mut [f32], w: usize, h: usize, max_area: usize, max_diff: f32) {
    let mut label = vec![u32::MAX; w * h];
    let mut stack = Vec::new();
    let mut members = Vec::new();
    let mut next = 0u32;
    for start in 0..w * h {
        if label[start] != u32::MAX || !data[start].is_finite() {
            continue;
        }
        members.clear();
        stack.push(start);
        label[start] = next;
        while let Some(p) = stack.pop() {
            members.push(p);
            let (x, y) = (p % w, p / w);
            let dp = data[p];
            let mut visit = |q: usize| {
                if label[q] == u32::MAX && data[q].is_finite() && (data[q] - dp).abs() <= max_diff {
                    label[q] = next;
                    stack.push(q);
                }
            };
            if x > 0 {
                visit(p - 1);
            }
            if x + 1 < w {
                visit(p + 1);
            }
            if y > 0 {
                visit(p - w);
            }
            if y + 1 < h {
                visit(p + w);
            }
        }
        if members.len() < max_area {
            for &p in &members {
                data[p] = f32::NAN;
            }
        }
        next += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random-texture pair where the right image is the left shifted by `shift` pixels.
    fn shifted_pair(w: usize, h: usize, shift: usize) -> (GrayImage, GrayImage) {
        let mut state = 12345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 56) as u8
        };
        let big: Vec<u8> = (0..(w + shift) * h).map(|_| noise()).collect();
        let left = GrayImage::new(
            w,
            h,
            (0..h)
                .flat_map(|y| big[y * (w + shift)..y * (w + shift) + w].to_vec())
                .collect(),
        )
        .unwrap();
        let right = GrayImage::new(
            w,
            h,
            (0..h)
                .flat_map(|y| big[y * (w + shift) + shift..y * (w + shift) + shift + w].to_vec())
                .collect(),
        )
        .unwrap();
        (left, right)
    }

    #[test]
    fn recovers_a_constant_shift() {
        let (left, right) = shifted_pair(120, 60, 7);
        let camera = StereoCamera::ipex().scaled(120.0 / 1280.0, 120, 60);
        let config = StereoConfig {
            levels: 0,
            max_disparity: 16,
            ..StereoConfig::default()
        };
        for paths in [4, 8] {
            let map = compute_disparity(
                &left,
                &right,
                &camera,
                &StereoConfig {
                    paths,
                    ..config.clone()
                },
            )
            .unwrap();
            let mut good = 0;
            let mut valid = 0;
            for y in 0..60 {
                for x in 20..120 {
                    if let Some(d) = map.get(x, y) {
                        valid += 1;
                        if (d - 7.0).abs() < 0.3 {
                            good += 1;
                        }
                    }
                }
            }
            assert!(valid > 5000, "valid {valid}");
            assert!(good as f64 > 0.98 * valid as f64, "good {good} of {valid}");
        }
    }

    #[test]
    fn mismatched_sizes_are_refused() {
        let a = GrayImage::zeros(64, 36);
        let b = GrayImage::zeros(64, 30);
        let camera = StereoCamera::ipex();
        assert!(compute_disparity(&a, &b, &camera, &StereoConfig::default()).is_err());
    }

    #[test]
    fn untextured_pixels_are_invalid() {
        let a = GrayImage::zeros(128, 72);
        let camera = StereoCamera::ipex();
        let map = compute_disparity(&a, &a, &camera, &StereoConfig::default()).unwrap();
        assert_eq!(map.valid_fraction(), 0.0);
    }
}
