//! A small ray tracer for synthetic stereo pairs of known geometry: a textured ground plane
//! with spheres (boulders) resting on it, lit by a low sun with hard shadows, seen by a
//! rectified stereo camera. Used to measure depth accuracy against exact ground truth.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::{GrayImage, StereoCamera};

/// A sphere in the left camera's optical frame (x right, y down, z forward).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre, metres.
    pub center: Point3<f64>,
    /// Radius, metres.
    pub radius_m: f64,
}

/// A ground plane (horizontal, `camera_height_m` below the left camera) with spheres.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticScene {
    /// Height of the camera above the ground, metres.
    pub camera_height_m: f64,
    /// The spheres.
    pub spheres: Vec<Sphere>,
    /// Direction towards the sun, optical frame (normalised on use).
    pub sun_direction: Vector3<f64>,
    /// Seed of the surface texture.
    pub texture_seed: u64,
    /// Samples per pixel along each axis (anti-aliasing).
    pub supersample: usize,
}

impl SyntheticScene {
    /// A sphere of `radius_m` resting on the ground with its centre `distance_m` ahead and
    /// `lateral_m` to the right of the camera.
    pub fn resting_sphere(&self, distance_m: f64, lateral_m: f64, radius_m: f64) -> Sphere {
        Sphere {
            center: Point3::new(lateral_m, self.camera_height_m - radius_m, distance_m),
            radius_m,
        }
    }
}

impl Default for SyntheticScene {
    fn default() -> Self {
        SyntheticScene {
            camera_height_m: 0.6,
            spheres: Vec::new(),
            sun_direction: Vector3::new(-0.6, -0.35, -0.3),
            texture_seed: 7,
            supersample: 2,
        }
    }
}

/// A rendered pair and the left image's ground truth.
#[derive(Clone, Debug)]
pub struct RenderedPair {
    /// Left image.
    pub left: GrayImage,
    /// Right image.
    pub right: GrayImage,
    /// Depth (z, metres) of the left image's pixel centres; infinite for the sky.
    pub depth_m: Vec<f64>,
    /// What each left pixel centre sees: 0 sky, 1 ground, 2 + k sphere k.
    pub object: Vec<u16>,
}

/// Render the scene seen by `camera` (left camera at the origin, right one at +baseline x).
pub fn render_stereo(scene: &SyntheticScene, camera: &StereoCamera) -> RenderedPair {
    let left = render_view(scene, camera, 0.0);
    let right = render_view(scene, camera, camera.baseline_m);
    let (w, h) = (camera.width, camera.height);
    let mut depth_m = vec![f64::INFINITY; w * h];
    let mut object = vec![0u16; w * h];
    for v in 0..h {
        for u in 0..w {
            let dir = Vector3::new(
                (u as f64 - camera.cx) / camera.fx,
                (v as f64 - camera.cy) / camera.fy,
                1.0,
            );
            if let Some((t, id)) = trace(scene, &Point3::origin(), &dir) {
                depth_m[v * w + u] = t;
                object[v * w + u] = id;
            }
        }
    }
    RenderedPair {
        left,
        right,
        depth_m,
        object,
    }
}

/// Nearest hit along `o + t dir` (dir.z = 1, so t is the depth): (t, object id).
fn trace(scene: &SyntheticScene, o: &Point3<f64>, dir: &Vector3<f64>) -> Option<(f64, u16)> {
    let mut best: Option<(f64, u16)> = None;
    if dir.y > 1e-9 {
        let t = (scene.camera_height_m - o.y) / dir.y;
        if t > 0.0 {
            best = Some((t, 1));
        }
    }
    for (k, s) in scene.spheres.iter().enumerate() {
        if let Some(t) = hit_sphere(s, o, dir) {
            if best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, 2 + k as u16));
            }
        }
    }
    best
}

fn hit_sphere(s: &Sphere, o: &Point3<f64>, dir: &Vector3<f64>) -> Option<f64> {
    let oc = o - s.center;
    let a = dir.norm_squared();
    let b = oc.dot(dir);
    let c = oc.norm_squared() - s.radius_m * s.radius_m;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / a;
    (t > 1e-9).then_some(t)
}

fn render_view(scene: &SyntheticScene, camera: &StereoCamera, offset_x: f64) -> GrayImage {
    let (w, h) = (camera.width, camera.height);
    let n = scene.supersample.max(1);
    let sun = scene.sun_direction.normalize();
    let origin = Point3::new(offset_x, 0.0, 0.0);
    let mut data = vec![0u8; w * h];
    data.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        for (u, out) in row.iter_mut().enumerate() {
            let mut acc = 0.0;
            for sy in 0..n {
                for sx in 0..n {
                    let pu = u as f64 - 0.5 + (sx as f64 + 0.5) / n as f64;
                    let pv = v as f64 - 0.5 + (sy as f64 + 0.5) / n as f64;
                    let dir = Vector3::new(
                        (pu - camera.cx) / camera.fx,
                        (pv - camera.cy) / camera.fy,
                        1.0,
                    );
                    acc += shade(scene, &origin, &dir, &sun);
                }
            }
            *out = (acc / (n * n) as f64).round().clamp(0.0, 255.0) as u8;
        }
    });
    GrayImage {
        width: w,
        height: h,
        data,
    }
}

fn shade(scene: &SyntheticScene, o: &Point3<f64>, dir: &Vector3<f64>, sun: &Vector3<f64>) -> f64 {
    let Some((t, id)) = trace(scene, o, dir) else {
        return 0.0;
    };
    let p = o + dir * t;
    let (normal, albedo) = if id == 1 {
        let tex = fractal_noise(p.x * 6.0, 0.0, p.z * 6.0, scene.texture_seed);
        (Vector3::new(0.0, -1.0, 0.0), 0.35 + 0.5 * tex)
    } else {
        let s = &scene.spheres[(id - 2) as usize];
        let tex = fractal_noise(p.x * 12.0, p.y * 12.0, p.z * 12.0, scene.texture_seed + 1);
        ((p - s.center).normalize(), 0.45 + 0.45 * tex)
    };
    let lambert = normal.dot(sun).max(0.0);
    // hard shadow: anything between the point and the sun
    let lift = p + normal * 1e-6;
    let shadowed = scene
        .spheres
        .iter()
        .any(|s| hit_sphere(s, &lift, sun).is_some());
    let light = if shadowed { 0.0 } else { lambert };
    (255.0 * albedo * (0.08 + 0.92 * light)).min(255.0)
}

/// Lattice value noise in [0, 1], four octaves, trilinear interpolation.
fn fractal_noise(x: f64, y: f64, z: f64, seed: u64) -> f64 {
    let mut total = 0.0;
    let mut amplitude = 0.5;
    let mut freq = 1.0;
    let mut norm = 0.0;
    for octave in 0..4 {
        total += amplitude * value_noise(x * freq, y * freq, z * freq, seed + octave);
        norm += amplitude;
        amplitude *= 0.5;
        freq *= 2.3;
    }
    total / norm
}

fn value_noise(x: f64, y: f64, z: f64, seed: u64) -> f64 {
    let (xi, yi, zi) = (x.floor(), y.floor(), z.floor());
    let (fx, fy, fz) = (x - xi, y - yi, z - zi);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy, sz) = (s(fx), s(fy), s(fz));
    let corner =
        |dx: i64, dy: i64, dz: i64| lattice(xi as i64 + dx, yi as i64 + dy, zi as i64 + dz, seed);
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let x00 = lerp(corner(0, 0, 0), corner(1, 0, 0), sx);
    let x10 = lerp(corner(0, 1, 0), corner(1, 1, 0), sx);
    let x01 = lerp(corner(0, 0, 1), corner(1, 0, 1), sx);
    let x11 = lerp(corner(0, 1, 1), corner(1, 1, 1), sx);
    lerp(lerp(x00, x10, sy), lerp(x01, x11, sy), sz)
}

fn lattice(x: i64, y: i64, z: i64, seed: u64) -> f64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (z as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
        ^ seed.wrapping_mul(0x27D4_EB2F_1656_67C5);
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ground_truth_matches_geometry() {
        let camera = StereoCamera::ipex().for_size(320, 180).unwrap();
        let mut scene = SyntheticScene::default();
        let sphere = scene.resting_sphere(5.0, 0.0, 0.3);
        scene.spheres.push(sphere);
        let pair = render_stereo(&scene, &camera);
        // the pixel looking at the sphere centre sees its front surface at 5 - 0.3 m
        let (u, v) = camera.project(&sphere.center).unwrap();
        let i = v.round() as usize * 320 + u.round() as usize;
        assert_eq!(pair.object[i], 2);
        assert!((pair.depth_m[i] - 4.7).abs() < 0.01);
        // the top row sees the sky, the bottom row the ground
        assert_eq!(pair.object[0], 0);
        assert_eq!(pair.object[179 * 320], 1);
        assert!(pair.left.data.iter().any(|&p| p > 50));
    }
}
