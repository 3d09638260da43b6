//! The previous whole-volume SGM (cost volume, two aggregated sweep volumes, then
//! winner-takes-all), kept for the tests only: the row sweeps must give the very same
//! disparities.

use super::StereoConfig;

/// Disparities before the speckle filter, as the whole-volume implementation computed them.
pub(super) fn reference_disparity(
    cl: &[u64],
    cr: &[u64],
    w: usize,
    h: usize,
    nd: usize,
    max_cost: u8,
    config: &StereoConfig,
    textured: &[bool],
) -> Vec<f32> {
    let mut cost = vec![max_cost; w * h * nd];
    for y in 0..h {
        for x in 0..w {
            for d in 0..nd.min(x + 1) {
                cost[(y * w + x) * nd + d] = (cl[y * w + x] ^ cr[y * w + x - d]).count_ones() as u8;
            }
        }
    }
    let diagonals = config.paths == 8;
    let (p1, p2) = (config.p1, config.p2);
    let down = aggregate_sweep(&cost, w, h, nd, true, diagonals, p1, p2);
    let up = aggregate_sweep(&cost, w, h, nd, false, diagonals, p1, p2);
    let mut data = vec![f32::NAN; w * h];
    for y in 0..h {
        let rows = y * w * nd..(y + 1) * w * nd;
        select_row(
            &down[rows.clone()],
            &up[rows],
            w,
            nd,
            config,
            &textured[y * w..(y + 1) * w],
            &mut data[y * w..(y + 1) * w],
        );
    }
    data
}

fn path_step(cost: &[u8], prev: &[u16], prev_min: u16, out: &mut [u16], p1: u16, p2: u16) -> u16 {
    let n = cost.len();
    let jump = prev_min + p2;
    out[0] = cost[0] as u16 + prev[0].min(prev[1] + p1).min(jump) - prev_min;
    out[n - 1] = cost[n - 1] as u16 + prev[n - 1].min(prev[n - 2] + p1).min(jump) - prev_min;
    for d in 1..n - 1 {
        out[d] = cost[d] as u16
            + prev[d]
                .min(prev[d - 1] + p1)
                .min(prev[d + 1] + p1)
                .min(jump)
            - prev_min;
    }
    out.iter().copied().fold(u16::MAX, u16::min)
}

fn path_start(cost: &[u8], out: &mut [u16]) -> u16 {
    for (o, &c) in out.iter_mut().zip(cost) {
        *o = c as u16;
    }
    out.iter().copied().fold(u16::MAX, u16::min)
}

fn aggregate_sweep(
    cost: &[u8],
    w: usize,
    h: usize,
    nd: usize,
    forward: bool,
    diagonals: bool,
    p1: u16,
    p2: u16,
) -> Vec<u16> {
    let mut sum = vec![0u16; w * h * nd];
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
    let add = |sum: &mut [u16], l: &[u16]| sum.iter_mut().zip(l).for_each(|(s, &v)| *s += v);
    for step in 0..h {
        let y = if forward { step } else { h - 1 - step };
        let row_cost = &cost[y * w * nd..(y + 1) * w * nd];
        let row_sum = &mut sum[y * w * nd..(y + 1) * w * nd];
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
            add(&mut row_sum[x * nd..(x + 1) * nd], cur);
            h_buf.swap(0, 1);
        }
        for x in 0..w {
            let c = &row_cost[x * nd..(x + 1) * nd];
            let cur = &mut v_cur[x * nd..(x + 1) * nd];
            v_cur_min[x] = if step == 0 {
                path_start(c, cur)
            } else {
                path_step(c, &v_prev[x * nd..(x + 1) * nd], v_prev_min[x], cur, p1, p2)
            };
            add(&mut row_sum[x * nd..(x + 1) * nd], cur);
        }
        std::mem::swap(&mut v_prev, &mut v_cur);
        std::mem::swap(&mut v_prev_min, &mut v_cur_min);
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
                add(&mut row_sum[x * nd..(x + 1) * nd], cur);
            }
        }
        for k in 0..n_diag {
            std::mem::swap(&mut d_prev[k], &mut d_cur[k]);
            std::mem::swap(&mut d_prev_min[k], &mut d_cur_min[k]);
        }
    }
    sum
}

fn slice_min(s: &[u16]) -> u16 {
    s.iter().copied().fold(u16::MAX, u16::min)
}

fn select_row(
    a: &[u16],
    b: &[u16],
    w: usize,
    nd: usize,
    config: &StereoConfig,
    textured: &[bool],
    out: &mut [f32],
) {
    let sum: Vec<u16> = a.iter().zip(b).map(|(x, y)| x + y).collect();
    let mut best_right = vec![(u16::MAX, 0u16); w];
    for x in 0..w {
        let s = &sum[x * nd..(x + 1) * nd];
        for (d, &v) in s[..nd.min(x + 1)].iter().enumerate() {
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
        let dmax = nd.min(x + 1);
        let s = &sum[x * nd..x * nd + dmax];
        let best = slice_min(s);
        let Some(bd) = s.iter().position(|&v| v == best) else {
            continue;
        };
        if bd == 0 || bd + 1 >= dmax {
            continue;
        }
        let second = slice_min(&s[..bd - 1]).min(slice_min(&s[(bd + 2).min(dmax)..]));
        if second != u16::MAX && (best as f32) > keep * second as f32 {
            continue;
        }
        if (best_right[x - bd].1 as f32 - bd as f32).abs() > config.lr_tolerance {
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
