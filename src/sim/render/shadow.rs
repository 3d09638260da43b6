//! The sun's shadow map: the scene drawn once by a parallel projection along the sunlight;
//! a point is in shadow when the map holds a surface nearer the sun than the point.
//!
//! Texels are `shadow_texel_m` across the sunlight and `shadow_texel_m · sin(elevation)`
//! along it, so that the ground under a low sun is resolved about evenly in both directions.
//! The map is looked up bilinearly (exact on planar surfaces), with a small slope-scaled bias.

use super::raster::{rasterize, screen_triangles, Projection, Raster};
use super::scene::Scene;
use nalgebra::{Point3, Vector3};

/// The shadow map of a scene under one sun.
#[derive(Clone, Debug)]
pub struct ShadowMap {
    projection: Projection,
    raster: Raster,
    texel_m: f64,
    toward_sun: Vector3<f64>,
}

impl ShadowMap {
    /// Draw `scene` as seen from the sun in direction `toward_sun` (unit, world frame).
    pub fn build(scene: &Scene, toward_sun: Vector3<f64>, texel_m: f64) -> ShadowMap {
        let toward = toward_sun.normalize();
        let across = Vector3::z().cross(&toward);
        let right = if across.norm() > 1e-6 {
            across.normalize()
        } else {
            Vector3::x()
        };
        let down = toward.cross(&right);
        let sin_e = toward.z.clamp(5f64.to_radians().sin(), 1.0);
        let (texel_right, texel_down) = (texel_m, texel_m * sin_e);
        let (mut r0, mut r1, mut d0, mut d1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for v in &scene.vertices {
            let p = Vector3::new(v[0], v[1], v[2]);
            let (r, d) = (p.dot(&right), p.dot(&down));
            (r0, r1, d0, d1) = (r0.min(r), r1.max(r), d0.min(d), d1.max(d));
        }
        let origin = Point3::from(right * (r0 - texel_right) + down * (d0 - texel_down));
        let width = ((r1 - r0) / texel_right).ceil() as usize + 3;
        let height = ((d1 - d0) / texel_down).ceil() as usize + 3;
        let projection = Projection::Orthographic {
            toward,
            right,
            down,
            origin,
            texel_right,
            texel_down,
        };
        let triangles = screen_triangles(scene, &projection, width, height, false);
        let raster = rasterize(&triangles, width, height);
        ShadowMap {
            projection,
            raster,
            texel_m,
            toward_sun: toward,
        }
    }

    /// Size of the map, texels (width, height).
    pub fn size(&self) -> (usize, usize) {
        (self.raster.width, self.raster.height)
    }

    /// Whether the sun reaches the surface point `p` of unit normal `normal`.
    pub fn lit(&self, p: &Point3<f64>, normal: &Vector3<f64>) -> bool {
        let [x, y, key] = self.projection.project(p);
        let (w, h) = (self.raster.width, self.raster.height);
        if !(x >= 0.0 && y >= 0.0 && x < (w - 1) as f64 && y < (h - 1) as f64) {
            return true;
        }
        let (i, j) = (x as usize, y as usize);
        let (tx, ty) = (x - i as f64, y - j as f64);
        let k = |i: usize, j: usize| self.raster.key[j * w + i] as f64;
        let corners = [k(i, j), k(i + 1, j), k(i, j + 1), k(i + 1, j + 1)];
        if corners.iter().any(|c| !c.is_finite()) {
            return true;
        }
        let top = corners[0] + tx * (corners[1] - corners[0]);
        let bottom = corners[2] + tx * (corners[3] - corners[2]);
        let nearest_to_sun = top + ty * (bottom - top);
        let cos = normal.dot(&self.toward_sun).clamp(1e-3, 1.0);
        let tan = (1.0 - cos * cos).sqrt() / cos;
        let bias = 0.005 + 0.25 * self.texel_m * tan.min(20.0);
        key >= nearest_to_sun - bias
    }
}
