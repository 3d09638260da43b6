//! The local ground surface seen in a disparity map, and every pixel's height above it.
//!
//! 1. Back-project the valid disparities within range to 3D points (left camera frame).
//! 2. Fit the dominant ground plane by RANSAC (normal within `max_tilt_deg` of the camera's
//!    up axis), refined by least squares on its inliers.
//! 3. Bin the points on a grid in the plane; each cell's ground level is a low percentile of
//!    its heights, and the local ground at a cell is the median of the cell levels around
//!    it (a window wider than a boulder, so boulders do not lift their own ground).
//! 4. A pixel's height above ground is its height over the plane minus its cell's local
//!    ground level: undulating terrain and slopes drop out, boulders stand out.

use nalgebra::{Matrix3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::DisparityMap;

/// Settings of the ground estimate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GroundConfig {
    /// Points nearer than this (metres) are ignored.
    pub min_range_m: f64,
    /// Points farther than this (metres) are ignored.
    pub max_range_m: f64,
    /// Largest angle between the ground normal and the camera's up axis, degrees.
    pub max_tilt_deg: f64,
    /// RANSAC inlier distance, metres.
    pub plane_inlier_m: f64,
    /// RANSAC iterations.
    pub ransac_iterations: usize,
    /// Grid cell size in the ground plane, metres.
    pub cell_m: f64,
    /// Local ground window radius, cells (the window is 2r + 1 cells wide).
    pub window_cells: usize,
    /// Percentile (0–1) of the heights in a cell taken as its ground level.
    pub cell_percentile: f64,
    /// Residual (metres) above which a cell counts as an obstacle, not ground, in the
    /// robust local plane fit.
    pub obstacle_residual_m: f64,
    /// Points more than this below the ground plane are mismatches and ignored, metres.
    pub max_below_plane_m: f64,
    /// Cells whose heights spread (10th to 90th percentile) more than this, metres, hold
    /// a vertical face (a boulder, the lander) and are left out of the local ground fit.
    pub max_cell_spread_m: f64,
}

impl Default for GroundConfig {
    fn default() -> Self {
        GroundConfig {
            min_range_m: 0.5,
            max_range_m: 14.0,
            max_tilt_deg: 35.0,
            plane_inlier_m: 0.06,
            ransac_iterations: 150,
            cell_m: 0.2,
            window_cells: 3,
            cell_percentile: 0.3,
            obstacle_residual_m: 0.03,
            max_below_plane_m: 0.6,
            max_cell_spread_m: 0.12,
        }
    }
}

/// Heights above the local ground, on the disparity map's grid.
#[derive(Clone, Debug)]
pub struct HeightMap {
    /// Width (as the disparity map).
    pub width: usize,
    /// Height (as the disparity map).
    pub height: usize,
    /// Height above the local ground, metres; NaN where there is no depth or out of range.
    pub above_ground_m: Vec<f32>,
    /// Depth of each pixel, metres (NaN where invalid).
    pub depth_m: Vec<f32>,
    /// The ground plane's unit normal (pointing up) in the camera frame.
    pub normal: Vector3<f64>,
}

/// Estimate the ground and each pixel's height above it; `None` with too few points.
pub fn height_above_ground(disparity: &DisparityMap, config: &GroundConfig) -> Option<HeightMap> {
    let (w, h) = (disparity.width, disparity.height);
    let camera = &disparity.camera;
    let mut points: Vec<(usize, Point3<f64>)> = Vec::new();
    let mut depth_m = vec![f32::NAN; w * h];
    for y in 0..h {
        for x in 0..w {
            if let Some(z) = disparity.depth_m(x, y) {
                depth_m[y * w + x] = z as f32;
                if (config.min_range_m..=config.max_range_m).contains(&z) {
                    points.push((y * w + x, camera.back_project(x as f64, y as f64, z)));
                }
            }
        }
    }
    if points.len() < 50 {
        return None;
    }
    let (normal, offset) = fit_ground_plane(&points, config);
    // in-plane axes: lateral (camera x projected) and forward
    let e1 = (Vector3::x() - normal * normal.x).normalize();
    let e2 = normal.cross(&e1);
    let n_cells = ((2.0 * config.max_range_m / config.cell_m).ceil() as usize).max(1);
    let cell_of = |p: &Point3<f64>| -> Option<usize> {
        let a = ((p.coords.dot(&e1) + config.max_range_m) / config.cell_m).floor();
        let b = ((p.coords.dot(&e2) + config.max_range_m) / config.cell_m).floor();
        (a >= 0.0 && b >= 0.0 && (a as usize) < n_cells && (b as usize) < n_cells)
            .then(|| b as usize * n_cells + a as usize)
    };
    let mut cells: Vec<Vec<f32>> = vec![Vec::new(); n_cells * n_cells];
    let mut point_cell = Vec::with_capacity(points.len());
    for (i, p) in &points {
        let height = (normal.dot(&p.coords) + offset) as f32;
        let c = cell_of(p);
        if let Some(c) = c {
            cells[c].push(height);
        }
        point_cell.push((*i, c, height));
    }
    // each cell's level, and whether it looks like ground: a cell holding a vertical face
    // (a boulder's front, the lander) spans a wide range of heights
    let mut ground_like = vec![false; n_cells * n_cells];
    let level: Vec<f32> = cells
        .iter_mut()
        .zip(ground_like.iter_mut())
        .map(|(v, ground)| {
            if v.is_empty() {
                return f32::NAN;
            }
            let rank = |q: f64| ((v.len() - 1) as f64 * q).round() as usize;
            let (k, k_lo, k_hi) = (rank(config.cell_percentile), rank(0.1), rank(0.9));
            let hi = *v.select_nth_unstable_by(k_hi, f32::total_cmp).1;
            let lo = *v[..=k_hi].select_nth_unstable_by(k_lo, f32::total_cmp).1;
            let level = *v[k_lo..=k_hi]
                .select_nth_unstable_by(k - k_lo, f32::total_cmp)
                .1;
            *ground = ((hi - lo) as f64) <= config.max_cell_spread_m;
            level
        })
        .collect();
    let local = local_ground(&level, &ground_like, n_cells, config);
    let mut above_ground_m = vec![f32::NAN; w * h];
    for (i, c, height) in point_cell {
        // points far below the plane are mismatches (nothing is seen through the ground)
        if let Some(c) = c.filter(|_| height > -config.max_below_plane_m as f32) {
            above_ground_m[i] = height - local[c];
        }
    }
    Some(HeightMap {
        width: w,
        height: h,
        above_ground_m,
        depth_m,
        normal,
    })
}

/// The local ground level at each non-empty cell: a plane fitted to the levels of the
/// ground-like cells in the surrounding window (twice as wide where too few; the global
/// plane, level 0, where still too few) by iteratively reweighted least squares with Cauchy weights, evaluated
/// at the cell. Cells off the plane by more than `obstacle_residual_m` (boulders) lose
/// weight; cells below it lose weight too, at twice that scale. A symmetric robust fit
/// keeps the plane on the terrain: an asymmetric one (cells below keep full weight) runs
/// away downhill past crests and occlusion gaps, putting whole terrain ridges 30 cm
/// "above ground" (seen on the real pair 1_155).
fn local_ground(level: &[f32], ground_like: &[bool], n: usize, config: &GroundConfig) -> Vec<f32> {
    let t = config.obstacle_residual_m.max(1e-3);
    let mut out = vec![f32::NAN; n * n];
    let mut cells: Vec<(f64, f64, f64)> = Vec::new();
    for cb in 0..n as isize {
        for ca in 0..n as isize {
            if level[cb as usize * n + ca as usize].is_nan() {
                continue;
            }
            for r in [
                config.window_cells as isize,
                2 * config.window_cells as isize,
            ] {
                cells.clear();
                for db in -r..=r {
                    for da in -r..=r {
                        let (a, b) = (ca + da, cb + db);
                        if a >= 0 && b >= 0 && (a as usize) < n && (b as usize) < n {
                            let c = b as usize * n + a as usize;
                            if ground_like[c] && level[c].is_finite() {
                                cells.push((da as f64, db as f64, level[c] as f64));
                            }
                        }
                    }
                }
                if cells.len() >= 6 {
                    break;
                }
            }
            if cells.len() < 3 {
                out[cb as usize * n + ca as usize] = 0.0;
                continue;
            }
            // start from the median level (flat), then fit planes
            let mut z: Vec<f64> = cells.iter().map(|c| c.2).collect();
            let mid = z.len() / 2;
            let mut plane = [*z.select_nth_unstable_by(mid, f64::total_cmp).1, 0.0, 0.0];
            if cells.len() >= 6 {
                for _ in 0..5 {
                    let mut ata = nalgebra::Matrix3::<f64>::zeros();
                    let mut atb = Vector3::<f64>::zeros();
                    for &(x, y, v) in &cells {
                        let res = v - (plane[0] + plane[1] * x + plane[2] * y);
                        let scale = if res > 0.0 { t } else { 2.0 * t };
                        let wgt = 1.0 / (1.0 + (res / scale).powi(2));
                        let row = Vector3::new(1.0, x, y);
                        ata += wgt * row * row.transpose();
                        atb += wgt * v * row;
                    }
                    // a ridge on the slopes keeps sparse or one-sided windows from tilting
                    ata[(1, 1)] += 1.0;
                    ata[(2, 2)] += 1.0;
                    match ata.cholesky() {
                        Some(ch) => {
                            let sol = ch.solve(&atb);
                            plane = [sol[0], sol[1], sol[2]];
                        }
                        None => break,
                    }
                }
            }
            out[cb as usize * n + ca as usize] = plane[0] as f32;
        }
    }
    out
}

/// RANSAC plane with the normal pointing up (−y in the camera frame) and tilted at most
/// `max_tilt_deg`; returns (unit normal, offset) with `normal · p + offset` = height.
fn fit_ground_plane(points: &[(usize, Point3<f64>)], config: &GroundConfig) -> (Vector3<f64>, f64) {
    let up = Vector3::new(0.0, -1.0, 0.0);
    let step = (points.len() / 3000).max(1);
    let sample: Vec<Point3<f64>> = points.iter().step_by(step).map(|(_, p)| *p).collect();
    let min_cos = config.max_tilt_deg.to_radians().cos();
    let mut rng = ChaCha8Rng::seed_from_u64(0x5E610C);
    let mut best: Option<(usize, Vector3<f64>, f64)> = None;
    for _ in 0..config.ransac_iterations {
        let pick = |rng: &mut ChaCha8Rng| sample[rng.random_range(0..sample.len())];
        let (a, b, c) = (pick(&mut rng), pick(&mut rng), pick(&mut rng));
        let n = (b - a).cross(&(c - a));
        let Some(mut n) = n.try_normalize(1e-12) else {
            continue;
        };
        if n.dot(&up) < 0.0 {
            n = -n;
        }
        if n.dot(&up) < min_cos {
            continue;
        }
        let off = -n.dot(&a.coords);
        let count = sample
            .iter()
            .filter(|p| (n.dot(&p.coords) + off).abs() < config.plane_inlier_m)
            .count();
        if best.as_ref().is_none_or(|b| count > b.0) {
            best = Some((count, n, off));
        }
    }
    let Some((_, n, off)) = best else {
        // no plane found: assume a level camera and the lowest-looking points as ground
        let mut heights: Vec<f64> = sample.iter().map(|p| up.dot(&p.coords)).collect();
        let k = heights.len() / 5;
        let level = *heights.select_nth_unstable_by(k, f64::total_cmp).1;
        return (up, -level);
    };
    // least-squares refinement on the inliers
    let inliers: Vec<&Point3<f64>> = sample
        .iter()
        .filter(|p| (n.dot(&p.coords) + off).abs() < config.plane_inlier_m)
        .collect();
    let mean = inliers.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / inliers.len() as f64;
    let mut cov = Matrix3::zeros();
    for p in &inliers {
        let d = p.coords - mean;
        cov += d * d.transpose();
    }
    let eig = cov.symmetric_eigen();
    let (imin, _) = eig.eigenvalues.argmin();
    let mut n2 = eig.eigenvectors.column(imin).into_owned();
    if n2.dot(&up) < 0.0 {
        n2 = -n2;
    }
    if n2.dot(&up) < min_cos {
        return (n, off);
    }
    (n2, -n2.dot(&mean))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::StereoCamera;

    #[test]
    fn flat_ground_has_zero_height_and_a_box_stands_out() {
        // disparity of a level plane 0.6 m below the camera, plus a block of pixels closer
        let camera = StereoCamera::ipex().for_size(320, 180).unwrap();
        let (w, h) = (320, 180);
        let mut data = vec![f32::NAN; w * h];
        for y in 0..h {
            for x in 0..w {
                let ray_y = (y as f64 - camera.cy) / camera.fy;
                if ray_y > 0.02 {
                    let z = 0.6 / ray_y;
                    data[y * w + x] = camera.disparity_from_depth(z) as f32;
                }
            }
        }
        // an object at 4 m spanning rows whose ground is farther away
        let d_obj = camera.disparity_from_depth(4.0) as f32;
        let v_base = camera.cy + camera.fy * 0.6 / 4.0;
        for y in (v_base as usize - 8)..(v_base as usize) {
            for x in 150..160 {
                data[y * w + x] = d_obj;
            }
        }
        let map = DisparityMap {
            width: w,
            height: h,
            data,
            scale: 1,
            camera,
        };
        let hm = height_above_ground(&map, &GroundConfig::default()).unwrap();
        assert!(hm.normal.y < -0.99);
        let ground = hm.above_ground_m[(h - 20) * w + 40];
        assert!(ground.abs() < 0.02, "ground {ground}");
        let top = hm.above_ground_m[(v_base as usize - 8) * w + 155];
        assert!(top > 0.08, "top {top}");
    }
}
