//! The rock layer from fused boulder landmarks: mark the cells the boulder covers.
//!
//! The LAC ground truth marks a cell as rock when any of a 4 × 4 grid of vertical rays
//! through the cell hits a rock. A landmark whose size is known marks exactly the cells
//! with a sample point within its footprint radius (half its diameter) of the boulder's
//! centre; a landmark of unknown size marks the cell its centroid falls in.
//!
//! A stereo centroid lies on the visible face of the boulder, a few centimetres towards
//! the camera from the boulder's centre; landmarks seen from all around average this out,
//! and the footprint test uses the landmark position as it is.

use segloc_maps::{LacGrid, Landmark};
use serde::{Deserialize, Serialize};

/// Parameters of [`rock_grid`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RockGridConfig {
    /// Landmarks with fewer observations are left out.
    pub min_observations: u32,
    /// Landmarks smaller than this diameter (m) are left out (when their size is known).
    pub min_size_m: f64,
    /// Footprint radius = this × half the diameter (1: the boulder's own outline).
    pub footprint_scale: f64,
    /// Sample points per cell side (4 in the LAC ground truth).
    pub samples_per_side: usize,
}

impl Default for RockGridConfig {
    fn default() -> Self {
        Self {
            min_observations: 2,
            min_size_m: 0.0,
            footprint_scale: 1.0,
            samples_per_side: 4,
        }
    }
}

/// The rock grid of `landmarks` on the geometry of `grid` (heights copied from it).
///
/// ```
/// use nalgebra::{Matrix3, Point3};
/// use segloc::mapping::{rock_grid, RockGridConfig};
/// use segloc_maps::{LacGrid, Landmark};
/// let mut big = Landmark::new(0, Point3::new(0.0, 0.0, 0.1), Matrix3::identity() * 1e-4);
/// big.size_m = Some(0.4);
/// big.observations = 5;
/// let g = rock_grid(&[big], &LacGrid::new_lac(), &RockGridConfig::default());
/// assert_eq!(g.rock_count(), 12); // a 0.2 m disc at a cell corner: 4 × 4 cells less the corners
/// ```
pub fn rock_grid(landmarks: &[Landmark], grid: &LacGrid, config: &RockGridConfig) -> LacGrid {
    let mut out = grid.clone();
    out.rock.iter_mut().for_each(|r| *r = false);
    let size = grid.cell_size_m;
    let s = config.samples_per_side.max(1);
    for lm in landmarks {
        if lm.observations < config.min_observations {
            continue;
        }
        let (x, y) = (lm.position.x, lm.position.y);
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        let radius = match lm.size_m {
            Some(d) if d.is_finite() && d > 0.0 => {
                if d < config.min_size_m {
                    continue;
                }
                0.5 * d * config.footprint_scale
            }
            _ => {
                if let Some((i, j)) = grid.cell_of(x, y) {
                    let k = grid.index(i, j);
                    out.rock[k] = true;
                }
                continue;
            }
        };
        let reach = (radius / size).ceil() as i64 + 1;
        let Some((ci, cj)) = grid
            .cell_of(x, y)
            .or_else(|| nearest_cell(grid, x, y, radius))
        else {
            continue;
        };
        let n = grid.cells_per_side as i64;
        for i in (ci as i64 - reach).max(0)..=(ci as i64 + reach).min(n - 1) {
            for j in (cj as i64 - reach).max(0)..=(cj as i64 + reach).min(n - 1) {
                let (cx, cy) = grid.cell_center(i as usize, j as usize);
                let hit = (0..s).any(|a| {
                    (0..s).any(|b| {
                        let sx = cx + ((a as f64 + 0.5) / s as f64 - 0.5) * size;
                        let sy = cy + ((b as f64 + 0.5) / s as f64 - 0.5) * size;
                        (sx - x).powi(2) + (sy - y).powi(2) <= radius * radius
                    })
                });
                if hit {
                    let k = grid.index(i as usize, j as usize);
                    out.rock[k] = true;
                }
            }
        }
    }
    out
}

/// The grid cell nearest (x, y) when the point is outside the grid but within `radius`.
fn nearest_cell(grid: &LacGrid, x: f64, y: f64, radius: f64) -> Option<(usize, usize)> {
    let h = grid.half_extent_m() - 1e-9;
    let (cx, cy) = (x.clamp(-h, h), y.clamp(-h, h));
    if (cx - x).hypot(cy - y) <= radius {
        grid.cell_of(cx, cy)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Point3};

    fn lm(x: f64, y: f64, size: Option<f64>, obs: u32) -> Landmark {
        let mut l = Landmark::new(0, Point3::new(x, y, 0.0), Matrix3::identity() * 1e-4);
        l.size_m = size;
        l.observations = obs;
        l
    }

    #[test]
    fn footprints_follow_the_sample_points() {
        let grid = LacGrid::new(20, 0.15);
        let cfg = RockGridConfig::default();
        // centre of cell (10, 10) is (0.075, 0.075); a 4 cm radius stays inside it
        let g = rock_grid(&[lm(0.075, 0.075, Some(0.08), 3)], &grid, &cfg);
        assert_eq!(g.rock_count(), 1);
        // on the edge x = 0 between cells 9 and 10, radius 3 cm reaches samples 1.875 cm away
        let g = rock_grid(&[lm(0.0, 0.075, Some(0.06), 3)], &grid, &cfg);
        assert_eq!(g.rock_count(), 2);
        // a 1 cm radius at the edge touches no sample point (nearest are 1.875 cm away)
        let g = rock_grid(&[lm(0.0, 0.075, Some(0.02), 3)], &grid, &cfg);
        assert_eq!(g.rock_count(), 0);
        // unknown size: the centroid's cell; too few observations: nothing
        let g = rock_grid(
            &[lm(0.2, 0.2, None, 3), lm(-0.5, 0.2, Some(0.5), 1)],
            &grid,
            &cfg,
        );
        assert_eq!(g.rock_count(), 1);
        assert!(g.rock[grid.index(11, 11)]);
        // too small
        let cfg_small = RockGridConfig {
            min_size_m: 0.1,
            ..RockGridConfig::default()
        };
        assert_eq!(
            rock_grid(&[lm(0.0, 0.0, Some(0.08), 3)], &grid, &cfg_small).rock_count(),
            0
        );
        // just outside the grid but overlapping it
        let g = rock_grid(&[lm(1.55, 0.075, Some(0.2), 3)], &grid, &cfg);
        assert_eq!(g.rock_count(), 1);
    }
}
