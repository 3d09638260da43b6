//! A generated boulder field and two rover sessions over it.
//!
//! Boulders are scattered uniformly over a square site with a heavy-tailed size
//! distribution (most small). Each session drives a closed loop of its own around the
//! site centre and detects, once a second, the boulders within range in front of it, with
//! stereo-like noise (depth error growing with the square of the range, much smaller
//! error across the line of sight), missed detections and spurious ones. The query session
//! is expressed in its own frame: the world moved by a random yaw and translation, which
//! is the transform a relocalizer must recover.

use crate::landmarks::{fuse_detections, FusionConfig};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use segloc_maps::{Detection, DetectionSet, ObjectMap};
use serde::{Deserialize, Serialize};

/// Parameters of the generated field and sessions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FieldConfig {
    /// Side of the square site (m), centred on the origin.
    pub site_m: f64,
    /// Number of boulders.
    pub boulders: usize,
    /// Radius (m) of the prior session's loop.
    pub prior_loop_radius_m: f64,
    /// Radius (m) of the query session's loop (its centre is offset from the prior's).
    pub query_loop_radius_m: f64,
    /// Offset (m) of the query loop's centre along x.
    pub query_loop_offset_m: f64,
    /// Detection range (m).
    pub max_range_m: f64,
    /// Half field of view (degrees).
    pub half_fov_deg: f64,
    /// Probability that a visible boulder is missed in a frame.
    pub miss_probability: f64,
    /// Spurious detections per frame (mean).
    pub spurious_per_frame: f64,
    /// Depth noise coefficient k (m⁻¹): σ_depth = k · range².
    pub depth_noise_per_m2: f64,
    /// Cross-range noise (m).
    pub lateral_noise_m: f64,
}

impl Default for FieldConfig {
    fn default() -> Self {
        Self {
            site_m: 30.0,
            boulders: 300,
            prior_loop_radius_m: 6.0,
            query_loop_radius_m: 5.0,
            query_loop_offset_m: 3.0,
            max_range_m: 6.0,
            half_fov_deg: 35.0,
            miss_probability: 0.2,
            spurious_per_frame: 0.3,
            depth_noise_per_m2: 0.0012,
            lateral_noise_m: 0.003,
        }
    }
}

/// Boulder centres (world frame) of a generated field.
pub fn boulders(config: &FieldConfig, rng: &mut ChaCha8Rng) -> Vec<Point3<f64>> {
    let half = config.site_m / 2.0;
    (0..config.boulders)
        .map(|_| {
            // Heavy tail: radius 5–50 cm, most small; the centre sits at ground + radius/2.
            let u: f64 = rng.random();
            let radius = 0.05 + 0.45 * u.powi(4);
            Point3::new(
                rng.random_range(-half..half),
                rng.random_range(-half..half),
                0.3 * (0.2 * rng.random_range(-half..half)).sin() + radius / 2.0,
            )
        })
        .collect()
}

/// One session's detections along a circular loop of `radius_m` around `centre`, in the
/// world frame, one frame a second at 0.4 m/s.
pub fn drive_loop(
    world: &[Point3<f64>],
    centre: Vector2<f64>,
    radius_m: f64,
    session: &str,
    config: &FieldConfig,
    rng: &mut ChaCha8Rng,
) -> DetectionSet {
    let mut set = DetectionSet::new(session, "world", true);
    let frames = ((2.0 * std::f64::consts::PI * radius_m) / 0.4).ceil() as u64;
    let unit = Normal::new(0.0, 1.0).unwrap_or_else(|_| unreachable!());
    let half_fov = config.half_fov_deg.to_radians();
    for frame in 0..frames {
        let angle = 2.0 * std::f64::consts::PI * frame as f64 / frames as f64;
        let rover = Point3::new(
            centre.x + radius_m * angle.cos(),
            centre.y + radius_m * angle.sin(),
            0.3,
        );
        let heading = angle + std::f64::consts::FRAC_PI_2;
        for b in world {
            let v = Vector2::new(b.x - rover.x, b.y - rover.y);
            let range = v.norm();
            let bearing = (v.y.atan2(v.x) - heading + std::f64::consts::PI)
                .rem_euclid(2.0 * std::f64::consts::PI)
                - std::f64::consts::PI;
            if range < 1.0 || range > config.max_range_m || bearing.abs() > half_fov {
                continue;
            }
            if rng.random::<f64>() < config.miss_probability {
                continue;
            }
            let along = v / range;
            let across = Vector2::new(-along.y, along.x);
            let depth_err = config.depth_noise_per_m2 * range * range * unit.sample(rng);
            let lateral_err = config.lateral_noise_m * unit.sample(rng);
            let p = Point3::new(
                b.x + depth_err * along.x + lateral_err * across.x,
                b.y + depth_err * along.y + lateral_err * across.y,
                b.z + 0.002 * unit.sample(rng),
            );
            set.detections.push(detection(frame, p, rover));
        }
        let spurious = (config.spurious_per_frame + rng.random::<f64>()).floor() as usize;
        for _ in 0..spurious {
            let range = rng.random_range(1.5..config.max_range_m);
            let bearing = heading + rng.random_range(-half_fov..half_fov);
            let p = Point3::new(
                rover.x + range * bearing.cos(),
                rover.y + range * bearing.sin(),
                rng.random_range(-0.2..0.3),
            );
            set.detections.push(detection(frame, p, rover));
        }
    }
    set
}

fn detection(frame: u64, p_world: Point3<f64>, rover: Point3<f64>) -> Detection {
    Detection {
        frame,
        p_world,
        rover_position: Some(rover),
        size_m: None,
        score: None,
    }
}

/// A random yaw (any) and translation (±20 m in x and y, ±1 m in z).
pub fn random_yaw_transform(rng: &mut ChaCha8Rng) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(
            rng.random_range(-20.0..20.0),
            rng.random_range(-20.0..20.0),
            rng.random_range(-1.0..1.0),
        ),
        UnitQuaternion::from_axis_angle(
            &Vector3::z_axis(),
            rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
        ),
    )
}

/// Detections of two sessions and the truth: (prior in the world frame, query in its own
/// frame, `prior_from_query`).
pub fn two_session_detections(
    config: &FieldConfig,
    seed: u64,
) -> (DetectionSet, DetectionSet, Isometry3<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let world = boulders(config, &mut rng);
    let prior = drive_loop(
        &world,
        Vector2::zeros(),
        config.prior_loop_radius_m,
        "prior",
        config,
        &mut rng,
    );
    let query_world = drive_loop(
        &world,
        Vector2::new(config.query_loop_offset_m, 0.0),
        config.query_loop_radius_m,
        "query",
        config,
        &mut rng,
    );
    let prior_from_query = random_yaw_transform(&mut rng);
    let query = query_world.transformed(&prior_from_query.inverse(), "query");
    (prior, query, prior_from_query)
}

/// Two fused object maps and the truth: (prior, query, `prior_from_query`).
pub fn two_sessions(config: &FieldConfig, seed: u64) -> (ObjectMap, ObjectMap, Isometry3<f64>) {
    let (prior, query, truth) = two_session_detections(config, seed);
    let fusion = FusionConfig::default();
    (
        fuse_detections(&prior, &fusion),
        fuse_detections(&query, &fusion),
        truth,
    )
}
