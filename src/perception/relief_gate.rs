//! The stereo check of an image-only segmenter's boulders: a boulder stands out of the
//! ground, sits on it, is no part of a structure and is not a shadow.
//!
//! A segmenter that looks only at the image (the learned U-Net, an ONNX model) takes dark
//! patches of flat ground for rocks (the real LAC images are full of micro-relief shadows a
//! rendered moon never showed it) and the lander's patterned sides too. Stereo tells them
//! apart, on the heights above the local ground
//! ([`height_above_ground`](super::ground::height_above_ground)) under each boulder's mask:
//! 1. **relief**: a high quantile of the heights reaches a threshold that grows with the
//!    square of the range, as the height noise of stereo does ([`Rejection::Flat`]);
//! 2. **base**: a low quantile is within the geometric segmenter's `max_base_height_m` of
//!    the ground: boulders do not float ([`Rejection::Floating`]);
//! 3. **structure**: nothing higher than its `max_height_m` stands straight above the mask
//!    at its depth (the geometric segmenter's own rule, `geometric::under_structure`):
//!    [`Rejection::Structure`];
//! 4. **shadow**: more than the geometric segmenter's `max_shadow_fraction` of the mask's
//!    pixels are in hard shadow and fewer than its `min_sunlit_fraction` are sunlit (its own
//!    rule again: a shadow, where stereo matches only noise): [`Rejection::Shadow`].
//!
//! The geometric segmenter needs none of it: its regions are grown from heights, under
//! the same rules.

use serde::{Deserialize, Serialize};

use super::boulders::Rejection;
use super::geometric::{under_structure, GeometricConfig};
use super::ground::HeightMap;
use super::{DisparityMap, GrayImage, Mask, PerceptionError};

/// Settings of the stereo check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReliefGateConfig {
    /// Check the boulders of image-only segmenters (`learned`, `onnx`).
    pub enabled: bool,
    /// Apply rule 4 (shadow) too.
    pub reject_shadows: bool,
    /// Height above the local ground the mask must reach, metres, at zero range.
    pub min_relief_m: f64,
    /// The threshold grows by this much per square metre of range (metres per m²).
    pub relief_per_range_sq: f64,
    /// The quantile (0–1) of the mask's heights compared with the threshold: high, so a
    /// rock's top counts, but not the maximum, which is a stereo outlier as often as not.
    pub quantile: f64,
    /// The quantile (0–1) of the mask's heights that must lie within the geometric
    /// segmenter's `max_base_height_m` of the ground: low, but not the minimum (a mask's
    /// edge may spill onto the ground behind).
    pub base_quantile: f64,
    /// A mask with fewer pixels with a height than this is not judged (kept).
    pub min_samples: usize,
    /// The boulder stage's elongation limit for these segmenters' masks, in place of
    /// `boulders.max_elongation`: that limit keeps the shadows and terrain edges out of the
    /// geometric segmenter's regions; here the relief check does, and a small rock seen at a
    /// grazing angle is wide and low.
    pub max_elongation: f64,
    /// Before the boulder stage, trim each mask to its pixels standing at least
    /// `trim_fraction` of the mask's relief (its `quantile` height) above the ground: the
    /// rock, without the ground a coarse mask spills onto (0: no trimming).
    pub trim_fraction: f64,
}

impl Default for ReliefGateConfig {
    fn default() -> Self {
        ReliefGateConfig {
            enabled: true,
            reject_shadows: true,
            // chosen on rendered tuning seeds 11-15 (docs/design/relief-gate.md)
            min_relief_m: 0.01,
            relief_per_range_sq: 0.001,
            quantile: 0.9,
            base_quantile: 0.1,
            min_samples: 3,
            max_elongation: 16.0,
            // chosen on rendered tuning seeds 11-15 (docs/design/relief-gate.md)
            trim_fraction: 0.1,
        }
    }
}

impl ReliefGateConfig {
    /// Checks the ranges; errors name the TOML path (`relief.*`).
    pub fn validate(&self) -> Result<(), PerceptionError> {
        let bad = |m: &str| Err(PerceptionError::Config(format!("relief.{m}")));
        if !(self.min_relief_m.is_finite() && self.min_relief_m >= 0.0) {
            return bad("min_relief_m must be finite and ≥ 0");
        }
        if !(self.relief_per_range_sq.is_finite() && self.relief_per_range_sq >= 0.0) {
            return bad("relief_per_range_sq must be finite and ≥ 0");
        }
        if !(0.0..=1.0).contains(&self.quantile) || !(0.0..=1.0).contains(&self.base_quantile) {
            return bad("quantile and base_quantile must be in [0, 1]");
        }
        if self.max_elongation.is_nan() || self.max_elongation < 1.0 {
            return bad("max_elongation must be ≥ 1");
        }
        Ok(())
    }

    /// The relief a boulder at `range_m` must reach, metres.
    pub fn threshold_at(&self, range_m: f64) -> f64 {
        self.min_relief_m + self.relief_per_range_sq * range_m * range_m
    }
}

/// What stereo says about a boulder's mask at `depth_m`: `Ok` when it stands out of the
/// ground, sits on it, is no part of a structure and is not a shadow (see the module
/// documentation);
/// a mask with fewer than `min_samples` heights is not judged. `heights` is on the grid
/// of `disparity`; `geometric` gives the base, structure and shadow limits; `left` is the
/// image the mask is in.
pub fn check_mask(
    mask: &Mask,
    left: &GrayImage,
    depth_m: f64,
    heights: &HeightMap,
    disparity: &DisparityMap,
    geometric: &GeometricConfig,
    config: &ReliefGateConfig,
) -> Result<(), Rejection> {
    let cells = grid_cells(mask, heights.width, heights.height, disparity.scale);
    let Some(mut values) = judged_heights(&cells, heights, config) else {
        return Ok(());
    };
    if (quantile(&mut values, config.quantile) as f64) < config.threshold_at(depth_m) {
        return Err(Rejection::Flat);
    }
    if quantile(&mut values, config.base_quantile) as f64 > geometric.max_base_height_m {
        return Err(Rejection::Floating);
    }
    let (hag, data, w) = (&heights.above_ground_m, &disparity.data, disparity.width);
    if under_structure(&cells, hag, data, w, &disparity.camera, geometric) {
        return Err(Rejection::Structure);
    }
    if config.reject_shadows && in_shadow(mask, left, geometric) {
        return Err(Rejection::Shadow);
    }
    Ok(())
}

/// `mask` trimmed to its pixels whose height above the ground (`heights`, on a grid of
/// `scale` image pixels a side) reaches `config.trim_fraction` of the mask's relief (its
/// `config.quantile` height); `None` when trimming is off, the mask has too few heights to
/// judge, or fewer than a quarter of its pixels (or `min_pixels`) would be left.
pub fn trim_to_relief(
    mask: &Mask,
    heights: &HeightMap,
    scale: usize,
    config: &ReliefGateConfig,
    min_pixels: usize,
) -> Option<Mask> {
    if config.trim_fraction <= 0.0 {
        return None;
    }
    let scale = scale.max(1);
    let height_at = |(x, y): (usize, usize)| {
        let (gx, gy) = (x / scale, y / scale);
        (gx < heights.width && gy < heights.height)
            .then(|| heights.above_ground_m[gy * heights.width + gx])
            .filter(|v| v.is_finite())
    };
    let cells = grid_cells(mask, heights.width, heights.height, scale);
    let mut values = judged_heights(&cells, heights, config)?;
    let cut = config.trim_fraction as f32 * quantile(&mut values, config.quantile);
    let kept: Vec<(usize, usize)> = mask
        .pixels()
        .filter(|&px| height_at(px).is_some_and(|h| h >= cut))
        .collect();
    (kept.len() >= min_pixels.max(mask.area() / 4))
        .then(|| Mask::from_pixels(&kept, mask.score))
        .flatten()
}

/// Rule 4: mostly in hard shadow, without a sunlit face (the geometric segmenter's rule on
/// the mask's grey levels).
fn in_shadow(mask: &Mask, left: &GrayImage, geometric: &GeometricConfig) -> bool {
    let grey = mask
        .pixels()
        .filter(|&(x, y)| x < left.width && y < left.height)
        .map(|(x, y)| left.get(x, y));
    let (shadow, lit) = geometric.shade_fractions(grey);
    geometric.is_shadow(shadow, lit)
}

/// The finite heights above the ground of `cells`; `None` when fewer than the
/// `min_samples` a judgement needs.
fn judged_heights(
    cells: &[usize],
    heights: &HeightMap,
    config: &ReliefGateConfig,
) -> Option<Vec<f32>> {
    let values: Vec<f32> = cells
        .iter()
        .map(|&p| heights.above_ground_m[p])
        .filter(|v| v.is_finite())
        .collect();
    (values.len() >= config.min_samples.max(1)).then_some(values)
}

/// The disparity-grid cells (`scale` image pixels a side) holding `mask`'s pixels, each
/// once, in order.
fn grid_cells(mask: &Mask, width: usize, height: usize, scale: usize) -> Vec<usize> {
    let scale = scale.max(1);
    let mut cells: Vec<usize> = mask
        .pixels()
        .map(|(x, y)| (x / scale, y / scale))
        .filter(|&(gx, gy)| gx < width && gy < height)
        .map(|(gx, gy)| gy * width + gx)
        .collect();
    cells.sort_unstable();
    cells.dedup();
    cells
}

/// The value at rank `round(q · (n − 1))` of `values` (not empty), reordering them.
fn quantile(values: &mut [f32], q: f64) -> f32 {
    let k = ((values.len() - 1) as f64 * q).round() as usize;
    *values.select_nth_unstable_by(k, f32::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::StereoCamera;
    use nalgebra::Vector3;

    const W: usize = 8;

    /// An 8 × 8 grid at one disparity (about 4.9 m away), the heights given per cell.
    fn scene(heights: impl Fn(usize, usize) -> f32) -> (HeightMap, DisparityMap) {
        let camera = StereoCamera::ipex();
        let above_ground_m = (0..W * W).map(|p| heights(p % W, p / W)).collect();
        let map = HeightMap {
            width: W,
            height: W,
            depth_m: vec![4.9; W * W],
            above_ground_m,
            normal: Vector3::z(),
        };
        let disparity = DisparityMap {
            width: W,
            height: W,
            data: vec![30.0; W * W],
            scale: 1,
            camera,
        };
        (map, disparity)
    }

    /// The mask of columns 2–4, rows 5–7.
    fn mask() -> Mask {
        let px: Vec<(usize, usize)> = (5..8).flat_map(|y| (2..5).map(move |x| (x, y))).collect();
        Mask::from_pixels(&px, 1.0).unwrap()
    }

    fn judge(heights: impl Fn(usize, usize) -> f32) -> Result<(), Rejection> {
        judge_in(heights, 90)
    }

    /// As [`judge`], the image one grey level.
    fn judge_in(heights: impl Fn(usize, usize) -> f32, grey: u8) -> Result<(), Rejection> {
        let (map, disparity) = scene(heights);
        let geometric = GeometricConfig::default();
        let left = GrayImage::new(W, W, vec![grey; W * W]).unwrap();
        check_mask(
            &mask(),
            &left,
            4.9,
            &map,
            &disparity,
            &geometric,
            &ReliefGateConfig::default(),
        )
    }

    #[test]
    fn a_rock_on_the_ground_passes() {
        // its top 10 cm up, its foot on the ground
        assert_eq!(judge(|_, y| if y == 5 { 0.1 } else { 0.01 }), Ok(()));
    }

    #[test]
    fn flat_floating_and_structure_masks_are_rejected() {
        assert_eq!(judge(|_, _| 0.01), Err(Rejection::Flat));
        assert_eq!(judge(|_, _| 0.5), Err(Rejection::Floating));
        // a 2 m high thing straight above the mask, at its depth
        let under = |x: usize, y: usize| if (x, y) == (3, 1) { 2.0 } else { 0.1 };
        assert_eq!(judge(under), Err(Rejection::Structure));
        // beside it, not above: a rock
        let beside = |x: usize, y: usize| if (x, y) == (7, 1) { 2.0 } else { 0.1 };
        assert_eq!(judge(beside), Ok(()));
    }

    #[test]
    fn a_mask_in_hard_shadow_without_a_lit_face_is_rejected() {
        let rock = |_: usize, y: usize| if y == 5 { 0.1 } else { 0.01 };
        assert_eq!(judge_in(rock, 10), Err(Rejection::Shadow));
        assert_eq!(judge_in(rock, 200), Ok(()));
    }

    #[test]
    fn a_mask_without_heights_is_not_judged() {
        assert_eq!(judge(|_, _| f32::NAN), Ok(()));
    }

    #[test]
    fn the_threshold_grows_with_the_square_of_the_range() {
        let c = ReliefGateConfig::default();
        assert!((c.threshold_at(0.0) - 0.01).abs() < 1e-12);
        assert!((c.threshold_at(5.0) - 0.035).abs() < 1e-12);
        assert!(ReliefGateConfig { quantile: 1.5, ..c }.validate().is_err());
    }

    #[test]
    fn trimming_keeps_the_pixels_that_stand_out_of_the_ground() {
        // the mask's top row stands 6 cm high, the two rows below lie on the ground
        let (heights, _) = scene(|_, y| if y == 5 { 0.06 } else { 0.0 });
        let config = ReliefGateConfig::default();
        let trimmed = trim_to_relief(&mask(), &heights, 1, &config, 1).unwrap();
        assert_eq!((trimmed.y0, trimmed.height, trimmed.area()), (5, 1, 3));
        // off, or too little left (fewer than a quarter of the pixels, or min_pixels)
        let off = ReliefGateConfig {
            trim_fraction: 0.0,
            ..config.clone()
        };
        assert!(trim_to_relief(&mask(), &heights, 1, &off, 1).is_none());
        assert!(trim_to_relief(&mask(), &heights, 1, &config, 4).is_none());
        // one stray high pixel is no relief: its 0.9 quantile is the ground, all pixels stay
        let (one, _) = scene(|x, y| if (x, y) == (2, 5) { 0.06 } else { 0.0 });
        let kept = trim_to_relief(&mask(), &one, 1, &config, 1).unwrap();
        assert_eq!(kept.area(), 9);
    }
}
