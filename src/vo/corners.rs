//! Shi–Tomasi corners with good spread: the strongest corner of every empty cell of a grid.

use super::pyramid::FloatImage;
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
pub fn detect_corners(
    image: &FloatImage,
    config: &CornerConfig,
    occupied: &[bool],
) -> Vec<(f32, f32)> {
    let (cols, rows) = grid_size(image, config);
    let mut best = vec![(0.0f32, 0usize, 0usize); cols * rows];
    let (w, h) = (image.width, image.height);
    let b = config.border_px.max(3);
    if w <= 2 * b || h <= 2 * b {
        return Vec::new();
    }
    // Gradient products on the rows that matter, summed over 5 × 5 windows.
    let mut gxx = vec![0.0f32; w * h];
    let mut gxy = vec![0.0f32; w * h];
    let mut gyy = vec![0.0f32; w * h];
    for y in b - 3..h - b + 3 {
        for x in b - 3..w - b + 3 {
            let i = y * w + x;
            let gx = 0.5 * (image.data[i + 1] - image.data[i - 1]);
            let gy = 0.5 * (image.data[i + w] - image.data[i - w]);
            gxx[i] = gx * gx;
            gxy[i] = gx * gy;
            gyy[i] = gy * gy;
        }
    }
    let box_rows = |g: &[f32]| -> Vec<f32> {
        let mut out = vec![0.0f32; w * h];
        for y in b - 2..h - b + 2 {
            let row = &g[y * w..(y + 1) * w];
            for x in b..w - b {
                out[y * w + x] = row[x - 2] + row[x - 1] + row[x] + row[x + 1] + row[x + 2];
            }
        }
        out
    };
    let (sxx, sxy, syy) = (box_rows(&gxx), box_rows(&gxy), box_rows(&gyy));
    for y in b..h - b {
        let cell_row = (y / config.cell_px).min(rows - 1);
        for x in b..w - b {
            let cell = cell_row * cols + (x / config.cell_px).min(cols - 1);
            if occupied.get(cell).copied().unwrap_or(false) {
                continue;
            }
            let sum = |s: &[f32]| (y - 2..=y + 2).map(|yy| s[yy * w + x]).sum::<f32>();
            let (a, c, d) = (sum(&sxx), sum(&sxy), sum(&syy));
            let response = 0.5 * (a + d) - (0.25 * (a - d) * (a - d) + c * c).sqrt();
            let response = response / 25.0;
            if response > best[cell].0 {
                best[cell] = (response, x, y);
            }
        }
    }
    best.iter()
        .filter(|(r, _, _)| *r >= config.min_response)
        .map(|&(_, x, y)| (x as f32, y as f32))
        .collect()
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
