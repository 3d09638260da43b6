//! The rover's exteroceptive sensors at one instant: boulder detections and ground points
//! from the front and back stereo pairs, and points on the lander's sides.
//!
//! For each camera the rocks within range are taken from the moon's rock grid and culled by
//! the field of view; a rock is detected when the ray from the camera to the upper part of its
//! visible face reaches it first (parry3d ray casts against the terrain height field, the
//! other rocks and the lander), when it spans enough pixels, and when the detector does not
//! miss it (a miss probability rising with depth). The reported centroid is the centre of the
//! visible face (pulled `face_bias_fraction` × radius toward the camera) with stereo noise
//! ([`crate::sim::stereo_noise`]). Spurious detections land on random ground in view.
//! Ground points are stereo points on whatever the rays through random pixels below the
//! horizon hit (terrain or rock, the lander excluded), with the same noise. Ground farther
//! than `ground_max_range_m` (up to `far_ground_max_range_m`) lies in a band of rows just
//! below the horizon; [`observe_far`] samples that band, and the lander's sides beyond
//! `max_range_m` (up to `far_lander_max_range_m`), from a random stream of its own, so that
//! how far the maps and the lander fit look changes nothing else the cameras report.

use crate::sim::ipex::{
    BACK_LEFT_CAMERA_M, CX_PX, CY_PX, FOCAL_PX, FRONT_LEFT_CAMERA_M, IMAGE_HEIGHT_PX,
    IMAGE_WIDTH_PX, LANDER_HALF_EXTENT_M,
};
use crate::sim::moon::{Moon, Rock};
use crate::sim::stereo_noise::StereoNoiseConfig;
use crate::sim::world_rays::RayTarget;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson};
use serde::{Deserialize, Serialize};

/// Parameters of the cameras' detections and ground points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    /// Farthest detected rock (depth along the optical axis), metres.
    pub max_range_m: f64,
    /// Nearest detected rock (depth), metres.
    pub min_range_m: f64,
    /// Smallest detectable rock, as its radius in pixels.
    pub min_radius_px: f64,
    /// Probability of missing a visible rock, at zero depth.
    pub miss_probability: f64,
    /// Added miss probability per metre of depth.
    pub miss_probability_per_m: f64,
    /// Mean number of spurious detections per camera and frame.
    pub spurious_per_frame: f64,
    /// How far the measured centroid sits toward the camera, as a fraction of the radius
    /// (the segment covers the visible face only).
    pub face_bias_fraction: f64,
    /// Relative error (1 σ) of the reported radius.
    pub radius_error_sigma: f64,
    /// Stereo noise model.
    pub stereo: StereoNoiseConfig,
    /// Ground points per camera and frame (rays through random pixels below the horizon).
    pub ground_points_per_camera: usize,
    /// Farthest ground point (depth), metres.
    pub ground_max_range_m: f64,
    /// Rays per camera and frame through the band of rows just below the horizon, for ground
    /// points beyond `ground_max_range_m` ([`observe_far`]; 0: none).
    pub far_ground_points_per_camera: usize,
    /// Farthest of those far ground points (depth), metres.
    pub far_ground_max_range_m: f64,
    /// Points on the lander's sides are also measured beyond `max_range_m`, up to this depth
    /// ([`observe_far`]), metres: the lander is large, and its bearing stays precise far
    /// away even where stereo depth is not.
    pub far_lander_max_range_m: f64,
    /// Error (1 σ per axis) of the IMU's gravity direction, radians: white noise, drawn
    /// anew every tick.
    pub gravity_sigma_rad: f64,
    /// Constant bias of the IMU's gravity direction for the whole session, radians: a tilt
    /// of this size in the rover frame, about a horizontal axis of random direction drawn
    /// from the session's seed (its own stream: 0 changes nothing else).
    pub gravity_bias_rad: f64,
    /// Spacing of the points sampled on the lander's sides, metres.
    pub lander_point_spacing_m: f64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self {
            max_range_m: 7.0,
            min_range_m: 0.5,
            min_radius_px: 3.0,
            miss_probability: 0.05,
            miss_probability_per_m: 0.03,
            spurious_per_frame: 0.2,
            face_bias_fraction: 1.0 / 3.0,
            radius_error_sigma: 0.15,
            stereo: StereoNoiseConfig::default(),
            ground_points_per_camera: 250,
            ground_max_range_m: 5.0,
            far_ground_points_per_camera: 100,
            far_ground_max_range_m: 10.0,
            far_lander_max_range_m: 15.0,
            gravity_sigma_rad: 0.001,
            gravity_bias_rad: 0.0,
            lander_point_spacing_m: 0.3,
        }
    }
}

/// Which stereo pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CameraId {
    /// Front pair, looking forward.
    Front,
    /// Back pair, looking backward.
    Back,
}

/// A stereo pair's reference (left) camera: frame x along the optical axis, y left, z up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Which pair.
    pub id: CameraId,
    /// Pose of the camera in the rover frame.
    pub rover_from_camera: Isometry3<f64>,
}

/// The front and back stereo pairs of the IPEX rover.
pub fn cameras() -> [Camera; 2] {
    let at = |p: [f64; 3], yaw: f64| {
        Isometry3::from_parts(
            Translation3::new(p[0], p[1], p[2]),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        )
    };
    [
        Camera {
            id: CameraId::Front,
            rover_from_camera: at(FRONT_LEFT_CAMERA_M, 0.0),
        },
        Camera {
            id: CameraId::Back,
            rover_from_camera: at(BACK_LEFT_CAMERA_M, std::f64::consts::PI),
        },
    ]
}

/// Pixel (u, v) of a point in a camera frame (x forward, y left, z up), if in front.
pub fn project(p_cam: &Vector3<f64>) -> Option<(f64, f64)> {
    (p_cam.x > 1e-6).then(|| {
        (
            CX_PX - FOCAL_PX * p_cam.y / p_cam.x,
            CY_PX - FOCAL_PX * p_cam.z / p_cam.x,
        )
    })
}

/// Unit ray, camera frame, through pixel (u, v).
pub fn pixel_ray(u: f64, v: f64) -> Vector3<f64> {
    Vector3::new(1.0, -(u - CX_PX) / FOCAL_PX, -(v - CY_PX) / FOCAL_PX).normalize()
}

fn in_image(u: f64, v: f64, margin_px: f64) -> bool {
    u >= -margin_px
        && u < IMAGE_WIDTH_PX + margin_px
        && v >= -margin_px
        && v < IMAGE_HEIGHT_PX + margin_px
}

/// One boulder detection.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoulderObservation {
    /// Which camera saw it.
    pub camera: CameraId,
    /// Measured centroid, rover frame, metres.
    pub p_rover: Point3<f64>,
    /// Measured radius, metres.
    pub radius_m: f64,
    /// The true rock (index into [`Moon::rocks`]); `None` for a spurious detection.
    pub rock: Option<usize>,
}

/// One stereo ground point.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundObservation {
    /// Which camera measured it.
    pub camera: CameraId,
    /// Measured point, rover frame, metres.
    pub p_rover: Point3<f64>,
}

/// What the cameras report at one instant.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Observation {
    /// Boulder detections.
    pub boulders: Vec<BoulderObservation>,
    /// Ground points.
    pub ground: Vec<GroundObservation>,
    /// Points measured on the lander's sides, rover frame (an obstacle for the planner).
    pub lander_points_rover: Vec<Point3<f64>>,
}

/// Observe `moon` from `world_from_rover` with all cameras.
pub fn observe(
    moon: &Moon,
    world_from_rover: &Isometry3<f64>,
    config: &SensorConfig,
    rng: &mut ChaCha8Rng,
) -> Observation {
    let mut out = Observation::default();
    let lander_points = lander_side_points(moon, config.lander_point_spacing_m);
    for camera in cameras() {
        let cam = ViewContext::new(moon, config, camera, world_from_rover);
        let candidates = cam.rocks_in_view();
        cam.detect_rocks(&candidates, rng, &mut out.boulders);
        cam.spurious(&candidates, rng, &mut out.boulders);
        cam.ground_points(&candidates, rng, &mut out.ground);
        let depths_m = (config.min_range_m, config.max_range_m);
        cam.lander_points(&lander_points, depths_m, rng, &mut out.lander_points_rover);
    }
    out
}

/// What the cameras measure beyond the near ranges ([`observe`]'s), from their own stream.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FarObservation {
    /// Ground points beyond `ground_max_range_m`, within `far_ground_max_range_m`.
    pub ground: Vec<GroundObservation>,
    /// Points on the lander's sides beyond `max_range_m`, within `far_lander_max_range_m`,
    /// rover frame.
    pub lander_points_rover: Vec<Point3<f64>>,
}

/// Ground points beyond `ground_max_range_m` and within `far_ground_max_range_m` (rays
/// through random pixels of the rows where flat ground that far appears, with room for the
/// rover's tilt), then points on the lander's sides beyond `max_range_m` and within
/// `far_lander_max_range_m`, from all cameras, with the same stereo noise. `rng` is a
/// stream of its own, apart from the one [`observe`] draws from.
pub fn observe_far(
    moon: &Moon,
    world_from_rover: &Isometry3<f64>,
    config: &SensorConfig,
    rng: &mut ChaCha8Rng,
) -> FarObservation {
    let mut out = FarObservation::default();
    if config.far_ground_points_per_camera > 0
        && config.far_ground_max_range_m > config.ground_max_range_m
    {
        for camera in cameras() {
            let cam = ViewContext::new(moon, config, camera, world_from_rover);
            let candidates = cam.rocks_within(config.far_ground_max_range_m);
            cam.far_ground_points(&candidates, rng, &mut out.ground);
        }
    }
    if config.far_lander_max_range_m > config.max_range_m {
        let lander_points = lander_side_points(moon, config.lander_point_spacing_m);
        // just past the near pass's range, so no point is measured twice
        let depths_m = (config.max_range_m + 1e-9, config.far_lander_max_range_m);
        for camera in cameras() {
            let cam = ViewContext::new(moon, config, camera, world_from_rover);
            cam.lander_points(&lander_points, depths_m, rng, &mut out.lander_points_rover);
        }
    }
    out
}

struct ViewContext<'a> {
    moon: &'a Moon,
    config: &'a SensorConfig,
    camera: Camera,
    world_from_camera: Isometry3<f64>,
    camera_from_world: Isometry3<f64>,
    origin: Point3<f64>,
}

impl<'a> ViewContext<'a> {
    fn new(
        moon: &'a Moon,
        config: &'a SensorConfig,
        camera: Camera,
        world_from_rover: &Isometry3<f64>,
    ) -> Self {
        let world_from_camera = world_from_rover * camera.rover_from_camera;
        ViewContext {
            moon,
            config,
            camera,
            world_from_camera,
            camera_from_world: world_from_camera.inverse(),
            origin: Point3::from(world_from_camera.translation.vector),
        }
    }

    /// Rocks that may appear in (or block rays of) this camera: within range and inside the
    /// image once their radius is allowed for.
    fn rocks_in_view(&self) -> Vec<usize> {
        self.rocks_within(self.config.max_range_m.max(self.config.ground_max_range_m))
    }

    /// Rocks within `range_m` (plus the largest rock radius) that may appear in the image.
    fn rocks_within(&self, range_m: f64) -> Vec<usize> {
        let reach = range_m + self.moon.max_rock_radius_m();
        let mut out = Vec::new();
        self.moon
            .for_each_rock_near(self.origin.x, self.origin.y, reach, |i, rock| {
                let p = self.camera_from_world * rock.center;
                if p.x < -rock.radius_m {
                    return;
                }
                let depth = p.x.max(rock.radius_m);
                let margin = FOCAL_PX * rock.radius_m / depth * 1.5 + 2.0;
                let q = Vector3::new(depth, p.y, p.z);
                if project(&q).is_some_and(|(u, v)| in_image(u, v, margin)) {
                    out.push(i);
                }
            });
        out
    }

    fn to_rover(&self, p_cam: &Vector3<f64>) -> Point3<f64> {
        self.camera.rover_from_camera * Point3::from(*p_cam)
    }

    /// Whether a line of sight reaches rock `i`: to the middle of its height above its
    /// centre, or else to just under its top (a low rock behind a rise shows its top only).
    fn sees_rock(&self, i: usize, rock: &Rock, candidates: &[usize]) -> bool {
        let above_center = rock
            .shape
            .surface_point(&rock.center, rock.radius_m, &Vector3::z())
            - rock.center;
        [0.5, 0.9].iter().any(|fraction| {
            let target = rock.center + above_center * *fraction;
            let to = target - self.origin;
            let dist = to.norm();
            let dir = to / dist;
            self.moon
                .cast_ray(&self.origin, &dir, dist + rock.radius_m, Some(candidates))
                .is_some_and(|h| h.target == RayTarget::Rock(i))
        })
    }

    fn detect_rocks(
        &self,
        candidates: &[usize],
        rng: &mut ChaCha8Rng,
        out: &mut Vec<BoulderObservation>,
    ) {
        let c = self.config;
        for &i in candidates {
            let rock = self.moon.rocks()[i];
            let p = self.camera_from_world * rock.center;
            let depth = p.x;
            if depth < c.min_range_m || depth > c.max_range_m {
                continue;
            }
            let size_radius_m = self.moon.rock_size_radius_m(i);
            if FOCAL_PX * size_radius_m / depth < c.min_radius_px {
                continue;
            }
            if !project(&p.coords).is_some_and(|(u, v)| in_image(u, v, 0.0)) {
                continue;
            }
            if !self.sees_rock(i, &rock, candidates) {
                continue;
            }
            let miss = (c.miss_probability + c.miss_probability_per_m * depth).clamp(0.0, 1.0);
            if rng.random::<f64>() < miss {
                continue;
            }
            let toward_camera = (self.origin - rock.center).normalize();
            let face = rock.center + toward_camera * (c.face_bias_fraction * size_radius_m);
            let p_cam = self.camera_from_world * face;
            let measured = c.stereo.perturb(&p_cam.coords, rng);
            let radius_m = size_radius_m * (1.0 + c.radius_error_sigma * gaussian(rng)).max(0.2);
            out.push(BoulderObservation {
                camera: self.camera.id,
                p_rover: self.to_rover(&measured),
                radius_m,
                rock: Some(i),
            });
        }
    }

    /// A ray through a random pixel below the horizon and what it hits within `max_depth_m`.
    fn random_ground_ray(
        &self,
        candidates: &[usize],
        max_depth_m: f64,
        rng: &mut ChaCha8Rng,
    ) -> Option<(Vector3<f64>, RayTarget)> {
        self.random_ray_in_rows(candidates, CY_PX + 1.0..IMAGE_HEIGHT_PX, max_depth_m, rng)
    }

    /// A ray through a random pixel in `rows` and what it hits within `max_depth_m`.
    fn random_ray_in_rows(
        &self,
        candidates: &[usize],
        rows: std::ops::Range<f64>,
        max_depth_m: f64,
        rng: &mut ChaCha8Rng,
    ) -> Option<(Vector3<f64>, RayTarget)> {
        let u = rng.random_range(0.0..IMAGE_WIDTH_PX);
        let v = rng.random_range(rows);
        let ray_cam = pixel_ray(u, v);
        let dir = self.world_from_camera.rotation * ray_cam;
        let max_m = max_depth_m / ray_cam.x;
        let hit = self
            .moon
            .cast_ray(&self.origin, &dir, max_m, Some(candidates))?;
        Some(((self.camera_from_world * hit.point).coords, hit.target))
    }

    fn spurious(
        &self,
        candidates: &[usize],
        rng: &mut ChaCha8Rng,
        out: &mut Vec<BoulderObservation>,
    ) {
        let c = self.config;
        let count = match Poisson::new(c.spurious_per_frame) {
            Ok(p) => p.sample(rng) as usize,
            Err(_) => 0,
        };
        for _ in 0..count {
            let Some((p_cam, target)) = self.random_ground_ray(candidates, c.max_range_m, rng)
            else {
                continue;
            };
            if target == RayTarget::Lander || p_cam.x < c.min_range_m {
                continue;
            }
            let radius_m = rng.random_range(0.04..0.15);
            let lifted = p_cam + Vector3::new(0.0, 0.0, radius_m / 2.0);
            let measured = c.stereo.perturb(&lifted, rng);
            out.push(BoulderObservation {
                camera: self.camera.id,
                p_rover: self.to_rover(&measured),
                radius_m,
                rock: None,
            });
        }
    }

    fn ground_points(
        &self,
        candidates: &[usize],
        rng: &mut ChaCha8Rng,
        out: &mut Vec<GroundObservation>,
    ) {
        let c = self.config;
        let rows = CY_PX + 1.0..IMAGE_HEIGHT_PX;
        let depths_m = (0.0, c.ground_max_range_m);
        self.sample_ground(
            candidates,
            rows,
            depths_m,
            c.ground_points_per_camera,
            rng,
            out,
        );
    }

    /// `rays` rays through random pixels in `rows`; those that hit the terrain (the
    /// segmentation labels lander and rock pixels: only ground pixels give height points, the
    /// LAC's cell height is the terrain's, rocks excluded) at a depth within `depths_m`
    /// (exclusive, inclusive) give a stereo point.
    fn sample_ground(
        &self,
        candidates: &[usize],
        rows: std::ops::Range<f64>,
        depths_m: (f64, f64),
        rays: usize,
        rng: &mut ChaCha8Rng,
        out: &mut Vec<GroundObservation>,
    ) {
        for _ in 0..rays {
            let Some((p_cam, target)) =
                self.random_ray_in_rows(candidates, rows.clone(), depths_m.1, rng)
            else {
                continue;
            };
            if target != RayTarget::Terrain || p_cam.x <= depths_m.0 {
                continue;
            }
            let measured = self.config.stereo.perturb(&p_cam, rng);
            out.push(GroundObservation {
                camera: self.camera.id,
                p_rover: self.to_rover(&measured),
            });
        }
    }

    /// Ground points between `ground_max_range_m` and `far_ground_max_range_m`: the rows from
    /// just below the horizon down to where level ground at `ground_max_range_m` appears
    /// from the camera's height over its own ground, widened by 20 px for tilt.
    fn far_ground_points(
        &self,
        candidates: &[usize],
        rng: &mut ChaCha8Rng,
        out: &mut Vec<GroundObservation>,
    ) {
        let c = self.config;
        let ground_z = self.moon.height_at(self.origin.x, self.origin.y);
        let height_m = (self.origin.z - ground_z).max(0.05);
        let last_row =
            (CY_PX + FOCAL_PX * height_m / c.ground_max_range_m + 20.0).min(IMAGE_HEIGHT_PX);
        let depths_m = (c.ground_max_range_m, c.far_ground_max_range_m);
        let rays = c.far_ground_points_per_camera;
        self.sample_ground(candidates, CY_PX..last_row, depths_m, rays, rng, out);
    }

    /// The lander's side points in view at a depth within `depths_m` (inclusive), not
    /// occluded, with stereo noise.
    fn lander_points(
        &self,
        points: &[Point3<f64>],
        depths_m: (f64, f64),
        rng: &mut ChaCha8Rng,
        out: &mut Vec<Point3<f64>>,
    ) {
        let c = self.config;
        for q in points {
            let p = self.camera_from_world * q;
            if p.x < depths_m.0 || p.x > depths_m.1 {
                continue;
            }
            if !project(&p.coords).is_some_and(|(u, v)| in_image(u, v, 0.0)) {
                continue;
            }
            let to = q - self.origin;
            let dist = to.norm();
            let dir = to / dist;
            let seen = self
                .moon
                .cast_ray(&self.origin, &dir, dist + 0.05, Some(&[]))
                .is_some_and(|h| h.target == RayTarget::Lander && h.distance_m > dist - 0.05);
            if seen {
                let measured = c.stereo.perturb(&p.coords, rng);
                out.push(self.to_rover(&measured));
            }
        }
    }
}

/// Points on the lander's four sides, 0.3 m above its base, every `spacing_m`.
fn lander_side_points(moon: &Moon, spacing_m: f64) -> Vec<Point3<f64>> {
    let h = LANDER_HALF_EXTENT_M;
    let z = moon.lander_base_m() + 0.3;
    let n = ((2.0 * h / spacing_m.max(0.05)).ceil() as usize).max(1);
    let mut out = Vec::with_capacity(4 * n);
    for k in 0..n {
        let t = -h + 2.0 * h * k as f64 / n as f64;
        out.push(Point3::new(t, -h, z));
        out.push(Point3::new(h, t, z));
        out.push(Point3::new(-t, h, z));
        out.push(Point3::new(-h, -t, z));
    }
    out
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    rand_distr::StandardNormal.sample(rng)
}
