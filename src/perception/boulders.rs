//! From instance masks to boulders (LunarLoc's front end): drop masks touching the border,
//! compute each mask's centroid and pixel spread, its depth from stereo, the physical size
//! s = k · σ · D · α, gate the size and the elongation, and back-project the centroid.

use nalgebra::{Isometry3, Point3};
use serde::{Deserialize, Serialize};

use super::depth_refine::{refine_disparity, RefineSettings};
use super::{CameraMount, DisparityMap, GrayImage, Mask, PerceptionError, StereoCamera};

/// Settings of the mask-to-boulder stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BoulderConfig {
    /// Masks with a pixel within this many pixels of the image border are dropped (the
    /// object may be cut off, so centroid and size would be wrong).
    pub border_margin_px: usize,
    /// Smallest mask area, image pixels.
    pub min_area_px: usize,
    /// Smallest boulder size kept, metres.
    pub min_size_m: f64,
    /// Largest boulder size kept, metres.
    pub max_size_m: f64,
    /// Largest ratio of the pixel covariance's eigenvalues (major² / minor² axis): shadows
    /// and terrain edges are long and thin.
    pub max_elongation: f64,
    /// k in s = k · σ · D · α, with σ the RMS pixel spread per axis; 4 makes the size of a
    /// disk equal its diameter.
    pub spread_to_size: f64,
    /// Smallest fraction of the mask's pixels with a valid disparity.
    pub min_valid_depth_fraction: f64,
    /// Boulders farther than this (metres) are dropped: stereo depth degrades with the
    /// square of the range.
    pub max_range_m: f64,
    /// Re-match each boulder's interior at full resolution for a finer depth (see
    /// [`depth_refine`](super::depth_refine)); only matters when stereo ran at a reduced
    /// resolution.
    pub refine_depth: bool,
    /// Settings of that refinement.
    pub refine: RefineSettings,
}

impl Default for BoulderConfig {
    fn default() -> Self {
        BoulderConfig {
            border_margin_px: 2,
            min_area_px: 40,
            min_size_m: 0.08,
            max_size_m: 2.5,
            max_elongation: 8.0,
            spread_to_size: 4.0,
            min_valid_depth_fraction: 0.2,
            max_range_m: 10.0,
            refine_depth: true,
            refine: RefineSettings::default(),
        }
    }
}

impl BoulderConfig {
    /// Check the values are usable.
    pub fn validate(&self) -> Result<(), PerceptionError> {
        let ok = self.min_size_m >= 0.0
            && self.max_size_m > self.min_size_m
            && self.max_elongation >= 1.0
            && self.spread_to_size > 0.0
            && (0.0..=1.0).contains(&self.min_valid_depth_fraction)
            && self.max_range_m > 0.0
            && self.refine.is_valid();
        if ok {
            Ok(())
        } else {
            Err(PerceptionError::Config(
                "boulders: need 0 <= min_size_m < max_size_m, max_elongation >= 1, \
                 spread_to_size > 0, min_valid_depth_fraction in [0, 1], max_range_m > 0, \
                 refine.radius >= 1, refine.max_samples >= 5, refine.disparity_quantile in [0, 1], \
                 refine.min_zncc finite"
                    .into(),
            ))
        }
    }
}

/// One boulder seen in the left image.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Boulder {
    /// Mask centroid (u, v) in left-image pixels.
    pub pixel_centroid: [f64; 2],
    /// Mask bounding box [x0, y0, x1, y1] in left-image pixels (x1, y1 exclusive).
    pub pixel_box: [usize; 4],
    /// Mask area, pixels.
    pub area_px: usize,
    /// RMS pixel spread per axis, σ = sqrt((λ1 + λ2) / 2).
    pub spread_px: f64,
    /// Eigenvalue ratio λ1 / λ2 of the mask's pixel covariance.
    pub elongation: f64,
    /// Depth of the boulder's visible surface (a quantile of its disparities, see
    /// [`RefineSettings::disparity_quantile`](super::depth_refine::RefineSettings)), metres.
    pub depth_m: f64,
    /// Centroid of the visible surface in the left camera's optical frame (x right, y down,
    /// z forward), metres.
    pub position_camera: [f64; 3],
    /// The same point in the rover body frame (x forward, y left, z up), metres.
    pub position_rover: [f64; 3],
    /// Physical size s = k · σ · D · α, metres.
    pub size_m: f64,
    /// Segmenter confidence.
    pub score: f64,
}

impl Boulder {
    /// The centroid in the world frame, given the rover pose `world_from_rover`.
    pub fn position_world(&self, world_from_rover: &Isometry3<f64>) -> Point3<f64> {
        let [x, y, z] = self.position_rover;
        world_from_rover * Point3::new(x, y, z)
    }
}

/// Why a mask did not become a boulder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rejection {
    /// The mask touches the image border.
    Border,
    /// Fewer pixels than `min_area_px`.
    TooSmall,
    /// Too few valid disparities in the mask.
    NoDepth,
    /// Farther than `max_range_m`.
    TooFar,
    /// Eigenvalue ratio above `max_elongation`.
    Elongated,
    /// Physical size outside [min_size_m, max_size_m].
    Size,
    /// The mask does not stand out of the ground (the front end's stereo check of
    /// image-only segmenters, [`relief_gate`](super::relief_gate)).
    Flat,
    /// The mask floats above the ground (same check).
    Floating,
    /// The mask lies under or against a structure, the lander (same check).
    Structure,
    /// The mask lies in hard shadow without a sunlit face (same check).
    Shadow,
}

/// The outcome for each mask, in mask order.
pub type Verdicts = Vec<Result<Boulder, Rejection>>;

/// Turn masks into boulders (or rejections). `camera` is the camera of the image the masks
/// are in; `disparity` may be at a reduced resolution. With `pair` (the full-resolution
/// left and right images) and [`BoulderConfig::refine_depth`], each boulder's depth is
/// refined at full resolution.
pub fn boulders_from_masks(
    masks: &[Mask],
    disparity: &DisparityMap,
    camera: &StereoCamera,
    mount: &CameraMount,
    config: &BoulderConfig,
    pair: Option<(&GrayImage, &GrayImage)>,
) -> Verdicts {
    let rover_from_camera = mount.rover_from_camera();
    let pair = pair.filter(|_| config.refine_depth && disparity.scale > 1);
    masks
        .iter()
        .map(|m| boulder_from_mask(m, disparity, camera, &rover_from_camera, config, pair))
        .collect()
}

fn boulder_from_mask(
    mask: &Mask,
    disparity: &DisparityMap,
    camera: &StereoCamera,
    rover_from_camera: &Isometry3<f64>,
    config: &BoulderConfig,
    pair: Option<(&GrayImage, &GrayImage)>,
) -> Result<Boulder, Rejection> {
    let area = mask.area();
    if area < config.min_area_px.max(1) {
        return Err(Rejection::TooSmall);
    }
    if mask.touches_border(camera.width, camera.height, config.border_margin_px) {
        return Err(Rejection::Border);
    }
    let n = area as f64;
    let (mut su, mut sv) = (0.0, 0.0);
    let mut disparities = Vec::with_capacity(area);
    for (x, y) in mask.pixels() {
        su += x as f64;
        sv += y as f64;
        if let Some(d) = disparity.at_image_pixel(x, y) {
            disparities.push(d);
        }
    }
    let (cu, cv) = (su / n, sv / n);
    let (mut cuu, mut cuv, mut cvv) = (0.0, 0.0, 0.0);
    for (x, y) in mask.pixels() {
        let (du, dv) = (x as f64 - cu, y as f64 - cv);
        cuu += du * du;
        cuv += du * dv;
        cvv += dv * dv;
    }
    // +1/12: the variance of a uniform pixel footprint, so one pixel has a spread too
    let (cuu, cuv, cvv) = (cuu / n + 1.0 / 12.0, cuv / n, cvv / n + 1.0 / 12.0);
    let mean = 0.5 * (cuu + cvv);
    let disc = (0.25 * (cuu - cvv).powi(2) + cuv * cuv).sqrt();
    let (l1, l2) = (mean + disc, (mean - disc).max(1e-12));
    let elongation = l1 / l2;
    let spread = mean.sqrt();

    if (disparities.len() as f64) < config.min_valid_depth_fraction * n || disparities.is_empty() {
        return Err(Rejection::NoDepth);
    }
    let mid = disparities.len() / 2;
    let (_, &mut mut d, _) = disparities.select_nth_unstable_by(mid, f64::total_cmp);
    if let Some((left, right)) = pair {
        if let Some(fine) = refine_disparity(left, right, mask, d, &config.refine) {
            d = fine;
        }
    }
    let depth = camera.depth_from_disparity(d).ok_or(Rejection::NoDepth)?;
    if depth > config.max_range_m {
        return Err(Rejection::TooFar);
    }
    if elongation > config.max_elongation {
        return Err(Rejection::Elongated);
    }
    let size = config.spread_to_size * spread * depth * camera.angular_resolution_rad();
    if !(config.min_size_m..=config.max_size_m).contains(&size) {
        return Err(Rejection::Size);
    }
    let p_camera = camera.back_project(cu, cv, depth);
    let p_rover = rover_from_camera * p_camera;
    Ok(Boulder {
        pixel_centroid: [cu, cv],
        pixel_box: mask.bbox(),
        area_px: area,
        spread_px: spread,
        elongation,
        depth_m: depth,
        position_camera: [p_camera.x, p_camera.y, p_camera.z],
        position_rover: [p_rover.x, p_rover.y, p_rover.z],
        size_m: size,
        score: mask.score as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat_disparity(camera: &StereoCamera, d: f32) -> DisparityMap {
        DisparityMap {
            width: camera.width,
            height: camera.height,
            data: vec![d; camera.width * camera.height],
            scale: 1,
            camera: *camera,
        }
    }

    fn disk(cx: f64, cy: f64, r: f64) -> Mask {
        let mut px = Vec::new();
        for y in 0..720usize {
            for x in 0..1280usize {
                if (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2) <= r * r {
                    px.push((x, y));
                }
            }
        }
        Mask::from_pixels(&px, 0.9).unwrap()
    }

    #[test]
    fn disk_gives_its_diameter_and_position() {
        let camera = StereoCamera::ipex();
        // a 0.5 m wide disk at 5 m covers a radius of 914.015 * 0.25 / 5 = 45.7 px
        let disparity = flat_disparity(&camera, camera.disparity_from_depth(5.0) as f32);
        let mask = disk(700.0, 400.0, 45.7);
        let v = boulders_from_masks(
            &[mask],
            &disparity,
            &camera,
            &CameraMount::ipex_front_left(),
            &BoulderConfig::default(),
            None,
        );
        let b = v[0].as_ref().unwrap();
        assert!((b.depth_m - 5.0).abs() < 1e-5);
        assert!((b.size_m - 0.5).abs() < 0.01, "size {}", b.size_m);
        assert!((b.position_camera[0] - 60.0 / 914.015 * 5.0).abs() < 1e-3);
        assert!((b.position_rover[0] - 5.28).abs() < 1e-5);
        assert!(b.elongation < 1.05);
    }

    #[test]
    fn border_elongated_and_far_masks_are_rejected() {
        let camera = StereoCamera::ipex();
        let disparity = flat_disparity(&camera, 30.0);
        let config = BoulderConfig::default();
        let mount = CameraMount::ipex_front_left();
        let at_border = disk(10.0, 300.0, 20.0);
        let line: Vec<(usize, usize)> = (300..400).flat_map(|x| [(x, 500), (x, 501)]).collect();
        let streak = Mask::from_pixels(&line, 1.0).unwrap();
        let v = boulders_from_masks(
            &[at_border, streak],
            &disparity,
            &camera,
            &mount,
            &config,
            None,
        );
        assert_eq!(v[0], Err(Rejection::Border));
        assert_eq!(v[1], Err(Rejection::Elongated));
        let far = flat_disparity(&camera, 2.0);
        let v = boulders_from_masks(
            &[disk(600.0, 300.0, 20.0)],
            &far,
            &camera,
            &mount,
            &config,
            None,
        );
        assert_eq!(v[0], Err(Rejection::TooFar));
        let invalid = flat_disparity(&camera, f32::NAN);
        let v = boulders_from_masks(
            &[disk(600.0, 300.0, 20.0)],
            &invalid,
            &camera,
            &mount,
            &config,
            None,
        );
        assert_eq!(v[0], Err(Rejection::NoDepth));
    }
}
