//! A session's odometry from pixels instead of the drift model
//! ([`crate::sim::visual_odometry`]).
//!
//! Every `period_ticks` simulator ticks (10 Hz by default): render the front stereo pair
//! from the true rover pose ([`Renderer`]) → read the gyro over the interval since the last
//! pair ([`Gyro`]) → measure the left camera's motion with the stereo visual odometry
//! ([`StereoOdometry`]), given the gyro and the IMU's gravity as `segloc vo --images` is
//! (tilt anchored to gravity, heading from the bias-corrected gyro) → move it to the rover
//! frame; where the VO lost the pair or its translation disagrees with the wheels', take
//! the wheels' distance instead ([`crate::sim::wheel_odometry`]). The ticks between two
//! pairs move by a tick's share of the last measured motion (constant velocity, what the
//! planner drives on); the tick of the next pair takes what is left, so that the odometry
//! over a pair's interval is exactly the pair's motion.

use crate::graph::StereoCalibration;
use crate::sim::gyro::{Gyro, GyroConfig};
use crate::sim::render::scoring::Quantiles;
use crate::sim::render::{rover_from_front_left_optical, Renderer};
use crate::sim::wheel_odometry::{take_wheels, wheel_motion, WheelOdometry, WheelOdometryConfig};
use crate::vo::{StereoOdometry, VoConfig, VoError};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Noise frames of the odometry's renders start here (keys from 2⁴⁰), apart from the
/// boulder pairs'.
const NOISE_FRAME_BASE: u64 = 1 << 39;

/// Settings of the image odometry (TOML `[perception.image_odometry]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImageOdometryConfig {
    /// A stereo pair every this many simulator ticks (20 Hz ticks: 2 is 10 Hz).
    pub period_ticks: usize,
    /// The stereo visual odometry.
    pub vo: VoConfig,
    /// The gyro the odometry reads.
    pub gyro: GyroConfig,
    /// The wheel odometry the VO falls back on.
    pub wheel: WheelOdometryConfig,
}

impl Default for ImageOdometryConfig {
    fn default() -> Self {
        Self {
            period_ticks: 2,
            vo: VoConfig::default(),
            gyro: GyroConfig::default(),
            wheel: WheelOdometryConfig::default(),
        }
    }
}

/// What the image odometry did in one session (the mission report's `image_odometry`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImageOdometryStats {
    /// A pair every this many simulator ticks.
    pub period_ticks: usize,
    /// Stereo pairs processed.
    pub pairs: usize,
    /// Pairs whose motion could not be estimated (the pose is the VO's prediction).
    pub lost: usize,
    /// Pairs whose rotation is the gyro's (the image motion failed or disagreed with it).
    pub gyro_rotation: usize,
    /// Pairs whose translation is the wheels' (the VO lost the pair or disagreed with them).
    pub wheel_translation: usize,
    /// Features tracked from the previous pair, median.
    pub tracked_median: f64,
    /// Rendering one pair (both views), milliseconds.
    pub render_ms: Quantiles,
    /// The VO on one pair, milliseconds.
    pub vo_ms: Quantiles,
    /// Every pair (written as `sessionN_vo.csv` by `segloc mission --out`, not to the
    /// report).
    #[serde(skip)]
    pub per_pair: Vec<PairRecord>,
}

/// What the VO did on one stereo pair, beside where the rover truly was.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairRecord {
    /// Session time, s.
    pub time_s: f64,
    /// Features tracked from the previous pair.
    pub tracked: usize,
    /// Inliers of the motion estimate.
    pub inliers: usize,
    /// Features alive after the pair.
    pub features: usize,
    /// The image motion could not be estimated.
    pub lost: bool,
    /// The rotation is the gyro's.
    pub gyro_rotation: bool,
    /// The translation is the wheels'.
    pub wheel_translation: bool,
    /// The VO's time on the pair, ms.
    pub vo_ms: f64,
    /// The odometry's pose of the rover after the pair (the pairs' motions composed).
    pub odom_from_rover: Isometry3<f64>,
    /// The true pose of the rover.
    pub world_from_rover: Isometry3<f64>,
}

/// One session's odometry state.
struct SessionOdometry {
    odometry: StereoOdometry,
    gyro: Gyro,
    wheels: WheelOdometry,
    /// The VO's own `odom_from_rover` at the last pair.
    vo_at_pair: Isometry3<f64>,
    /// The true pose at the last pair (what the wheels turn over).
    world_from_rover_at_pair: Option<Isometry3<f64>>,
    /// The steps handed out since the last pair, composed.
    since_pair: Isometry3<f64>,
    /// A tick's share of the last pair's motion.
    per_tick: Isometry3<f64>,
    render_ms: Vec<f64>,
    pairs: Vec<PairRecord>,
}

/// The stereo VO on rendered pairs, one session at a time.
pub struct RenderedOdometry {
    config: ImageOdometryConfig,
    camera: StereoCalibration,
    rover_from_left: Isometry3<f64>,
    /// Pairs rendered so far, all sessions (each pair's image noise is drawn from it).
    pairs: u64,
    session: Option<SessionOdometry>,
}

impl RenderedOdometry {
    /// Odometry for the images of `renderer`; fails when the VO's configuration is invalid.
    pub fn new(config: &ImageOdometryConfig, renderer: &Renderer) -> Result<Self, VoError> {
        config.vo.validate()?;
        Ok(Self {
            config: config.clone(),
            camera: renderer.camera().calibration(),
            rover_from_left: rover_from_front_left_optical(),
            pairs: 0,
            session: None,
        })
    }

    /// Start a session at its first tick (time `time_s`, the rover truly at
    /// `world_from_rover`, the IMU reading `gravity_rover`); `seed` draws its gyro's bias
    /// and noise.
    pub fn begin_session(
        &mut self,
        renderer: &Renderer,
        seed: u64,
        time_s: f64,
        world_from_rover: &Isometry3<f64>,
        gravity_rover: Option<Vector3<f64>>,
    ) -> Result<(), VoError> {
        let mut odometry = StereoOdometry::new(self.camera, self.config.vo.clone())?;
        odometry.set_gyro_mount(self.rover_from_left.rotation);
        self.session = Some(SessionOdometry {
            odometry,
            gyro: Gyro::new(&self.config.gyro, seed),
            wheels: WheelOdometry::new(&self.config.wheel, seed),
            vo_at_pair: Isometry3::identity(),
            world_from_rover_at_pair: None,
            since_pair: Isometry3::identity(),
            per_tick: Isometry3::identity(),
            render_ms: Vec::new(),
            pairs: Vec::new(),
        });
        self.process_pair(renderer, time_s, world_from_rover, gravity_rover);
        Ok(())
    }

    /// The measured step of tick `tick` (time `time_s`; the rover truly at
    /// `world_from_rover`, the IMU reading `gravity_rover`, rover frame): `prev_from_cur` in
    /// the rover frame. Identity before [`RenderedOdometry::begin_session`].
    pub fn measure(
        &mut self,
        renderer: &Renderer,
        tick: usize,
        time_s: f64,
        world_from_rover: &Isometry3<f64>,
        gravity_rover: Option<Vector3<f64>>,
    ) -> Isometry3<f64> {
        let period = self.config.period_ticks.max(1);
        if !tick.is_multiple_of(period) {
            return match self.session.as_mut() {
                Some(s) => {
                    s.since_pair *= s.per_tick;
                    s.per_tick
                }
                None => Isometry3::identity(),
            };
        }
        let Some(motion) = self.process_pair(renderer, time_s, world_from_rover, gravity_rover)
        else {
            return Isometry3::identity();
        };
        let Some(s) = self.session.as_mut() else {
            return Isometry3::identity();
        };
        let step = s.since_pair.inverse() * motion;
        s.per_tick = share(&motion, period);
        s.since_pair = Isometry3::identity();
        step
    }

    /// Render the pair at `world_from_rover`, run the VO on it with the gyro and
    /// `gravity_rover`; the rover's motion since the last pair, `prev_from_cur` (`None`
    /// without a session).
    fn process_pair(
        &mut self,
        renderer: &Renderer,
        time_s: f64,
        world_from_rover: &Isometry3<f64>,
        gravity_rover: Option<Vector3<f64>>,
    ) -> Option<Isometry3<f64>> {
        let s = self.session.as_mut()?;
        let world_from_left = world_from_rover * self.rover_from_left;
        let (left, right, render_ms) =
            renderer.render_stereo_views(&world_from_left, NOISE_FRAME_BASE + self.pairs);
        self.pairs += 1;
        s.render_ms.push(render_ms);
        let rate = s.gyro.read(time_s, world_from_rover);
        let result = s.odometry.process_with_imu(
            &left.image,
            &right.image,
            time_s,
            Some(rate),
            gravity_rover,
        );
        let vo_pose = self.rover_from_left * result.pose * self.rover_from_left.inverse();
        let (motion, wheel_translation) =
            s.pair_motion(&self.config.wheel, &vo_pose, result.lost, world_from_rover);
        let odom_at_pair = s.pairs.last().map(|p| p.odom_from_rover);
        let odom_from_rover = odom_at_pair.unwrap_or_else(Isometry3::identity) * motion;
        s.pairs.push(PairRecord {
            time_s,
            tracked: result.tracked,
            inliers: result.inliers,
            features: result.features,
            lost: result.lost,
            gyro_rotation: result.gyro_rotation,
            wheel_translation,
            vo_ms: result.time_ms,
            odom_from_rover,
            world_from_rover: *world_from_rover,
        });
        Some(motion)
    }

    /// The current session's figures (`None` before the first session).
    pub fn session_stats(&self) -> Option<ImageOdometryStats> {
        let s = self.session.as_ref()?;
        let count = |flag: fn(&PairRecord) -> bool| s.pairs.iter().filter(|p| flag(p)).count();
        let tracked: Vec<f64> = s.pairs.iter().map(|p| p.tracked as f64).collect();
        let vo_ms: Vec<f64> = s.pairs.iter().map(|p| p.vo_ms).collect();
        Some(ImageOdometryStats {
            period_ticks: self.config.period_ticks,
            pairs: s.pairs.len(),
            lost: count(|p| p.lost),
            gyro_rotation: count(|p| p.gyro_rotation),
            wheel_translation: count(|p| p.wheel_translation),
            tracked_median: Quantiles::of(&tracked).median,
            render_ms: Quantiles::of(&s.render_ms),
            vo_ms: Quantiles::of(&vo_ms),
            per_pair: s.pairs.clone(),
        })
    }
}

impl SessionOdometry {
    /// The motion of the pair whose VO pose (rover frame) is `vo_pose`, the rover truly at
    /// `world_from_rover`: the VO's since the last pair, or its rotation with the wheels'
    /// translation when the VO lost the pair or disagrees with them; and whether the wheels
    /// were taken.
    fn pair_motion(
        &mut self,
        config: &WheelOdometryConfig,
        vo_pose: &Isometry3<f64>,
        vo_lost: bool,
        world_from_rover: &Isometry3<f64>,
    ) -> (Isometry3<f64>, bool) {
        let vo_motion = self.vo_at_pair.inverse() * vo_pose;
        self.vo_at_pair = *vo_pose;
        let before = self.world_from_rover_at_pair.replace(*world_from_rover);
        let Some(before) = before else {
            return (vo_motion, false);
        };
        let distance_m = self
            .wheels
            .distance_m(&(before.inverse() * world_from_rover));
        let wheels = wheel_motion(&vo_motion, distance_m);
        if take_wheels(config, vo_lost, &vo_motion, &wheels) {
            (wheels, true)
        } else {
            (vo_motion, false)
        }
    }
}

/// `motion` split into `n` equal steps: one of them (the rotation about the same axis by an
/// `n`-th of the angle, an `n`-th of the translation).
fn share(motion: &Isometry3<f64>, n: usize) -> Isometry3<f64> {
    let n = n.max(1) as f64;
    Isometry3::from_parts(
        Translation3::from(motion.translation.vector / n),
        UnitQuaternion::from_scaled_axis(motion.rotation.scaled_axis() / n),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::moon::{Moon, MoonConfig};
    use crate::sim::render::RenderConfig;
    use crate::sim::rover::RoverState;

    #[test]
    fn the_steps_between_two_pairs_compose_to_the_vo_motion() {
        let motion = Isometry3::from_parts(
            Translation3::new(0.04, 0.002, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.01),
        );
        let half = share(&motion, 2);
        let rest = half.inverse() * motion;
        assert!(((half * rest).inverse() * motion).translation.vector.norm() < 1e-15);
        assert!((half.rotation.angle() - 0.005).abs() < 1e-12);
        assert!((half.translation.vector.x - 0.02).abs() < 1e-15);
    }

    /// Moon 4 and its renderer at half resolution.
    fn half_resolution_scene() -> (Moon, Renderer) {
        let moon = Moon::generate(&MoonConfig::default(), 4).unwrap();
        let render = RenderConfig {
            resolution_scale: 0.5,
            ..RenderConfig::default()
        };
        let renderer = Renderer::new(&moon, &render, 4).unwrap();
        (moon, renderer)
    }

    #[test]
    fn a_straight_drive_is_measured_from_the_rendered_pairs() {
        let (moon, renderer) = half_resolution_scene();
        let mut odometry =
            RenderedOdometry::new(&ImageOdometryConfig::default(), &renderer).unwrap();
        let (x, y) = moon.nearest_clear_position(5.0, 3.0, 1.0, 0.08);
        let pose_at = |d: f64| RoverState::at_rest(x + d, y, 0.0).pose(&moon);
        odometry
            .begin_session(&renderer, 9, 0.0, &pose_at(0.0), None)
            .unwrap();
        // 0.4 m/s at 20 Hz: 2 cm a tick, a pair every other tick
        let mut session_from_rover = Isometry3::identity();
        for tick in 1..=20 {
            let step = odometry.measure(
                &renderer,
                tick,
                tick as f64 * 0.05,
                &pose_at(0.02 * tick as f64),
                None,
            );
            session_from_rover *= step;
        }
        let truth = pose_at(0.0).inverse() * pose_at(0.4);
        let error = (truth.inverse() * session_from_rover)
            .translation
            .vector
            .norm();
        assert!(error < 0.01, "{error} m off over 0.4 m");
        let stats = odometry.session_stats().unwrap();
        assert_eq!(stats.pairs, 11);
        assert_eq!(stats.lost, 0);
        // on lit, textured ground the VO's translation stands: the wheels are not taken
        assert_eq!(stats.wheel_translation, 0);
    }

    #[test]
    fn a_blind_pair_moves_by_the_wheels() {
        let (moon, renderer) = half_resolution_scene();
        let config = ImageOdometryConfig {
            wheel: WheelOdometryConfig {
                scale_sigma: 0.0,
                noise_fraction: 0.0,
                ..WheelOdometryConfig::default()
            },
            ..ImageOdometryConfig::default()
        };
        let mut odometry = RenderedOdometry::new(&config, &renderer).unwrap();
        let (x, y) = moon.nearest_clear_position(5.0, 3.0, 1.0, 0.08);
        let pose_at = |d: f64| RoverState::at_rest(x + d, y, 0.0).pose(&moon);
        odometry
            .begin_session(&renderer, 9, 0.0, &pose_at(0.0), None)
            .unwrap();
        // the rover jumps 0.5 m between two pairs, farther than the VO can track: the pair's
        // translation is the wheels'
        odometry.measure(&renderer, 1, 0.05, &pose_at(0.25), None);
        let step = odometry.measure(&renderer, 2, 0.1, &pose_at(0.5), None);
        let stats = odometry.session_stats().unwrap();
        assert_eq!(stats.wheel_translation, 1, "{stats:?}");
        let truth = pose_at(0.0).inverse() * pose_at(0.5);
        let forward = truth.translation.vector.x;
        assert!((step.translation.vector.norm() - forward).abs() < 0.01 * forward + 0.005);
    }
}
