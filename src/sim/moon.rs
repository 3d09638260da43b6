//! The synthetic moon: a seeded 40 m × 40 m site with rolling relief, craters, rocks and the
//! lander at the origin, and its ground truth on the LAC grid.
//!
//! Terrain is a height field sampled every `resolution_m` (bilinear between samples); rocks
//! are angular bodies ([`RockShape`]: flattened, elongated ellipsoids chipped by flat cuts,
//! or plain spheres with `angular_rocks = false`) whose centres sit a little above the
//! ground, their undersides buried; the lander is a box on the ground at the origin. The
//! same scene answers ray casts (see [`crate::sim::world_rays`]: a parry3d `HeightField`
//! built from the same samples, and each rock's exact shape), the renderer draws the same
//! shapes, and the ground truth's rock cells are their footprints.
//!
//! Ground truth follows the LAC definition (shared data `README.md`): on the 180 × 180 grid
//! of 0.15 m cells centred on the lander, a cell's height is the mean terrain height over a
//! 4 × 4 grid of samples in the cell (rocks and lander excluded), and the cell is a rock cell
//! when any of those samples falls on a rock.

use crate::sim::crater::Crater;
use crate::sim::ipex::{LANDER_HALF_EXTENT_M, LANDER_HEIGHT_M};
use crate::sim::rock_shape::{Footprint, RockShape, ShapeRanges};
use crate::sim::value_noise::FractalNoise;
use crate::spatial::GridIndex;
use nalgebra::{Point3, Vector3};
use parry3d_f64::shape::HeightField;
use parry3d_f64::utils::Array2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use segloc_maps::LacGrid;
use serde::{Deserialize, Serialize};

/// Samples per cell side in the LAC ground truth (4 × 4 rays per cell).
pub const GT_SAMPLES_PER_SIDE: usize = 4;

/// Errors building a moon.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MoonError {
    /// A configuration value is out of range.
    #[error("invalid moon configuration: {0}")]
    InvalidConfig(String),
}

/// Parameters of the synthetic moon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MoonConfig {
    /// Side of the square site, metres, centred on the lander.
    pub size_m: f64,
    /// Height-field sample spacing, metres.
    pub resolution_m: f64,
    /// Amplitude of the largest relief octave (values within ±amplitude), metres.
    pub relief_amplitude_m: f64,
    /// Wavelength of the largest relief octave, metres.
    pub relief_wavelength_m: f64,
    /// Number of relief octaves (each half the wavelength and amplitude of the previous).
    pub relief_octaves: usize,
    /// Number of craters.
    pub craters: usize,
    /// Smallest crater rim radius, metres.
    pub crater_radius_min_m: f64,
    /// Largest crater rim radius, metres.
    pub crater_radius_max_m: f64,
    /// No crater centre closer than this to the lander, metres.
    pub crater_clear_of_lander_m: f64,
    /// Number of rocks.
    pub rocks: usize,
    /// Smallest rock radius, metres.
    pub rock_radius_min_m: f64,
    /// Largest rock radius, metres.
    pub rock_radius_max_m: f64,
    /// Exponent α of the truncated power law of rock radii, P(R > r) ∝ r^−α (most small).
    pub rock_size_exponent: f64,
    /// No rock within this distance of the lander's footprint, metres.
    pub rock_clear_of_lander_m: f64,
    /// Rocks are angular (ellipsoids chipped by flat cuts, [`RockShape::draw`]); `false`
    /// keeps the plain spheres of earlier versions (for comparisons).
    pub angular_rocks: bool,
}

impl Default for MoonConfig {
    fn default() -> Self {
        Self {
            size_m: 40.0,
            resolution_m: 0.1,
            relief_amplitude_m: 0.3,
            relief_wavelength_m: 16.0,
            relief_octaves: 4,
            craters: 35,
            crater_radius_min_m: 0.6,
            crater_radius_max_m: 4.0,
            crater_clear_of_lander_m: 4.0,
            rocks: 500,
            rock_radius_min_m: 0.05,
            rock_radius_max_m: 0.5,
            rock_size_exponent: 3.0,
            rock_clear_of_lander_m: 0.5,
            angular_rocks: true,
        }
    }
}

impl MoonConfig {
    /// Check every value is in range.
    pub fn validate(&self) -> Result<(), MoonError> {
        let bad = |m: &str| Err(MoonError::InvalidConfig(m.to_string()));
        let finite_pos = |v: f64| v.is_finite() && v > 0.0;
        if !finite_pos(self.size_m) || !finite_pos(self.resolution_m) {
            return bad("size_m and resolution_m must be positive");
        }
        if self.size_m / self.resolution_m > 4000.0 || self.size_m / self.resolution_m < 2.0 {
            return bad("size_m / resolution_m must be within 2..4000");
        }
        if !finite_pos(self.relief_wavelength_m) || !self.relief_amplitude_m.is_finite() {
            return bad("relief wavelength must be positive and amplitude finite");
        }
        if self.relief_octaves > 12 {
            return bad("relief_octaves must be at most 12");
        }
        if !finite_pos(self.crater_radius_min_m)
            || self.crater_radius_max_m.is_nan()
            || self.crater_radius_max_m < self.crater_radius_min_m
        {
            return bad("crater radii must satisfy 0 < min ≤ max");
        }
        if !finite_pos(self.rock_radius_min_m)
            || self.rock_radius_max_m.is_nan()
            || self.rock_radius_max_m < self.rock_radius_min_m
            || !finite_pos(self.rock_size_exponent)
        {
            return bad("rock radii must satisfy 0 < min ≤ max and the exponent be positive");
        }
        if !self.crater_clear_of_lander_m.is_finite() || !self.rock_clear_of_lander_m.is_finite() {
            return bad("clearances must be finite");
        }
        if self.rocks > 1_000_000 || self.craters > 100_000 {
            return bad("too many rocks or craters");
        }
        Ok(())
    }
}

/// One rock: a body of [`RockShape`] inside the sphere of `radius_m` around `center`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rock {
    /// Centre, world frame, metres.
    pub center: Point3<f64>,
    /// Radius of the sphere that holds the rock (its shape only cuts into it), metres.
    pub radius_m: f64,
    /// Its shape (a sphere when absent from a file).
    #[serde(default)]
    pub shape: RockShape,
}

impl Rock {
    /// A spherical rock.
    pub fn sphere(center: Point3<f64>, radius_m: f64) -> Self {
        Self {
            center,
            radius_m,
            shape: RockShape::sphere(),
        }
    }

    /// Distance along the unit direction `dir` from `origin` to the rock, if hit within
    /// `max_m` (0 from inside).
    pub fn cast_ray(&self, origin: &Point3<f64>, dir: &Vector3<f64>, max_m: f64) -> Option<f64> {
        self.shape
            .cast_ray(&self.center, self.radius_m, origin, dir, max_m)
    }

    /// Whether the rock covers (x, y) seen from above.
    pub fn covers_xy(&self, x: f64, y: f64) -> bool {
        (self.center.x - x).hypot(self.center.y - y) < self.radius_m
            && self.shape.covers_xy(&self.center, self.radius_m, x, y)
    }
}

/// The synthetic moon: terrain, craters, rocks and lander.
#[derive(Clone, Debug)]
pub struct Moon {
    config: MoonConfig,
    /// Samples per side of the height field.
    n: usize,
    half_m: f64,
    /// Terrain heights, `heights[iy * n + ix]` at (−half + ix·res, −half + iy·res).
    heights: Vec<f64>,
    craters: Vec<Crater>,
    rocks: Vec<Rock>,
    /// Per rock: its footprint seen from above.
    rock_footprints: Vec<Footprint>,
    rock_index: GridIndex,
    max_rock_radius_m: f64,
    /// The same terrain for ray casts; local frame (x, height, y).
    pub(crate) heightfield: HeightField,
}

/// Cell size of the rock lookup grid, metres.
const ROCK_GRID_M: f64 = 1.0;

impl Moon {
    /// Generate the moon of `config` from `seed` (the same seed gives the same moon).
    pub fn generate(config: &MoonConfig, seed: u64) -> Result<Moon, MoonError> {
        config.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let relief_seed = rng.random();
        let n = (config.size_m / config.resolution_m).round() as usize + 1;
        let half_m = (n - 1) as f64 * config.resolution_m / 2.0;
        let craters = place_craters(config, half_m, &mut rng);
        let mut moon = Self::from_parts(config, relief_seed, craters)?;
        moon.place_rocks(&mut rng);
        Ok(moon)
    }

    /// A moon without rocks from its parts: the relief drawn from `relief_seed` plus the
    /// given craters (for tests and hand-made scenes; add rocks with [`Moon::set_rocks`]).
    pub fn from_parts(
        config: &MoonConfig,
        relief_seed: u64,
        craters: Vec<Crater>,
    ) -> Result<Moon, MoonError> {
        config.validate()?;
        let n = (config.size_m / config.resolution_m).round() as usize + 1;
        let half_m = (n - 1) as f64 * config.resolution_m / 2.0;
        let noise = FractalNoise::new(
            relief_seed,
            config.relief_wavelength_m,
            config.relief_amplitude_m,
            config.relief_octaves,
        );
        let mut heights = vec![0.0; n * n];
        for iy in 0..n {
            let y = -half_m + iy as f64 * config.resolution_m;
            for ix in 0..n {
                let x = -half_m + ix as f64 * config.resolution_m;
                heights[iy * n + ix] = noise.at(x, y);
            }
        }
        for c in &craters {
            // Only the samples within the crater's reach.
            let reach = c.reach_m();
            let lo = |v: f64| {
                ((v - reach + half_m) / config.resolution_m)
                    .floor()
                    .clamp(0.0, (n - 1) as f64) as usize
            };
            let hi = |v: f64| {
                ((v + reach + half_m) / config.resolution_m)
                    .ceil()
                    .clamp(0.0, (n - 1) as f64) as usize
            };
            for iy in lo(c.y)..=hi(c.y) {
                let y = -half_m + iy as f64 * config.resolution_m;
                for ix in lo(c.x)..=hi(c.x) {
                    let x = -half_m + ix as f64 * config.resolution_m;
                    heights[iy * n + ix] += c.offset_at(x, y);
                }
            }
        }
        // parry's height field: rows advance along its z (our y), columns along its x.
        let mut zx = Vec::with_capacity(n * n);
        for ix in 0..n {
            for iy in 0..n {
                zx.push(heights[iy * n + ix]);
            }
        }
        let size = (n - 1) as f64 * config.resolution_m;
        let heightfield = HeightField::new(
            Array2::new(n, n, zx),
            parry3d_f64::math::Vector::new(size, 1.0, size),
        );
        Ok(Moon {
            config: config.clone(),
            n,
            half_m,
            heights,
            craters,
            rocks: Vec::new(),
            rock_footprints: Vec::new(),
            rock_index: GridIndex::new(ROCK_GRID_M),
            max_rock_radius_m: 0.0,
            heightfield,
        })
    }

    /// Replace the rocks.
    pub fn set_rocks(&mut self, rocks: Vec<Rock>) {
        self.max_rock_radius_m = rocks.iter().map(|r| r.radius_m).fold(0.0, f64::max);
        self.rock_footprints = rocks
            .iter()
            .map(|r| r.shape.footprint(r.radius_m))
            .collect();
        self.rock_index = GridIndex::new(ROCK_GRID_M);
        for (i, r) in rocks.iter().enumerate() {
            self.rock_index.insert(i as u32, &r.center);
        }
        self.rocks = rocks;
    }

    fn place_rocks(&mut self, rng: &mut ChaCha8Rng) {
        let c = &self.config;
        let (lo, hi, alpha) = (
            c.rock_radius_min_m,
            c.rock_radius_max_m,
            c.rock_size_exponent,
        );
        let tail = 1.0 - (lo / hi).powf(alpha);
        let limit = self.half_m - hi;
        let mut rocks = Vec::with_capacity(c.rocks);
        let mut attempts = 0usize;
        while limit > 0.0 && rocks.len() < c.rocks && attempts < 100 * c.rocks + 1000 {
            attempts += 1;
            let x = rng.random_range(-limit..limit);
            let y = rng.random_range(-limit..limit);
            let u: f64 = rng.random();
            let embed: f64 = rng.random_range(0.05..0.4);
            // truncated power law by inversion: P(R > r) ∝ r^−α on [lo, hi]
            let radius_m = lo * (1.0 - u * tail).powf(-1.0 / alpha);
            if self.distance_to_lander_m(x, y) < radius_m + c.rock_clear_of_lander_m {
                continue;
            }
            rocks.push((x, y, radius_m, embed));
        }
        // the shapes from their own stream, so that the layout is that of the spheres
        let mut shape_rng = ChaCha8Rng::seed_from_u64(rng.random());
        let rocks = rocks
            .into_iter()
            .map(|(x, y, radius_m, embed)| {
                let shape = if c.angular_rocks {
                    RockShape::draw(&mut shape_rng, &ShapeRanges::default())
                } else {
                    RockShape::sphere()
                };
                // the centre sits `embed` of the rock's half-height above the ground
                let ground = self.height_at(x, y);
                let center = Point3::new(x, y, ground + embed * shape.axes[2] * radius_m);
                Rock {
                    center,
                    radius_m,
                    shape,
                }
            })
            .collect();
        self.set_rocks(rocks);
    }

    /// Size of rock `i` as a radius: the mean radius of its footprint, half the width a
    /// camera sees of it, metres; 0 for an index out of range.
    pub fn rock_size_radius_m(&self, i: usize) -> f64 {
        self.rock_footprints
            .get(i)
            .map_or(0.0, Footprint::mean_radius_m)
    }

    /// Horizontal distance from (x, y) to rock `i`'s footprint, metres (0 on it; infinite
    /// for an index out of range).
    pub fn distance_to_rock_m(&self, i: usize, x: f64, y: f64) -> f64 {
        match (self.rocks.get(i), self.rock_footprints.get(i)) {
            (Some(r), Some(footprint)) => footprint.distance_m(x - r.center.x, y - r.center.y),
            _ => f64::INFINITY,
        }
    }

    /// The configuration it was generated from.
    pub fn config(&self) -> &MoonConfig {
        &self.config
    }

    /// Half the side of the terrain, metres (terrain spans [−half, half]² ).
    pub fn half_extent_m(&self) -> f64 {
        self.half_m
    }

    /// The height-field samples: samples per side `n`, spacing (metres) and the heights,
    /// `heights[iy * n + ix]` at (−half + ix·spacing, −half + iy·spacing). The ray casts
    /// split each cell (ix, iy) along the diagonal from (ix, iy + 1) to (ix + 1, iy).
    pub fn height_samples(&self) -> (usize, f64, &[f64]) {
        (self.n, self.config.resolution_m, &self.heights)
    }

    /// The rocks.
    pub fn rocks(&self) -> &[Rock] {
        &self.rocks
    }

    /// The craters.
    pub fn craters(&self) -> &[Crater] {
        &self.craters
    }

    /// Largest rock radius, metres.
    pub fn max_rock_radius_m(&self) -> f64 {
        self.max_rock_radius_m
    }

    /// Calls `visit(index, rock)` for every rock whose centre is within `radius_m` of (x, y)
    /// horizontally.
    pub fn for_each_rock_near(
        &self,
        x: f64,
        y: f64,
        radius_m: f64,
        mut visit: impl FnMut(usize, &Rock),
    ) {
        let p = Point3::new(x, y, 0.0);
        self.rock_index.for_each_near(&p, radius_m, |id| {
            let rock = &self.rocks[id as usize];
            if (rock.center.x - x).hypot(rock.center.y - y) <= radius_m {
                visit(id as usize, rock);
            }
        });
    }

    /// Terrain height at (x, y), metres: bilinear between height-field samples; outside the
    /// site the nearest edge value.
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        if !x.is_finite() || !y.is_finite() {
            return f64::NAN;
        }
        let res = self.config.resolution_m;
        let max = (self.n - 1) as f64;
        let u = ((x + self.half_m) / res).clamp(0.0, max);
        let v = ((y + self.half_m) / res).clamp(0.0, max);
        let (i0, j0) = (
            (u.floor() as usize).min(self.n - 2),
            (v.floor() as usize).min(self.n - 2),
        );
        let (tu, tv) = (u - i0 as f64, v - j0 as f64);
        let h = |i: usize, j: usize| self.heights[j * self.n + i];
        let a = h(i0, j0) + tu * (h(i0 + 1, j0) - h(i0, j0));
        let b = h(i0, j0 + 1) + tu * (h(i0 + 1, j0 + 1) - h(i0, j0 + 1));
        a + tv * (b - a)
    }

    /// Unit terrain normal at (x, y), from central differences over one sample spacing.
    pub fn normal_at(&self, x: f64, y: f64) -> Vector3<f64> {
        let d = self.config.resolution_m;
        let dzdx = (self.height_at(x + d, y) - self.height_at(x - d, y)) / (2.0 * d);
        let dzdy = (self.height_at(x, y + d) - self.height_at(x, y - d)) / (2.0 * d);
        Vector3::new(-dzdx, -dzdy, 1.0).normalize()
    }

    /// Whether (x, y) lies on a rock seen from above (inside a rock's footprint).
    pub fn on_rock(&self, x: f64, y: f64) -> bool {
        let mut hit = false;
        self.for_each_rock_near(x, y, self.max_rock_radius_m, |_, r| {
            hit |= r.covers_xy(x, y);
        });
        hit
    }

    /// Horizontal distance from (x, y) to the lander's footprint (0 inside).
    pub fn distance_to_lander_m(&self, x: f64, y: f64) -> f64 {
        let dx = (x.abs() - LANDER_HALF_EXTENT_M).max(0.0);
        let dy = (y.abs() - LANDER_HALF_EXTENT_M).max(0.0);
        dx.hypot(dy)
    }

    /// Whether (x, y) is at least `clearance_m` from the lander and from the edge of every
    /// rock of size ≥ `min_rock_radius_m` ([`Moon::rock_size_radius_m`]; its holding sphere is the
    /// edge, conservatively).
    pub fn is_clear(&self, x: f64, y: f64, clearance_m: f64, min_rock_radius_m: f64) -> bool {
        if self.distance_to_lander_m(x, y) < clearance_m {
            return false;
        }
        let mut clear = true;
        self.for_each_rock_near(x, y, clearance_m + self.max_rock_radius_m, |i, r| {
            if self.rock_size_radius_m(i) >= min_rock_radius_m
                && (r.center.x - x).hypot(r.center.y - y) < clearance_m + r.radius_m
            {
                clear = false;
            }
        });
        clear
    }

    /// The clear position (see [`Moon::is_clear`]) nearest (x, y), searched on rings 0.1 m
    /// apart out to 5 m; (x, y) itself if nothing clear is found.
    pub fn nearest_clear_position(
        &self,
        x: f64,
        y: f64,
        clearance_m: f64,
        min_rock_radius_m: f64,
    ) -> (f64, f64) {
        for ring in 0..=50 {
            let r = 0.1 * ring as f64;
            let n = (ring * 8).max(1);
            for k in 0..n {
                let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
                let (px, py) = (x + r * a.cos(), y + r * a.sin());
                if self.is_clear(px, py, clearance_m, min_rock_radius_m) {
                    return (px, py);
                }
            }
        }
        (x, y)
    }

    /// Lowest terrain height under the lander: the lander box spans this to
    /// `+ LANDER_HEIGHT_M`.
    pub fn lander_base_m(&self) -> f64 {
        let h = LANDER_HALF_EXTENT_M;
        [(-h, -h), (-h, h), (h, -h), (h, h), (0.0, 0.0)]
            .iter()
            .map(|&(x, y)| self.height_at(x, y))
            .fold(f64::INFINITY, f64::min)
    }

    /// Lander top height, metres.
    pub fn lander_top_m(&self) -> f64 {
        self.lander_base_m() + LANDER_HEIGHT_M
    }

    /// Ground truth on the LAC grid (180 × 180 cells of 0.15 m centred on the lander):
    /// height = mean of a 4 × 4 grid of terrain samples per cell, rock = any sample on a rock.
    pub fn ground_truth_grid(&self) -> LacGrid {
        let mut grid = LacGrid::new_lac();
        let k = GT_SAMPLES_PER_SIDE;
        let step = grid.cell_size_m / k as f64;
        let offsets: Vec<f64> = (0..k)
            .map(|s| -grid.cell_size_m / 2.0 + (s as f64 + 0.5) * step)
            .collect();
        for i in 0..grid.cells_per_side {
            for j in 0..grid.cells_per_side {
                let (cx, cy) = grid.cell_center(i, j);
                let mut sum = 0.0;
                let mut rock = false;
                for &dx in &offsets {
                    for &dy in &offsets {
                        sum += self.height_at(cx + dx, cy + dy);
                        rock = rock || self.on_rock(cx + dx, cy + dy);
                    }
                }
                let idx = grid.index(i, j);
                grid.height[idx] = sum / (k * k) as f64;
                grid.rock[idx] = rock;
            }
        }
        grid
    }
}

fn place_craters(config: &MoonConfig, half_m: f64, rng: &mut ChaCha8Rng) -> Vec<Crater> {
    let mut craters = Vec::with_capacity(config.craters);
    let (lo, hi) = (config.crater_radius_min_m, config.crater_radius_max_m);
    let mut attempts = 0;
    while craters.len() < config.craters && attempts < 100 * config.craters + 100 {
        attempts += 1;
        let x = rng.random_range(-half_m..half_m);
        let y = rng.random_range(-half_m..half_m);
        // more small craters than large: radius ∝ 1 / (1 − u·(1 − lo/hi)) (P(R > r) ∝ 1/r)
        let u: f64 = rng.random();
        let radius = lo / (1.0 - u * (1.0 - lo / hi));
        let freshness = rng.random_range(0.3..1.0);
        if x.hypot(y) < config.crater_clear_of_lander_m + radius {
            continue;
        }
        craters.push(Crater::new(x, y, radius, freshness));
    }
    craters
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moon() -> Moon {
        Moon::generate(&MoonConfig::default(), 11).unwrap()
    }

    #[test]
    fn deterministic() {
        let a = moon();
        let b = moon();
        assert_eq!(a.rocks(), b.rocks());
        assert_eq!(a.height_at(3.3, -7.1), b.height_at(3.3, -7.1));
        let c = Moon::generate(&MoonConfig::default(), 12).unwrap();
        assert_ne!(a.rocks(), c.rocks());
    }

    #[test]
    fn relief_about_a_metre() {
        let m = moon();
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for i in 0..200 {
            for j in 0..200 {
                let h = m.height_at(-19.5 + 0.195 * i as f64, -19.5 + 0.195 * j as f64);
                lo = lo.min(h);
                hi = hi.max(h);
            }
        }
        assert!(hi - lo > 0.6 && hi - lo < 2.5, "relief {}", hi - lo);
    }

    #[test]
    fn bilinear_matches_samples_and_normals_point_up() {
        let m = moon();
        let res = m.config().resolution_m;
        let x = -m.half_extent_m() + 37.0 * res;
        let y = -m.half_extent_m() + 52.0 * res;
        assert!((m.height_at(x, y) - m.heights[52 * m.n + 37]).abs() < 1e-12);
        let n = m.normal_at(1.0, 2.0);
        assert!((n.norm() - 1.0).abs() < 1e-12 && n.z > 0.5);
    }

    #[test]
    fn rocks_sizes_heavy_tailed_and_clear_of_lander() {
        let m = moon();
        let r: Vec<f64> = m.rocks().iter().map(|r| r.radius_m).collect();
        assert_eq!(r.len(), 500);
        assert!(r.iter().all(|&x| (0.05..=0.5).contains(&x)));
        let small = r.iter().filter(|&&x| x < 0.08).count();
        let large = r.iter().filter(|&&x| x > 0.25).count();
        assert!(small > r.len() / 2, "{small}");
        assert!(large > 0 && large < r.len() / 10, "{large}");
        for rock in m.rocks() {
            assert!(m.distance_to_lander_m(rock.center.x, rock.center.y) > rock.radius_m);
        }
    }

    #[test]
    fn ground_truth_grid_is_sensible() {
        let m = moon();
        let g = m.ground_truth_grid();
        assert_eq!(g.filled_count(), 32_400);
        let fraction = g.rock_count() as f64 / 32_400.0;
        // LAC's Moon_Map_01 preset 1 has 848 / 32,400 ≈ 2.6 % rock cells.
        assert!(
            fraction > 0.01 && fraction < 0.06,
            "rock fraction {fraction}"
        );
        // a cell holding a rock centre is a rock cell
        for rock in m.rocks() {
            if let Some((i, j)) = g.cell_of(rock.center.x, rock.center.y) {
                let (cx, cy) = g.cell_center(i, j);
                if (rock.center.x - cx).abs() < 0.05 && (rock.center.y - cy).abs() < 0.05 {
                    assert!(g.rock[g.index(i, j)]);
                }
            }
        }
        // heights are the terrain's, within the cell's variation
        let (cx, cy) = g.cell_center(40, 130);
        assert!((g.height[g.index(40, 130)] - m.height_at(cx, cy)).abs() < 0.02);
    }

    #[test]
    fn rejects_bad_config() {
        let c = MoonConfig {
            resolution_m: 0.0,
            ..MoonConfig::default()
        };
        assert!(Moon::generate(&c, 1).is_err());
        let c = MoonConfig {
            rock_radius_max_m: 0.01,
            ..MoonConfig::default()
        };
        assert!(Moon::generate(&c, 1).is_err());
    }
}
