//! The renderer: the IPEX front stereo pair's view of the synthetic moon as 8-bit images,
//! with per-pixel depth and object, in three stages per view:
//!
//! 1. rasterize ([`super::raster`]): the scene's triangles into a z-buffer of the scene
//!    triangle per pixel;
//! 2. shade: the pixel's surface point from its depth; on the terrain the sun's side
//!    (`μ0 · lit`) baked once per renderer ([`super::terrain_light`]) and the viewing angle
//!    from the triangle's normal; on rocks the normal of the rock's exact shape and the sun's shadow map
//!    ([`super::shadow`]); then the lunar-Lambert reflectance and the albedo textures;
//! 3. expose ([`super::sensor`]): fixed exposure, shot and read noise, gamma, 8 bits, each
//!    pixel as it is shaded (no radiance image).
//!
//! What does not change between the frames of one drive (scene, textures, shadow map, the
//! terrain's sunlight, triangle normals) is built in [`Renderer::new`]; z-buffers are reused.

use super::config::{RenderConfig, RenderError};
use super::raster::{rasterize_into, screen_triangles, Projection, Raster, ScreenTriangle};
use super::scene::{ObjectKind, Scene};
use super::sensor::Sensor;
use super::shadow::ShadowMap;
use super::terrain_light::TerrainLight;
use crate::perception::{GrayImage, StereoCamera};
use crate::sim::moon::Moon;
use crate::sim::sensors::{cameras, Camera};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// One rendered view.
#[derive(Clone, Debug)]
pub struct RenderedView {
    /// The camera image.
    pub image: GrayImage,
    /// Depth along the optical axis per pixel, metres (0: sky).
    pub depth_m: Vec<f32>,
    /// Scene object per pixel (index into the scene's objects; `u32::MAX`: sky).
    pub object: Vec<u32>,
    /// The projected triangles (for silhouettes).
    pub(crate) triangles: Vec<ScreenTriangle>,
    /// Milliseconds spent rasterizing and shading.
    pub time_ms: f64,
}

/// The renderer of one moon under one sun.
pub struct Renderer {
    config: RenderConfig,
    scene: Scene,
    shadow: ShadowMap,
    /// `μ0 · lit` of the terrain, baked from the shadow map.
    terrain_light: TerrainLight,
    /// Unit normal of every scene triangle (terrain: for the viewing angle only).
    face_normals: Vec<[f32; 3]>,
    camera: StereoCamera,
    sensor: Sensor,
    /// Z-buffers of earlier views, reused (one per view drawn at once).
    rasters: std::sync::Mutex<Vec<Raster>>,
    /// Unit vector toward the sun, world frame.
    sun: Vector3<f64>,
    /// The Lommel–Seeliger weight against the phase angle.
    phase_weights: PhaseWeights,
}

/// `rover_from_left_camera` of the front pair, optical frame (x right, y down, z forward).
pub fn rover_from_front_left_optical() -> Isometry3<f64> {
    let [front, _] = cameras();
    rover_from_left_optical(&front)
}

/// `rover_from_left_camera` of any stereo pair of the sensor model ([`cameras`]), optical
/// frame (x right, y down, z forward).
pub fn rover_from_left_optical(camera: &Camera) -> Isometry3<f64> {
    camera.rover_from_camera * sim_camera_from_optical()
}

/// The sim's camera frame (x forward, y left, z up) from the optical frame.
fn sim_camera_from_optical() -> Isometry3<f64> {
    let m = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
    )
}

impl Renderer {
    /// A renderer of `moon` (its textures and pebbles drawn from `seed`, the moon's seed).
    pub fn new(moon: &Moon, config: &RenderConfig, seed: u64) -> Result<Renderer, RenderError> {
        config.validate()?;
        let scene = Scene::build(moon, config, seed);
        let shadow = ShadowMap::build(&scene, config.sun_direction(), config.shadow_texel_m);
        let (w, h) = (config.width(), config.height());
        let camera = StereoCamera::ipex().scaled(config.resolution_scale, w, h);
        let sun = config.sun_direction();
        let terrain_light = TerrainLight::bake(&scene, &shadow, &sun, TERRAIN_LIGHT_TEXEL_M);
        let face_normals = (0..scene.triangles.len())
            .into_par_iter()
            .map(|t| face_normal(&scene, t as u32).map(|c| c as f32))
            .collect();
        Ok(Renderer {
            config: config.clone(),
            scene,
            shadow,
            terrain_light,
            face_normals,
            camera,
            sensor: Sensor::new(config),
            rasters: std::sync::Mutex::new(Vec::new()),
            sun: config.sun_direction(),
            phase_weights: PhaseWeights::new(config),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &RenderConfig {
        &self.config
    }

    /// The camera model of the images (scaled with the resolution).
    pub fn camera(&self) -> &StereoCamera {
        &self.camera
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The shadow map.
    pub fn shadow_map(&self) -> &ShadowMap {
        &self.shadow
    }

    /// Render the view of a camera at `world_from_camera` (optical frame); `noise_key`
    /// draws the image noise (give each image its own).
    pub fn render_view(&self, world_from_camera: &Isometry3<f64>, noise_key: u64) -> RenderedView {
        let start = std::time::Instant::now();
        let c = &self.camera;
        let projection = Projection::Perspective {
            camera_from_world: world_from_camera.inverse(),
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
            near_m: self.config.near_m,
        };
        let triangles = screen_triangles(&self.scene, &projection, c.width, c.height, true);
        let t1 = start.elapsed().as_secs_f64() * 1e3;
        let mut raster = self.take_raster();
        rasterize_into(&triangles, &mut raster);
        let t2 = start.elapsed().as_secs_f64() * 1e3;
        let key = noise_key ^ self.config.noise_seed.wrapping_mul(0x9E37_79B9);
        let (image, depth_m, object) = self.shade(&raster, world_from_camera, key);
        if let Ok(mut pool) = self.rasters.lock() {
            pool.push(raster);
        }
        if std::env::var_os("SEGLOC_RENDER_PROFILE").is_some() {
            let t3 = start.elapsed().as_secs_f64() * 1e3;
            eprintln!(
                "tris {} setup {t1:.1} raster {:.1} shade+expose {:.1}",
                triangles.len(),
                t2 - t1,
                t3 - t2,
            );
        }
        RenderedView {
            image,
            depth_m,
            object,
            triangles,
            time_ms: start.elapsed().as_secs_f64() * 1e3,
        }
    }

    /// A z-buffer of the image's size from the pool, or a new one.
    fn take_raster(&self) -> Raster {
        let reused = self.rasters.lock().ok().and_then(|mut pool| pool.pop());
        reused.unwrap_or(Raster {
            width: self.camera.width,
            height: self.camera.height,
            key: Vec::new(),
            triangle: Vec::new(),
        })
    }

    /// Per pixel: the exposed grey level (noise drawn from `noise_key`), depth and object.
    fn shade(
        &self,
        raster: &Raster,
        world_from_camera: &Isometry3<f64>,
        noise_key: u64,
    ) -> (GrayImage, Vec<f32>, Vec<u32>) {
        let (w, h) = (raster.width, raster.height);
        let mut grey = vec![0u8; w * h];
        let mut depth = vec![0f32; w * h];
        let mut object = vec![u32::MAX; w * h];
        let eye = Point3::from(world_from_camera.translation.vector);
        let rotation = world_from_camera.rotation.to_rotation_matrix().into_inner();
        let c = &self.camera;
        // the world ray of pixel (x, y) at unit depth is row_start(y) + x · step
        let step: Vector3<f64> = rotation.column(0) / c.fx;
        grey.par_chunks_mut(w)
            .zip(depth.par_chunks_mut(w))
            .zip(object.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, ((out, dep), obj))| {
                let row_start =
                    rotation * Vector3::new(-c.cx / c.fx, (y as f64 - c.cy) / c.fy, 1.0);
                for x in 0..w {
                    let idx = y * w + x;
                    let tri = raster.triangle[idx];
                    let radiance = if tri == u32::MAX {
                        0.0
                    } else {
                        let z = 1.0 / raster.key[idx] as f64;
                        let ray = row_start + step * x as f64;
                        let o = self.scene.triangle_object[tri as usize];
                        dep[x] = z as f32;
                        obj[x] = o;
                        self.radiance(&(eye + ray * z), &ray, o, tri)
                    };
                    out[x] = self.sensor.grey(radiance, noise_key, idx);
                }
            });
        let image = GrayImage {
            width: w,
            height: h,
            data: grey,
        };
        (image, depth, object)
    }

    /// Radiance (relative to a unit-albedo, unit-reflectance surface) leaving `p` back along
    /// the viewing ray `ray` (any length).
    #[inline]
    fn radiance(&self, p: &Point3<f64>, ray: &Vector3<f64>, object: u32, triangle: u32) -> f64 {
        let o = &self.scene.objects[object as usize];
        let ray_norm = ray.norm();
        let l = self
            .phase_weights
            .at(-self.sun.dot(ray) / ray_norm.max(1e-300));
        let view_cos = |n: &Vector3<f64>| (-n.dot(ray) / ray_norm).max(1e-3);
        let (normal, albedo) = match o.kind {
            ObjectKind::Terrain => {
                // the sun's side baked (smooth normal, shadow map); the viewing angle from
                // the triangle's own normal
                let mu0 = self.terrain_light.at(p.x, p.y);
                let mu = view_cos(&self.triangle_normal(triangle));
                let direct = if mu0 > 0.0 {
                    lunar_lambert(mu0, mu, l)
                } else {
                    0.0
                };
                return self.scene.terrain_albedo(p.x, p.y) * (direct + self.config.ambient);
            }
            ObjectKind::Rock(_) | ObjectKind::Pebble => {
                let center = Point3::from(o.center);
                let normal = o.shape.normal_at(&center, o.radius_m, p);
                let grain = self.scene.fine_detail(p.x + 0.37 * p.z, p.y - 0.61 * p.z);
                (normal, o.albedo * grain)
            }
            ObjectKind::Lander => (self.triangle_normal(triangle), o.albedo),
        };
        let mu0 = normal.dot(&self.sun);
        let mu = view_cos(&normal);
        let direct = if mu0 > 0.0 && self.shadow.lit(p, &normal) {
            lunar_lambert(mu0, mu, l)
        } else {
            0.0
        };
        albedo * (direct + self.config.ambient)
    }

    /// The stored unit normal of scene triangle `triangle`.
    #[inline]
    fn triangle_normal(&self, triangle: u32) -> Vector3<f64> {
        let f = self.face_normals[triangle as usize];
        Vector3::new(f[0] as f64, f[1] as f64, f[2] as f64)
    }
}

/// The lunar-Lambert reflectance of a lit surface: a Lommel–Seeliger part of weight `l` and
/// a Lambert part, for the cosines `mu0` (toward the sun) and `mu` (toward the viewer).
#[inline]
fn lunar_lambert(mu0: f64, mu: f64, l: f64) -> f64 {
    2.0 * l * mu0 / (mu0 + mu) + (1.0 - l) * mu0
}

/// Steps of the table of the Lommel–Seeliger weight against `sin(α/2)`.
const PHASE_TABLE_STEPS: usize = 256;

/// The Lommel–Seeliger weight against the phase angle α: the configured one, or McEwen's
/// phase function of it ([`RenderConfig::phase_dependent_weight`]), tabulated on even steps
/// of `sin(α/2)` (smooth in that variable, unlike in `cos α`) so that no pixel pays an `acos`.
struct PhaseWeights {
    /// The weight at `sin(α/2) = k / PHASE_TABLE_STEPS`, `k = 0..=PHASE_TABLE_STEPS`.
    table: Vec<f64>,
}

impl PhaseWeights {
    fn new(config: &RenderConfig) -> PhaseWeights {
        let l0 = config.lommel_seeliger_weight;
        let table = (0..=PHASE_TABLE_STEPS)
            .map(|k| {
                if !config.phase_dependent_weight {
                    return l0;
                }
                let half_phase = (k as f64 / PHASE_TABLE_STEPS as f64).asin();
                l0 * mcewen_weight(2.0 * half_phase.to_degrees())
            })
            .collect();
        PhaseWeights { table }
    }

    /// The weight at the phase angle whose cosine is `cos_phase`, interpolated linearly.
    #[inline]
    fn at(&self, cos_phase: f64) -> f64 {
        // sin(α/2) = sqrt((1 − cos α) / 2)
        let t = ((1.0 - cos_phase) / 2.0).clamp(0.0, 1.0).sqrt() * PHASE_TABLE_STEPS as f64;
        let k = (t as usize).min(PHASE_TABLE_STEPS - 1);
        let f = t - k as f64;
        self.table[k] * (1.0 - f) + self.table[k + 1] * f
    }
}

/// McEwen's (1991) lunar Lommel–Seeliger weight at phase angle `phase_deg`, clamped to
/// [0, 1]: 1 at opposition, about 0.6 at 30°, 0.4 at 60°, 0.2 at 90°, 0 beyond about 105°.
#[inline]
fn mcewen_weight(phase_deg: f64) -> f64 {
    let a = phase_deg;
    (1.0 - 0.019 * a + 2.42e-4 * a * a - 1.46e-6 * a * a * a).clamp(0.0, 1.0)
}

/// Texel of the baked terrain sunlight, metres.
const TERRAIN_LIGHT_TEXEL_M: f64 = 0.01;

/// Unit normal of a scene triangle (counter-clockwise seen from outside).
fn face_normal(scene: &Scene, triangle: u32) -> [f64; 3] {
    let t = scene.triangles[triangle as usize];
    let v = t.map(|k| Vector3::from(scene.vertices[k as usize]));
    let n = (v[1] - v[0]).cross(&(v[2] - v[0]));
    let n = n / n.norm().max(1e-300);
    [n.x, n.y, n.z]
}

#[cfg(test)]
mod tests {
    use super::{mcewen_weight, PhaseWeights};
    use crate::sim::render::config::RenderConfig;

    #[test]
    fn mcewens_weight_falls_from_opposition_to_lambert() {
        assert!((mcewen_weight(0.0) - 1.0).abs() < 1e-12);
        // McEwen's table: about 0.61 at 30°, 0.42 at 60°, 0.19 at 90°
        assert!((mcewen_weight(30.0) - 0.609).abs() < 2e-3);
        assert!((mcewen_weight(60.0) - 0.416).abs() < 2e-3);
        assert!((mcewen_weight(90.0) - 0.186).abs() < 2e-3);
        assert_eq!(mcewen_weight(130.0), 0.0);
        let mut last = 1.0;
        for a in 0..180 {
            let w = mcewen_weight(a as f64);
            assert!(w <= last + 1e-12 && (0.0..=1.0).contains(&w), "{a}: {w}");
            last = w;
        }
    }

    #[test]
    fn the_phase_table_interpolates_mcewens_weight_within_a_hundredth() {
        let weights = PhaseWeights::new(&RenderConfig::default());
        for a in 0..=1800 {
            let alpha = a as f64 / 10.0;
            let w = weights.at(alpha.to_radians().cos());
            // worst at the clamp near 106° (0.005), elsewhere under 0.001
            let tolerance = if (100.0..110.0).contains(&alpha) {
                0.01
            } else {
                1e-3
            };
            assert!(
                (w - mcewen_weight(alpha)).abs() < tolerance,
                "{alpha}°: {w}"
            );
        }
    }
}
