//! The rasterizer: triangles of a [`Scene`] projected (perspective camera or orthographic sun
//! view), clipped at the near plane, binned into bands of rows and drawn with a z-buffer, the
//! bands in parallel (rayon).
//!
//! Coverage uses exact integer edge functions on vertices snapped to 1/256 pixel with a
//! top-left rule, so that triangles sharing an edge leave no crack and draw no pixel twice.
//! A pixel's sample is its centre, at integer coordinates (the camera model's convention).
//! The z-buffer keeps, per pixel, the largest *key*: 1/depth for the camera (exact for planar
//! triangles, since 1/depth is affine in the image), the distance toward the sun for the sun
//! view.

use super::scene::Scene;
use nalgebra::{Isometry3, Point3, Vector3};
use rayon::prelude::*;

/// Sub-pixel precision of the snapped vertices (1/256 pixel).
const SUBPIXEL: f64 = 256.0;
/// Rows per band (the unit of parallel work).
const BAND_ROWS: usize = 16;
/// Triangles reaching farther than this from the image (pixels) are dropped (integer range).
const MAX_COORD_PX: f64 = 1.0e6;

/// How scene points map to the image.
#[derive(Clone, Copy, Debug)]
pub enum Projection {
    /// A pinhole camera; `camera_from_world` in the optical frame (x right, y down, z
    /// forward).
    Perspective {
        /// World to camera (optical frame).
        camera_from_world: Isometry3<f64>,
        /// Focal lengths and principal point, pixels.
        fx: f64,
        /// Vertical focal length, pixels.
        fy: f64,
        /// Principal point column.
        cx: f64,
        /// Principal point row.
        cy: f64,
        /// Near clipping plane, metres.
        near_m: f64,
    },
    /// A parallel projection along `-toward`: image axes `right` and `down` (unit, world),
    /// pixel (0, 0) at `origin`, texels of `texel_right` × `texel_down` metres.
    Orthographic {
        /// Unit vector toward the viewer (the sun).
        toward: Vector3<f64>,
        /// Unit vector of increasing columns.
        right: Vector3<f64>,
        /// Unit vector of increasing rows.
        down: Vector3<f64>,
        /// World point of pixel (0, 0).
        origin: Point3<f64>,
        /// Texel size along `right`, metres.
        texel_right: f64,
        /// Texel size along `down`, metres.
        texel_down: f64,
    },
}

/// A triangle in the image: vertices in pixels, the key as an affine function of the pixel,
/// and the scene triangle it came from.
#[derive(Clone, Copy, Debug)]
pub struct ScreenTriangle {
    /// Vertex columns and rows, pixels.
    pub xy: [[f64; 2]; 3],
    /// Key = `key[0]·(x − x0) + key[1]·(y − y0) + key[2]` with (x0, y0) the first vertex.
    pub key: [f64; 3],
    /// Index of the scene triangle.
    pub triangle: u32,
}

/// A drawn image: per pixel the z-buffer key (−∞: nothing drawn) and the scene triangle
/// (`u32::MAX`: none).
#[derive(Clone, Debug)]
pub struct Raster {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Z-buffer keys, row-major.
    pub key: Vec<f32>,
    /// Scene triangle per pixel, row-major.
    pub triangle: Vec<u32>,
}

impl Projection {
    /// Pixel and key of a world point (perspective: only meaningful in front of the camera).
    pub fn project(&self, p: &Point3<f64>) -> [f64; 3] {
        match self {
            Projection::Perspective {
                camera_from_world,
                fx,
                fy,
                cx,
                cy,
                ..
            } => {
                let q = camera_from_world * p;
                [cx + fx * q.x / q.z, cy + fy * q.y / q.z, 1.0 / q.z]
            }
            Projection::Orthographic {
                toward,
                right,
                down,
                origin,
                texel_right,
                texel_down,
            } => {
                let d = p - origin;
                [
                    d.dot(right) / texel_right,
                    d.dot(down) / texel_down,
                    d.dot(toward),
                ]
            }
        }
    }
}

/// Project, clip and cull the scene's triangles for `projection` on a `width × height`
/// image; with `cull_back_faces`, triangles facing away from a perspective camera are
/// dropped.
pub fn screen_triangles(
    scene: &Scene,
    projection: &Projection,
    width: usize,
    height: usize,
    cull_back_faces: bool,
) -> Vec<ScreenTriangle> {
    let (w, h) = (width as f64, height as f64);
    let Projection::Perspective {
        camera_from_world,
        fx,
        fy,
        cx,
        cy,
        near_m,
    } = *projection
    else {
        let transformed: Vec<[f64; 3]> = scene
            .vertices
            .par_iter()
            .map(|v| projection.project(&Point3::new(v[0], v[1], v[2])))
            .collect();
        return scene
            .triangles
            .par_iter()
            .enumerate()
            .filter_map(|(i, t)| setup(t.map(|k| transformed[k as usize]), i as u32, w, h))
            .collect();
    };
    let rotation = camera_from_world.rotation.to_rotation_matrix().into_inner();
    let shift = camera_from_world.translation.vector;
    let to_camera = |v: &[f64; 3]| {
        let q = rotation * Vector3::new(v[0], v[1], v[2]) + shift;
        [q.x, q.y, q.z]
    };
    // inward normals of the frustum's side planes (through the camera centre)
    let plane = |a: f64, b: f64, c: f64| Vector3::new(a, b, c).normalize();
    let sides = [
        plane(1.0, 0.0, (cx + 1.0) / fx),
        plane(-1.0, 0.0, (w - cx) / fx),
        plane(0.0, 1.0, (cy + 1.0) / fy),
        plane(0.0, -1.0, (h - cy) / fy),
    ];
    let project = |q: [f64; 3]| [cx + fx * q[0] / q[2], cy + fy * q[1] / q[2], 1.0 / q[2]];
    scene
        .clusters
        .par_iter()
        .filter(|c| {
            let q = Vector3::from(to_camera(&c.center));
            q.z + c.radius_m >= near_m && sides.iter().all(|n| n.dot(&q) >= -c.radius_m)
        })
        .flat_map_iter(|c| c.triangles.clone())
        .flat_map_iter(|i| {
            let v = scene.triangles[i as usize].map(|k| to_camera(&scene.vertices[k as usize]));
            let mut out: [Option<ScreenTriangle>; 2] = [None, None];
            if !(cull_back_faces && faces_away(&v)) {
                let (parts, n) = clip_near(&v, near_m);
                for (slot, clipped) in out.iter_mut().zip(&parts[..n]) {
                    *slot = setup(clipped.map(project), i, w, h);
                }
            }
            out.into_iter().flatten()
        })
        .collect()
}

/// Whether a camera-frame triangle (counter-clockwise from outside) faces away from the
/// camera at the origin.
fn faces_away(v: &[[f64; 3]; 3]) -> bool {
    let e1 = [v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]];
    let e2 = [v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]];
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2] >= 0.0
}

/// The parts of a camera-frame triangle at depth ≥ `near` (zero, one or two triangles, and
/// how many).
fn clip_near(v: &[[f64; 3]; 3], near: f64) -> ([[[f64; 3]; 3]; 2], usize) {
    let inside = v.map(|p| p[2] >= near);
    if inside.iter().all(|&b| b) {
        return ([*v, *v], 1);
    }
    if !inside.iter().any(|&b| b) {
        return ([*v, *v], 0);
    }
    let mut poly: Vec<[f64; 3]> = Vec::with_capacity(4);
    for k in 0..3 {
        let (a, b) = (v[k], v[(k + 1) % 3]);
        if inside[k] {
            poly.push(a);
        }
        if inside[k] != inside[(k + 1) % 3] {
            let t = (near - a[2]) / (b[2] - a[2]);
            poly.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), near]);
        }
    }
    let first = [poly[0], poly[1], poly[2]];
    match poly.get(3) {
        Some(&last) => ([first, [poly[0], poly[2], last]], 2),
        None => ([first, first], 1),
    }
}

/// A screen triangle from pixel-and-key vertices, or `None` when it misses the image or is
/// degenerate.
fn setup(v: [[f64; 3]; 3], triangle: u32, w: f64, h: f64) -> Option<ScreenTriangle> {
    let (xs, ys) = (v.map(|p| p[0]), v.map(|p| p[1]));
    let fmin = |a: [f64; 3]| a[0].min(a[1]).min(a[2]);
    let fmax = |a: [f64; 3]| a[0].max(a[1]).max(a[2]);
    if fmax(xs) < 0.0 || fmin(xs) > w - 1.0 || fmax(ys) < 0.0 || fmin(ys) > h - 1.0 {
        return None;
    }
    // written so that a NaN coordinate fails the test too
    let within = |a: [f64; 3]| fmin(a) > -MAX_COORD_PX && fmax(a) < MAX_COORD_PX;
    if !(within(xs) && within(ys)) {
        return None;
    }
    let (dx1, dy1, dk1) = (v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]);
    let (dx2, dy2, dk2) = (v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]);
    let det = dx1 * dy2 - dx2 * dy1;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let a = (dk1 * dy2 - dk2 * dy1) / det;
    let b = (dx1 * dk2 - dx2 * dk1) / det;
    Some(ScreenTriangle {
        xy: [[v[0][0], v[0][1]], [v[1][0], v[1][1]], [v[2][0], v[2][1]]],
        key: [a, b, v[0][2]],
        triangle,
    })
}

/// Draw `triangles` into a `width × height` z-buffer, bands of rows in parallel.
pub fn rasterize(triangles: &[ScreenTriangle], width: usize, height: usize) -> Raster {
    let mut raster = Raster {
        width,
        height,
        key: Vec::new(),
        triangle: Vec::new(),
    };
    rasterize_into(triangles, &mut raster);
    raster
}

/// Draw `triangles` into `raster` (its size kept, its buffers cleared and reused: no fresh
/// pages to fault in per frame).
pub fn rasterize_into(triangles: &[ScreenTriangle], raster: &mut Raster) {
    let (width, height) = (raster.width, raster.height);
    let bands = height.div_ceil(BAND_ROWS);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); bands];
    for (i, t) in triangles.iter().enumerate() {
        let ys = t.xy.map(|p| p[1]);
        let lo = ys[0].min(ys[1]).min(ys[2]).ceil().max(0.0) as usize;
        let hi = ys[0].max(ys[1]).max(ys[2]).floor().min((height - 1) as f64);
        if hi < 0.0 || lo as f64 > hi {
            continue;
        }
        for bin in bins
            .iter_mut()
            .take(hi as usize / BAND_ROWS + 1)
            .skip(lo / BAND_ROWS)
        {
            bin.push(i as u32);
        }
    }
    raster.key.clear();
    raster.key.resize(width * height, f32::NEG_INFINITY);
    raster.triangle.clear();
    raster.triangle.resize(width * height, u32::MAX);
    raster
        .key
        .par_chunks_mut(BAND_ROWS * width)
        .zip(raster.triangle.par_chunks_mut(BAND_ROWS * width))
        .zip(bins.par_iter())
        .enumerate()
        .for_each(|(band, ((keys, ids), bin))| {
            let rows = (band * BAND_ROWS)..((band + 1) * BAND_ROWS).min(height);
            for &i in bin {
                let t = &triangles[i as usize];
                draw(t, width, rows.clone(), keys, ids);
            }
        });
}

/// Count the pixels a set of triangles covers in a `width × height` image (no z-buffer).
pub fn coverage(triangles: &[&ScreenTriangle], width: usize, height: usize) -> usize {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for t in triangles {
        for p in t.xy {
            (x0, y0, x1, y1) = (x0.min(p[0]), y0.min(p[1]), x1.max(p[0]), y1.max(p[1]));
        }
    }
    if triangles.is_empty() {
        return 0;
    }
    let cx0 = x0.ceil().max(0.0) as usize;
    let cy0 = y0.ceil().max(0.0) as usize;
    let cx1 = (x1.floor().min((width - 1) as f64)).max(0.0) as usize;
    let cy1 = (y1.floor().min((height - 1) as f64)).max(0.0) as usize;
    if cx0 > cx1 || cy0 > cy1 {
        return 0;
    }
    let (bw, bh) = (cx1 - cx0 + 1, cy1 - cy0 + 1);
    let mut covered = vec![false; bw * bh];
    let mut keys = vec![f32::NEG_INFINITY; bw * bh];
    let mut ids = vec![u32::MAX; bw * bh];
    for t in triangles {
        let mut s = **t;
        for p in s.xy.iter_mut() {
            p[0] -= cx0 as f64;
            p[1] -= cy0 as f64;
        }
        draw(&s, bw, 0..bh, &mut keys, &mut ids);
        for (c, &id) in covered.iter_mut().zip(&ids) {
            *c |= id != u32::MAX;
        }
        ids.iter_mut().for_each(|id| *id = u32::MAX);
        keys.iter_mut().for_each(|k| *k = f32::NEG_INFINITY);
    }
    covered.iter().filter(|&&c| c).count()
}

/// Whether an edge from `a` to `b` (snapped) owns its pixels (top-left rule, antisymmetric).
#[inline]
fn owns(a: [i64; 2], b: [i64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    dy < 0 || (dy == 0 && dx > 0)
}

/// Draw one triangle into the rows `rows` of a buffer whose first row is `rows.start`
/// (keys and ids are those rows, `width` wide); `accept(x, y)` may veto a pixel.
fn draw(
    t: &ScreenTriangle,
    width: usize,
    rows: std::ops::Range<usize>,
    keys: &mut [f32],
    ids: &mut [u32],
) {
    let snap = |p: [f64; 2]| {
        [
            (p[0] * SUBPIXEL).round() as i64,
            (p[1] * SUBPIXEL).round() as i64,
        ]
    };
    let mut v = t.xy.map(snap);
    let edge = |a: [i64; 2], b: [i64; 2], p: [i64; 2]| {
        (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
    };
    let area = edge(v[0], v[1], v[2]);
    if area == 0 {
        return;
    }
    if area < 0 {
        v.swap(1, 2);
    }
    let s = SUBPIXEL as i64;
    let xmin = v.iter().map(|p| p[0]).min().unwrap_or(0);
    let xmax = v.iter().map(|p| p[0]).max().unwrap_or(0);
    let ymin = v.iter().map(|p| p[1]).min().unwrap_or(0);
    let ymax = v.iter().map(|p| p[1]).max().unwrap_or(0);
    let px0 = ((xmin + s - 1).div_euclid(s)).max(0) as usize;
    let px1 = (xmax.div_euclid(s)).min(width as i64 - 1);
    let py0 = ((ymin + s - 1).div_euclid(s)).max(rows.start as i64);
    let py1 = (ymax.div_euclid(s)).min(rows.end as i64 - 1);
    if px1 < px0 as i64 || py1 < py0 {
        return;
    }
    let edges = [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])];
    let bias: [i64; 3] = edges.map(|(a, b)| if owns(a, b) { 0 } else { -1 });
    let (x0, y0) = (t.xy[0][0], t.xy[0][1]);
    for py in py0..=py1 {
        let row = (py as usize - rows.start) * width;
        let p = [px0 as i64 * s, py * s];
        let mut e = [0i64; 3];
        for (k, (a, b)) in edges.iter().enumerate() {
            e[k] = edge(*a, *b, p) + bias[k];
        }
        let step = edges.map(|(a, b)| -(b[1] - a[1]) * s);
        let ky = t.key[1] * (py as f64 - y0) + t.key[2];
        for px in px0..=px1 as usize {
            if e[0] >= 0 && e[1] >= 0 && e[2] >= 0 {
                let k = (t.key[0] * (px as f64 - x0) + ky) as f32;
                let idx = row + px;
                if k > keys[idx] {
                    keys[idx] = k;
                    ids[idx] = t.triangle;
                }
            }
            for k in 0..3 {
                e[k] += step[k];
            }
        }
    }
}
