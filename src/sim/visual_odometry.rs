//! Visual odometry as a drifting relative-pose sensor: each step's true motion comes back with
//! a per-session scale error, a yaw drift proportional to distance, a yaw-rate scale error and
//! random-walk noise growing with the square root of the distance. Seeded.

use crate::localizer::odometry_bias::OdometryBias;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Parameters of the odometry errors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VoConfig {
    /// Per-session scale error (1 σ, fraction of distance).
    pub scale_error_sigma: f64,
    /// Per-session yaw drift (1 σ), radians per metre travelled.
    pub yaw_drift_sigma_rad_per_m: f64,
    /// Per-session yaw-rate scale error (1 σ, fraction of the turned angle).
    pub yaw_scale_error_sigma: f64,
    /// Translation random walk (1 σ per axis), metres per √metre travelled.
    pub translation_walk_m_per_sqrt_m: f64,
    /// Rotation random walk (1 σ per axis), radians per √metre travelled.
    pub rotation_walk_rad_per_sqrt_m: f64,
}

impl Default for VoConfig {
    fn default() -> Self {
        Self {
            scale_error_sigma: 0.01,
            yaw_drift_sigma_rad_per_m: 0.0005,
            yaw_scale_error_sigma: 0.003,
            translation_walk_m_per_sqrt_m: 0.004,
            rotation_walk_rad_per_sqrt_m: 0.0005,
        }
    }
}

/// The odometry sensor of one session (its biases drawn once, at creation).
#[derive(Clone, Debug)]
pub struct VisualOdometry {
    config: VoConfig,
    scale_error: f64,
    yaw_drift_rad_per_m: f64,
    yaw_scale_error: f64,
    rng: ChaCha8Rng,
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

impl VisualOdometry {
    /// A sensor with biases drawn from `seed`.
    pub fn new(config: &VoConfig, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        Self {
            config: config.clone(),
            scale_error: config.scale_error_sigma * normal(&mut rng),
            yaw_drift_rad_per_m: config.yaw_drift_sigma_rad_per_m * normal(&mut rng),
            yaw_scale_error: config.yaw_scale_error_sigma * normal(&mut rng),
            rng,
        }
    }

    /// The session's drawn biases, in the terms of the localizer's calibration.
    pub fn biases(&self) -> OdometryBias {
        OdometryBias {
            scale_error: self.scale_error,
            yaw_drift_rad_per_m: self.yaw_drift_rad_per_m,
            yaw_scale_error: self.yaw_scale_error,
        }
    }

    /// A measurement of the true motion `prev_from_cur` (rover frame at the previous step
    /// from rover frame now).
    pub fn measure(&mut self, prev_from_cur: &Isometry3<f64>) -> Isometry3<f64> {
        let t = prev_from_cur.translation.vector;
        let dist = t.norm();
        let walk = dist.sqrt();
        let c = &self.config;
        let mut noisy_t = t * (1.0 + self.scale_error);
        for k in 0..3 {
            noisy_t[k] += c.translation_walk_m_per_sqrt_m * walk * normal(&mut self.rng);
        }
        let (_, _, dyaw) = prev_from_cur.rotation.euler_angles();
        let rw = c.rotation_walk_rad_per_sqrt_m * walk;
        let yaw_error = self.yaw_drift_rad_per_m * dist
            + self.yaw_scale_error * dyaw
            + rw * normal(&mut self.rng);
        let error = UnitQuaternion::from_euler_angles(
            rw * normal(&mut self.rng),
            rw * normal(&mut self.rng),
            yaw_error,
        );
        Isometry3::from_parts(Translation3::from(noisy_t), prev_from_cur.rotation * error)
    }
}

/// The gravity direction an IMU at rest reports, in the rover frame: −g·ẑ rotated into the
/// rover frame, tilted by a random error of `sigma_rad` per axis.
pub fn gravity_in_rover(
    world_from_rover: &Isometry3<f64>,
    gravity_mps2: f64,
    sigma_rad: f64,
    rng: &mut ChaCha8Rng,
) -> Vector3<f64> {
    let g = world_from_rover.rotation.inverse() * Vector3::new(0.0, 0.0, -gravity_mps2);
    let tilt =
        UnitQuaternion::from_euler_angles(sigma_rad * normal(rng), sigma_rad * normal(rng), 0.0);
    tilt * g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drift_is_about_a_percent_of_distance() {
        // straight 50 m drives over many seeds: end error / distance around 1–2 %
        let step = Isometry3::translation(0.02, 0.0, 0.0);
        let mut ratios = Vec::new();
        for seed in 0..40 {
            let mut vo = VisualOdometry::new(&VoConfig::default(), seed);
            let mut est = Isometry3::identity();
            let mut truth = Isometry3::identity();
            for _ in 0..2500 {
                est *= vo.measure(&step);
                truth *= step;
            }
            ratios.push((est.translation.vector - truth.translation.vector).norm() / 50.0);
        }
        ratios.sort_by(f64::total_cmp);
        let median = ratios[ratios.len() / 2];
        assert!(median > 0.003 && median < 0.03, "median drift {median}");
    }

    #[test]
    fn gravity_points_down_in_a_level_rover() {
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let g = gravity_in_rover(&Isometry3::identity(), 1.622, 0.0, &mut rng);
        assert!((g - Vector3::new(0.0, 0.0, -1.622)).norm() < 1e-12);
    }
}
