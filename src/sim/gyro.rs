//! The IMU's gyroscope: the rover's true angular rate between two camera frames, plus a
//! constant bias and white noise, as a rate gyro integrated over the frame interval reads.
//!
//! The simulator's session does not draw these (its random streams, and so the mission,
//! stay as they are); `segloc sim render` computes them from the logged true poses of the
//! frames it writes ([`gyro_rates`]), and the mission's odometry from images reads them
//! pair by pair as it drives ([`Gyro`]), each with a stream of its own.

use nalgebra::{Isometry3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Mixed into the seed for the gyro's bias and noise ("gyro").
const GYRO_STREAM: u64 = 0x6779_726f_0000_0000;

/// Error model of the gyroscope.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GyroConfig {
    /// Angle random walk (white rate noise density), rad/s/√Hz; a frame interval of `dt`
    /// seconds reads its mean rate with a standard deviation of this over √dt per axis.
    /// Default 1e-4 (0.34°/√h, a good MEMS gyro).
    pub noise_density_rad_s_sqrt_hz: f64,
    /// Constant bias for the whole drive, rad/s, in a random direction drawn from the seed.
    /// Default 1e-4 (about 20°/h).
    pub bias_rad_s: f64,
}

impl Default for GyroConfig {
    fn default() -> Self {
        Self {
            noise_density_rad_s_sqrt_hz: 1e-4,
            bias_rad_s: 1e-4,
        }
    }
}

/// The rates a gyro reads at a sequence of frames: for each frame, the mean angular rate in
/// the rover frame since the previous frame (rad/s; the first frame reads the bias and noise
/// alone).
///
/// `frames` holds each frame's time (seconds, increasing) and `world_from_rover`.
pub fn gyro_rates(
    frames: &[(f64, Isometry3<f64>)],
    config: &GyroConfig,
    seed: u64,
) -> Vec<Vector3<f64>> {
    let mut gyro = Gyro::new(config, seed);
    frames
        .iter()
        .map(|(time_s, world_from_rover)| gyro.read(*time_s, world_from_rover))
        .collect()
}

/// A gyro read frame by frame, as a drive goes (the same readings as [`gyro_rates`] over
/// the same frames).
#[derive(Clone, Debug)]
pub struct Gyro {
    config: GyroConfig,
    rng: ChaCha8Rng,
    bias_rad_s: Vector3<f64>,
    /// The previous frame's time (seconds) and `world_from_rover`.
    previous: Option<(f64, Isometry3<f64>)>,
}

impl Gyro {
    /// A gyro whose bias direction and noise are drawn from `seed`.
    pub fn new(config: &GyroConfig, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ GYRO_STREAM);
        let bias_rad_s = random_direction(&mut rng) * config.bias_rad_s;
        Self {
            config: *config,
            rng,
            bias_rad_s,
            previous: None,
        }
    }

    /// The mean rate (rad/s, rover frame) since the previous reading, read at `time_s` with
    /// the rover at `world_from_rover` (the first reading: the bias and noise alone).
    pub fn read(&mut self, time_s: f64, world_from_rover: &Isometry3<f64>) -> Vector3<f64> {
        let (rate, dt) = match self.previous {
            Some((t0, world_from_prev)) if time_s > t0 => {
                let dt = time_s - t0;
                let prev_from_curr = world_from_prev.rotation.inverse() * world_from_rover.rotation;
                (prev_from_curr.scaled_axis() / dt, dt)
            }
            _ => (Vector3::zeros(), 1.0),
        };
        self.previous = Some((time_s, *world_from_rover));
        let sigma = self.config.noise_density_rad_s_sqrt_hz / dt.sqrt();
        let rng = &mut self.rng;
        let noise = Vector3::from_fn(|_, _| rng.sample::<f64, _>(StandardNormal)) * sigma;
        rate + self.bias_rad_s + noise
    }
}

/// A unit vector uniform on the sphere.
fn random_direction(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::from_fn(|_, _| StandardNormal.sample(rng));
        let n: f64 = v.norm();
        if n > 1e-9 {
            return v / n;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn an_exact_gyro_reads_the_mean_rate_between_frames() {
        let exact = GyroConfig {
            noise_density_rad_s_sqrt_hz: 0.0,
            bias_rad_s: 0.0,
        };
        let turn = |yaw: f64, roll: f64| {
            Isometry3::from_parts(
                Translation3::new(yaw, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(roll, 0.0, yaw),
            )
        };
        let frames = [
            (0.0, turn(0.0, 0.0)),
            (0.1, turn(0.04, 0.0)),
            (0.3, turn(0.04, 0.02)),
        ];
        let rates = gyro_rates(&frames, &exact, 7);
        assert_eq!(rates[0], Vector3::zeros());
        assert!((rates[1] - Vector3::new(0.0, 0.0, 0.4)).norm() < 1e-12);
        // the roll is about the rover's own x axis, after the yaw
        assert!((rates[2] - Vector3::new(0.1, 0.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn the_bias_is_constant_and_the_noise_shrinks_with_the_interval() {
        let config = GyroConfig {
            noise_density_rad_s_sqrt_hz: 1e-3,
            bias_rad_s: 0.01,
        };
        let frames: Vec<_> = (0..2001)
            .map(|k| (k as f64 * 0.1, Isometry3::identity()))
            .collect();
        let rates = gyro_rates(&frames, &config, 3);
        let mean = rates[1..].iter().sum::<Vector3<f64>>() / 2000.0;
        assert!((mean.norm() - 0.01).abs() < 2e-4, "{mean}");
        let spread = (rates[1..]
            .iter()
            .map(|r| (r - mean).norm_squared())
            .sum::<f64>()
            / 2000.0)
            .sqrt();
        // three axes of 1e-3 / √0.1 each
        assert!(
            (spread - 1e-3 / 0.1f64.sqrt() * 3f64.sqrt()).abs() < 2e-4,
            "{spread}"
        );
        assert_eq!(rates, gyro_rates(&frames, &config, 3));
    }
}
