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

use super::select::{select_row, SelectScratch};
use super::sweep::{Lane, RowCosts, Sweep};
use super::StereoConfig;

/// Buffers of the row matcher, reused from one pair to the next.
#[derive(Clone, Debug, Default)]
pub(super) struct RowMatcher {
    /// Sweeps on bytes (when a sweep's paths sum to at most 255, as with the defaults).
    narrow: Sweeps<u8>,
    /// Sweeps on 16-bit integers otherwise.
    wide: Sweeps<u16>,
    /// Matching costs `[(y w + x) nd + d]`, kept by phase 1 for phase 2.
    costs: Vec<u8>,
    /// Per thread: scratch of [`select_row`] and the row's total sums.
    rows: [(SelectScratch, Vec<u16>); 2],
}

/// The two sweeps and their volume of half-sums, all of one lane type.
#[derive(Clone, Debug, Default)]
struct Sweeps<L: Lane> {
    down: Sweep<L>,
    up: Sweep<L>,
    /// Half-sums `[(y w + x) nd + d]`: the down sweep's in the top half, the up sweep's in
    /// the bottom half.
    volume: Vec<L>,
}

/// The inputs of one matching run.
pub(super) struct MatchInput<'a> {
    /// Census planes (`census_planes_into`) of the left image at the working resolution.
    pub cl: &'a [u16],
    /// The same of the right image.
    pub cr: &'a [u16],
    /// Width of the images at the working resolution, pixels.
    pub w: usize,
    /// Height, pixels.
    pub h: usize,
    /// Disparities searched (0 .. nd − 1).
    pub nd: usize,
    /// Cost where the right pixel falls outside the image (the census bit count).
    pub max_cost: u16,
    /// Penalties, paths and the checks of the winner-takes-all.
    pub config: &'a StereoConfig,
    /// Pixels worth matching.
    pub textured: &'a [bool],
}

impl MatchInput<'_> {
    /// The largest sum one row sweep (its 2 or 4 path directions) can aggregate for a pixel
    /// and disparity: what decides the lane width, and half the bound of the two sweeps'
    /// total.
    fn sweep_max(&self) -> u32 {
        let per_sweep = if self.config.paths == 8 { 4 } else { 2 };
        per_sweep * (self.max_cost as u32 + self.config.p2 as u32)
    }
}

impl RowMatcher {
    /// Disparities of every pixel into `out` (`w h`, NaN-filled; NaN stays where no
    /// reliable match is found).
    pub(super) fn run(&mut self, input: &MatchInput, out: &mut [f32]) {
        ensure_len(&mut self.costs, input.w * input.h * input.nd);
        if input.sweep_max() <= u8::MAX as u32 {
            self.narrow.run(input, &mut self.costs, &mut self.rows, out);
        } else {
            self.wide.run(input, &mut self.costs, &mut self.rows, out);
        }
    }
}

impl<L: Lane> Sweeps<L> {
    fn run(
        &mut self,
        input: &MatchInput,
        costs: &mut [u8],
        rows: &mut [(SelectScratch, Vec<u16>); 2],
        out: &mut [f32],
    ) {
        let (w, h, nd) = (input.w, input.h, input.nd);
        let diagonals = input.config.paths == 8;
        self.down.reset(w, nd, true, diagonals);
        self.up.reset(w, nd, false, diagonals);
        ensure_len(&mut self.volume, w * h * nd);
        let mid = h / 2;
        let (vol_top, vol_bottom) = self.volume.split_at_mut(mid * w * nd);
        let (cost_top, cost_bottom) = costs.split_at_mut(mid * w * nd);
        let (out_top, out_bottom) = out.split_at_mut(mid * w);
        let [rows_down, rows_up] = rows;
        let (down, up) = (&mut self.down, &mut self.up);
        // phase 1: each sweep over its own half, keeping its costs and sums
        rayon::join(
            || store_half(input, down, 0..mid, vol_top, cost_top),
            || store_half(input, up, mid..h, vol_bottom, cost_bottom),
        );
        // phase 2: each sweep over the other half with the costs kept there, adding the
        // other's sums and picking disparities row by row
        rayon::join(
            || {
                finish_half(
                    input,
                    down,
                    mid..h,
                    (vol_bottom, cost_bottom),
                    rows_down,
                    out_bottom,
                )
            },
            || finish_half(input, up, 0..mid, (vol_top, cost_top), rows_up, out_top),
        );
    }
}

/// Make `v` hold `len` cells; a new buffer is asked for huge pages before its first touch
/// (fewer page faults on a cold start: the kernel zeroes 2 MB at a time).
fn ensure_len<T: Copy + Default>(v: &mut Vec<T>, len: usize) {
    if v.len() == len {
        return;
    }
    *v = Vec::new();
    *v = vec![T::default(); len];
    crate::memory::advise_huge_pages(v.as_mut_ptr() as *mut u8, len * std::mem::size_of::<T>());
}

/// The rows of `rows` in the sweep's order.
fn in_sweep_order<L: Lane>(sweep: &Sweep<L>, rows: Range<usize>) -> impl Iterator<Item = usize> {
    let down = sweep.is_down();
    let (a, b) = (rows.start, rows.end);
    (0..b - a).map(move |i| if down { a + i } else { b - 1 - i })
}

/// Phase 1: sweep `rows`, storing the sums into `vol` and the matching costs into `costs`
/// (row `y` at `y − rows.start`).
fn store_half<L: Lane>(
    input: &MatchInput,
    sweep: &mut Sweep<L>,
    rows: Range<usize>,
    vol: &mut [L],
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
unsafe fn store_half_avx2<L: Lane>(
    input: &MatchInput,
    sweep: &mut Sweep<L>,
    rows: Range<usize>,
    vol: &mut [L],
    costs: &mut [u8],
) {
    store_half_generic(input, sweep, rows, vol, costs)
}

#[inline(always)]
fn store_half_generic<L: Lane>(
    input: &MatchInput,
    sweep: &mut Sweep<L>,
    rows: Range<usize>,
    vol: &mut [L],
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
        sweep.row(costs, Some(&mut vol[cells]), L::of(c.p1), L::of(c.p2));
    }
}

/// Phase 2: sweep `rows` with the costs the other sweep kept, add its sums and write the
/// disparities of each row into `out` (row `y` at `y − rows.start` in all three).
fn finish_half<L: Lane>(
    input: &MatchInput,
    sweep: &mut Sweep<L>,
    rows: Range<usize>,
    (vol, costs): (&[L], &[u8]),
    row_scratch: &mut (SelectScratch, Vec<u16>),
    out: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU supports AVX2 and POPCNT (checked just above).
        return unsafe { finish_half_avx2(input, sweep, rows, (vol, costs), row_scratch, out) };
    }
    finish_half_generic(input, sweep, rows, (vol, costs), row_scratch, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn finish_half_avx2<L: Lane>(
    input: &MatchInput,
    sweep: &mut Sweep<L>,
    rows: Range<usize>,
    (vol, costs): (&[L], &[u8]),
    row_scratch: &mut (SelectScratch, Vec<u16>),
    out: &mut [f32],
) {
    finish_half_generic(input, sweep, rows, (vol, costs), row_scratch, out)
}

#[inline(always)]
fn finish_half_generic<L: Lane>(
    input: &MatchInput,
    sweep: &mut Sweep<L>,
    rows: Range<usize>,
    (vol, costs): (&[L], &[u8]),
    row_scratch: &mut (SelectScratch, Vec<u16>),
    out: &mut [f32],
) {
    let (w, nd, c) = (input.w, input.nd, input.config);
    let (best_rev, sum) = row_scratch;
    let max_sum = 2 * input.sweep_max();
    let start = rows.start;
    for y in in_sweep_order(sweep, rows) {
        let cells = (y - start) * w * nd..(y - start + 1) * w * nd;
        sweep.row(
            RowCosts::Stored(&costs[cells.clone()]),
            None,
            L::of(c.p1),
            L::of(c.p2),
        );
        sum.clear();
        sum.extend(
            sweep
                .part
                .iter()
                .zip(&vol[cells])
                .map(|(p, s)| p.wide() + s.wide()),
        );
        let textured = &input.textured[y * w..(y + 1) * w];
        let out_row = &mut out[(y - start) * w..(y - start + 1) * w];
        select_row(sum, nd, max_sum, c, textured, out_row, best_rev);
    }
}
