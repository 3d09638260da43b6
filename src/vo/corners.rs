//! Shi–Tomasi corners with good spread: the strongest corner of every empty cell of a grid.

use super::pyramid::FloatImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Corner detection settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CornerConfig {
    /// Cell size of the grid, pixels; at most one corner per cell.
    pub cell_px: usize,
    /// Smallest accepted Shi–Tomasi response (smaller eigenvalue of the 5 × 5 structure
    /// tensor of intensity gradients, grey levels² per pixel).
    pub min_response: f32,
    /// Margin to the image border, pixels.
    pub border_px: usize,
}

impl Default for CornerConfig {
    fn default() -> Self {
        Self {
            cell_px: 24,
            min_response: 60.0,
            border_px: 12,
        }
    }
}

/// The strongest corner of every cell not marked `occupied` (cells row-major, `cols` per
/// row as [`grid_size`] gives), as `(x, y)` pixel coordinates.
///
/// Each empty cell is scored on its own (its gradients with a margin of the window's
/// half-size), so occupied cells cost nothing and no image-sized buffer is made.
pub fn detect_corners(
    image: &FloatImage,
    config: &CornerConfig,
    occupied: &[bool],
) -> Vec<(f32, f32)> {
    let (cols, rows) = grid_size(image, config);
    let (w, h) = (image.width, image.height);
    let b = config.border_px.max(3);
    if w <= 2 * b || h <= 2 * b {
        return Vec::new();
    }
    // rows of cells in parallel (rayon), concatenated in order: the same corners for any
    // number of threads
    let per_row: Vec<Vec<(f32, f32)>> = (0..rows)
        .into_par_iter()
        .map(|cy| {
            let free = |cx: usize| !occupied.get(cy * cols + cx).copied().unwrap_or(false);
            row_corners(image, config, (cols, rows), cy, free)
        })
        .collect();
    per_row.concat()
}

/// The corners of the free cells (`free(cx)`) of the row of cells `cy`, left to right.
fn row_corners(
    image: &FloatImage,
    config: &CornerConfig,
    (cols, rows): (usize, usize),
    cy: usize,
    free: impl Fn(usize) -> bool,
) -> Vec<(f32, f32)> {
    let (w, h) = (image.width, image.height);
    let b = config.border_px.max(3);
    let cell = config.cell_px.max(1);
    let last = |c: usize, n: usize| {
        if c + 1 == n {
            usize::MAX
        } else {
            (c + 1) * cell
        }
    };
    let mut scratch = CellScratch::default();
    let mut corners = Vec::new();
    for cx in (0..cols).filter(|&cx| free(cx)) {
        let (x0, x1) = ((cx * cell).max(b), last(cx, cols).min(w - b));
        let (y0, y1) = ((cy * cell).max(b), last(cy, rows).min(h - b));
        if x0 >= x1 || y0 >= y1 {
            continue;
        }
        let (response, x, y) = strongest_in(image, (x0, x1), (y0, y1), &mut scratch);
        if response >= config.min_response && response > 0.0 {
            corners.push((x as f32, y as f32));
        }
    }
    corners
}

/// Buffers of one cell's gradient products, reused from cell to cell.
#[derive(Default)]
struct CellScratch {
    products: [Vec<f32>; 3],
    rows: [Vec<f32>; 3],
    columns: [Vec<f32>; 3],
    response: Vec<f32>,
}

/// The strongest Shi–Tomasi response over pixels `xs.0..xs.1` × `ys.0..ys.1` (5 × 5 windows
/// of the central-difference gradients' products) and where it is; the first of equals in
/// row-major order, `(0, _, _)` when none is positive.
///
/// Every stage runs a whole row of the cell at a time over contiguous slices (vectorised);
/// each sum adds its five terms left to right or top to bottom, as a pixel-by-pixel loop
/// does, so the responses are the same to the bit.
fn strongest_in(
    image: &FloatImage,
    xs: (usize, usize),
    ys: (usize, usize),
    scratch: &mut CellScratch,
) -> (f32, usize, usize) {
    let w = image.width;
    // gradient products over the cell and a margin of 2 (the window's half-size)
    let (gx0, gy0) = (xs.0 - 2, ys.0 - 2);
    let (gw, gh) = (xs.1 - xs.0 + 4, ys.1 - ys.0 + 4);
    for p in &mut scratch.products {
        p.clear();
    }
    for y in gy0..gy0 + gh {
        let i = y * w + gx0;
        let left = &image.data[i - 1..][..gw];
        let right = &image.data[i + 1..][..gw];
        let up = &image.data[i - w..][..gw];
        let down = &image.data[i + w..][..gw];
        let gradient = |k: usize| (0.5 * (right[k] - left[k]), 0.5 * (down[k] - up[k]));
        let [xx, xy, yy] = &mut scratch.products;
        xx.extend((0..gw).map(gradient).map(|(gx, _)| gx * gx));
        xy.extend((0..gw).map(gradient).map(|(gx, gy)| gx * gy));
        yy.extend((0..gw).map(gradient).map(|(_, gy)| gy * gy));
    }
    // horizontal sums of 5, per row of the margin-extended cell
    let cw = xs.1 - xs.0;
    for (row_sums, g) in scratch.rows.iter_mut().zip(&scratch.products) {
        row_sums.clear();
        for row in g.chunks_exact(gw) {
            row_sums.extend(row.windows(5).map(|v| v[0] + v[1] + v[2] + v[3] + v[4]));
        }
    }
    let mut best = (0.0f32, 0usize, 0usize);
    for y in ys.0..ys.1 {
        let r = y - gy0;
        for (column, sums) in scratch.columns.iter_mut().zip(&scratch.rows) {
            let row = |k: usize| &sums[(r - 2 + k) * cw..][..cw];
            let (r0, r1, r2, r3, r4) = (row(0), row(1), row(2), row(3), row(4));
            column.clear();
            column.extend((0..cw).map(|c| r0[c] + r1[c] + r2[c] + r3[c] + r4[c]));
        }
        let [a, m, d] = &scratch.columns;
        scratch.response.clear();
        scratch.response.extend((0..cw).map(|c| {
            let (a, m, d) = (a[c], m[c], d[c]);
            (0.5 * (a + d) - (0.25 * (a - d) * (a - d) + m * m).sqrt()) / 25.0
        }));
        for (c, &v) in scratch.response.iter().enumerate() {
            if v > best.0 {
                best = (v, xs.0 + c, y);
            }
        }
    }
    best
}

/// Columns and rows of the corner grid of an image.
pub fn grid_size(image: &FloatImage, config: &CornerConfig) -> (usize, usize) {
    let cell = config.cell_px.max(1);
    (
        image.width.div_ceil(cell).max(1),
        image.height.div_ceil(cell).max(1),
    )
}

/// The cell of a point.
pub fn cell_of(x: f32, y: f32, image: &FloatImage, config: &CornerConfig) -> usize {
    let (cols, rows) = grid_size(image, config);
    let cell = config.cell_px.max(1) as f32;
    let cx = ((x / cell).max(0.0) as usize).min(cols - 1);
    let cy = ((y / cell).max(0.0) as usize).min(rows - 1);
    cy * cols + cx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bright_square_has_corners_at_its_corners() {
        let (w, h) = (96, 96);
        let mut data = vec![20.0f32; w * h];
        for y in 30..60 {
            for x in 30..60 {
                data[y * w + x] = 220.0;
            }
        }
        let image = FloatImage {
            width: w,
            height: h,
            data,
        };
        let config = CornerConfig::default();
        let corners = detect_corners(&image, &config, &[]);
        assert!(corners.len() >= 4, "{corners:?}");
        for (x, y) in &corners {
            let near = [(30.0, 30.0), (59.0, 30.0), (30.0, 59.0), (59.0, 59.0)]
                .iter()
                .any(|(cx, cy)| (x - cx).abs() <= 2.0 && (y - cy).abs() <= 2.0);
            assert!(near, "corner at {x}, {y}");
        }
    }
}
