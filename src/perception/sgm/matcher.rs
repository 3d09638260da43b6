//! Semi-global matching by two row sweeps that meet in the middle, on two threads.
//!
//! The down sweep (rows top to bottom) and the up sweep (bottom to top) each carry their
//! paths' costs for the previous row only. Phase 1: the down sweep runs over the top half,
//! computes the matching costs and stores them with its per-row sums; the up sweep does
//! the same over the bottom half. Phase 2: each sweep continues into the other half with
//! the costs kept there, adds the other sweep's stored sums row by row and picks the
//! disparities of that row at once. So each cost is computed once, and the image-sized
//! buffers are the costs (u8) and one volume of half-sums (u8 when a sweep's paths cannot
//! exceed 255, as with the defaults: 2 paths × (48 + 48); u16 otherwise): 2 × 22 MB at half
//! resolution with 96 disparities, where whole-image aggregation took 22 + 2 × 44 MB. The
//! result is exactly that of summing all paths over whole-image volumes.
//! The two phases are `rayon::join`s, so the result does not depend on the thread count
//! and one thread cannot deadlock.

use std::ops::Range;

use super::select::select_row;
use super::sweep::{RowCosts, Sweep};
use super::StereoConfig;

/// One cell of the half-sum volume.
trait Cell: Copy + Default + Send + Sync {
    fn narrow(v: u16) -> Self;
    fn widen(self) -> u16;
}

impl Cell for u8 {
    #[inline(always)]
    fn narrow(v: u16) -> u8 {
        v as u8
    }
    #[inline(always)]
    fn widen(self) -> u16 {
        self as u16
    }
}

impl Cell for u16 {
    #[inline(always)]
    fn narrow(v: u16) -> u16 {
        v
    }
    #[inline(always)]
    fn widen(self) -> u16 {
        self
    }
}

/// Buffers of the row matcher, reused from one pair to the next.
#[derive(Clone, Debug, Default)]
pub(super) struct RowMatcher {
    down: Sweep,
    up: Sweep,
    best_rev: [Vec<u32>; 2],
    narrow: Vec<u8>,
    wide: Vec<u16>,
    costs: Vec<u8>,
}

/// The inputs of one matching run.
pub(super) struct MatchInput<'a> {
    /// Census planes (`census_planes_into`) of the left and right image at the working
    /// resolution.
    pub cl: &'a [u16],
    pub cr: &'a [u16],
    pub w: usize,
    pub h: usize,
    /// Disparities searched (0 .. nd − 1).
    pub nd: usize,
    /// Cost where the right pixel falls outside the image (the census bit count).
    pub max_cost: u16,
    pub config: &'a StereoConfig,
    /// Pixels worth matching.
    pub textured: &'a [bool],
}

impl RowMatcher {
    /// Disparities of every pixel into `out` (`w h`, NaN-filled; NaN stays where no
    /// reliable match is found).
    pub(super) fn run(&mut self, input: &MatchInput, out: &mut [f32]) {
        let c = input.config;
        let diagonals = c.paths == 8;
        self.down.reset(input.w, input.nd, true, diagonals);
        self.up.reset(input.w, input.nd, false, diagonals);
        let per_sweep = if diagonals { 4u32 } else { 2 };
        let cells = input.w * input.h * input.nd;
        ensure_len(&mut self.costs, cells);
        let costs = &mut self.costs;
        if per_sweep * (input.max_cost as u32 + c.p2 as u32) <= u8::MAX as u32 {
            ensure_len(&mut self.narrow, cells);
            let volume = &mut self.narrow;
            run_phases(
                input,
                &mut self.down,
                &mut self.up,
                volume,
                costs,
                &mut self.best_rev,
                out,
            );
        } else {
            ensure_len(&mut self.wide, cells);
            let volume = &mut self.wide;
            run_phases(
                input,
                &mut self.down,
                &mut self.up,
                volume,
                costs,
                &mut self.best_rev,
                out,
            );
        }
    }
}

/// Make `v` hold `len` cells; a new buffer is asked for huge pages before its first touch
/// (fewer page faults on a cold start: the kernel zeroes 2 MB at a time).
fn ensure_len<T: Cell>(v: &mut Vec<T>, len: usize) {
    if v.len() == len {
        return;
    }
    *v = Vec::new();
    *v = vec![T::default(); len];
    super::huge_pages::advise(v.as_mut_ptr() as *mut u8, len * std::mem::size_of::<T>());
}

fn run_phases<T: Cell>(
    input: &MatchInput,
    down: &mut Sweep,
    up: &mut Sweep,
    volume: &mut [T],
    costs: &mut [u8],
    best_rev: &mut [Vec<u32>; 2],
    out: &mut [f32],
) {
    let (w, h, nd) = (input.w, input.h, input.nd);
    let mid = h / 2;
    let (vol_top, vol_bottom) = volume.split_at_mut(mid * w * nd);
    let (cost_top, cost_bottom) = costs.split_at_mut(mid * w * nd);
    let (out_top, out_bottom) = out.split_at_mut(mid * w);
    let [rev_down, rev_up] = best_rev;
    // phase 1: each sweep over its own half, storing its sums
    rayon::join(
        || store_half(input, down, 0..mid, vol_top, cost_top),
        || store_half(input, up, mid..h, vol_bottom, cost_bottom),
    );
    // phase 2: each sweep over the other half, adding the other's sums, picking disparities
    rayon::join(
        || {
            finish_half(
                input,
                down,
                mid..h,
                (vol_bottom, cost_bottom),
                rev_down,
                out_bottom,
            )
        },
        || finish_half(input, up, 0..mid, (vol_top, cost_top), rev_up, out_top),
    );
}

/// The rows of `rows` in the sweep's order.
fn in_sweep_order(sweep: &Sweep, rows: Range<usize>) -> impl Iterator<Item = usize> {
    let down = sweep.is_down();
    let (a, b) = (rows.start, rows.end);
    (0..b - a).map(move |i| if down { a + i } else { b - 1 - i })
}

/// Phase 1: sweep `rows`, storing the sums into `vol` and the matching costs into `costs`
/// (row `y` at `y − rows.start`).
fn store_half<T: Cell>(
    input: &MatchInput,
    sweep: &mut Sweep,
    rows: Range<usize>,
    vol: &mut [T],
    costs: &mut [u8],
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU supports AVX2 and POPCNT (checked just above).
        return unsafe { store_half_avx2(input, sweep, rows, vol, costs) };
    }
    store_half_generic(input, sweep, rows, vol, costs)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn store_half_avx2<T: Cell>(
    input: &MatchInput,
    sweep: &mut Sweep,
    rows: Range<usize>,
    vol: &mut [T],
    costs: &mut [u8],
) {
    store_half_generic(input, sweep, rows, vol, costs)
}

#[inline(always)]
fn store_half_generic<T: Cell>(
    input: &MatchInput,
    sweep: &mut Sweep,
    rows: Range<usize>,
    vol: &mut [T],
    costs: &mut [u8],
) {
    let (w, nd, c) = (input.w, input.nd, input.config);
    let start = rows.start;
    for y in in_sweep_order(sweep, rows) {
        let cells = (y - start) * w * nd..(y - start + 1) * w * nd;
        let costs = RowCosts::Compute {
            cl: &input.cl[3 * y * w..3 * (y + 1) * w],
            cr: &input.cr[3 * y * w..3 * (y + 1) * w],
            max_cost: input.max_cost,
            keep: &mut costs[cells.clone()],
        };
        sweep.row(costs, c.p1, c.p2);
        let stored = &mut vol[cells];
        for (s, &p) in stored.iter_mut().zip(&sweep.part) {
            *s = T::narrow(p);
        }
    }
}

/// Phase 2: sweep `rows` with the costs the other sweep kept, add its sums and write the
/// disparities of each row into `out` (row `y` at `y − rows.start` in all three).
fn finish_half<T: Cell>(
    input: &MatchInput,
    sweep: &mut Sweep,
    rows: Range<usize>,
    (vol, costs): (&[T], &[u8]),
    best_rev: &mut Vec<u32>,
    out: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU supports AVX2 and POPCNT (checked just above).
        return unsafe { finish_half_avx2(input, sweep, rows, (vol, costs), best_rev, out) };
    }
    finish_half_generic(input, sweep, rows, (vol, costs), best_rev, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn finish_half_avx2<T: Cell>(
    input: &MatchInput,
    sweep: &mut Sweep,
    rows: Range<usize>,
    (vol, costs): (&[T], &[u8]),
    best_rev: &mut Vec<u32>,
    out: &mut [f32],
) {
    finish_half_generic(input, sweep, rows, (vol, costs), best_rev, out)
}

#[inline(always)]
fn finish_half_generic<T: Cell>(
    input: &MatchInput,
    sweep: &mut Sweep,
    rows: Range<usize>,
    (vol, costs): (&[T], &[u8]),
    best_rev: &mut Vec<u32>,
    out: &mut [f32],
) {
    let (w, nd, c) = (input.w, input.nd, input.config);
    let start = rows.start;
    for y in in_sweep_order(sweep, rows) {
        let cells = (y - start) * w * nd..(y - start + 1) * w * nd;
        sweep.row(RowCosts::Stored(&costs[cells.clone()]), c.p1, c.p2);
        let stored = &vol[cells];
        for (p, &s) in sweep.part.iter_mut().zip(stored) {
            *p += s.widen();
        }
        let textured = &input.textured[y * w..(y + 1) * w];
        let out_row = &mut out[(y - start) * w..(y - start + 1) * w];
        select_row(&sweep.part, nd, c, textured, out_row, best_rev);
    }
}
