//! What the cameras give a session when the mission runs on images: the boulders of every
//! camera frame ([`RenderedBoulders`]) and, when set, the odometry ([`RenderedOdometry`]),
//! both from the same renderer.

use crate::sim::rendered_boulders::RenderedBoulders;
use crate::sim::rendered_odometry::{ImageOdometryStats, RenderedOdometry};
use crate::sim::sensors::{BoulderObservation, SensorConfig};
use crate::vo::VoError;
use nalgebra::{Isometry3, Vector3};

/// The rendered cameras of a mission's sessions.
pub struct RenderedSensors {
    /// The boulders of every camera frame.
    pub boulders: RenderedBoulders,
    /// The odometry from the front pair (`None`: the drift model's odometry).
    pub odometry: Option<RenderedOdometry>,
}

impl RenderedSensors {
    /// The boulders both stereo pairs see from `world_from_rover` at tick `tick`
    /// ([`RenderedBoulders::observe`]).
    pub fn observe_boulders(
        &mut self,
        world_from_rover: &Isometry3<f64>,
        tick: usize,
        sensors: &SensorConfig,
    ) -> Vec<BoulderObservation> {
        self.boulders.observe(world_from_rover, tick, sensors)
    }

    /// Start a session's odometry at its first tick ([`RenderedOdometry::begin_session`]);
    /// nothing without image odometry.
    pub fn begin_session(
        &mut self,
        seed: u64,
        time_s: f64,
        world_from_rover: &Isometry3<f64>,
        gravity_rover: Option<Vector3<f64>>,
    ) -> Result<(), VoError> {
        match self.odometry.as_mut() {
            Some(odometry) => odometry.begin_session(
                self.boulders.renderer(),
                seed,
                time_s,
                world_from_rover,
                gravity_rover,
            ),
            None => Ok(()),
        }
    }

    /// The odometry's step of tick `tick` ([`RenderedOdometry::measure`]); `None` without
    /// image odometry.
    pub fn measure_step(
        &mut self,
        tick: usize,
        time_s: f64,
        world_from_rover: &Isometry3<f64>,
        gravity_rover: Option<Vector3<f64>>,
    ) -> Option<Isometry3<f64>> {
        let odometry = self.odometry.as_mut()?;
        Some(odometry.measure(
            self.boulders.renderer(),
            tick,
            time_s,
            world_from_rover,
            gravity_rover,
        ))
    }

    /// The current session's odometry figures (`None` without image odometry).
    pub fn odometry_stats(&self) -> Option<ImageOdometryStats> {
        self.odometry.as_ref()?.session_stats()
    }
}
