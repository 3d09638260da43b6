//! Full-resolution depth refinement of one boulder.
//!
//! Semi-global matching at half resolution is fast but quantises depth coarsely (at 5 m a
//! tenth of a half-resolution pixel is 3.4 cm). For each boulder this step re-matches the
//! pixels of its mask at full resolution: zero-mean normalised cross-correlation (ZNCC) of
//! a small window, searched a few pixels around the coarse disparity, with a parabolic
//! sub-pixel fit; a quantile of the matched disparities is the boulder's disparity.

use serde::{Deserialize, Serialize};

use super::{GrayImage, Mask};

/// Settings of the refinement (the defaults and why: `docs/design/boulder-depth.md`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefineSettings {
    /// Window radius (the window is 2r + 1 wide).
    pub radius: usize,
    /// Search ± this many pixels around the coarse disparity.
    pub search_px: usize,
    /// Pixels closer than this to the mask's outline are not used. Small far rocks have
    /// few pixels, so the default uses them all.
    pub erode_px: usize,
    /// Smallest ZNCC of an accepted match.
    pub min_zncc: f64,
    /// At most this many pixels are matched per boulder.
    pub max_samples: usize,
    /// The quantile of the matched disparities taken as the boulder's (0.5: the median;
    /// higher: nearer). Windows on the rock's upper outline also see the ground behind it,
    /// which pulls the median farther than the rock's visible surface.
    pub disparity_quantile: f64,
}

impl Default for RefineSettings {
    fn default() -> Self {
        RefineSettings {
            radius: 3,
            search_px: 3,
            erode_px: 0,
            min_zncc: 0.8,
            max_samples: 600,
            disparity_quantile: 0.6,
        }
    }
}

impl RefineSettings {
    /// Whether the values are usable: a window of radius ≥ 1, at least 5 samples, a
    /// quantile in [0, 1] and a finite smallest ZNCC.
    pub fn is_valid(&self) -> bool {
        self.radius >= 1
            && self.max_samples >= 5
            && (0.0..=1.0).contains(&self.disparity_quantile)
            && self.min_zncc.is_finite()
    }
}

/// The refined disparity (full-resolution pixels) of the mask, or `None` when too few
/// interior pixels match well (then the coarse value should stand).
pub fn refine_disparity(
    left: &GrayImage,
    right: &GrayImage,
    mask: &Mask,
    coarse_disparity: f64,
    settings: &RefineSettings,
) -> Option<f64> {
    let r = settings.radius as isize;
    let e = settings.erode_px as isize;
    let interior: Vec<(usize, usize)> = mask
        .pixels()
        .filter(|&(x, y)| {
            (-e..=e).all(|dy| {
                (-e..=e).all(|dx| {
                    let (qx, qy) = (x as isize + dx, y as isize + dy);
                    qx >= 0 && qy >= 0 && mask.contains(qx as usize, qy as usize)
                })
            })
        })
        .collect();
    if interior.len() < 8 {
        return None;
    }
    let step = interior.len().div_ceil(settings.max_samples).max(1);
    let d0 = coarse_disparity.round() as isize;
    let s = settings.search_px as isize;
    let (w, h) = (left.width as isize, left.height as isize);
    let mut found = Vec::new();
    for &(x, y) in interior.iter().step_by(step) {
        let (x, y) = (x as isize, y as isize);
        if y - r < 0 || y + r >= h || x - r < 0 || x + r >= w {
            continue;
        }
        let scores: Vec<f64> = (d0 - s..=d0 + s)
            .map(|d| {
                if x - d - r < 0 || x - d + r >= w || d < 1 {
                    f64::NEG_INFINITY
                } else {
                    zncc(left, right, x, y, d, r)
                }
            })
            .collect();
        let Some((k, &best)) = scores.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)) else {
            continue;
        };
        if best < settings.min_zncc || k == 0 || k + 1 == scores.len() {
            continue;
        }
        let (a, b, c) = (scores[k - 1], best, scores[k + 1]);
        let denom = a - 2.0 * b + c;
        let offset = if denom < 0.0 {
            0.5 * (a - c) / denom
        } else {
            0.0
        };
        found.push((d0 - s + k as isize) as f64 + offset.clamp(-0.5, 0.5));
    }
    if found.len() < 5 {
        return None;
    }
    let rank = ((found.len() - 1) as f64 * settings.disparity_quantile).round() as usize;
    Some(*found.select_nth_unstable_by(rank, f64::total_cmp).1)
}

/// ZNCC of the left window at (x, y) with the right window at (x − d, y).
fn zncc(left: &GrayImage, right: &GrayImage, x: isize, y: isize, d: isize, r: isize) -> f64 {
    let (mut sl, mut sr, mut sll, mut srr, mut slr) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for dy in -r..=r {
        let yy = (y + dy) as usize;
        let lrow = &left.data[yy * left.width..];
        let rrow = &right.data[yy * right.width..];
        for dx in -r..=r {
            let a = lrow[(x + dx) as usize] as f64;
            let b = rrow[(x - d + dx) as usize] as f64;
            sl += a;
            sr += b;
            sll += a * a;
            srr += b * b;
            slr += a * b;
        }
    }
    let n = ((2 * r + 1) * (2 * r + 1)) as f64;
    let cov = slr - sl * sr / n;
    let vl = sll - sl * sl / n;
    let vr = srr - sr * sr / n;
    if vl <= 1e-9 || vr <= 1e-9 {
        return f64::NEG_INFINITY;
    }
    cov / (vl * vr).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_fractional_shift() {
        // a smooth random texture, the right image shifted by 10.3 px (linear interpolation)
        let (w, h) = (120, 40);
        let f = |x: f64, y: f64| {
            128.0 + 60.0 * (0.37 * x).sin() * (0.23 * y).cos() + 40.0 * (0.11 * x + 0.3 * y).sin()
        };
        let left = GrayImage::new(
            w,
            h,
            (0..w * h)
                .map(|i| f((i % w) as f64, (i / w) as f64) as u8)
                .collect(),
        )
        .unwrap();
        let right = GrayImage::new(
            w,
            h,
            (0..w * h)
                .map(|i| f((i % w) as f64 + 10.3, (i / w) as f64) as u8)
                .collect(),
        )
        .unwrap();
        let px: Vec<(usize, usize)> = (10..30)
            .flat_map(|y| (40..80).map(move |x| (x, y)))
            .collect();
        let mask = Mask::from_pixels(&px, 1.0).unwrap();
        let d = refine_disparity(&left, &right, &mask, 11.0, &RefineSettings::default()).unwrap();
        assert!((d - 10.3).abs() < 0.1, "{d}");
    }
}
