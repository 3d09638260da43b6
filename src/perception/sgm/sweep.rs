//! One SGM sweep over the image rows: the path costs of the paths that are causal in its
//! row order, kept for the previous row only.
//!
//! The *down* sweep visits rows top to bottom and each row left to right: its paths come
//! from the left, from above and (with diagonals) from above-left and above-right. The *up*
//! sweep is its mirror image (bottom to top, right to left, from below). The matching costs
//! of a pixel (census Hamming distances, disparity 0 .. nd − 1) are computed when the sweep
//! reaches it, so no cost volume is kept either.
//!
//! Path buffers hold each pixel's `nd` costs between two sentinels (`SENTINEL`, never the
//! minimum), so the step `L(d) = C(d) + min(L'(d), L'(d ± 1) + P1, min L' + P2) − min L'`
//! has no special case at the ends of the disparity range and vectorises.

/// Stands for "no such disparity" at both ends of a path buffer; adding P1 (≤ 1000) stays
/// below `u16::MAX`, and real path costs never reach it (at most 48 + 1000 per path).
const SENTINEL: u16 = 0x7FFF;

/// State of one sweep (path costs of the previous row) and its output for the last row.
#[derive(Clone, Debug, Default)]
pub(super) struct Sweep {
    /// Top to bottom, left to right (else bottom to top, right to left).
    down: bool,
    diagonals: bool,
    w: usize,
    nd: usize,
    rows_done: usize,
    /// Horizontal path: the previous pixel's slot and this pixel's.
    hor: [Vec<u16>; 2],
    /// Vertical path: `w` slots for the previous row, `w` for this row.
    vert: [Vec<u16>; 2],
    vert_min: [Vec<u16>; 2],
    /// Diagonal paths (k = 0 from column x − 1 of the previous row, k = 1 from x + 1).
    diag: [[Vec<u16>; 2]; 2],
    diag_min: [[Vec<u16>; 2]; 2],
    /// Matching costs of the current pixel.
    cost: Vec<u16>,
    /// The sum of this sweep's paths for the last row done: `part[x nd + d]`.
    pub(super) part: Vec<u16>,
}

impl Sweep {
    /// Make the sweep ready for a new image of width `w` with `nd` disparities; buffers
    /// are reused when the shape is unchanged.
    pub(super) fn reset(&mut self, w: usize, nd: usize, down: bool, diagonals: bool) {
        let slots = w * (nd + 2);
        let same = self.w == w && self.nd == nd && self.diagonals == diagonals;
        if !same || self.part.len() != w * nd {
            let n_diag = if diagonals { slots } else { 0 };
            let fresh = |n: usize| vec![SENTINEL; n];
            *self = Sweep {
                down,
                diagonals,
                w,
                nd,
                rows_done: 0,
                hor: [fresh(nd + 2), fresh(nd + 2)],
                vert: [fresh(slots), fresh(slots)],
                vert_min: [vec![0; w], vec![0; w]],
                diag: [
                    [fresh(n_diag), fresh(n_diag)],
                    [fresh(n_diag), fresh(n_diag)],
                ],
                diag_min: [[vec![0; w], vec![0; w]], [vec![0; w], vec![0; w]]],
                cost: vec![0; nd],
                part: vec![0; w * nd],
            };
        }
        self.down = down;
        self.rows_done = 0;
    }

    /// Whether the sweep runs top to bottom.
    pub(super) fn is_down(&self) -> bool {
        self.down
    }

    /// Aggregate the next row (census strings of this row in the left and right image)
    /// into [`Sweep::part`]. Call only from code compiled for the instruction set in use
    /// (the callers in `matcher.rs` dispatch once per half image).
    #[inline(always)]
    pub(super) fn row(&mut self, cl: &[u64], cr: &[u64], max_cost: u16, p1: u16, p2: u16) {
        let (w, nd) = (self.w, self.nd);
        let sp = nd + 2;
        let first_row = self.rows_done == 0;
        let mut h_min = 0u16;
        for i in 0..w {
            let x = if self.down { i } else { w - 1 - i };
            fill_costs(&mut self.cost, cl[x], &cr[..=x], max_cost);
            let cost = &self.cost[..];
            let part = &mut self.part[x * nd..(x + 1) * nd];

            let [h_prev, h_cur] = &mut self.hor;
            h_min = if i == 0 {
                path_start(cost, h_cur)
            } else {
                path_step(cost, h_prev, h_min, h_cur, p1, p2)
            };
            part.copy_from_slice(&h_cur[1..=nd]);
            self.hor.swap(0, 1);

            let slot = x * sp..(x + 1) * sp;
            let [v_prev, v_cur] = &mut self.vert;
            let v_cur = &mut v_cur[slot.clone()];
            self.vert_min[1][x] = if first_row {
                path_start(cost, v_cur)
            } else {
                path_step(
                    cost,
                    &v_prev[slot.clone()],
                    self.vert_min[0][x],
                    v_cur,
                    p1,
                    p2,
                )
            };
            accumulate(part, &v_cur[1..=nd]);

            if self.diagonals {
                for k in 0..2 {
                    let from = if k == 0 {
                        x.checked_sub(1)
                    } else {
                        Some(x + 1).filter(|&p| p < w)
                    };
                    let [d_prev, d_cur] = &mut self.diag[k];
                    let d_cur = &mut d_cur[slot.clone()];
                    self.diag_min[k][1][x] = match from {
                        Some(p) if !first_row => path_step(
                            cost,
                            &d_prev[p * sp..(p + 1) * sp],
                            self.diag_min[k][0][p],
                            d_cur,
                            p1,
                            p2,
                        ),
                        _ => path_start(cost, d_cur),
                    };
                    accumulate(part, &d_cur[1..=nd]);
                }
            }
        }
        self.vert.swap(0, 1);
        self.vert_min.swap(0, 1);
        for k in 0..2 {
            self.diag[k].swap(0, 1);
            self.diag_min[k].swap(0, 1);
        }
        self.rows_done += 1;
    }
}

/// `cost[d]` = Hamming distance between the left string `l` and the right image's string
/// at column x − d (`right_to_x` = that row's strings up to column x); `max_cost` where
/// x − d falls outside the image.
#[inline(always)]
fn fill_costs(cost: &mut [u16], l: u64, right_to_x: &[u64], max_cost: u16) {
    let dmax = cost.len().min(right_to_x.len());
    for (c, &r) in cost[..dmax].iter_mut().zip(right_to_x.iter().rev()) {
        *c = (l ^ r).count_ones() as u16;
    }
    cost[dmax..].fill(max_cost);
}

/// Start a path: `out = cost` (between the sentinels); returns its minimum.
#[inline(always)]
fn path_start(cost: &[u16], out: &mut [u16]) -> u16 {
    let nd = cost.len();
    out[1..=nd].copy_from_slice(cost);
    cost.iter().copied().fold(u16::MAX, u16::min)
}

/// One path step from the previous pixel's slot `prev` (minimum `prev_min`) into `out`;
/// returns the minimum of the new costs.
#[inline(always)]
fn path_step(cost: &[u16], prev: &[u16], prev_min: u16, out: &mut [u16], p1: u16, p2: u16) -> u16 {
    let nd = cost.len();
    let jump = prev_min + p2;
    let mut min = u16::MAX;
    let (lo, mid, hi) = (&prev[..nd], &prev[1..=nd], &prev[2..nd + 2]);
    for ((((o, &c), &a), &b), &z) in out[1..=nd].iter_mut().zip(cost).zip(lo).zip(mid).zip(hi) {
        let v = c + b.min(a.min(z) + p1).min(jump) - prev_min;
        *o = v;
        min = min.min(v);
    }
    min
}

#[inline(always)]
fn accumulate(sum: &mut [u16], l: &[u16]) {
    for (s, &v) in sum.iter_mut().zip(l) {
        *s += v;
    }
}
