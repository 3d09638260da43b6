//! The rock layer from fused boulder landmarks: mark the cells the boulder covers.
//!
//! The LAC ground truth marks a cell as rock when any of a 4 × 4 grid of vertical rays
//! through the cell hits a rock. A landmark whose size is known marks exactly the cells
//! with a sample point within its footprint radius (half its diameter) of the boulder's
//! centre; a landmark of unknown size marks the cell its centroid falls in.
//!
//! A stereo centroid lies on the visible face of the boulder, towards the camera from the
//! boulder's centre by a fraction of its radius; a rover mostly sees a boulder from one
//! side, so this does not average out. [`rock_grid_from_detections`] fuses with the
//! viewpoint-bias correction ([`FusionConfig::view_bias_size_fraction`]: every detection
//! of known size moved that far away from the rover, horizontally; the mission calibrates
//! it from its own passes, [`crate::localizer::view_bias`]), clusters with
//! a radius wide enough to keep a large boulder's detections from different sides
//! together, centres each boulder with the fusion's centroid (the mission's weights near
//! views, whose depth is good to millimetres, above far ones:
//! [`crate::landmarks::estimate`]) and paints the footprints of the boulders seen often
//! enough. On the synthetic
//! mission (10 seeds, BENCHMARKS.md) the face correction is worth +0.035 F1, the wider
//! clusters +0.02, and the third observation (spurious clusters) +0.01.

use crate::landmarks::{fuse_detections, FusionConfig};
use segloc_maps::{DetectionSet, LacGrid, Landmark};
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
    /// [`rock_grid_from_detections`], when the fusion brings no viewpoint-bias correction
    /// of its own (`view_bias_size_fraction` 0): a detection of known size is moved this
    /// fraction of its radius away from the rover (horizontally), as the stereo centroid
    /// of the visible face sits that far in front of the boulder's centre (0: none).
    pub face_offset_fraction: f64,
    /// [`rock_grid_from_detections`]: detections within this distance (m) of a cluster's
    /// centroid join it (replaces the fusion's radius for the rock map only).
    pub cluster_radius_m: f64,
}

impl Default for RockGridConfig {
    fn default() -> Self {
        Self {
            min_observations: 3,
            min_size_m: 0.0,
            footprint_scale: 1.0,
            samples_per_side: 4,
            face_offset_fraction: 1.0 / 3.0,
            cluster_radius_m: 0.3,
        }
    }
}

/// The rock grid of raw detections (world frame, with rover positions and sizes): fused
/// with `fusion` (its viewpoint-bias correction, or else `face_offset_fraction`, moving the
/// centroids to the boulders' centres) but the rock map's own cluster radius, and painted
/// by [`rock_grid`]. Returns the grid and
/// the number of fused boulders.
pub fn rock_grid_from_detections(
    detections: &DetectionSet,
    grid: &LacGrid,
    fusion: &FusionConfig,
    config: &RockGridConfig,
) -> (LacGrid, usize) {
    let view_bias_size_fraction = match fusion.view_bias_size_fraction {
        f if f != 0.0 => f,
        // a fraction of the radius is half that fraction of the size
        _ => 0.5 * config.face_offset_fraction,
    };
    let fusion = FusionConfig {
        view_bias_size_fraction,
        cluster_radius_m: if config.cluster_radius_m.is_finite() && config.cluster_radius_m > 0.0 {
            config.cluster_radius_m
        } else {
            fusion.cluster_radius_m
        },
        ..fusion.clone()
    };
    let map = fuse_detections(detections, &fusion);
    (rock_grid(&map.landmarks, grid, config), map.len())
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
    use segloc_maps::Detection;

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

    fn det(p: [f64; 3], rover: [f64; 3], size: Option<f64>) -> Detection {
        Detection {
            frame: 0,
            p_world: Point3::new(p[0], p[1], p[2]),
            rover_position: Some(Point3::new(rover[0], rover[1], rover[2])),
            size_m: size,
            score: None,
        }
    }

    #[test]
    fn a_boulder_seen_from_two_sides_paints_its_own_footprint() {
        // a 0.4 m boulder centred at (2.0, 0.0) whose detections sit a third of its radius
        // in front of it, seen from the west and from the east
        let grid = LacGrid::new(60, 0.15);
        let (r, f) = (0.2, 1.0 / 3.0);
        let mut set = DetectionSet::new("t", "world", true);
        for k in 0..4 {
            let y = 0.002 * k as f64;
            set.detections
                .push(det([2.0 - f * r, y, 0.1], [-1.0, y, 0.3], Some(2.0 * r)));
            set.detections
                .push(det([2.0 + f * r, y, 0.1], [5.0, y, 0.3], Some(2.0 * r)));
        }
        // a spurious pair and a boulder seen only twice stay out (fewer than 3 observations)
        for k in 0..2 {
            set.detections.push(det(
                [-2.0, 2.0 + 0.01 * k as f64, 0.0],
                [-2.0, 0.0, 0.3],
                Some(0.1),
            ));
        }
        let config = RockGridConfig::default();
        let (g, boulders) =
            rock_grid_from_detections(&set, &grid, &FusionConfig::default(), &config);
        assert_eq!(boulders, 2);
        let centred = rock_grid(&[lm(2.0, 0.0, Some(2.0 * r), 8)], &grid, &config);
        assert!(centred.rock_count() > 4);
        assert_eq!(g.rock, centred.rock);
        // without the face correction the default fusion radius splits the boulder in two
        let raw = RockGridConfig {
            face_offset_fraction: 0.0,
            cluster_radius_m: 0.05,
            ..config
        };
        let (g2, boulders2) =
            rock_grid_from_detections(&set, &grid, &FusionConfig::default(), &raw);
        assert_eq!(boulders2, 3);
        assert_ne!(g2.rock, centred.rock);
        // the fusion's own (calibrated) correction, as a fraction of the size, takes the
        // place of the face offset
        let calibrated = FusionConfig {
            view_bias_size_fraction: f / 2.0,
            ..FusionConfig::default()
        };
        let none = RockGridConfig {
            face_offset_fraction: 0.0,
            ..config
        };
        let (g3, boulders3) = rock_grid_from_detections(&set, &grid, &calibrated, &none);
        assert_eq!(boulders3, 2);
        assert_eq!(g3.rock, centred.rock);
    }
}
