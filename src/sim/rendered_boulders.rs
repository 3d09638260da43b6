//! The cameras' boulder detections from pixels instead of the sensor model.
//!
//! Per camera frame of a session, for each stereo pair of the sensor model ([`cameras`]:
//! front and back): render the pair from the true rover pose ([`Renderer`]) → run the
//! perception front end on it ([`FrontEnd`]) → keep its boulders within the sensor model's
//! depth window, moved to the rover frame with the radius the front end measured → score them
//! against the renderer's truth ([`score_frame`]) for the report ([`PerceptionSummary`]).
//!
//! Ground points and lander points still come from the sensor model
//! ([`crate::sim::sensors::observe`]); only the boulders are replaced.

use crate::perception::{FrontEnd, PerceptionError};
use crate::sim::moon::Moon;
use crate::sim::render::scoring::{score_frame, summarize, FrameScore, MatchConfig, Quantiles};
use crate::sim::render::{rover_from_left_optical, RenderConfig, RenderError, Renderer};
use crate::sim::sensors::{cameras, BoulderObservation, SensorConfig};
use nalgebra::{Isometry3, Point3};
use serde::Serialize;

/// Renders the camera frames of a mission and detects their boulders with the front end.
pub struct RenderedBoulders {
    renderer: Renderer,
    front_end: FrontEnd,
    matching: MatchConfig,
    /// Moon seed (recorded in the frame scores).
    seed: u64,
    /// Stereo pairs rendered so far (each pair's image noise is drawn from its index).
    pairs: u64,
    scores: Vec<FrameScore>,
    /// The first front-end failure (its pair gave no boulders).
    error: Option<PerceptionError>,
}

/// How the front end did on the mission's rendered frames (the mission report's
/// `perception`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PerceptionSummary {
    /// Segmenter name.
    pub segmenter: &'static str,
    /// Image width, pixels.
    pub width_px: usize,
    /// Stereo pairs rendered and processed (two per camera frame).
    pub pairs: usize,
    /// Counted truth rocks (summed over pairs; see [`MatchConfig`]).
    pub rocks: usize,
    /// Detections within the counted range (summed over pairs).
    pub detections: usize,
    /// Matched counted rocks over counted rocks.
    pub recall: f64,
    /// True detections over detections within range.
    pub precision: f64,
    /// Centroid error of the matched counted rocks, metres.
    pub centroid_error_m: Quantiles,
    /// Rendering time of one stereo pair (both views, without the truth), milliseconds.
    pub render_ms: Quantiles,
    /// Front-end time of one stereo pair (stereo, segmentation, boulders), milliseconds.
    pub front_end_ms: Quantiles,
}

impl RenderedBoulders {
    /// Render `moon` (of seed `seed`) with `render` and detect with `front_end`, scoring with
    /// `matching`.
    pub fn new(
        moon: &Moon,
        render: &RenderConfig,
        seed: u64,
        front_end: FrontEnd,
        matching: MatchConfig,
    ) -> Result<Self, RenderError> {
        Ok(RenderedBoulders {
            renderer: Renderer::new(moon, render, seed)?,
            front_end,
            matching,
            seed,
            pairs: 0,
            scores: Vec::new(),
            error: None,
        })
    }

    /// The boulders both stereo pairs see from `world_from_rover` (true pose) at simulator
    /// tick `tick`: the front end's detections with depth within the sensor model's
    /// `min_range_m..=max_range_m`, rover frame; `rock` is the rock each matched in the
    /// truth (diagnostics only).
    pub fn observe(
        &mut self,
        world_from_rover: &Isometry3<f64>,
        tick: usize,
        sensors: &SensorConfig,
    ) -> Vec<BoulderObservation> {
        let mut out = Vec::new();
        for camera in cameras() {
            let rover_from_left = rover_from_left_optical(&camera);
            let world_from_left = world_from_rover * rover_from_left;
            let frame = self
                .renderer
                .render_stereo_from(&world_from_left, self.pairs);
            self.pairs += 1;
            let result = match self.front_end.process(&frame.left, &frame.right) {
                Ok(result) => result,
                Err(e) => {
                    self.error.get_or_insert(e);
                    continue;
                }
            };
            let mut score = score_frame(&frame, &result.boulders, &self.matching);
            score.seed = self.seed;
            score.sun_elevation_deg = self.renderer.config().sun_elevation_deg;
            score.tick = tick;
            score.front_end_ms = result.timing.total_ms;
            for (b, outcome) in result.boulders.iter().zip(&score.detections) {
                let [x, y, z] = b.position_camera;
                let in_window = z >= sensors.min_range_m && z <= sensors.max_range_m;
                if !(in_window && b.size_m.is_finite() && b.size_m > 0.0) {
                    continue;
                }
                out.push(BoulderObservation {
                    camera: camera.id,
                    p_rover: rover_from_left * Point3::new(x, y, z),
                    radius_m: 0.5 * b.size_m,
                    rock: outcome.rock,
                });
            }
            self.scores.push(score);
        }
        out
    }

    /// The renderer (shared with the image odometry).
    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    /// Every processed pair's score, in order.
    pub fn scores(&self) -> &[FrameScore] {
        &self.scores
    }

    /// The first front-end failure so far, if any (taken: asked once).
    pub fn take_error(&mut self) -> Option<PerceptionError> {
        self.error.take()
    }

    /// Recall, precision, centroid error and timings over every pair so far.
    pub fn summary(&self) -> PerceptionSummary {
        let frames: Vec<&FrameScore> = self.scores.iter().collect();
        let all = summarize(&frames, (0.0, f64::INFINITY), &self.matching);
        let errors: Vec<f64> = frames
            .iter()
            .flat_map(|f| f.rocks.iter())
            .filter(|r| r.counted && r.range_m <= self.matching.max_range_m)
            .filter_map(|r| r.error_m)
            .collect();
        let render: Vec<f64> = frames.iter().map(|f| f.render_ms).collect();
        let front_end: Vec<f64> = frames.iter().map(|f| f.front_end_ms).collect();
        PerceptionSummary {
            segmenter: self.front_end.segmenter_name(),
            width_px: self.renderer.config().width(),
            pairs: frames.len(),
            rocks: all.rocks,
            detections: all.detections,
            recall: all.recall,
            precision: all.precision,
            centroid_error_m: Quantiles::of(&errors),
            render_ms: Quantiles::of(&render),
            front_end_ms: Quantiles::of(&front_end),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::{FrontEndConfig, GeometricSegmenter};
    use crate::sim::moon::MoonConfig;

    #[test]
    fn both_pairs_are_rendered_and_detections_land_in_the_rover_frame() {
        let moon = Moon::generate(&MoonConfig::default(), 3).unwrap();
        let render = RenderConfig {
            resolution_scale: 0.5,
            ..RenderConfig::default()
        };
        let config = FrontEndConfig::default();
        let segmenter = Box::new(GeometricSegmenter::new(config.geometric.clone()));
        let front_end = FrontEnd::new(config, segmenter).unwrap();
        let mut rendered =
            RenderedBoulders::new(&moon, &render, 3, front_end, MatchConfig::default()).unwrap();
        let (x, y) = moon.nearest_clear_position(4.5, 0.0, 1.0, 0.08);
        let pose = crate::sim::rover::RoverState::at_rest(x, y, 1.5).pose(&moon);
        let sensors = SensorConfig::default();
        let found = rendered.observe(&pose, 0, &sensors);
        assert_eq!(rendered.scores().len(), 2, "front and back pairs");
        assert!(rendered.take_error().is_none());
        for b in &found {
            let [front, back] = cameras();
            let camera = if b.camera == front.id { front } else { back };
            let p_camera = camera.rover_from_camera.inverse() * b.p_rover;
            assert!(p_camera.x >= sensors.min_range_m - 1e-9, "{b:?}");
            assert!(p_camera.x <= sensors.max_range_m + 1e-9, "{b:?}");
            assert!(b.radius_m > 0.0);
        }
        let s = rendered.summary();
        assert_eq!((s.pairs, s.width_px), (2, 640));
        assert!(s.render_ms.median > 0.0 && s.front_end_ms.median > 0.0);
    }
}
