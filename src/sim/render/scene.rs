//! The renderer's scene: one triangle mesh of the moon (terrain, lander, rocks, pebbles) with
//! an object per triangle, the terrain's vertex normals and the albedo textures.
//!
//! The terrain mesh is the moon's height field split exactly as the ray casts of
//! [`crate::sim::world_rays`] split it, so a drawn pixel's depth is the ray-cast depth. Rocks
//! are the moon's [`RockShape`]s as geodesic polyhedra (a geodesic sphere's vertices pushed
//! onto the rock's surface, more facets for larger rocks); pebbles are small flattened
//! polyhedra that are drawn but are not rocks of the ground truth.

use super::config::RenderConfig;
use super::hash_noise::{hash64, value_noise};
use crate::sim::ipex::LANDER_HALF_EXTENT_M;
use crate::sim::moon::{Moon, Rock};
use crate::sim::rock_shape::RockShape;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// What a scene object is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObjectKind {
    /// The terrain.
    Terrain,
    /// The lander.
    Lander,
    /// The rock at this index in [`Moon::rocks`].
    Rock(usize),
    /// A pebble (drawn only).
    Pebble,
}

/// One object of the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneObject {
    /// What it is.
    pub kind: ObjectKind,
    /// Centre of a rock or pebble, world frame.
    pub center: [f64; 3],
    /// Radius of the sphere holding a rock or pebble, metres.
    pub radius_m: f64,
    /// Shape of a rock or pebble (the moon's rock shapes; pebbles are flattened
    /// ellipsoids).
    pub shape: RockShape,
    /// Size of a rock as a radius (the mean radius of its footprint), metres.
    pub size_radius_m: f64,
    /// Albedo relative to the regolith's.
    pub albedo: f64,
}

/// Object index of the terrain.
pub const TERRAIN_OBJECT: u32 = 0;
/// Object index of the lander.
pub const LANDER_OBJECT: u32 = 1;
/// Object index of rock 0; rock `i` is `FIRST_ROCK_OBJECT + i`.
pub const FIRST_ROCK_OBJECT: u32 = 2;

/// Side of the fine albedo tile, texels (tileable; a power of two, wrapped by a mask).
const FINE_TEXELS: usize = 512;
const _: () = assert!(FINE_TEXELS.is_power_of_two());
/// Texel of the fine albedo tile, metres.
const FINE_TEXEL_M: f64 = 0.002;
/// Texel of the site-wide albedo texture, metres.
const COARSE_TEXEL_M: f64 = 0.02;

/// A run of consecutive triangles inside a bounding sphere, culled as a whole.
#[derive(Clone, Debug, PartialEq)]
pub struct Cluster {
    /// The triangles, indices into [`Scene::triangles`].
    pub triangles: std::ops::Range<u32>,
    /// Centre of the bounding sphere, world frame.
    pub center: [f64; 3],
    /// Radius of the bounding sphere, metres.
    pub radius_m: f64,
}

/// Terrain cells per side of a cluster.
const TERRAIN_BLOCK: usize = 16;

/// The scene: a triangle mesh with an object per triangle, and the textures.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Vertices, world frame.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Object of each triangle (index into `objects`).
    pub triangle_object: Vec<u32>,
    /// The objects.
    pub objects: Vec<SceneObject>,
    /// The triangles in bounding spheres: terrain blocks, each rock, pebble and the lander.
    pub clusters: Vec<Cluster>,
    terrain_n: usize,
    terrain_spacing_m: f64,
    half_m: f64,
    terrain_normals: Vec<[f32; 3]>,
    coarse_n: usize,
    coarse_albedo: Vec<f32>,
    fine_albedo: Vec<f32>,
}

impl Scene {
    /// Build the scene of `moon`; `seed` draws the pebbles and the textures.
    pub fn build(moon: &Moon, config: &RenderConfig, seed: u64) -> Scene {
        let (n, spacing, heights) = moon.height_samples();
        let half_m = moon.half_extent_m();
        let mut scene = Scene {
            vertices: Vec::new(),
            triangles: Vec::new(),
            triangle_object: Vec::new(),
            objects: Vec::new(),
            clusters: Vec::new(),
            terrain_n: n,
            terrain_spacing_m: spacing,
            half_m,
            terrain_normals: terrain_normals(n, spacing, heights),
            coarse_n: 0,
            coarse_albedo: Vec::new(),
            fine_albedo: Vec::new(),
        };
        scene.add_terrain(n, spacing, heights);
        scene.add_lander(moon);
        let mut rng = seed ^ 0x524f_434b;
        let mut next = move || {
            rng = hash64(rng);
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        for (i, rock) in moon.rocks().iter().enumerate() {
            let level = match rock.radius_m {
                r if r < 0.1 => 2,
                r if r < 0.25 => 2,
                _ => 3,
            };
            let albedo = config.rock_albedo * (0.7 + 0.6 * next());
            let size_radius_m = moon.rock_size_radius_m(i);
            scene.add_body(ObjectKind::Rock(i), rock, size_radius_m, albedo, level);
        }
        let count = (config.pebbles_per_m2 * (2.0 * half_m).powi(2)).round() as usize;
        let r_max = config.pebble_radius_max_m;
        for _ in 0..count {
            let (x, y) = ((2.0 * next() - 1.0) * half_m, (2.0 * next() - 1.0) * half_m);
            // P(R > r) ∝ r^−2 on [r_max/4, r_max]
            let r = r_max / 4.0 * (1.0 - next() * (1.0 - 1.0 / 16.0)).powf(-0.5);
            if moon.distance_to_lander_m(x, y) < r {
                continue;
            }
            let flatten = 0.5 + 0.3 * next();
            let z = moon.height_at(x, y) + r * flatten * (0.1 + 0.3 * next());
            let albedo = config.rock_albedo * (0.6 + 0.8 * next());
            let pebble = Rock {
                center: Point3::new(x, y, z),
                radius_m: r,
                shape: RockShape::flattened(flatten),
            };
            scene.add_body(ObjectKind::Pebble, &pebble, r, albedo, 0);
        }
        scene.make_textures(config, seed);
        scene
    }

    fn add_object(&mut self, object: SceneObject) -> u32 {
        self.objects.push(object);
        (self.objects.len() - 1) as u32
    }

    fn add_terrain(&mut self, n: usize, spacing: f64, heights: &[f64]) {
        let id = self.add_object(SceneObject {
            kind: ObjectKind::Terrain,
            center: [0.0; 3],
            radius_m: 0.0,
            shape: RockShape::sphere(),
            size_radius_m: 0.0,
            albedo: 1.0,
        });
        let half = (n - 1) as f64 * spacing / 2.0;
        for iy in 0..n {
            for ix in 0..n {
                let (x, y) = (-half + ix as f64 * spacing, -half + iy as f64 * spacing);
                self.vertices.push([x, y, heights[iy * n + ix]]);
            }
        }
        // the ray casts' split: diagonal from (ix, iy + 1) to (ix + 1, iy); blocks of cells
        // are clusters
        for by in (0..n - 1).step_by(TERRAIN_BLOCK) {
            for bx in (0..n - 1).step_by(TERRAIN_BLOCK) {
                let first = self.triangles.len() as u32;
                let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
                for iy in by..(by + TERRAIN_BLOCK).min(n - 1) {
                    for ix in bx..(bx + TERRAIN_BLOCK).min(n - 1) {
                        let v = |dx: usize, dy: usize| ((iy + dy) * n + ix + dx) as u32;
                        self.triangles.push([v(0, 0), v(1, 0), v(0, 1)]);
                        self.triangles.push([v(0, 1), v(1, 0), v(1, 1)]);
                        self.triangle_object.extend([id, id]);
                        for k in [v(0, 0), v(1, 1), v(1, 0), v(0, 1)] {
                            let p = self.vertices[k as usize];
                            for a in 0..3 {
                                (lo[a], hi[a]) = (lo[a].min(p[a]), hi[a].max(p[a]));
                            }
                        }
                    }
                }
                self.push_cluster(first, lo, hi);
            }
        }
    }

    /// A cluster of the triangles from `first` on, bounded by the box `lo`–`hi`.
    fn push_cluster(&mut self, first: u32, lo: [f64; 3], hi: [f64; 3]) {
        let center = [0, 1, 2].map(|a| (lo[a] + hi[a]) / 2.0);
        let radius_m = [0, 1, 2]
            .map(|a| (hi[a] - lo[a]) / 2.0)
            .iter()
            .map(|d| d * d)
            .sum::<f64>()
            .sqrt();
        self.clusters.push(Cluster {
            triangles: first..self.triangles.len() as u32,
            center,
            radius_m: radius_m + 1e-6,
        });
    }

    fn add_lander(&mut self, moon: &Moon) {
        let id = self.add_object(SceneObject {
            kind: ObjectKind::Lander,
            center: [0.0; 3],
            radius_m: 0.0,
            shape: RockShape::sphere(),
            size_radius_m: 0.0,
            albedo: 1.6,
        });
        let h = LANDER_HALF_EXTENT_M;
        let (z0, z1) = (moon.lander_base_m(), moon.lander_top_m());
        let base = self.vertices.len() as u32;
        let first = self.triangles.len() as u32;
        for k in 0..8 {
            let x = if k & 1 == 0 { -h } else { h };
            let y = if k & 2 == 0 { -h } else { h };
            let z = if k & 4 == 0 { z0 } else { z1 };
            self.vertices.push([x, y, z]);
        }
        // faces as corner indices, counter-clockwise seen from outside
        let quads = [
            [0, 2, 3, 1], // bottom (−z)
            [4, 5, 7, 6], // top (+z)
            [0, 1, 5, 4], // −y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // −x
            [1, 3, 7, 5], // +x
        ];
        for q in quads {
            self.triangles.push([base + q[0], base + q[1], base + q[2]]);
            self.triangles.push([base + q[0], base + q[2], base + q[3]]);
            self.triangle_object.extend([id, id]);
        }
        self.push_cluster(first, [-h, -h, z0], [h, h, z1]);
    }

    /// Mesh a rock or pebble (`size_radius_m`: its size, [`SceneObject::size_radius_m`]).
    fn add_body(
        &mut self,
        kind: ObjectKind,
        body: &Rock,
        size_radius_m: f64,
        albedo: f64,
        level: usize,
    ) {
        let c = body.center;
        let id = self.add_object(SceneObject {
            kind,
            center: [c.x, c.y, c.z],
            radius_m: body.radius_m,
            shape: body.shape,
            size_radius_m,
            albedo,
        });
        let (unit_vertices, unit_triangles) = super::icosphere::icosphere(level);
        let base = self.vertices.len() as u32;
        let first = self.triangles.len() as u32;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for v in unit_vertices {
            let u = Vector3::new(v[0], v[1], v[2]);
            let p = body.shape.surface_point(&c, body.radius_m, &u);
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
            self.vertices.push([p.x, p.y, p.z]);
        }
        for t in unit_triangles {
            self.triangles.push([base + t[0], base + t[1], base + t[2]]);
            self.triangle_object.push(id);
        }
        self.push_cluster(first, lo, hi);
    }

    fn make_textures(&mut self, config: &RenderConfig, seed: u64) {
        let contrast = config.albedo_contrast;
        let base = config.regolith_albedo;
        // several scales: metre-scale patches down to centimetre grains; the finest
        // scales live in a tileable 1 m tile multiplied on top
        let coarse: [(f64, f64); 6] = [
            (6.0, 0.9),
            (2.5, 0.8),
            (1.0, 0.6),
            (0.35, 0.5),
            (0.12, 0.4),
            (0.05, 0.3),
        ];
        let n = (2.0 * self.half_m / COARSE_TEXEL_M).ceil() as usize + 2;
        let half = self.half_m;
        self.coarse_n = n;
        self.coarse_albedo = (0..n * n)
            .into_par_iter()
            .map(|k| {
                let (x, y) = (
                    -half + (k % n) as f64 * COARSE_TEXEL_M,
                    -half + (k / n) as f64 * COARSE_TEXEL_M,
                );
                let s: f64 = coarse
                    .iter()
                    .enumerate()
                    .map(|(o, &(wl, a))| a * value_noise(seed ^ o as u64, x, y, wl, None))
                    .sum();
                (base * (contrast * s).exp()) as f32
            })
            .collect();
        let fine: [(f64, f64); 3] = [(0.016, 0.6), (0.008, 0.5), (0.004, 0.4)];
        let m = FINE_TEXELS;
        self.fine_albedo = (0..m * m)
            .into_par_iter()
            .map(|k| {
                let (x, y) = ((k % m) as f64 * FINE_TEXEL_M, (k / m) as f64 * FINE_TEXEL_M);
                let s: f64 = fine
                    .iter()
                    .enumerate()
                    .map(|(o, &(wl, a))| {
                        let period = (m as f64 * FINE_TEXEL_M / wl).round() as i64;
                        a * value_noise(seed ^ (100 + o as u64), x, y, wl, Some(period))
                    })
                    .sum();
                (contrast * s).exp() as f32
            })
            .collect();
    }

    /// Regolith albedo at (x, y): the site texture times the fine tile.
    #[inline]
    pub fn terrain_albedo(&self, x: f64, y: f64) -> f64 {
        let n = self.coarse_n;
        let u = ((x + self.half_m) / COARSE_TEXEL_M).clamp(0.0, (n - 2) as f64);
        let v = ((y + self.half_m) / COARSE_TEXEL_M).clamp(0.0, (n - 2) as f64);
        bilinear(&self.coarse_albedo, n, u, v) * self.fine_detail(x, y)
    }

    /// The fine tile's factor at (x, y) (also the grain of rocks).
    #[inline]
    pub fn fine_detail(&self, x: f64, y: f64) -> f64 {
        // shifted by a whole number of tiles so that truncation is the floor (no libm call
        // nor fmod per pixel) within ±2 km of the origin
        const SHIFT: f64 = (FINE_TEXELS * 1024) as f64;
        const MASK: usize = FINE_TEXELS - 1;
        let u = (x * (1.0 / FINE_TEXEL_M) + SHIFT).max(0.0);
        let v = (y * (1.0 / FINE_TEXEL_M) + SHIFT).max(0.0);
        let (iu, iv) = (u as usize, v as usize);
        let (tu, tv) = (u - iu as f64, v - iv as f64);
        let (i0, j0) = (iu & MASK, iv & MASK);
        let (i1, j1) = ((iu + 1) & MASK, (iv + 1) & MASK);
        let t = |i: usize, j: usize| self.fine_albedo[j * FINE_TEXELS + i] as f64;
        let a = t(i0, j0) + tu * (t(i1, j0) - t(i0, j0));
        let b = t(i0, j1) + tu * (t(i1, j1) - t(i0, j1));
        a + tv * (b - a)
    }

    /// Terrain normal at (x, y): the vertex normals interpolated bilinearly.
    #[inline]
    pub fn terrain_normal(&self, x: f64, y: f64) -> [f64; 3] {
        let n = self.terrain_n;
        let max = (n - 1) as f64 - 1e-9;
        let u = ((x + self.half_m) / self.terrain_spacing_m).clamp(0.0, max);
        let v = ((y + self.half_m) / self.terrain_spacing_m).clamp(0.0, max);
        let (i0, j0) = (u as usize, v as usize);
        let (tu, tv) = ((u - i0 as f64) as f32, (v - j0 as f64) as f32);
        let k = j0 * n + i0;
        let t = &self.terrain_normals;
        let (a, b, c, d) = (t[k], t[k + 1], t[k + n], t[k + n + 1]);
        let mut out = [0.0; 3];
        for (m, o) in out.iter_mut().enumerate() {
            let top = a[m] + tu * (b[m] - a[m]);
            let bottom = c[m] + tu * (d[m] - c[m]);
            *o = (top + tv * (bottom - top)) as f64;
        }
        let norm = (out[0] * out[0] + out[1] * out[1] + out[2] * out[2]).sqrt();
        [out[0] / norm, out[1] / norm, out[2] / norm]
    }

    /// Half the side of the terrain mesh, metres.
    pub fn terrain_half_extent_m(&self) -> f64 {
        (self.terrain_n - 1) as f64 * self.terrain_spacing_m / 2.0
    }

    /// Height of the terrain mesh at (x, y) (its triangles, split as the ray casts split
    /// the cells), clamped to the mesh.
    pub fn terrain_height(&self, x: f64, y: f64) -> f64 {
        let n = self.terrain_n;
        let half = self.terrain_half_extent_m();
        let max = (n - 1) as f64 - 1e-9;
        let u = ((x + half) / self.terrain_spacing_m).clamp(0.0, max);
        let v = ((y + half) / self.terrain_spacing_m).clamp(0.0, max);
        let (i, j) = (u as usize, v as usize);
        let (tx, ty) = (u - i as f64, v - j as f64);
        let h = |di: usize, dj: usize| self.vertices[(j + dj) * n + i + di][2];
        if tx + ty <= 1.0 {
            h(0, 0) + tx * (h(1, 0) - h(0, 0)) + ty * (h(0, 1) - h(0, 0))
        } else {
            h(1, 1) + (1.0 - tx) * (h(0, 1) - h(1, 1)) + (1.0 - ty) * (h(1, 0) - h(1, 1))
        }
    }

    /// Number of the moon's rocks in the scene.
    pub fn rock_count(&self) -> usize {
        self.objects
            .iter()
            .filter(|o| matches!(o.kind, ObjectKind::Rock(_)))
            .count()
    }
}

fn bilinear(texture: &[f32], n: usize, u: f64, v: f64) -> f64 {
    let (i0, j0) = (u as usize, v as usize);
    let (tu, tv) = (u - i0 as f64, v - j0 as f64);
    let t = |i: usize, j: usize| texture[j * n + i] as f64;
    let a = t(i0, j0) + tu * (t(i0 + 1, j0) - t(i0, j0));
    let b = t(i0, j0 + 1) + tu * (t(i0 + 1, j0 + 1) - t(i0, j0 + 1));
    a + tv * (b - a)
}

fn terrain_normals(n: usize, spacing: f64, heights: &[f64]) -> Vec<[f32; 3]> {
    let h = |ix: usize, iy: usize| heights[iy.min(n - 1) * n + ix.min(n - 1)];
    (0..n * n)
        .map(|k| {
            let (ix, iy) = (k % n, k / n);
            let (xl, xh) = (ix.saturating_sub(1), (ix + 1).min(n - 1));
            let (yl, yh) = (iy.saturating_sub(1), (iy + 1).min(n - 1));
            let dzdx = (h(xh, iy) - h(xl, iy)) / ((xh - xl) as f64 * spacing);
            let dzdy = (h(ix, yh) - h(ix, yl)) / ((yh - yl) as f64 * spacing);
            let norm = (dzdx * dzdx + dzdy * dzdy + 1.0).sqrt();
            [
                (-dzdx / norm) as f32,
                (-dzdy / norm) as f32,
                (1.0 / norm) as f32,
            ]
        })
        .collect()
}
