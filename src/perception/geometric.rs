//! Training-free boulder segmentation from stereo depth.
//!
//! A boulder is what stands out of the local ground surface ([`ground`](super::ground)):
//! pixels higher than a seed threshold start a region, which grows (hysteresis) into
//! neighbours that are still above a lower threshold and at a similar disparity (so a
//! boulder does not merge with one behind it). The image helps where depth alone cannot
//! tell: regions lying mostly in hard shadow (black, where stereo finds only noise) are
//! dropped, and a region that also has a sunlit face scores higher. Regions reaching far
//! above the ground (the lander, the rover's own parts) or floating above it are no
//! boulders.

use serde::{Deserialize, Serialize};

use nalgebra::Point3;

use super::ground::{height_above_ground, GroundConfig, HeightMap};
use super::segmenter::{SegmentInput, Segmenter};
use super::{DisparityMap, Mask, PerceptionError};

/// Settings of the geometric segmenter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GeometricConfig {
    /// The ground estimate.
    pub ground: GroundConfig,
    /// Height above the local ground that starts a region, metres, at zero range.
    pub seed_height_m: f64,
    /// Height above ground that keeps growing a region, metres, at zero range.
    pub grow_height_m: f64,
    /// Both thresholds grow by this much per metre of range (stereo noise grows with it).
    pub height_per_range: f64,
    /// And by this much per square metre of range (metres per m²): height noise from stereo
    /// grows faster than linearly far out, where a linear term strict enough for the far
    /// field would hide the small rocks near by.
    pub height_per_range_sq: f64,
    /// Disparity difference (fraction of the disparity) that still connects neighbours.
    pub connect_disparity_frac: f64,
    /// A region stops growing this far (metres, in 3D) from its seed: boulders are compact,
    /// terrain ridges are not.
    pub max_extent_m: f64,
    /// Regions smaller than this (disparity-map pixels) are dropped.
    pub min_region_px: usize,
    /// Regions reaching higher than this above the ground are structures, not boulders.
    pub max_height_m: f64,
    /// Regions whose lowest pixel is higher than this above the ground float: not boulders.
    pub max_base_height_m: f64,
    /// Gray level below which a pixel is in hard shadow.
    pub shadow_level: u8,
    /// Regions with more than this fraction of their pixels in hard shadow are dropped,
    /// unless they also show a sunlit face (see `min_sunlit_fraction`).
    pub max_shadow_fraction: f64,
    /// Gray level above which a pixel is sunlit.
    pub sunlit_level: u8,
    /// A region with at least this fraction of sunlit pixels has a lit face: a rock whose
    /// front is in its own shadow, not stereo noise inside a shadow.
    pub min_sunlit_fraction: f64,
    /// Once a region is found it extends down its vertical face to the ground: into
    /// neighbours below or beside it (within its columns) that are above the ground at all
    /// and within this many disparity pixels of their neighbour in the region. The ground
    /// in front of a rock changes disparity by about baseline / camera height (0.65 px) per
    /// row, a rock's face by none, so the extension stops at the rock's foot.
    pub face_disparity_px: f32,
    /// Regions touching (same disparity, adjacent pixels) something higher than
    /// `max_height_m` are parts of a structure (the lander's feet and boxes): dropped.
    pub reject_touching_structures: bool,
    /// Regions with something higher than `max_height_m` above the ground straight above
    /// them in the image (within their columns), at their own depth (disparity within
    /// 15 %), and at most this many metres above their top, stand under or against a
    /// structure (the boxes and feet under the lander's deck): dropped. Natural terrain
    /// has nothing at a rock's own depth a metre over the ground above it: what lies above
    /// a rock in the image is farther away (smaller disparity) or sky. 0 disables the check.
    pub structure_overhead_m: f64,
}

impl Default for GeometricConfig {
    fn default() -> Self {
        GeometricConfig {
            ground: GroundConfig::default(),
            // chosen on rendered tuning seeds 11-15 (docs/design/front-end-recall.md)
            seed_height_m: 0.035,
            grow_height_m: 0.015,
            height_per_range: 0.0,
            height_per_range_sq: 0.0015,
            connect_disparity_frac: 0.08,
            max_extent_m: 1.2,
            min_region_px: 12,
            max_height_m: 1.0,
            max_base_height_m: 0.2,
            shadow_level: 25,
            max_shadow_fraction: 0.5,
            sunlit_level: 110,
            min_sunlit_fraction: 0.02,
            face_disparity_px: 0.4,
            reject_touching_structures: true,
            structure_overhead_m: 3.0,
        }
    }
}

impl GeometricConfig {
    /// A height threshold, `base` metres at zero range, at range `z_m`:
    /// `base + height_per_range · z + height_per_range_sq · z²`.
    pub fn threshold_at(&self, base: f64, z_m: f64) -> f64 {
        base + self.height_per_range * z_m + self.height_per_range_sq * z_m * z_m
    }

    /// The fractions of `grey` levels in hard shadow (below `shadow_level`) and sunlit
    /// (above `sunlit_level`); zeros when there are none.
    pub fn shade_fractions(&self, grey: impl Iterator<Item = u8>) -> (f64, f64) {
        let (mut n, mut dark, mut lit) = (0usize, 0usize, 0usize);
        for v in grey {
            n += 1;
            dark += usize::from(v < self.shadow_level);
            lit += usize::from(v > self.sunlit_level);
        }
        let n = n.max(1) as f64;
        (dark as f64 / n, lit as f64 / n)
    }

    /// The shadow rule: more than `max_shadow_fraction` in hard shadow and less than
    /// `min_sunlit_fraction` sunlit (fractions from [`Self::shade_fractions`]) is a shadow,
    /// where stereo matches only noise, not a rock whose front is in its own shadow.
    pub fn is_shadow(&self, shadow: f64, lit: f64) -> bool {
        shadow > self.max_shadow_fraction && lit < self.min_sunlit_fraction
    }
}

/// The training-free geometric segmenter (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct GeometricSegmenter {
    /// Its settings.
    pub config: GeometricConfig,
}

impl GeometricSegmenter {
    /// A segmenter with these settings.
    pub fn new(config: GeometricConfig) -> Self {
        GeometricSegmenter { config }
    }
}

impl Segmenter for GeometricSegmenter {
    fn name(&self) -> &'static str {
        "geometric"
    }

    fn checks_relief(&self) -> bool {
        true
    }

    fn segment(&mut self, input: &SegmentInput<'_>) -> Result<Vec<Mask>, PerceptionError> {
        Ok(segment_geometric(input, &self.config))
    }
}

/// Why the geometric segmenter dropped a grown region (diagnostics).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum RegionDrop {
    /// Fewer pixels than `min_region_px`.
    TooSmall,
    /// Touches, stands near or under something higher than `max_height_m` (a structure).
    Structure,
    /// Reaches higher than `max_height_m` above the ground.
    TooHigh,
    /// Its lowest pixel floats more than `max_base_height_m` above the ground.
    Floating,
    /// Mostly in hard shadow without a lit face.
    Shadow,
}

/// A grown region of the geometric segmenter and what became of it.
#[derive(Clone, Debug)]
pub struct Region {
    /// Its pixels, indices into the disparity map (`y * width + x`).
    pub pixels: Vec<usize>,
    /// Its mask in left-image pixels, or why it was dropped.
    pub outcome: Result<Mask, RegionDrop>,
}

/// Masks (in left-image pixels) of what stands out of the ground.
pub fn segment_geometric(input: &SegmentInput<'_>, config: &GeometricConfig) -> Vec<Mask> {
    let mut masks = Vec::new();
    segment_geometric_with(input, config, |_, outcome| {
        if let Ok(mask) = outcome {
            masks.push(mask);
        }
    });
    masks
}

/// Every grown region with its outcome (kept as a mask or dropped, and why), in seed
/// order: [`segment_geometric`] with its diagnostics.
pub fn segment_geometric_regions(
    input: &SegmentInput<'_>,
    config: &GeometricConfig,
) -> Vec<Region> {
    let mut regions = Vec::new();
    segment_geometric_with(input, config, |pixels, outcome| {
        regions.push(Region {
            pixels: pixels.to_vec(),
            outcome,
        })
    });
    regions
}

/// The segmenter's loop: grows every region from its seed and hands each (pixels, outcome)
/// to `emit` in seed order.
fn segment_geometric_with(
    input: &SegmentInput<'_>,
    config: &GeometricConfig,
    mut emit: impl FnMut(&[usize], Result<Mask, RegionDrop>),
) {
    let disparity = input.disparity;
    let Some(heights) = height_above_ground(disparity, &config.ground) else {
        return;
    };
    let (w, h) = (disparity.width, disparity.height);
    let scene = Scene {
        config,
        disparity,
        heights: &heights,
        intensity: intensity_at_disparity_scale(input),
    };
    let hag = &heights.above_ground_m;
    let structure_peak = if config.reject_touching_structures {
        component_peaks(
            hag,
            &disparity.data,
            w,
            h,
            |i| scene.threshold(config.grow_height_m, i),
            config,
        )
    } else {
        vec![f32::MIN; w * h]
    };
    let mut label = vec![u32::MAX; w * h];
    let mut next_id = 1u32;
    let mut stack = Vec::new();
    let mut region = Vec::new();
    for seed in 0..w * h {
        let is_seed = hag[seed] > scene.threshold(config.seed_height_m, seed);
        if label[seed] != u32::MAX || !is_seed {
            continue;
        }
        let id = next_id;
        next_id += 1;
        let touches_structure = structure_peak[seed] > config.max_height_m as f32
            || (config.reject_touching_structures
                && near_structure(
                    seed,
                    hag,
                    &disparity.data,
                    (w, h),
                    &disparity.camera,
                    config,
                ));
        scene.grow(seed, id, &mut label, &mut stack, &mut region);
        if region.len() < config.min_region_px {
            emit(&region, Err(RegionDrop::TooSmall));
            continue;
        }
        if touches_structure && config.reject_touching_structures {
            emit(&region, Err(RegionDrop::Structure));
            continue;
        }
        extend_down_face(
            &mut region,
            &mut label,
            id,
            hag,
            &disparity.data,
            (w, h),
            scene.foot_rows(seed),
            config,
        );
        let mask = scene.boulder_score(&region, seed).and_then(|score| {
            let pixels: Vec<(usize, usize)> = region.iter().map(|&p| (p % w, p / w)).collect();
            Mask::from_pixels(&pixels, score)
                .map(|m| m.upscaled(disparity.scale))
                .ok_or(RegionDrop::TooSmall)
        });
        emit(&region, mask);
    }
}

/// The left image's intensity at the disparity map's resolution (mean of each block).
fn intensity_at_disparity_scale(input: &SegmentInput<'_>) -> Vec<u8> {
    let disparity = input.disparity;
    let (w, h) = (disparity.width, disparity.height);
    let scale = disparity.scale;
    if scale == 1 {
        return input.left.data.clone();
    }
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0u32;
            for dy in 0..scale {
                for dx in 0..scale {
                    s += input.left.get(x * scale + dx, y * scale + dy) as u32;
                }
            }
            out[y * w + x] = (s / (scale * scale) as u32) as u8;
        }
    }
    out
}

/// What the segmenter reads at every pixel of the disparity map.
struct Scene<'a> {
    config: &'a GeometricConfig,
    disparity: &'a DisparityMap,
    heights: &'a HeightMap,
    /// The left image at the disparity map's resolution.
    intensity: Vec<u8>,
}

impl Scene<'_> {
    /// A height threshold (`base` metres at zero range) at pixel `i`'s range.
    fn threshold(&self, base: f64, i: usize) -> f32 {
        self.config
            .threshold_at(base, self.heights.depth_m[i] as f64) as f32
    }

    /// Pixel `p` in 3D, camera frame.
    fn point(&self, p: usize) -> Point3<f64> {
        let w = self.disparity.width;
        let z = self.heights.depth_m[p] as f64;
        self.disparity
            .camera
            .back_project((p % w) as f64, (p / w) as f64, z)
    }

    /// Grows the region of `seed` (labelled `id`) into `region`: neighbours above the grow
    /// threshold, at a similar disparity and within `max_extent_m` of the seed.
    fn grow(
        &self,
        seed: usize,
        id: u32,
        label: &mut [u32],
        stack: &mut Vec<usize>,
        region: &mut Vec<usize>,
    ) {
        let config = self.config;
        let (w, h) = (self.disparity.width, self.disparity.height);
        let data = &self.disparity.data;
        let hag = &self.heights.above_ground_m;
        let seed_point = self.point(seed);
        let max_extent2 = config.max_extent_m * config.max_extent_m;
        region.clear();
        label[seed] = id;
        stack.push(seed);
        while let Some(p) = stack.pop() {
            region.push(p);
            let (px, py) = ((p % w) as isize, (p / w) as isize);
            let dp = data[p];
            let tol = (config.connect_disparity_frac as f32 * dp).max(0.75);
            for dy in -1..=1isize {
                for dx in -1..=1isize {
                    let (qx, qy) = (px + dx, py + dy);
                    if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                        continue;
                    }
                    let q = qy as usize * w + qx as usize;
                    if label[q] == u32::MAX
                        && hag[q] > self.threshold(config.grow_height_m, q)
                        && (data[q] - dp).abs() <= tol
                        && (self.point(q) - seed_point).norm_squared() <= max_extent2
                    {
                        label[q] = id;
                        stack.push(q);
                    }
                }
            }
        }
    }

    /// Rows below a region (seeded at `seed`) its foot may reach: the grow threshold's
    /// height at the seed's range, in rows, plus one.
    fn foot_rows(&self, seed: usize) -> usize {
        let z_seed = self.heights.depth_m[seed] as f64;
        (self.threshold(self.config.grow_height_m, seed) as f64 * self.disparity.camera.fy
            / z_seed.max(0.1))
        .ceil() as usize
            + 1
    }

    /// The score of a grown region as a boulder, or why it is no boulder: too high,
    /// floating, under a structure, or lying in hard shadow without a lit face.
    fn boulder_score(&self, region: &[usize], seed: usize) -> Result<f32, RegionDrop> {
        let config = self.config;
        let hag = &self.heights.above_ground_m;
        let intensity = &self.intensity;
        let peak = region.iter().map(|&p| hag[p]).fold(f32::MIN, f32::max) as f64;
        let base = region.iter().map(|&p| hag[p]).fold(f32::MAX, f32::min) as f64;
        let (shadow, lit) = config.shade_fractions(region.iter().map(|&p| intensity[p]));
        let (w, data, camera) = (
            self.disparity.width,
            &self.disparity.data,
            &self.disparity.camera,
        );
        if peak > config.max_height_m {
            return Err(RegionDrop::TooHigh);
        }
        if base > config.max_base_height_m {
            return Err(RegionDrop::Floating);
        }
        if config.reject_touching_structures
            && under_structure(region, hag, data, w, camera, config)
        {
            return Err(RegionDrop::Structure);
        }
        if config.is_shadow(shadow, lit) {
            return Err(RegionDrop::Shadow);
        }
        // sunlit face: a clearly brighter part than the region's median
        let mut values: Vec<u8> = region.iter().map(|&p| intensity[p]).collect();
        let mid = values.len() / 2;
        let median = *values.select_nth_unstable(mid).1;
        let sunlit = values
            .iter()
            .filter(|&&v| v as f64 > 1.3 * median as f64 + 10.0)
            .count() as f64
            / values.len() as f64;
        let z = self.heights.depth_m[seed] as f64;
        let prominence = peak / config.threshold_at(config.seed_height_m, z);
        let score = ((0.4 + 0.15 * prominence.min(4.0) + 0.3 * (sunlit * 4.0).min(1.0))
            * (1.0 - shadow).max(lit))
        .clamp(0.0, 1.0);
        Ok(score as f32)
    }
}

/// Whether something higher than `max_height_m` stands within half a metre (in the image,
/// at a similar disparity) of the seed: the feet, boxes and struts of the lander.
fn near_structure(
    seed: usize,
    hag: &[f32],
    disparity: &[f32],
    (w, h): (usize, usize),
    camera: &super::StereoCamera,
    config: &GeometricConfig,
) -> bool {
    let d0 = disparity[seed];
    let Some(z) = camera.depth_from_disparity(d0 as f64) else {
        return false;
    };
    let r = (0.5 * camera.fy / z).ceil() as usize;
    let (sx, sy) = (seed % w, seed / w);
    let tol = 0.15 * d0;
    (sy.saturating_sub(r)..(sy + r + 1).min(h)).any(|y| {
        (sx.saturating_sub(r)..(sx + r + 1).min(w)).any(|x| {
            let q = y * w + x;
            hag[q] > config.max_height_m as f32 && (disparity[q] - d0).abs() <= tol
        })
    })
}

/// Whether something higher than `max_height_m` above the ground stands straight above the
/// region in the image (its columns, up to `structure_overhead_m` above its top row) at the
/// region's depth (disparity within 15 % of the region's median): the region lies under or
/// against a structure (see [`GeometricConfig::structure_overhead_m`]).
pub(crate) fn under_structure(
    region: &[usize],
    hag: &[f32],
    disparity: &[f32],
    w: usize,
    camera: &super::StereoCamera,
    config: &GeometricConfig,
) -> bool {
    if config.structure_overhead_m <= 0.0 || region.is_empty() {
        return false;
    }
    let mut values: Vec<f32> = region
        .iter()
        .map(|&p| disparity[p])
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if values.is_empty() {
        return false;
    }
    let mid = values.len() / 2;
    let d0 = *values.select_nth_unstable_by(mid, f32::total_cmp).1;
    let Some(z) = camera.depth_from_disparity(d0 as f64) else {
        return false;
    };
    let x_min = region.iter().map(|&p| p % w).min().unwrap_or(0);
    let x_max = region.iter().map(|&p| p % w).max().unwrap_or(0);
    let y_top = region.iter().map(|&p| p / w).min().unwrap_or(0);
    let rows = (config.structure_overhead_m * camera.fy / z).ceil() as usize;
    let tol = 0.15 * d0;
    (y_top.saturating_sub(rows)..y_top).any(|y| {
        (x_min..=x_max).any(|x| {
            let q = y * w + x;
            hag[q] > config.max_height_m as f32 && (disparity[q] - d0).abs() <= tol
        })
    })
}

/// For each pixel above its grow threshold, the highest height above ground in its
/// connected component (neighbours at a similar disparity, no extent limit); `f32::MIN`
/// elsewhere. A boulder candidate whose component reaches higher than a boulder can be is
/// part of a structure (a box at the lander's foot).
fn component_peaks(
    hag: &[f32],
    disparity: &[f32],
    w: usize,
    h: usize,
    grow_threshold: impl Fn(usize) -> f32,
    config: &GeometricConfig,
) -> Vec<f32> {
    let mut peak = vec![f32::MIN; w * h];
    let mut seen = vec![false; w * h];
    let mut stack = Vec::new();
    let mut component = Vec::new();
    for start in 0..w * h {
        if seen[start] || hag[start].is_nan() || hag[start] <= grow_threshold(start) {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        component.clear();
        let mut top = f32::MIN;
        while let Some(p) = stack.pop() {
            component.push(p);
            top = top.max(hag[p]);
            let (px, py) = ((p % w) as isize, (p / w) as isize);
            let dp = disparity[p];
            let tol = (config.connect_disparity_frac as f32 * dp).max(0.75);
            for dy in -1..=1isize {
                for dx in -1..=1isize {
                    let (qx, qy) = (px + dx, py + dy);
                    if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                        continue;
                    }
                    let q = qy as usize * w + qx as usize;
                    if !seen[q] && hag[q] > grow_threshold(q) && (disparity[q] - dp).abs() <= tol {
                        seen[q] = true;
                        stack.push(q);
                    }
                }
            }
        }
        for &p in &component {
            peak[p] = top;
        }
    }
    peak
}

/// Extend a region down its vertical face (see [`GeometricConfig::face_disparity_px`]):
/// breadth-first from its pixels into unlabelled neighbours below or beside them, within the
/// region's columns, that are above the ground and at nearly the same disparity.
fn extend_down_face(
    region: &mut Vec<usize>,
    label: &mut [u32],
    id: u32,
    hag: &[f32],
    disparity: &[f32],
    (w, h): (usize, usize),
    foot_rows: usize,
    config: &GeometricConfig,
) {
    if config.face_disparity_px <= 0.0 || region.is_empty() {
        return;
    }
    let x_min = region.iter().map(|&p| p % w).min().unwrap_or(0);
    let x_max = region.iter().map(|&p| p % w).max().unwrap_or(0);
    // the foot is at most the grow threshold's height (in rows) below the region
    let y_max = region.iter().map(|&p| p / w).max().unwrap_or(0) + foot_rows;
    let mut next = 0;
    while next < region.len() {
        let p = region[next];
        next += 1;
        let (px, py) = (p % w, p / w);
        let dp = disparity[p];
        for (dx, dy) in [(-1isize, 0isize), (1, 0), (-1, 1), (0, 1), (1, 1)] {
            let (qx, qy) = (px as isize + dx, py as isize + dy);
            if qx < x_min as isize
                || qx > x_max as isize
                || qy < 0
                || qy >= h.min(y_max + 1) as isize
            {
                continue;
            }
            let q = qy as usize * w + qx as usize;
            if label[q] == u32::MAX
                && hag[q] > 0.0
                && (disparity[q] - dp).abs() <= config.face_disparity_px
            {
                label[q] = id;
                region.push(q);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::{GrayImage, StereoCamera};

    /// A 10 × 10 map: a low region (rows 6–8, columns 3–5, 0.3 m high) at disparity 10 and
    /// one pixel `above` at row 2 with the given column, disparity and height.
    fn scene(column: usize, disparity_px: f32, height_m: f32) -> bool {
        let w = 10;
        let mut hag = vec![0.0f32; w * w];
        let mut disparity = vec![10.0f32; w * w];
        let mut region = Vec::new();
        for y in 6..9 {
            for x in 3..6 {
                hag[y * w + x] = 0.3;
                region.push(y * w + x);
            }
        }
        hag[2 * w + column] = height_m;
        disparity[2 * w + column] = disparity_px;
        let camera = StereoCamera::default();
        under_structure(
            &region,
            &hag,
            &disparity,
            w,
            &camera,
            &GeometricConfig::default(),
        )
    }

    #[test]
    fn the_threshold_grows_with_the_square_of_range() {
        let c = GeometricConfig {
            seed_height_m: 0.03,
            height_per_range: 0.001,
            height_per_range_sq: 0.002,
            ..GeometricConfig::default()
        };
        assert!((c.threshold_at(0.03, 0.0) - 0.03).abs() < 1e-12);
        assert!((c.threshold_at(0.03, 5.0) - (0.03 + 0.005 + 0.05)).abs() < 1e-12);
    }

    /// A flat ground 1 m below a 320 × 180 camera, with vertical faces (constant disparity:
    /// the ground's at their bottom row) of `(column, bottom row, width, height)` pixels.
    fn ground_with_faces(faces: &[(usize, usize, usize, usize)]) -> (DisparityMap, GrayImage) {
        let camera = StereoCamera::default().for_size(320, 180).unwrap();
        let (w, h) = (camera.width, camera.height);
        let ground = |y: usize| {
            let v = y as f64 - camera.cy;
            (v > 2.0).then(|| (camera.fx * camera.baseline_m * v / camera.fy) as f32)
        };
        let mut data: Vec<f32> = (0..w * h)
            .map(|i| ground(i / w).unwrap_or(f32::NAN))
            .collect();
        for &(x0, bottom, fw, fh) in faces {
            let d = ground(bottom).unwrap();
            for y in bottom + 1 - fh..=bottom {
                for x in x0..x0 + fw {
                    data[y * w + x] = d;
                }
            }
        }
        let disparity = DisparityMap {
            width: w,
            height: h,
            data,
            scale: 1,
            camera,
        };
        (disparity, GrayImage::new(w, h, vec![120; w * h]).unwrap())
    }

    #[test]
    fn regions_report_why_they_were_dropped() {
        // a 12 × 12 px face (26 cm high) and a 2 × 6 px one (6 cm high), both at 2.9 m
        let (disparity, left) = ground_with_faces(&[(100, 170, 12, 12), (250, 170, 2, 6)]);
        let input = SegmentInput {
            left: &left,
            disparity: &disparity,
            camera: &disparity.camera,
        };
        let config = GeometricConfig::default();
        let regions = segment_geometric_regions(&input, &config);
        let masks = segment_geometric(&input, &config);
        let kept: Vec<&Mask> = regions
            .iter()
            .filter_map(|r| r.outcome.as_ref().ok())
            .collect();
        assert_eq!(kept.len(), masks.len());
        assert_eq!(masks.len(), 1, "{regions:?}");
        assert!(masks[0].contains(105, 165));
        let small = regions
            .iter()
            .find(|r| r.pixels.contains(&(165 * 320 + 250)));
        assert_eq!(
            small.map(|r| r.outcome.clone()),
            Some(Err(RegionDrop::TooSmall))
        );
    }

    #[test]
    fn a_region_under_something_tall_at_its_depth_is_under_a_structure() {
        assert!(scene(4, 10.5, 1.5));
    }

    #[test]
    fn tall_things_farther_away_lower_or_beside_do_not_count() {
        // farther away (terrain behind the rock)
        assert!(!scene(4, 5.0, 1.5));
        // not higher than a boulder can be
        assert!(!scene(4, 10.0, 0.8));
        // outside the region's columns
        assert!(!scene(8, 10.0, 1.5));
    }
}
