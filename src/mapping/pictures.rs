//! PNG pictures of LAC maps: the height layer coloured by its error, the rock layer with
//! true / false positives and negatives, and trajectories over the terrain.
//!
//! Every picture shows the grid with +x to the right and +y up, 4 pixels per cell, a title
//! line above and a legend below; files are written atomically.

use std::path::Path;

use segloc_maps::LacGrid;

use super::raster::{Canvas, PictureError, Rgb};
use super::score::HEIGHT_TOLERANCE_M;

const PX: i64 = 4;
const MARGIN: i64 = 12;
const TOP: i64 = 30;
const BOTTOM: i64 = 44;
const TEXT: Rgb = [20, 20, 20];
/// Colour of a cell whose height is within 5 cm of the truth.
pub const WITHIN: Rgb = [40, 170, 70];
/// Colour of a cell whose height is off by 5 cm or more.
pub const OVER: Rgb = [220, 50, 40];
/// Colour of an unfilled cell.
pub const UNFILLED: Rgb = [70, 70, 70];
/// Colour of a rock cell found (true positive).
pub const TRUE_POSITIVE: Rgb = [20, 150, 40];
/// Colour of a cell marked as rock wrongly (false positive).
pub const FALSE_POSITIVE: Rgb = [225, 45, 35];
/// Colour of a rock cell missed (false negative).
pub const FALSE_NEGATIVE: Rgb = [40, 90, 235];

/// One polyline of a trajectory picture.
#[derive(Clone, Debug, PartialEq)]
pub struct Polyline {
    /// Legend label.
    pub label: String,
    /// Colour.
    pub colour: Rgb,
    /// World (x, y) points, metres.
    pub points_xy: Vec<(f64, f64)>,
    /// Line width in pixels: draw ground truth wide and estimates narrow on top of it, so
    /// that both stay visible where they agree.
    pub width_px: f64,
}

struct Frame {
    n: i64,
    half: f64,
    cell: f64,
}

impl Frame {
    fn of(grid: &LacGrid) -> Self {
        Frame {
            n: grid.cells_per_side as i64,
            half: grid.half_extent_m(),
            cell: grid.cell_size_m,
        }
    }
    fn canvas(&self) -> Result<Canvas, PictureError> {
        let side = (self.n * PX) as usize;
        Canvas::new(
            side + 2 * MARGIN as usize,
            side + (TOP + BOTTOM) as usize,
            [250, 250, 248],
        )
    }
    fn cell_px(&self, i: usize, j: usize) -> (i64, i64) {
        (MARGIN + i as i64 * PX, TOP + (self.n - 1 - j as i64) * PX)
    }
    fn world_px(&self, x: f64, y: f64) -> (f64, f64) {
        (
            MARGIN as f64 + (x + self.half) / self.cell * PX as f64,
            TOP as f64 + (self.half - y) / self.cell * PX as f64,
        )
    }
    fn legend_y(&self) -> i64 {
        TOP + self.n * PX + 12
    }
}

/// A grey level for height `h` within [lo, hi] (light = high), for terrain backgrounds.
fn shade(h: f64, lo: f64, hi: f64) -> u8 {
    if !h.is_finite() || hi <= lo {
        return 200;
    }
    (150.0 + 90.0 * ((h - lo) / (hi - lo)).clamp(0.0, 1.0)) as u8
}

fn range(values: &[f64]) -> (f64, f64) {
    values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// Tint colour `c` by the terrain grey `g` so the relief stays visible.
fn tint(c: Rgb, g: u8) -> Rgb {
    let f = 0.65 + 0.35 * (g as f64 - 150.0) / 90.0;
    [
        (c[0] as f64 * f) as u8,
        (c[1] as f64 * f) as u8,
        (c[2] as f64 * f) as u8,
    ]
}

fn check_same(a: &LacGrid, b: &LacGrid) -> Result<(), PictureError> {
    if a.cells_per_side != b.cells_per_side
        || a.height.len() != b.height.len()
        || a.rock.len() != b.rock.len()
        || a.height.len() != a.num_cells()
        || a.rock.len() != a.num_cells()
    {
        return Err(PictureError::Size {
            width: a.cells_per_side,
            height: b.cells_per_side,
        });
    }
    Ok(())
}

/// The estimate's heights coloured green within 5 cm of the truth, red beyond, dark grey
/// where unfilled, shaded by the true relief.
pub fn height_error_png(
    estimate: &LacGrid,
    truth: &LacGrid,
    title: &str,
    path: &Path,
) -> Result<(), PictureError> {
    check_same(estimate, truth)?;
    let f = Frame::of(truth);
    let mut c = f.canvas()?;
    let (lo, hi) = range(&truth.height);
    let n = truth.cells_per_side;
    let (mut within, mut over, mut unfilled) = (0usize, 0usize, 0usize);
    for i in 0..n {
        for j in 0..n {
            let k = truth.index(i, j);
            let (e, t) = (estimate.height[k], truth.height[k]);
            let colour = if e.is_nan() {
                unfilled += 1;
                UNFILLED
            } else if (e - t).abs() < HEIGHT_TOLERANCE_M {
                within += 1;
                tint(WITHIN, shade(t, lo, hi))
            } else {
                over += 1;
                tint(OVER, shade(t, lo, hi))
            };
            let (x, y) = f.cell_px(i, j);
            c.fill_rect(x, y, PX, PX, colour);
        }
    }
    c.text(MARGIN, 8, title, 3, TEXT);
    let total = (n * n).max(1) as f64;
    let pct = |v: usize| format!("{:.1}%", 100.0 * v as f64 / total);
    let y = f.legend_y();
    let mut x = MARGIN;
    x = c.legend(x, y, WITHIN, &format!("WITHIN 5 CM {}", pct(within)), 3);
    x = c.legend(x, y, OVER, &format!("OVER {}", pct(over)), 3);
    c.legend(x, y, UNFILLED, &format!("UNFILLED {}", pct(unfilled)), 3);
    c.write_png(path)
}

/// The rock layers compared: found rocks green, false rocks red, missed rocks blue, on
/// the truth's relief.
pub fn rock_map_png(
    estimate: &LacGrid,
    truth: &LacGrid,
    title: &str,
    path: &Path,
) -> Result<(), PictureError> {
    check_same(estimate, truth)?;
    let f = Frame::of(truth);
    let mut c = f.canvas()?;
    let (lo, hi) = range(&truth.height);
    let n = truth.cells_per_side;
    let (mut tp, mut fp, mut fn_) = (0usize, 0usize, 0usize);
    for i in 0..n {
        for j in 0..n {
            let k = truth.index(i, j);
            let g = shade(truth.height[k], lo, hi);
            let colour = match (estimate.rock[k], truth.rock[k]) {
                (true, true) => {
                    tp += 1;
                    TRUE_POSITIVE
                }
                (true, false) => {
                    fp += 1;
                    FALSE_POSITIVE
                }
                (false, true) => {
                    fn_ += 1;
                    FALSE_NEGATIVE
                }
                (false, false) => [g, g, g],
            };
            let (x, y) = f.cell_px(i, j);
            c.fill_rect(x, y, PX, PX, colour);
        }
    }
    c.text(MARGIN, 8, title, 3, TEXT);
    let y = f.legend_y();
    let mut x = MARGIN;
    x = c.legend(x, y, TRUE_POSITIVE, &format!("FOUND {tp}"), 3);
    x = c.legend(x, y, FALSE_POSITIVE, &format!("FALSE {fp}"), 3);
    x = c.legend(x, y, FALSE_NEGATIVE, &format!("MISSED {fn_}"), 3);
    let f1 = if tp + fp + fn_ == 0 {
        1.0
    } else {
        2.0 * tp as f64 / (2 * tp + fp + fn_) as f64
    };
    c.text(x, y, &format!("F1 {f1:.3}"), 3, TEXT);
    c.write_png(path)
}

/// Trajectories over the grid's relief (rock cells dark), each polyline in its colour,
/// with a dot at its start.
pub fn trajectory_png(
    grid: &LacGrid,
    polylines: &[Polyline],
    title: &str,
    path: &Path,
) -> Result<(), PictureError> {
    check_same(grid, grid)?;
    let f = Frame::of(grid);
    let mut c = f.canvas()?;
    let (lo, hi) = range(&grid.height);
    let n = grid.cells_per_side;
    for i in 0..n {
        for j in 0..n {
            let k = grid.index(i, j);
            let g = shade(grid.height[k], lo, hi);
            let colour = if grid.rock[k] {
                [90, 80, 70]
            } else {
                [g, g, g]
            };
            let (x, y) = f.cell_px(i, j);
            c.fill_rect(x, y, PX, PX, colour);
        }
    }
    for line in polylines {
        for w in line.points_xy.windows(2) {
            let (x0, y0) = f.world_px(w[0].0, w[0].1);
            let (x1, y1) = f.world_px(w[1].0, w[1].1);
            c.line(x0, y0, x1, y1, line.width_px, line.colour);
        }
        if let Some(&(x, y)) = line.points_xy.first() {
            let (px, py) = f.world_px(x, y);
            c.dot(px, py, 5.0, line.colour);
        }
    }
    c.text(MARGIN, 8, title, 3, TEXT);
    let y = f.legend_y();
    let mut x = MARGIN;
    for line in polylines {
        x = c.legend(x, y, line.colour, &line.label, 3);
    }
    c.write_png(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grids() -> (LacGrid, LacGrid) {
        let mut t = LacGrid::new(20, 0.15);
        for (k, h) in t.height.iter_mut().enumerate() {
            *h = (k % 20) as f64 * 0.01;
        }
        t.rock[0] = true;
        t.rock[1] = true;
        let mut e = t.clone();
        e.height[5] += 0.2;
        e.height[6] = f64::NAN;
        e.rock[1] = false;
        e.rock[399] = true;
        (e, t)
    }

    #[test]
    fn pictures_colour_the_cells() {
        let dir = tempfile::tempdir().unwrap();
        let (e, t) = grids();
        let p = dir.path().join("h.png");
        height_error_png(&e, &t, "HEIGHT", &p).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.width() as i64, 20 * PX + 2 * MARGIN);
        let f = Frame::of(&t);
        // cell (0, 6) (index 6) is unfilled; cell (0, 5) is over
        let (x, y) = f.cell_px(0, 6);
        assert_eq!(img.get_pixel(x as u32 + 1, y as u32 + 1).0, UNFILLED);
        let (x, y) = f.cell_px(0, 5);
        assert!(img.get_pixel(x as u32 + 1, y as u32 + 1).0[0] > 100);
        let p = dir.path().join("r.png");
        rock_map_png(&e, &t, "ROCKS", &p).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        for (k, colour) in [
            (0, TRUE_POSITIVE),
            (1, FALSE_NEGATIVE),
            (399, FALSE_POSITIVE),
        ] {
            let (x, y) = f.cell_px(k / 20, k % 20);
            assert_eq!(img.get_pixel(x as u32 + 1, y as u32 + 1).0, colour);
        }
        let p = dir.path().join("t.png");
        let line = Polyline {
            label: "TRUTH".into(),
            colour: [0, 0, 200],
            points_xy: vec![(-1.0, -1.0), (1.0, 1.0)],
            width_px: 2.0,
        };
        trajectory_png(&t, &[line], "PATH", &p).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        let (x, y) = f.world_px(0.0, 0.0);
        assert_eq!(img.get_pixel(x as u32, y as u32).0, [0, 0, 200]);
        // mismatched grids are refused
        assert!(height_error_png(&LacGrid::new(3, 0.15), &t, "", &p).is_err());
    }
}
