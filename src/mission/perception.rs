//! Where the mission's boulder detections and odometry come from: the sensor models
//! (default) or the rendered stereo pairs ([`RenderedSensors`]: the perception front end's
//! boulders, and the stereo visual odometry unless `odometry = "model"`), and their settings.

use super::MissionError;
use crate::perception::{FrontEnd, FrontEndConfig, GeometricSegmenter, Segmenter};
use crate::sim::moon::Moon;
use crate::sim::render::scoring::MatchConfig;
use crate::sim::render::{RenderConfig, RenderError};
use crate::sim::rendered_boulders::RenderedBoulders;
use crate::sim::rendered_odometry::{ImageOdometryConfig, RenderedOdometry};
use crate::sim::rendered_sensors::RenderedSensors;
use serde::{Deserialize, Serialize};

/// The source of the sessions' boulder detections.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoulderSensors {
    /// The sensor model ([`crate::sim::sensors::observe`]).
    #[default]
    Model,
    /// The front end on the rendered stereo pairs of every camera frame.
    Rendered,
}

/// The source of the sessions' odometry when the boulders come from images.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OdometrySource {
    /// The stereo visual odometry on the rendered front pair ([`RenderedOdometry`]).
    #[default]
    Images,
    /// The drift model ([`crate::sim::visual_odometry`]), as with `sensors = "model"`.
    Model,
}

/// The mission's perception settings (TOML section `[perception]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PerceptionConfig {
    /// Boulder detections from `"model"` (the sensor model) or `"rendered"` (images).
    pub sensors: BoulderSensors,
    /// The renderer, with `sensors = "rendered"`.
    pub render: RenderConfig,
    /// The front end, with `sensors = "rendered"` (geometric segmenter unless the caller
    /// gives another).
    pub front_end: FrontEndConfig,
    /// What counts as a true detection in the report's `perception`.
    pub matching: MatchConfig,
    /// With `sensors = "rendered"`: the odometry from `"images"` (the stereo VO) or
    /// `"model"` (the drift model). The sensor model always uses the drift model.
    pub odometry: OdometrySource,
    /// The odometry from images.
    pub image_odometry: ImageOdometryConfig,
}

impl PerceptionConfig {
    /// Check the values are in range; the error names the TOML path.
    pub fn validate(&self) -> Result<(), MissionError> {
        let bad = |m: String| Err(MissionError::InvalidConfig(m));
        if let Err(RenderError::InvalidConfig { field, message }) = self.render.validate() {
            return bad(format!("perception.render.{field}: {message}"));
        }
        if let Err(e) = self.front_end.stereo.validate() {
            return bad(format!("perception.front_end.stereo: {e}"));
        }
        if let Err(e) = self.front_end.boulders.validate() {
            return bad(format!("perception.front_end.boulders: {e}"));
        }
        let m = &self.matching;
        let positive = [
            ("max_range_m", m.max_range_m),
            ("match_size_fraction", m.match_size_fraction),
            ("match_max_range_m", m.match_max_range_m),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!(
                    "perception.matching.{field} must be positive (got {v})"
                ));
            }
        }
        if !(m.min_size_m.is_finite() && m.min_size_m >= 0.0) {
            return bad("perception.matching.min_size_m must be a non-negative number".into());
        }
        if !(0.0..=1.0).contains(&m.min_visible_fraction) {
            return bad("perception.matching.min_visible_fraction must be within [0, 1]".into());
        }
        if self.image_odometry.period_ticks == 0 {
            return bad("perception.image_odometry.period_ticks must be at least 1".into());
        }
        if let Err(e) = self.image_odometry.vo.validate() {
            return bad(format!("perception.image_odometry.vo: {e}"));
        }
        if let Some(field) = self.image_odometry.wheel.invalid_field() {
            return bad(format!(
                "perception.image_odometry.wheel.{field} must be finite and >= 0"
            ));
        }
        Ok(())
    }

    /// The renderer, front end and image odometry of a mission on `moon` (of seed `seed`)
    /// when `sensors = "rendered"`, with `segmenter` (default: the geometric one); `None`
    /// with the sensor model.
    pub fn rendered_sensors(
        &self,
        moon: &Moon,
        seed: u64,
        segmenter: Option<Box<dyn Segmenter>>,
    ) -> Result<Option<RenderedSensors>, MissionError> {
        if self.sensors == BoulderSensors::Model {
            return Ok(None);
        }
        let segmenter = segmenter
            .unwrap_or_else(|| Box::new(GeometricSegmenter::new(self.front_end.geometric.clone())));
        let front_end = FrontEnd::new(self.front_end.clone(), segmenter)?;
        let boulders =
            RenderedBoulders::new(moon, &self.render, seed, front_end, self.matching.clone())?;
        let odometry = match self.odometry {
            OdometrySource::Images => {
                let odometry = RenderedOdometry::new(&self.image_odometry, boulders.renderer())
                    .map_err(|e| {
                        MissionError::InvalidConfig(format!("perception.image_odometry: {e}"))
                    })?;
                Some(odometry)
            }
            OdometrySource::Model => None,
        };
        Ok(Some(RenderedSensors { boulders, odometry }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_toml_path() {
        let mut c = PerceptionConfig::default();
        c.render.sun_elevation_deg = -3.0;
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("perception.render.sun_elevation_deg"), "{e}");
        let mut c = PerceptionConfig::default();
        c.matching.match_size_fraction = 0.0;
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("perception.matching.match_size_fraction"), "{e}");
        let mut c = PerceptionConfig::default();
        c.image_odometry.wheel.noise_fraction = -0.05;
        let e = c.validate().unwrap_err().to_string();
        assert!(
            e.contains("perception.image_odometry.wheel.noise_fraction"),
            "{e}"
        );
        let c: PerceptionConfig = toml::from_str("sensors = \"rendered\"").unwrap();
        assert_eq!(c.sensors, BoulderSensors::Rendered);
        assert!(toml::from_str::<PerceptionConfig>("sensors = \"pixels\"").is_err());
    }
}
