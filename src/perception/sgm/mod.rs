//! Semi-global matching (Hirschmüller 2008) on census costs: dense disparity for a rectified
//! grayscale pair.
//!
//! Steps: optional reduction of both images by 2^levels; census transform; Hamming costs;
//! aggregation along 4 or 8 image paths with the penalties P1 (disparity steps of 1) and P2
//! (larger jumps); winner-takes-all with a uniqueness test; a left–right consistency check
//! against the right image's disparities taken from the same aggregated sums; parabolic
//! sub-pixel refinement; removal of weakly textured pixels and small speckles.
//!
//! The paths are aggregated by two row sweeps (top-down with left-to-right, bottom-up with
//! right-to-left, see `matcher.rs`) that run on two threads and meet in the middle: the
//! image-sized buffers are the matching costs and one volume of half-sums (u8 each, 2 ×
//! 22 MB at half resolution with 96 disparities), reused from frame to frame through
//! [`StereoScratch`].

use serde::{Deserialize, Serialize};

use super::census::{census_bits, census_planes_into};
use super::{DisparityMap, GrayImage, PerceptionError, StereoCamera};

mod filters;
mod matcher;
#[cfg(test)]
mod reference;
mod select;
mod sweep;

use filters::{remove_speckles, texture_mask};
use matcher::{MatchInput, RowMatcher};

/// Semi-global matching settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StereoConfig {
    /// Work on images reduced by 2^levels (0 = full resolution; 1 = half, the default,
    /// which keeps a 1280 × 720 pair within the 100 ms budget on two cores).
    pub levels: u32,
    /// Disparities searched, at the working resolution (0 .. max_disparity − 1). At half
    /// resolution 96 reaches down to 0.77 m.
    pub max_disparity: usize,
    /// Census window radius (3 = 7 × 7, the maximum).
    pub census_radius: usize,
    /// Penalty for a disparity change of one pixel between neighbours.
    pub p1: u16,
    /// Penalty for larger disparity jumps.
    pub p2: u16,
    /// Aggregation paths: 4 (horizontal and vertical) or 8 (also the diagonals).
    pub paths: u8,
    /// Uniqueness margin: the best cost must beat every non-adjacent cost by this fraction.
    pub uniqueness: f32,
    /// Largest disagreement between left and right disparity, pixels.
    pub lr_tolerance: f32,
    /// Smallest local intensity standard deviation (7 × 7, gray levels) for a match to be
    /// trusted: the black sky and deep shadows have none.
    pub min_texture: f32,
    /// Connected patches of similar disparity smaller than this (pixels) are removed.
    pub speckle_max_area: usize,
    /// Disparity difference that still connects two neighbours in the speckle filter.
    pub speckle_max_diff: f32,
}

impl Default for StereoConfig {
    fn default() -> Self {
        StereoConfig {
            levels: 1,
            max_disparity: 96,
            census_radius: 3,
            p1: 6,
            p2: 48,
            paths: 4,
            uniqueness: 0.05,
            lr_tolerance: 1.0,
            min_texture: 2.0,
            speckle_max_area: 40,
            speckle_max_diff: 1.0,
        }
    }
}

impl StereoConfig {
    /// Check the values are usable.
    pub fn validate(&self) -> Result<(), PerceptionError> {
        let bad = |m: &str| Err(PerceptionError::Config(format!("stereo: {m}")));
        if !(4..=1024).contains(&self.max_disparity) {
            return bad("max_disparity must be within 4..=1024");
        }
        if self.census_radius == 0 || self.census_radius > 3 {
            return bad("census_radius must be 1, 2 or 3");
        }
        if self.paths != 4 && self.paths != 8 {
            return bad("paths must be 4 or 8");
        }
        if self.p1 == 0 || self.p2 < self.p1 || self.p2 > 1000 {
            return bad("need 0 < p1 <= p2 <= 1000");
        }
        if self.levels > 3 {
            return bad("levels must be at most 3");
        }
        if !(0.0..1.0).contains(&self.uniqueness)
            || self.lr_tolerance.is_nan()
            || self.lr_tolerance < 0.0
        {
            return bad("uniqueness must be in [0, 1) and lr_tolerance >= 0");
        }
        Ok(())
    }
}

/// Buffers reused from one pair to the next (the census planes, the texture mask and the
/// matcher's costs, half-sums and row buffers: about 48 MB at half resolution with 96
/// disparities), so a stream of frames does not pay for fresh memory every time.
#[derive(Clone, Debug, Default)]
pub struct StereoScratch {
    census_left: Vec<u16>,
    census_right: Vec<u16>,
    textured: Vec<bool>,
    matcher: RowMatcher,
}

/// Dense disparity of the left image of a rectified pair (same size; the camera must match
/// the images). The result is at the working resolution (see [`StereoConfig::levels`]).
pub fn compute_disparity(
    left: &GrayImage,
    right: &GrayImage,
    camera: &StereoCamera,
    config: &StereoConfig,
) -> Result<DisparityMap, PerceptionError> {
    compute_disparity_with(left, right, camera, config, &mut StereoScratch::default())
}

/// [`compute_disparity`] reusing the buffers of `scratch`.
pub fn compute_disparity_with(
    left: &GrayImage,
    right: &GrayImage,
    camera: &StereoCamera,
    config: &StereoConfig,
    scratch: &mut StereoScratch,
) -> Result<DisparityMap, PerceptionError> {
    config.validate()?;
    if left.width != right.width || left.height != right.height {
        return Err(PerceptionError::ImageSize {
            path: "<stereo pair>".into(),
            message: format!(
                "left is {} × {} but right is {} × {}",
                left.width, left.height, right.width, right.height
            ),
        });
    }
    let camera = camera.for_size(left.width, left.height)?;
    let (l, r) = rayon::join(
        || left.reduced(config.levels),
        || right.reduced(config.levels),
    );
    let (w, h) = (l.width, l.height);
    if w < 2 * config.census_radius + 2 || h < 2 * config.census_radius + 2 {
        return Err(PerceptionError::ImageSize {
            path: "<stereo pair>".into(),
            message: format!("images too small for stereo at the working resolution ({w} × {h})"),
        });
    }
    let scale = 1usize << config.levels;
    let map_camera = camera.scaled(1.0 / scale as f64, w, h);
    let nd = config.max_disparity.min(w - 1).max(2);

    let StereoScratch {
        census_left,
        census_right,
        textured,
        matcher,
    } = scratch;
    let radius = config.census_radius;
    rayon::join(
        || {
            rayon::join(
                || census_planes_into(&l, radius, census_left),
                || census_planes_into(&r, radius, census_right),
            )
        },
        || texture_mask(&l, config.min_texture, textured),
    );
    let mut data = vec![f32::NAN; w * h];
    let input = MatchInput {
        cl: census_left,
        cr: census_right,
        w,
        h,
        nd,
        max_cost: census_bits(radius) as u16,
        config,
        textured,
    };
    matcher.run(&input, &mut data);
    if config.speckle_max_area > 0 {
        remove_speckles(
            &mut data,
            w,
            h,
            config.speckle_max_area,
            config.speckle_max_diff,
        );
    }
    Ok(DisparityMap {
        width: w,
        height: h,
        data,
        scale,
        camera: map_camera,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random-texture pair where the right image is the left shifted by `shift` pixels.
    fn shifted_pair(w: usize, h: usize, shift: usize) -> (GrayImage, GrayImage) {
        let mut state = 12345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 56) as u8
        };
        let big: Vec<u8> = (0..(w + shift) * h).map(|_| noise()).collect();
        let left = GrayImage::new(
            w,
            h,
            (0..h)
                .flat_map(|y| big[y * (w + shift)..y * (w + shift) + w].to_vec())
                .collect(),
        )
        .unwrap();
        let right = GrayImage::new(
            w,
            h,
            (0..h)
                .flat_map(|y| big[y * (w + shift) + shift..y * (w + shift) + shift + w].to_vec())
                .collect(),
        )
        .unwrap();
        (left, right)
    }

    #[test]
    fn recovers_a_constant_shift() {
        let (left, right) = shifted_pair(120, 60, 7);
        let camera = StereoCamera::ipex().scaled(120.0 / 1280.0, 120, 60);
        let config = StereoConfig {
            levels: 0,
            max_disparity: 16,
            ..StereoConfig::default()
        };
        for paths in [4, 8] {
            let map = compute_disparity(
                &left,
                &right,
                &camera,
                &StereoConfig {
                    paths,
                    ..config.clone()
                },
            )
            .unwrap();
            let mut good = 0;
            let mut valid = 0;
            for y in 0..60 {
                for x in 20..120 {
                    if let Some(d) = map.get(x, y) {
                        valid += 1;
                        if (d - 7.0).abs() < 0.3 {
                            good += 1;
                        }
                    }
                }
            }
            assert!(valid > 5000, "valid {valid}");
            assert!(good as f64 > 0.98 * valid as f64, "good {good} of {valid}");
        }
    }

    /// The disparities before the speckle filter from the row sweeps and from the
    /// whole-volume reference.
    fn row_sweeps_and_reference(
        l: &GrayImage,
        r: &GrayImage,
        config: &StereoConfig,
        scratch: &mut StereoScratch,
    ) -> (Vec<f32>, Vec<f32>) {
        let (w, h) = (l.width, l.height);
        let nd = config.max_disparity.min(w - 1).max(2);
        let radius = config.census_radius;
        let (mut cl, mut cr) = (Vec::new(), Vec::new());
        census_planes_into(l, radius, &mut cl);
        census_planes_into(r, radius, &mut cr);

        let mut textured = Vec::new();
        texture_mask(l, config.min_texture, &mut textured);
        let max_cost = census_bits(radius) as u16;
        let input = MatchInput {
            cl: &cl,
            cr: &cr,
            w,
            h,
            nd,
            max_cost,
            config,
            textured: &textured,
        };
        let mut rows = vec![f32::NAN; w * h];
        scratch.matcher.run(&input, &mut rows);
        let reference = reference::reference_disparity(
            &crate::perception::census::census_transform(l, radius),
            &crate::perception::census::census_transform(r, radius),
            w,
            h,
            nd,
            max_cost as u8,
            config,
            &textured,
        );
        (rows, reference)
    }

    /// A textured pair whose disparity changes across the image (a slanted plane and a
    /// nearer block), so paths, ties and the left–right check all have work to do.
    fn slanted_pair(w: usize, h: usize) -> (GrayImage, GrayImage) {
        let (left, _) = shifted_pair(w + 40, h, 1);
        let mut right = GrayImage::zeros(w, h);
        let mut l = GrayImage::zeros(w, h);
        for y in 0..h {
            for x in 0..w {
                l.data[y * w + x] = left.data[y * (w + 40) + x + 20];
                let block = (w / 3..w / 2).contains(&x) && (h / 3..2 * h / 3).contains(&y);
                let d = if block { 14 } else { 2 + 8 * y / h };
                right.data[y * w + x] = left.data[y * (w + 40) + x + 20 - d.min(x + 20)];
            }
        }
        (l, right)
    }

    #[test]
    fn row_sweeps_equal_the_whole_volume_reference() {
        let mut scratch = StereoScratch::default();
        let pairs = [
            shifted_pair(97, 41, 5),
            slanted_pair(120, 64),
            slanted_pair(64, 1),
        ];
        let configs = [
            StereoConfig::default(),
            StereoConfig {
                paths: 8,
                ..StereoConfig::default()
            },
            StereoConfig {
                max_disparity: 21,
                p2: 200,
                ..StereoConfig::default()
            },
            StereoConfig {
                max_disparity: 16,
                census_radius: 2,
                paths: 8,
                p1: 3,
                p2: 30,
                ..StereoConfig::default()
            },
        ];
        for (k, (l, r)) in pairs.iter().enumerate() {
            for config in &configs {
                let (rows, reference) = row_sweeps_and_reference(l, r, config, &mut scratch);
                let same = rows
                    .iter()
                    .zip(&reference)
                    .filter(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()))
                    .count();
                assert_eq!(same, rows.len(), "pair {k}, {config:?}");
                if k < 2 {
                    let valid = rows.iter().filter(|d| d.is_finite()).count();
                    assert!(valid > rows.len() / 5, "pair {k}: only {valid} valid");
                }
            }
        }
    }

    #[test]
    fn mismatched_sizes_are_refused() {
        let a = GrayImage::zeros(64, 36);
        let b = GrayImage::zeros(64, 30);
        let camera = StereoCamera::ipex();
        assert!(compute_disparity(&a, &b, &camera, &StereoConfig::default()).is_err());
    }

    #[test]
    fn untextured_pixels_are_invalid() {
        let a = GrayImage::zeros(128, 72);
        let camera = StereoCamera::ipex();
        let map = compute_disparity(&a, &a, &camera, &StereoConfig::default()).unwrap();
        assert_eq!(map.valid_fraction(), 0.0);
    }
}
