//! The shape of a synthetic rock: a sphere squashed into an ellipsoid and chipped by flat
//! cuts, so that rocks look angular, flattened and elongated like the LAC's, while every
//! question about them (a ray's first hit, a vertical line's hit for the ground truth, the
//! surface and its normal for the renderer) keeps an exact, cheap answer: the body is
//! convex, the intersection of an ellipsoid and a few half-spaces.
//!
//! The body is defined in a *unit frame* `q`: the unit ball cut by the planes
//! `n_i · q ≤ h_i`. A rock of centre `c` and radius `r` maps it to the world by
//! `p = c + r · R_z(yaw) · diag(axes) · q`, with every axis ≤ 1: the body stays inside the
//! sphere of radius `r` around `c`, which is what culling, collision and the rock index use.

use nalgebra::{Point3, Vector3};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Number of flat cuts of a rock (unused cuts sit outside the unit ball).
pub const ROCK_CUTS: usize = 8;

/// Azimuths at which a [`Footprint`] is sampled.
pub const FOOTPRINT_AZIMUTHS: usize = 32;

/// A rock's footprint seen from above, as a polygon around its centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Radius at each azimuth `2π·i/N` from +x, metres.
    pub radii: [f64; FOOTPRINT_AZIMUTHS],
}

/// `(sin, cos)` of the azimuth of a footprint's radius `i`: `2π·i/N` from +x.
fn azimuth(i: usize) -> (f64, f64) {
    (std::f64::consts::TAU * i as f64 / FOOTPRINT_AZIMUTHS as f64).sin_cos()
}

/// The unit normal of a cut `[nx, ny, nz, h]`.
fn cut_normal(cut: &[f64; 4]) -> Vector3<f64> {
    Vector3::new(cut[0], cut[1], cut[2])
}

impl Footprint {
    /// Mean of the radii, metres: half the rock's width seen from the side, on average.
    pub fn mean_radius_m(&self) -> f64 {
        self.radii.iter().sum::<f64>() / FOOTPRINT_AZIMUTHS as f64
    }

    /// Horizontal distance from the offset `(dx, dy)` (from the rock's centre) to the
    /// footprint polygon, metres; 0 inside.
    pub fn distance_m(&self, dx: f64, dy: f64) -> f64 {
        let vertex = |i: usize| {
            let (s, c) = azimuth(i);
            let r = self.radii[i % FOOTPRINT_AZIMUTHS];
            (r * c, r * s)
        };
        let mut inside = true;
        let mut best = f64::INFINITY;
        for i in 0..FOOTPRINT_AZIMUTHS {
            let (a, b) = (vertex(i), vertex(i + 1));
            let (ex, ey) = (b.0 - a.0, b.1 - a.1);
            let (px, py) = (dx - a.0, dy - a.1);
            // counter-clockwise polygon around the centre: inside is left of every edge
            inside &= ex * py - ey * px >= 0.0;
            let len2 = ex * ex + ey * ey;
            let t = if len2 > 0.0 {
                ((px * ex + py * ey) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            best = best.min((px - t * ex).hypot(py - t * ey));
        }
        if inside {
            0.0
        } else {
            best
        }
    }
}

/// A cut that removes nothing: its plane lies beyond the unit ball.
const NO_CUT: [f64; 4] = [0.0, 0.0, 1.0, 2.0];

/// The shape of a rock relative to its centre and radius (see the [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RockShape {
    /// Semi-axes as fractions of the rock's radius: along the rock's own x and y
    /// (horizontal, turned by `yaw_rad`) and z (up); each in (0, 1].
    pub axes: [f64; 3],
    /// Heading of the rock's own x axis, radians.
    pub yaw_rad: f64,
    /// The cuts in the unit frame: `[nx, ny, nz, h]`, unit normal `n` pointing out of the
    /// body, which keeps `n · q ≤ h`.
    pub cuts: [[f64; 4]; ROCK_CUTS],
}

impl Default for RockShape {
    fn default() -> Self {
        Self::sphere()
    }
}

/// The range of the random shapes of [`RockShape::draw`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeRanges {
    /// Smallest horizontal minor axis (the major one is 1).
    pub min_minor_axis: f64,
    /// Range of the vertical axis.
    pub vertical_axis: (f64, f64),
    /// Range of the cuts' distances from the centre (unit frame).
    pub cut_offset: (f64, f64),
}

impl Default for ShapeRanges {
    fn default() -> Self {
        Self {
            min_minor_axis: 0.7,
            vertical_axis: (0.6, 0.9),
            cut_offset: (0.6, 0.95),
        }
    }
}

impl RockShape {
    /// The plain sphere.
    pub const fn sphere() -> Self {
        Self {
            axes: [1.0, 1.0, 1.0],
            yaw_rad: 0.0,
            cuts: [NO_CUT; ROCK_CUTS],
        }
    }

    /// An uncut ellipsoid of vertical scale `flatten` (a pebble).
    pub const fn flattened(flatten: f64) -> Self {
        Self {
            axes: [1.0, 1.0, flatten],
            ..Self::sphere()
        }
    }

    /// A random angular shape within `ranges`. No cut faces steeply down, so the rock's
    /// underside stays round and buried.
    pub fn draw(rng: &mut impl Rng, ranges: &ShapeRanges) -> Self {
        let minor = rng.random_range(ranges.min_minor_axis..=1.0);
        let (z_lo, z_hi) = ranges.vertical_axis;
        let vertical = rng.random_range(z_lo..=z_hi);
        let yaw_rad = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let mut cuts = [NO_CUT; ROCK_CUTS];
        for cut in &mut cuts {
            // uniform on the sphere
            let z: f64 = rng.random_range(-1.0..1.0);
            let phi = rng.random_range(0.0..std::f64::consts::TAU);
            let s = (1.0 - z * z).sqrt();
            let z = if z < -0.2 { -z } else { z };
            let (lo, hi) = ranges.cut_offset;
            *cut = [s * phi.cos(), s * phi.sin(), z, rng.random_range(lo..=hi)];
        }
        Self {
            axes: [1.0, minor, vertical],
            yaw_rad,
            cuts,
        }
    }

    /// `v` in the rock's own axes turned into the world's by the rock's yaw.
    fn turned(&self, v: &Vector3<f64>) -> Vector3<f64> {
        let (s, c) = self.yaw_rad.sin_cos();
        Vector3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
    }

    /// World vector (relative to the centre) of the unit-frame vector `q` for radius `r`.
    fn world_vector(&self, q: &Vector3<f64>, radius_m: f64) -> Vector3<f64> {
        let a = Vector3::new(q.x * self.axes[0], q.y * self.axes[1], q.z * self.axes[2]);
        radius_m * self.turned(&a)
    }

    /// Unit-frame vector of the world vector `v` (relative to the centre).
    fn unit_vector(&self, v: &Vector3<f64>, radius_m: f64) -> Vector3<f64> {
        let (s, c) = self.yaw_rad.sin_cos();
        let (x, y) = (c * v.x + s * v.y, -s * v.x + c * v.y);
        Vector3::new(x / self.axes[0], y / self.axes[1], v.z / self.axes[2]) / radius_m
    }

    /// The surface point of the unit-frame direction `u` (unit vector), in the unit frame:
    /// the body is star-shaped about its centre.
    pub fn unit_surface(&self, u: &Vector3<f64>) -> Vector3<f64> {
        let rho = self.cuts.iter().fold(1.0_f64, |rho, cut| {
            let d = cut_normal(cut).dot(u);
            if d > 0.0 {
                rho.min(cut[3] / d)
            } else {
                rho
            }
        });
        u * rho
    }

    /// The surface point of a rock of centre `center` and radius `radius_m` in the
    /// unit-frame direction `u` (unit vector), world frame.
    pub fn surface_point(
        &self,
        center: &Point3<f64>,
        radius_m: f64,
        u: &Vector3<f64>,
    ) -> Point3<f64> {
        center + self.world_vector(&self.unit_surface(u), radius_m)
    }

    /// The parameter interval `[t_in, t_out]` where `origin + t · dir` is inside the body
    /// of a rock at `center` of radius `radius_m` (any `dir`, not only unit), if any.
    pub fn ray_interval(
        &self,
        center: &Point3<f64>,
        radius_m: f64,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
    ) -> Option<(f64, f64)> {
        let o = self.unit_vector(&(origin - center), radius_m);
        let d = self.unit_vector(dir, radius_m);
        // the unit ball: |o + t d|² = 1
        let a = d.norm_squared();
        if a <= 0.0 {
            return None;
        }
        let b = o.dot(&d);
        let disc = b * b - a * (o.norm_squared() - 1.0);
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let (mut t_in, mut t_out) = ((-b - root) / a, (-b + root) / a);
        for cut in &self.cuts {
            let n = cut_normal(cut);
            let (nd, gap) = (n.dot(&d), cut[3] - n.dot(&o));
            if nd.abs() < 1e-15 {
                if gap < 0.0 {
                    return None;
                }
                continue;
            }
            let t = gap / nd;
            if nd > 0.0 {
                t_out = t_out.min(t);
            } else {
                t_in = t_in.max(t);
            }
        }
        (t_in <= t_out).then_some((t_in, t_out))
    }

    /// Distance along the unit direction `dir` from `origin` to the body's surface, if hit
    /// within `max_m` (0 when `origin` is inside).
    pub fn cast_ray(
        &self,
        center: &Point3<f64>,
        radius_m: f64,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        max_m: f64,
    ) -> Option<f64> {
        let (t_in, t_out) = self.ray_interval(center, radius_m, origin, dir)?;
        (t_out >= 0.0 && t_in <= max_m).then_some(t_in.max(0.0))
    }

    /// Whether the vertical line through `(x, y)` passes through the body (its footprint).
    pub fn covers_xy(&self, center: &Point3<f64>, radius_m: f64, x: f64, y: f64) -> bool {
        let origin = Point3::new(x, y, center.z);
        self.ray_interval(center, radius_m, &origin, &Vector3::z())
            .is_some()
    }

    /// Outward unit normal of the body's surface at the world point `p` (on or near the
    /// surface): the face of the cut it lies on, or the ellipsoid's.
    pub fn normal_at(&self, center: &Point3<f64>, radius_m: f64, p: &Point3<f64>) -> Vector3<f64> {
        let q = self.unit_vector(&(p - center), radius_m);
        // the constraint the point is closest to violating is the face it lies on
        let mut best = (q.norm() - 1.0, q);
        for cut in &self.cuts {
            let n = cut_normal(cut);
            let excess = n.dot(&q) - cut[3];
            if excess > best.0 {
                best = (excess, n);
            }
        }
        // a unit-frame normal maps to the world by the inverse transpose of the scaling
        let g = best.1;
        let scaled = Vector3::new(g.x / self.axes[0], g.y / self.axes[1], g.z / self.axes[2]);
        self.turned(&scaled)
            .try_normalize(1e-12)
            .unwrap_or_else(Vector3::z)
    }

    /// The footprint seen from above: its radius from the centre at each of
    /// [`FOOTPRINT_AZIMUTHS`] azimuths (`2π·i/N` from +x), metres, for radius `radius_m`.
    pub fn footprint(&self, radius_m: f64) -> Footprint {
        let center = Point3::origin();
        let mut radii = [0.0; FOOTPRINT_AZIMUTHS];
        for (i, r) in radii.iter_mut().enumerate() {
            let (s, c) = azimuth(i);
            // the footprint is convex and holds the centre: bisect on the radius
            let (mut lo, mut hi) = (0.0, radius_m);
            for _ in 0..30 {
                let mid = 0.5 * (lo + hi);
                if self.covers_xy(&center, radius_m, mid * c, mid * s) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            *r = lo;
        }
        Footprint { radii }
    }

    /// The body's highest point above its centre, metres, for radius `radius_m`.
    pub fn top_m(&self, radius_m: f64) -> f64 {
        let (mut top, steps) = (0.0_f64, 24);
        for i in 0..=steps / 4 {
            let elevation = std::f64::consts::FRAC_PI_2 * (1.0 - i as f64 / steps as f64);
            for j in 0..steps {
                let azimuth = std::f64::consts::TAU * j as f64 / steps as f64;
                let u = Vector3::new(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                );
                top = top.max(self.world_vector(&self.unit_surface(&u), radius_m).z);
            }
        }
        top
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// Fraction of the circumscribing ball's volume (radius 1 in the unit frame, before
    /// the axes scale it) that the cuts keep, by a fixed grid of samples.
    fn kept_fraction(shape: &RockShape) -> f64 {
        const N: usize = 16;
        let (mut inside, mut total) = (0usize, 0usize);
        for i in 0..N {
            for j in 0..N {
                for k in 0..N {
                    let f = |a: usize| -1.0 + (2 * a + 1) as f64 / N as f64;
                    let q = Vector3::new(f(i), f(j), f(k));
                    if q.norm_squared() > 1.0 {
                        continue;
                    }
                    total += 1;
                    let kept = shape.cuts.iter().all(|c| cut_normal(c).dot(&q) <= c[3]);
                    inside += usize::from(kept);
                }
            }
        }
        inside as f64 / total.max(1) as f64
    }

    fn shapes() -> Vec<RockShape> {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        (0..20)
            .map(|_| RockShape::draw(&mut rng, &ShapeRanges::default()))
            .collect()
    }

    #[test]
    fn the_sphere_casts_like_a_ball() {
        let s = RockShape::sphere();
        let c = Point3::new(1.0, 2.0, 0.5);
        let o = Point3::new(-2.0, 2.0, 0.5);
        let hit = s.cast_ray(&c, 0.3, &o, &Vector3::x(), 10.0).unwrap();
        assert!((hit - 2.7).abs() < 1e-12);
        assert!(s.cast_ray(&c, 0.3, &o, &Vector3::y(), 10.0).is_none());
        assert!(s.cast_ray(&c, 0.3, &o, &Vector3::x(), 2.0).is_none());
        assert_eq!(kept_fraction(&s), 1.0);
        let n = s.normal_at(&c, 0.3, &(c + Vector3::new(0.0, 0.3, 0.0)));
        assert!((n - Vector3::y()).norm() < 1e-9);
    }

    #[test]
    fn mesh_points_lie_on_the_surface_that_rays_hit() {
        let c = Point3::new(0.0, 0.0, 0.0);
        for shape in shapes() {
            for k in 0..50 {
                let z = -1.0 + 2.0 * (k as f64 + 0.5) / 50.0;
                let phi = 2.399_963 * k as f64;
                let s = (1.0 - z * z).sqrt();
                let u = Vector3::new(s * phi.cos(), s * phi.sin(), z);
                let p = shape.surface_point(&c, 0.4, &u);
                // a ray from the centre outwards leaves the body at p
                let dir = (p - c).normalize();
                let (t_in, t_out) = shape.ray_interval(&c, 0.4, &c, &dir).unwrap();
                assert!(t_in < 0.0);
                assert!(
                    (t_out - (p - c).norm()).abs() < 1e-9,
                    "{t_out} vs {}",
                    (p - c).norm()
                );
                // and a ray from outside towards the centre enters it there
                let far = c + dir * 2.0;
                let hit = shape.cast_ray(&c, 0.4, &far, &(-dir), 5.0).unwrap();
                assert!((hit - (2.0 - (p - c).norm())).abs() < 1e-9);
                // the normal points outwards
                assert!(shape.normal_at(&c, 0.4, &p).dot(&dir) > 0.0);
            }
        }
    }

    #[test]
    fn the_footprint_polygon_measures_distances() {
        let sphere = RockShape::sphere().footprint(0.5);
        assert!(sphere.radii.iter().all(|r| (r - 0.5).abs() < 1e-6));
        assert_eq!(sphere.distance_m(0.1, 0.2), 0.0);
        // the polygon's edges sit a little inside the circle
        assert!((sphere.distance_m(1.0, 0.0) - 0.5).abs() < 1e-6);
        assert!((sphere.distance_m(0.0, -2.0) - 1.5).abs() < 0.01);
        for shape in shapes() {
            let f = shape.footprint(0.5);
            assert!(f.radii.iter().all(|r| *r > 0.1 && *r <= 0.5));
            for (i, r) in f.radii.iter().enumerate() {
                let (sin, cos) = azimuth(i);
                let c = Point3::origin();
                assert!(shape.covers_xy(&c, 0.5, 0.99 * r * cos, 0.99 * r * sin));
                assert!(!shape.covers_xy(&c, 0.5, 1.01 * r * cos, 1.01 * r * sin));
                // twice as far out along the same azimuth: at most that radius away (the
                // polygon may come nearer elsewhere), and outside it
                let d = f.distance_m(2.0 * r * cos, 2.0 * r * sin);
                assert!(d > 0.0 && d <= r + 1e-9, "{d} vs {r}");
            }
        }
    }

    #[test]
    fn drawn_shapes_stay_within_the_radius_and_keep_a_core() {
        for shape in shapes() {
            assert!(shape.axes.iter().all(|a| *a > 0.0 && *a <= 1.0));
            let f = kept_fraction(&shape);
            assert!(f > 0.2 && f < 1.0, "kept {f}");
            assert!(shape.top_m(1.0) <= shape.axes[2] + 1e-12);
            // the underside is not cut steeply: straight down stays on the ball
            let bottom = shape.unit_surface(&(-Vector3::z()));
            assert!(bottom.z < -0.55, "{bottom}");
            // the footprint holds the centre and nothing beyond the radius
            let c = Point3::new(3.0, -1.0, 0.2);
            assert!(shape.covers_xy(&c, 0.5, 3.0, -1.0));
            assert!(!shape.covers_xy(&c, 0.5, 3.51, -1.0));
        }
    }
}
