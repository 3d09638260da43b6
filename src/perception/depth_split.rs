//! Splitting an image-only segmenter's mask where it spans two depths.
//!
//! A segmenter that sees only the image merges a near rock with one behind it when the two
//! overlap in the picture: one mask, whose boulder lands between them, near neither. Stereo
//! tells them apart: the mask's disparities fall into two groups with nothing between
//! (an occlusion edge), where a single rock's face or the ground it spills onto vary
//! smoothly. The split is Otsu's threshold on the mask's disparities; it is made when the
//! two groups' means are apart by a fraction of the larger ([`DepthSplitConfig::min_gap`])
//! and by many times their spread ([`DepthSplitConfig::min_separation`]), and each holds a
//! share of the pixels. Pixels without a disparity go with the group whose pixel centroid
//! is nearer. A part may be split again, up to [`DepthSplitConfig::max_parts`].

use serde::{Deserialize, Serialize};

use super::{DisparityMap, Mask, PerceptionError};

/// Settings of the depth split.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepthSplitConfig {
    /// Split the masks of image-only segmenters (`learned`, `onnx`).
    pub enabled: bool,
    /// The groups' mean disparities differ by at least this fraction of the larger.
    pub min_gap: f64,
    /// … and by at least this many times their pooled standard deviation.
    pub min_separation: f64,
    /// Each group holds at least this fraction of the mask's valid disparities.
    pub min_fraction: f64,
    /// A mask is split into at most this many parts.
    pub max_parts: usize,
}

impl Default for DepthSplitConfig {
    fn default() -> Self {
        DepthSplitConfig {
            enabled: true,
            min_gap: 0.12,
            // chosen on rendered tuning seeds 11-15 (docs/design/depth-split.md); a
            // uniform spread of disparities (a smooth slope) separates by 3.46
            min_separation: 4.0,
            min_fraction: 0.15,
            max_parts: 3,
        }
    }
}

impl DepthSplitConfig {
    /// Checks the ranges; errors name the TOML path (`split.*`).
    pub fn validate(&self) -> Result<(), PerceptionError> {
        let bad = |m: &str| Err(PerceptionError::Config(format!("split.{m}")));
        if !(self.min_gap.is_finite() && self.min_gap >= 0.0) {
            return bad("min_gap must be finite and ≥ 0");
        }
        if !(self.min_separation.is_finite() && self.min_separation >= 0.0) {
            return bad("min_separation must be finite and ≥ 0");
        }
        if !(0.0..=0.5).contains(&self.min_fraction) {
            return bad("min_fraction must be in [0, 0.5]");
        }
        if self.max_parts == 0 {
            return bad("max_parts must be at least 1");
        }
        Ok(())
    }
}

/// Every mask of `masks` split where it spans two depths (see the module documentation);
/// the parts of a split mask replace it, in order. `disparity` is the pair's map.
pub fn split_by_depth(
    masks: &[Mask],
    disparity: &DisparityMap,
    config: &DepthSplitConfig,
) -> Vec<Mask> {
    if !config.enabled {
        return masks.to_vec();
    }
    let mut out = Vec::with_capacity(masks.len());
    for mask in masks {
        let mut parts = vec![mask.clone()];
        while parts.len() < config.max_parts {
            let Some((k, [a, b])) = parts
                .iter()
                .enumerate()
                .find_map(|(k, m)| split_once(m, disparity, config).map(|s| (k, s)))
            else {
                break;
            };
            parts.splice(k..=k, [a, b]);
        }
        out.extend(parts);
    }
    out
}

/// `mask` split in two at its disparities' Otsu threshold, when the groups qualify.
fn split_once(
    mask: &Mask,
    disparity: &DisparityMap,
    config: &DepthSplitConfig,
) -> Option<[Mask; 2]> {
    let pixels: Vec<((usize, usize), Option<f64>)> = mask
        .pixels()
        .map(|(x, y)| ((x, y), disparity.at_image_pixel(x, y)))
        .collect();
    let mut values: Vec<f64> = pixels.iter().filter_map(|p| p.1).collect();
    values.sort_by(f64::total_cmp);
    let (cut, [low, high]) = otsu_split(&values)?;
    let n = values.len() as f64;
    let min_count = (config.min_fraction * n).ceil() as usize;
    if low.count < min_count.max(1) || high.count < min_count.max(1) {
        return None;
    }
    let gap = high.mean - low.mean;
    let pooled = ((low.var * low.count as f64 + high.var * high.count as f64) / n).sqrt();
    if gap < config.min_gap * high.mean || gap < config.min_separation * pooled {
        return None;
    }
    let side = |d: f64| d >= cut;
    let centroid = |near: bool| {
        let (mut sx, mut sy, mut c) = (0.0, 0.0, 0.0);
        for ((x, y), d) in &pixels {
            if d.is_some_and(|d| side(d) == near) {
                (sx, sy, c) = (sx + *x as f64, sy + *y as f64, c + 1.0);
            }
        }
        (sx / c, sy / c)
    };
    let (near_c, far_c) = (centroid(true), centroid(false));
    let closer_to_near = |(x, y): (usize, usize)| {
        let dist = |c: (f64, f64)| (x as f64 - c.0).powi(2) + (y as f64 - c.1).powi(2);
        dist(near_c) <= dist(far_c)
    };
    let (mut near, mut far) = (Vec::new(), Vec::new());
    for (p, d) in pixels {
        let is_near = d.map_or_else(|| closer_to_near(p), side);
        if is_near {
            near.push(p);
        } else {
            far.push(p);
        }
    }
    Some([
        Mask::from_pixels(&near, mask.score)?,
        Mask::from_pixels(&far, mask.score)?,
    ])
}

/// Count, mean and variance of one group of values.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Group {
    count: usize,
    mean: f64,
    var: f64,
}

/// Otsu's threshold of `sorted` (ascending): the cut maximising the between-group variance,
/// and the two groups (below it, at or above it); `None` with fewer than two distinct values.
fn otsu_split(sorted: &[f64]) -> Option<(f64, [Group; 2])> {
    let n = sorted.len();
    if n < 2 {
        return None;
    }
    let total: f64 = sorted.iter().sum();
    let mut prefix = 0.0;
    let mut best: Option<(f64, usize)> = None;
    for i in 1..n {
        prefix += sorted[i - 1];
        if sorted[i] <= sorted[i - 1] {
            continue;
        }
        let (w0, w1) = (i as f64, (n - i) as f64);
        let (m0, m1) = (prefix / w0, (total - prefix) / w1);
        let between = w0 * w1 * (m1 - m0) * (m1 - m0);
        if best.is_none_or(|(b, _)| between > b) {
            best = Some((between, i));
        }
    }
    let (_, i) = best?;
    let group = |v: &[f64]| {
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
        Group {
            count: v.len(),
            mean,
            var,
        }
    };
    Some((sorted[i], [group(&sorted[..i]), group(&sorted[i..])]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::StereoCamera;

    /// A disparity map of `w × h` pixels at full resolution holding `f(x, y)`.
    fn map(w: usize, h: usize, f: impl Fn(usize, usize) -> f32) -> DisparityMap {
        let camera = StereoCamera::ipex();
        DisparityMap {
            width: w,
            height: h,
            data: (0..w * h).map(|i| f(i % w, i / w)).collect(),
            scale: 1,
            camera,
        }
    }

    fn block(x0: usize, y0: usize, x1: usize, y1: usize) -> Mask {
        let px: Vec<(usize, usize)> = (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .collect();
        Mask::from_pixels(&px, 0.9).unwrap()
    }

    #[test]
    fn a_near_rock_in_front_of_a_far_one_is_split_in_two() {
        // rows 0-19 at 31 px (4.8 m), rows 20-39 at 49 px (3 m), a little noise
        let d = map(60, 40, |x, y| {
            let noise = ((x * 7 + y * 13) % 5) as f32 * 0.1;
            if y < 20 {
                31.0 + noise
            } else {
                49.0 + noise
            }
        });
        let parts = split_by_depth(&[block(10, 0, 50, 40)], &d, &DepthSplitConfig::default());
        assert_eq!(parts.len(), 2);
        let rows = |m: &Mask| (m.y0, m.y0 + m.height);
        assert_eq!(rows(&parts[0]), (20, 40), "the near part");
        assert_eq!(rows(&parts[1]), (0, 20), "the far part");
    }

    #[test]
    fn a_smooth_slope_of_depth_stays_whole() {
        // ground receding smoothly: 49 px at the bottom to 31 px at the top
        let d = map(60, 40, |_, y| 31.0 + 18.0 * y as f32 / 39.0);
        let parts = split_by_depth(&[block(10, 0, 50, 40)], &d, &DepthSplitConfig::default());
        assert_eq!(parts.len(), 1);
    }

    #[test]
    fn a_small_group_is_not_split_off_and_disabled_keeps_all() {
        // 2 rows of 40 at a far depth: 5 % of the mask
        let d = map(60, 40, |_, y| if y < 2 { 20.0 } else { 49.0 });
        let config = DepthSplitConfig::default();
        assert_eq!(
            split_by_depth(&[block(10, 0, 50, 40)], &d, &config).len(),
            1
        );
        let two = map(60, 40, |_, y| if y < 20 { 31.0 } else { 49.0 });
        let off = DepthSplitConfig {
            enabled: false,
            ..config
        };
        assert_eq!(split_by_depth(&[block(10, 0, 50, 40)], &two, &off).len(), 1);
    }

    #[test]
    fn pixels_without_disparity_join_the_nearer_group() {
        let d = map(60, 40, |x, y| {
            if x < 14 {
                f32::NAN
            } else if y < 20 {
                31.0
            } else {
                49.0
            }
        });
        let parts = split_by_depth(&[block(10, 0, 50, 40)], &d, &DepthSplitConfig::default());
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0].area() + parts[1].area(), 40 * 40);
    }
}
