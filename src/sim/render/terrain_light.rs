//! The sunlight on the terrain, baked once per renderer (the sun does not move during a
//! drive): `μ0 · lit` on a square grid of `texel_m`, with `μ0` the cosine of the sun on the
//! smooth terrain normal and `lit` the shadow map's verdict for the terrain point. A terrain
//! pixel then needs one bilinear look-up instead of a normal interpolation and a shadow-map
//! look-up; shadow edges are resolved to the texel (1 cm by default, about the penumbra of
//! the real sun's half-degree disc behind a rock a metre away).

use super::scene::Scene;
use super::shadow::ShadowMap;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// `μ0 · lit` of the terrain on a grid.
#[derive(Clone, Debug)]
pub struct TerrainLight {
    n: usize,
    texel_m: f64,
    half_m: f64,
    /// `μ0 · lit` scaled to `u16::MAX`, row-major from (−half, −half).
    values: Vec<u16>,
}

impl TerrainLight {
    /// Bake the terrain of `scene` under the sun `toward_sun` (unit) with its shadow map.
    pub fn bake(
        scene: &Scene,
        shadow: &ShadowMap,
        toward_sun: &Vector3<f64>,
        texel_m: f64,
    ) -> TerrainLight {
        let half_m = scene.terrain_half_extent_m();
        let n = (2.0 * half_m / texel_m).ceil() as usize + 2;
        let values = (0..n * n)
            .into_par_iter()
            .map(|k| {
                let x = -half_m + (k % n) as f64 * texel_m;
                let y = -half_m + (k / n) as f64 * texel_m;
                let normal = Vector3::from(scene.terrain_normal(x, y));
                let mu0 = normal.dot(toward_sun);
                let p = Point3::new(x, y, scene.terrain_height(x, y));
                if mu0 <= 0.0 || !shadow.lit(&p, &normal) {
                    0
                } else {
                    (mu0.min(1.0) * u16::MAX as f64).round() as u16
                }
            })
            .collect();
        TerrainLight {
            n,
            texel_m,
            half_m,
            values,
        }
    }

    /// `μ0 · lit` at (x, y), interpolated bilinearly.
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> f64 {
        let max = (self.n - 2) as f64;
        let u = ((x + self.half_m) / self.texel_m).clamp(0.0, max);
        let v = ((y + self.half_m) / self.texel_m).clamp(0.0, max);
        let (i, j) = (u as usize, v as usize);
        let (tu, tv) = (u - i as f64, v - j as f64);
        let k = j * self.n + i;
        let t = |k: usize| self.values[k] as f64;
        let a = t(k) + tu * (t(k + 1) - t(k));
        let b = t(k + self.n) + tu * (t(k + self.n + 1) - t(k + self.n));
        (a + tv * (b - a)) * (1.0 / u16::MAX as f64)
    }
}
