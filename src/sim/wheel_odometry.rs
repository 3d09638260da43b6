//! The rover's wheel odometry: the distance driven along the rover's forward axis between
//! two stereo pairs, as the wheel encoders count it (a scale error for the whole session,
//! drawn from the seed, and white noise per step), and how the odometry from images falls
//! back on it.
//!
//! The stereo VO goes blind where the cameras see no texture (the rover turns into its own
//! shadow, faces the sun or the sky) and, just before, measures badly from the last few
//! features. The gyro still gives the rotation; the wheels give the distance. A pair's VO
//! translation is replaced by the wheels' when the VO lost the pair or when the two disagree
//! by more than [`WheelOdometryConfig::max_disagreement_m`] plus
//! [`WheelOdometryConfig::max_disagreement_fraction`] of the distance (the design note
//! `docs/design/vo-wheel-fallback.md` has the figures).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Mixed into the seed for the wheels' scale error and noise ("wheel").
const WHEEL_STREAM: u64 = 0x7768_6565_6c00_0000;

/// Error model of the wheel odometry and the rule of the fallback.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WheelOdometryConfig {
    /// Use the wheels at all (off: the VO's motion always, as before).
    pub enabled: bool,
    /// One σ of the session's scale error of the counted distance, fraction (the wheel
    /// radius on regolith: sinkage and slip). Default 0.03.
    pub scale_sigma: f64,
    /// One σ of the white noise of a step's distance, fraction of the step. Default 0.05.
    pub noise_fraction: f64,
    /// A measured VO translation is replaced by the wheels' when the two differ by more than
    /// this, metres, plus `max_disagreement_fraction` of the wheels' distance.
    pub max_disagreement_m: f64,
    /// See `max_disagreement_m`.
    pub max_disagreement_fraction: f64,
}

impl Default for WheelOdometryConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            scale_sigma: 0.03,
            noise_fraction: 0.05,
            max_disagreement_m: 0.01,
            max_disagreement_fraction: 0.2,
        }
    }
}

impl WheelOdometryConfig {
    /// `None` when every value is in range, else the name of the first that is not.
    pub fn invalid_field(&self) -> Option<&'static str> {
        [
            ("scale_sigma", self.scale_sigma),
            ("noise_fraction", self.noise_fraction),
            ("max_disagreement_m", self.max_disagreement_m),
            ("max_disagreement_fraction", self.max_disagreement_fraction),
        ]
        .into_iter()
        .find(|(_, v)| !(v.is_finite() && *v >= 0.0))
        .map(|(name, _)| name)
    }
}

/// The wheel encoders of one session.
#[derive(Clone, Debug)]
pub struct WheelOdometry {
    config: WheelOdometryConfig,
    scale: f64,
    rng: ChaCha8Rng,
}

impl WheelOdometry {
    /// The wheels of a session; `seed` draws the scale error and the noise.
    pub fn new(config: &WheelOdometryConfig, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ WHEEL_STREAM);
        let draw: f64 = StandardNormal.sample(&mut rng);
        Self {
            config: *config,
            scale: 1.0 + config.scale_sigma * draw,
            rng,
        }
    }

    /// The signed distance the wheels count over the true motion `prev_from_cur` (rover
    /// frame): its forward component, scaled and noisy.
    pub fn distance_m(&mut self, prev_from_cur: &Isometry3<f64>) -> f64 {
        let forward = prev_from_cur.translation.vector.x;
        let noise: f64 = StandardNormal.sample(&mut self.rng);
        forward * (self.scale + self.config.noise_fraction * noise)
    }
}

/// The motion of a pair with the VO's rotation and the wheels' translation: `distance_m`
/// along the forward axis turned by half the pair's rotation (the chord of the arc).
pub fn wheel_motion(vo_motion: &Isometry3<f64>, distance_m: f64) -> Isometry3<f64> {
    let half = UnitQuaternion::from_scaled_axis(vo_motion.rotation.scaled_axis() / 2.0);
    Isometry3::from_parts(
        Translation3::from(half * Vector3::new(distance_m, 0.0, 0.0)),
        vo_motion.rotation,
    )
}

/// Whether the wheels replace the VO's translation of a pair (see the [module docs](self)).
pub fn take_wheels(
    config: &WheelOdometryConfig,
    vo_lost: bool,
    vo_motion: &Isometry3<f64>,
    wheel: &Isometry3<f64>,
) -> bool {
    if !config.enabled {
        return false;
    }
    let gap = (vo_motion.translation.vector - wheel.translation.vector).norm();
    let tolerance = config.max_disagreement_m
        + config.max_disagreement_fraction * wheel.translation.vector.norm();
    vo_lost || gap > tolerance
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wheels_count_the_forward_distance_with_their_scale() {
        let config = WheelOdometryConfig {
            noise_fraction: 0.0,
            ..WheelOdometryConfig::default()
        };
        let mut wheels = WheelOdometry::new(&config, 3);
        let step = Isometry3::translation(0.045, 0.002, 0.001);
        let d = wheels.distance_m(&step);
        assert!((d / 0.045 - wheels.scale).abs() < 1e-12);
        assert!((wheels.scale - 1.0).abs() < 0.15, "{}", wheels.scale);
        let backwards = wheels.distance_m(&Isometry3::translation(-0.02, 0.0, 0.0));
        assert!(backwards < 0.0);
    }

    #[test]
    fn a_turning_step_moves_along_the_chord() {
        let turn = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.2),
        );
        let m = wheel_motion(&turn, 1.0);
        assert!(
            (m.translation.vector - Vector3::new(0.1f64.cos(), 0.1f64.sin(), 0.0)).norm() < 1e-12
        );
        assert_eq!(m.rotation, turn.rotation);
    }

    #[test]
    fn the_wheels_replace_a_lost_or_disagreeing_vo_step_only() {
        let config = WheelOdometryConfig::default();
        let wheel = Isometry3::translation(0.045, 0.0, 0.0);
        let close = Isometry3::translation(0.047, 0.003, 0.0);
        let sideways = Isometry3::translation(0.055, 0.021, 0.0);
        assert!(!take_wheels(&config, false, &close, &wheel));
        assert!(take_wheels(&config, true, &close, &wheel));
        assert!(take_wheels(&config, false, &sideways, &wheel));
        let off = WheelOdometryConfig {
            enabled: false,
            ..config
        };
        assert!(!take_wheels(&off, true, &sideways, &wheel));
    }

    #[test]
    fn out_of_range_values_are_named() {
        let bad = WheelOdometryConfig {
            noise_fraction: -0.1,
            ..WheelOdometryConfig::default()
        };
        assert_eq!(bad.invalid_field(), Some("noise_fraction"));
        assert_eq!(WheelOdometryConfig::default().invalid_field(), None);
    }
}
