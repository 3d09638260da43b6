//! The whole front end on one stereo pair: stereo → segmentation → boulders, timed.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::boulders::{boulders_from_masks, Boulder, BoulderConfig, Rejection};
use super::depth_split::split_by_depth;
use super::geometric::GeometricConfig;
use super::ground::{height_above_ground, HeightMap};
use super::relief_gate::{check_mask, trim_to_relief, ReliefGateConfig};
use super::segmenter::{SegmentInput, Segmenter};
use super::{compute_disparity_with, CameraMount, DisparityMap, GrayImage, Mask, PerceptionError};
use super::{StereoCamera, StereoConfig, StereoScratch};

/// Everything the front end can be configured with (printable / loadable as TOML).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FrontEndConfig {
    /// The stereo camera at full resolution.
    pub camera: StereoCamera,
    /// Where the left camera sits on the rover.
    pub mount: CameraMount,
    /// Semi-global matching.
    pub stereo: StereoConfig,
    /// The training-free segmenter.
    pub geometric: GeometricConfig,
    /// Masks to boulders.
    pub boulders: BoulderConfig,
    /// Decoding of an ONNX segmenter's outputs.
    pub onnx: super::onnx::YoloSegConfig,
    /// Decoding of the learned segmenter's outputs.
    pub learned: super::unet_decoder::UnetDecoderConfig,
    /// The stereo check of image-only segmenters' boulders (relief, foot, structure,
    /// shadow).
    pub relief: ReliefGateConfig,
    /// Splitting image-only segmenters' masks that span two depths.
    pub split: super::depth_split::DepthSplitConfig,
}

/// Wall-clock times of the stages, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrontEndTiming {
    /// Semi-global matching.
    pub stereo_ms: f64,
    /// Segmentation.
    pub segment_ms: f64,
    /// Masks to boulders.
    pub boulders_ms: f64,
    /// The whole front end.
    pub total_ms: f64,
}

/// What the front end found in one pair.
#[derive(Clone, Debug)]
pub struct FrameResult {
    /// The boulders, in mask order.
    pub boulders: Vec<Boulder>,
    /// Every mask the segmenter produced.
    pub masks: Vec<Mask>,
    /// For each mask: the index of its boulder, or why it was rejected.
    pub verdicts: Vec<Result<usize, Rejection>>,
    /// The disparity map.
    pub disparity: DisparityMap,
    /// Stage timings.
    pub timing: FrontEndTiming,
}

/// Stereo, a segmenter and the boulder stage, run on stereo pairs.
pub struct FrontEnd {
    config: FrontEndConfig,
    segmenter: Box<dyn Segmenter>,
    scratch: StereoScratch,
}

impl FrontEnd {
    /// A front end with this configuration and segmenter (validates the configuration).
    pub fn new(
        config: FrontEndConfig,
        segmenter: Box<dyn Segmenter>,
    ) -> Result<Self, PerceptionError> {
        config.stereo.validate()?;
        config.boulders.validate()?;
        config.relief.validate()?;
        config.split.validate()?;
        Ok(FrontEnd {
            config,
            segmenter,
            scratch: StereoScratch::default(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &FrontEndConfig {
        &self.config
    }

    /// The segmenter's name.
    pub fn segmenter_name(&self) -> &'static str {
        self.segmenter.name()
    }

    /// Run on one rectified pair (same size, a uniform scaling of the configured camera).
    pub fn process(
        &mut self,
        left: &GrayImage,
        right: &GrayImage,
    ) -> Result<FrameResult, PerceptionError> {
        let start = Instant::now();
        let camera = self.config.camera.for_size(left.width, left.height)?;
        let disparity =
            compute_disparity_with(left, right, &camera, &self.config.stereo, &mut self.scratch)?;
        let t_stereo = start.elapsed();
        let masks = self.segmenter.segment(&SegmentInput {
            left,
            disparity: &disparity,
            camera: &camera,
        })?;
        let image_only = !self.segmenter.checks_relief();
        let masks = if image_only {
            split_by_depth(&masks, &disparity, &self.config.split)
        } else {
            masks
        };
        let t_segment = start.elapsed();
        let check_relief = self.config.relief.enabled && image_only;
        let boulder_config = BoulderConfig {
            max_elongation: if check_relief {
                self.config.relief.max_elongation
            } else {
                self.config.boulders.max_elongation
            },
            ..self.config.boulders.clone()
        };
        // the heights above the ground the stereo check and the trimming judge by
        let heights = check_relief
            .then(|| height_above_ground(&disparity, &self.config.geometric.ground))
            .flatten();
        let trimmed = heights
            .as_ref()
            .and_then(|h| self.trimmed_masks(&masks, h, disparity.scale));
        let mut outcomes = boulders_from_masks(
            trimmed.as_deref().unwrap_or(&masks),
            &disparity,
            &camera,
            &self.config.mount,
            &boulder_config,
            Some((left, right)),
        );
        if let Some(heights) = &heights {
            self.apply_stereo_check(&masks, left, &disparity, heights, &mut outcomes);
        }
        let mut boulders = Vec::new();
        let verdicts = outcomes
            .into_iter()
            .map(|o| {
                o.map(|b| {
                    boulders.push(b);
                    boulders.len() - 1
                })
            })
            .collect();
        let total = start.elapsed();
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        Ok(FrameResult {
            boulders,
            masks,
            verdicts,
            disparity,
            timing: FrontEndTiming {
                stereo_ms: ms(t_stereo),
                segment_ms: ms(t_segment - t_stereo),
                boulders_ms: ms(total - t_segment),
                total_ms: ms(total),
            },
        })
    }

    /// The masks trimmed to the pixels that stand out of the ground
    /// ([`trim_to_relief`](super::relief_gate::trim_to_relief)); a mask that cannot be
    /// trimmed stays whole. `None` when trimming is off.
    fn trimmed_masks(
        &self,
        masks: &[Mask],
        heights: &HeightMap,
        scale: usize,
    ) -> Option<Vec<Mask>> {
        let gate = &self.config.relief;
        if gate.trim_fraction <= 0.0 {
            return None;
        }
        let min_pixels = self.config.boulders.min_area_px;
        let trim = |m: &Mask| trim_to_relief(m, heights, scale, gate, min_pixels);
        Some(
            masks
                .iter()
                .map(|m| trim(m).unwrap_or_else(|| m.clone()))
                .collect(),
        )
    }

    /// Rejects the boulders whose masks do not stand out of the ground, float, belong to a
    /// structure or lie in hard shadow (see [`relief_gate`](super::relief_gate)); without a
    /// ground estimate, nothing is judged.
    fn apply_stereo_check(
        &self,
        masks: &[Mask],
        left: &GrayImage,
        disparity: &DisparityMap,
        heights: &HeightMap,
        outcomes: &mut [Result<Boulder, Rejection>],
    ) {
        let (geometric, gate) = (&self.config.geometric, &self.config.relief);
        for (mask, outcome) in masks.iter().zip(outcomes.iter_mut()) {
            let Ok(boulder) = outcome else { continue };
            let depth_m = boulder.depth_m;
            let verdict = check_mask(mask, left, depth_m, heights, disparity, geometric, gate);
            if let Err(why) = verdict {
                *outcome = Err(why);
            }
        }
    }
}
