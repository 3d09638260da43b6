//! One SGM sweep over the image rows: the path costs of the paths that are causal in its
//! row order, kept for the previous row only.
//!
//! The *down* sweep visits rows top to bottom and each row left to right: its paths come
//! from the left, from above and (with diagonals) from above-left and above-right. The *up*
//! sweep is its mirror image (bottom to top, right to left, from below). The matching costs
//! of a pixel (census Hamming distances, disparity 0 .. nd − 1) are computed by the first
//! sweep that reaches it and kept for the other (see `matcher.rs`).
//!
//! Path buffers hold each pixel's `nd` costs between two sentinels (the lane type's
//! maximum, never the minimum; additions saturate), so the step
//! `L(d) = C(d) + min(L'(d), L'(d ± 1) + P1, min L' + P2) − min L'` has no special case at
//! the ends of the disparity range and vectorises. A path cost is at most
//! `max_cost + P2` (96 with the defaults), so when the sweep's paths sum to at most 255 the
//! sweep runs on bytes ([`Lane`] `u8`, 32 per AVX2 register), else on `u16`.

/// The integer type of a sweep's path costs and sums: `u8` or `u16`.
pub(super) trait Lane: Copy + Ord + Default + Send + Sync + std::fmt::Debug {
    /// The largest value, used as the sentinel.
    const MAX: Self;
    /// The value `v` (which the caller knows to fit).
    fn of(v: u16) -> Self;
    /// As `u16`.
    fn wide(self) -> u16;
    /// `self + other`, saturating.
    fn sat_add(self, other: Self) -> Self;
    /// `self + other` (the caller knows it fits).
    fn add(self, other: Self) -> Self;
    /// `self − other` (the caller knows `other ≤ self`).
    fn sub(self, other: Self) -> Self;
    /// Bytes as lanes, when the lanes are bytes.
    fn of_bytes(b: &[u8]) -> Option<&[Self]>;
    /// Bytes as lanes, when the lanes are bytes.
    fn of_bytes_mut(b: &mut [u8]) -> Option<&mut [Self]>;
}

macro_rules! lane {
    ($t:ty, $bytes:expr, $bytes_mut:expr) => {
        impl Lane for $t {
            const MAX: $t = <$t>::MAX;
            #[inline(always)]
            fn of(v: u16) -> $t {
                v as $t
            }
            #[inline(always)]
            fn wide(self) -> u16 {
                self as u16
            }
            #[inline(always)]
            fn sat_add(self, other: $t) -> $t {
                self.saturating_add(other)
            }
            #[inline(always)]
            fn add(self, other: $t) -> $t {
                self.wrapping_add(other)
            }
            #[inline(always)]
            fn sub(self, other: $t) -> $t {
                self.wrapping_sub(other)
            }
            #[inline(always)]
            fn of_bytes(b: &[u8]) -> Option<&[$t]> {
                $bytes(b)
            }
            #[inline(always)]
            fn of_bytes_mut(b: &mut [u8]) -> Option<&mut [$t]> {
                $bytes_mut(b)
            }
        }
    };
}
lane!(u8, Some, Some);
lane!(u16, |_| None, |_| None);

/// Where a row's matching costs come from.
pub(super) enum RowCosts<'a> {
    /// Computed from the census planes of the row (left `cl`, right `cr`, each `3 w` as
    /// `census_planes_into` lays them out; `max_cost` where the right pixel falls outside
    /// the image) and kept in `keep[x nd + d]`.
    Compute {
        cl: &'a [u16],
        cr: &'a [u16],
        max_cost: u16,
        keep: &'a mut [u8],
    },
    /// Read from `[x nd + d]`, as kept by the other sweep.
    Stored(&'a [u8]),
}

/// State of one sweep (path costs of the previous row) and its output for the last row.
#[derive(Clone, Debug, Default)]
pub(super) struct Sweep<L: Lane> {
    /// Top to bottom, left to right (else bottom to top, right to left).
    down: bool,
    diagonals: bool,
    w: usize,
    nd: usize,
    rows_done: usize,
    /// Horizontal path: the previous pixel's slot and this pixel's.
    hor: [Vec<L>; 2],
    /// Vertical path: `w` slots for the previous row, `w` for this row.
    vert: [Vec<L>; 2],
    vert_min: [Vec<L>; 2],
    /// Diagonal paths (k = 0 from column x − 1 of the previous row, k = 1 from x + 1).
    diag: [[Vec<L>; 2]; 2],
    diag_min: [[Vec<L>; 2]; 2],
    /// Matching costs of the current pixel.
    cost: Vec<L>,
    /// The right image's census strings of the current row, see [`fill_planes`].
    planes: [Vec<u16>; 3],
    /// The slot every path starts from (zeros between the sentinels).
    zero: Vec<L>,
    /// The sum of this sweep's paths for the last row done without a destination:
    /// `part[x nd + d]`.
    pub(super) part: Vec<L>,
}

impl<L: Lane> Sweep<L> {
    /// Make the sweep ready for a new image of width `w` with `nd` disparities; buffers
    /// are reused when the shape is unchanged.
    pub(super) fn reset(&mut self, w: usize, nd: usize, down: bool, diagonals: bool) {
        let slots = w * (nd + 2);
        let same = self.w == w && self.nd == nd && self.diagonals == diagonals;
        if !same || self.part.len() != w * nd {
            let n_diag = if diagonals { slots } else { 0 };
            let fresh = |n: usize| vec![L::MAX; n];
            let zeros = |n: usize| vec![L::default(); n];
            *self = Sweep {
                down,
                diagonals,
                w,
                nd,
                rows_done: 0,
                hor: [fresh(nd + 2), fresh(nd + 2)],
                vert: [fresh(slots), fresh(slots)],
                vert_min: [zeros(w), zeros(w)],
                diag: [
                    [fresh(n_diag), fresh(n_diag)],
                    [fresh(n_diag), fresh(n_diag)],
                ],
                diag_min: [[zeros(w), zeros(w)], [zeros(w), zeros(w)]],
                cost: zeros(nd),
                zero: [&[L::MAX][..], &zeros(nd), &[L::MAX]].concat(),
                planes: [vec![0; w], vec![0; w], vec![0; w]],
                part: zeros(w * nd),
            };
        }
        self.down = down;
        self.rows_done = 0;
    }

    /// Whether the sweep runs top to bottom.
    pub(super) fn is_down(&self) -> bool {
        self.down
    }

    /// Aggregate the next row into `dst` (`[x nd + d]`), or into [`Sweep::part`] without
    /// one, its matching costs computed (and kept) or read. Call only from code compiled
    /// for the instruction set in use (the callers in `matcher.rs` dispatch once per half
    /// image).
    #[inline(always)]
    pub(super) fn row(&mut self, costs: RowCosts, dst: Option<&mut [L]>, p1: L, p2: L) {
        let (w, nd) = (self.w, self.nd);
        let sp = nd + 2;
        let first_row = self.rows_done == 0;
        let Sweep {
            down,
            diagonals,
            hor,
            vert,
            vert_min,
            diag,
            diag_min,
            cost: scratch,
            part,
            zero,
            planes,
            ..
        } = self;
        let zero: &[L] = zero;
        let part: &mut [L] = match dst {
            Some(dst) => dst,
            None => part,
        };
        let mut costs = costs;
        if let RowCosts::Compute { cr, .. } = costs {
            fill_planes(planes, cr);
        }
        let planes: &[Vec<u16>; 3] = planes;
        let mut h_min = L::default();
        for i in 0..w {
            let x = if *down { i } else { w - 1 - i };
            let cost = column_costs(&mut costs, &mut scratch[..], planes, x);
            let slot = x * sp..(x + 1) * sp;
            let part = &mut part[x * nd..(x + 1) * nd];
            let [h_prev, h_cur] = &mut *hor;
            let h_from = if i == 0 {
                (zero, L::default())
            } else {
                (&h_prev[..], h_min)
            };
            let [v_prev, v_cur] = &mut *vert;
            let v_from = if first_row {
                (zero, L::default())
            } else {
                (&v_prev[slot.clone()], vert_min[0][x])
            };
            let v_cur = &mut v_cur[slot.clone()];
            h_min = step::<L, true>(cost, h_from, h_cur, part, p1, p2);
            vert_min[1][x] = step::<L, false>(cost, v_from, v_cur, part, p1, p2);
            if *diagonals {
                let [[a_prev, a_cur], [b_prev, b_cur]] = &mut *diag;
                let [a_min, b_min] = &mut *diag_min;
                let a_from = match x.checked_sub(1) {
                    Some(p) if !first_row => (&a_prev[p * sp..(p + 1) * sp], a_min[0][p]),
                    _ => (zero, L::default()),
                };
                let b_from = match Some(x + 1).filter(|&p| p < w) {
                    Some(p) if !first_row => (&b_prev[p * sp..(p + 1) * sp], b_min[0][p]),
                    _ => (zero, L::default()),
                };
                a_min[1][x] =
                    step::<L, false>(cost, a_from, &mut a_cur[slot.clone()], part, p1, p2);
                b_min[1][x] = step::<L, false>(cost, b_from, &mut b_cur[slot], part, p1, p2);
            }
            hor.swap(0, 1);
        }
        self.end_row();
    }

    /// This row's path costs become the previous row's.
    #[inline(always)]
    fn end_row(&mut self) {
        self.vert.swap(0, 1);
        self.vert_min.swap(0, 1);
        for k in 0..2 {
            self.diag[k].swap(0, 1);
            self.diag_min[k].swap(0, 1);
        }
        self.rows_done += 1;
    }
}

/// The matching costs of column `x` (`w` = the planes' width, `nd` = `scratch`'s length):
/// computed from the census planes and kept as bytes, or read from the kept ones. On bytes
/// the kept costs are the lane costs, computed and read in place; wider lanes go through
/// `scratch`.
#[inline(always)]
fn column_costs<'c, L: Lane>(
    costs: &'c mut RowCosts<'_>,
    scratch: &'c mut [L],
    planes: &[Vec<u16>; 3],
    x: usize,
) -> &'c [L] {
    let (w, nd) = (planes[0].len(), scratch.len());
    let cells = x * nd..(x + 1) * nd;
    match costs {
        RowCosts::Compute {
            cl, max_cost, keep, ..
        } => {
            let l = [cl[x], cl[w + x], cl[2 * w + x]];
            if L::of_bytes(&[]).is_some() {
                // the lanes are bytes (`of_bytes_mut` is `Some` exactly when `of_bytes` is)
                let kept = L::of_bytes_mut(&mut keep[cells]).unwrap_or_default();
                fill_costs(kept, l, planes, x, *max_cost);
                kept
            } else {
                fill_costs(scratch, l, planes, x, *max_cost);
                for (k, &c) in keep[cells].iter_mut().zip(scratch.iter()) {
                    *k = c.wide() as u8;
                }
                scratch
            }
        }
        RowCosts::Stored(stored) => {
            if let Some(kept) = L::of_bytes(&stored[cells.clone()]) {
                kept
            } else {
                for (c, &k) in scratch.iter_mut().zip(&stored[cells]) {
                    *c = L::of(k as u16);
                }
                scratch
            }
        }
    }
}

/// The right image's census planes of one row in reversed column order
/// (`planes[k][w − 1 − x]` = plane k at column x), so that the strings at x − d for
/// increasing d are contiguous and 16 costs fit in one AVX2 register.
#[inline(always)]
fn fill_planes(planes: &mut [Vec<u16>; 3], cr: &[u16]) {
    let w = planes[0].len();
    for (k, plane) in planes.iter_mut().enumerate() {
        for (p, &r) in plane.iter_mut().zip(cr[k * w..(k + 1) * w].iter().rev()) {
            *p = r;
        }
    }
}

/// `cost[d]` = Hamming distance between the left string `l` (three planes, at column x)
/// and the right image's string at column x − d, from the planes of [`fill_planes`];
/// `max_cost` where x − d falls outside the image.
#[inline(always)]
fn fill_costs<L: Lane>(
    cost: &mut [L],
    l: [u16; 3],
    planes: &[Vec<u16>; 3],
    x: usize,
    max_cost: u16,
) {
    let w = planes[0].len();
    let dmax = cost.len().min(x + 1);
    let j = w - 1 - x;
    let [l0, l1, l2] = l;
    let (r0, r1, r2) = (
        &planes[0][j..j + dmax],
        &planes[1][j..j + dmax],
        &planes[2][j..j + dmax],
    );
    for (((c, &a), &b), &e) in cost[..dmax].iter_mut().zip(r0).zip(r1).zip(r2) {
        *c = L::of(((l0 ^ a).count_ones() + (l1 ^ b).count_ones() + (l2 ^ e).count_ones()) as u16);
    }
    cost[dmax..].fill(L::of(max_cost));
}

/// One path step at one pixel, from the previous slot `from` (and its minimum) into `out`:
/// `L(d) = C(d) + min(L'(d), L'(d ± 1) + P1, min L' + P2) − min L'`. `part` gets `L`
/// (`FIRST`) or `L` added. A path starts from the zero slot with minimum 0 (then `L = C`).
/// Returns the new minimum.
#[inline(always)]
fn step<L: Lane, const FIRST: bool>(
    cost: &[L],
    from: (&[L], L),
    out: &mut [L],
    part: &mut [L],
    p1: L,
    p2: L,
) -> L {
    let nd = cost.len();
    let (prev, prev_min) = from;
    let jump = prev_min.sat_add(p2);
    let (lo, mid, hi) = (&prev[..nd], &prev[1..=nd], &prev[2..nd + 2]);
    let mut min = L::MAX;
    for (((((o, s), &c), &a), &b), &z) in out[1..=nd]
        .iter_mut()
        .zip(&mut part[..nd])
        .zip(cost)
        .zip(lo)
        .zip(mid)
        .zip(hi)
    {
        let v = b.min(a.min(z).sat_add(p1)).min(jump).sub(prev_min).add(c);
        *o = v;
        *s = if FIRST { v } else { s.add(v) };
        min = min.min(v);
    }
    min
}
