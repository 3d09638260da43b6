//! Stereo triangulation noise: depth error growing with the square of the depth,
//! σ_z = z² σ_d / (f B) for a disparity error σ_d (pixels), focal length f (pixels) and
//! baseline B; the triangulated point slides along its viewing ray. Across the ray the error
//! is the pixel error scaled by depth, σ = z σ_px / f.
//!
//! The model belongs to the measurements: landmark fusion weighs detections by it
//! ([`super::estimate::stereo_weighted`]) and the simulator draws its noisy detections from
//! it (`sim::sensors`, which reaches it through the re-export `sim::stereo_noise`).

use crate::ipex::{FOCAL_PX, STEREO_BASELINE_M};
use nalgebra::Vector3;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Parameters of the stereo noise model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StereoNoiseConfig {
    /// Disparity error (1 σ), pixels.
    pub disparity_sigma_px: f64,
    /// Image-position error of the measured point across the ray (1 σ), pixels.
    pub pixel_sigma_px: f64,
    /// Focal length, pixels.
    pub focal_px: f64,
    /// Stereo baseline, metres.
    pub baseline_m: f64,
}

impl Default for StereoNoiseConfig {
    fn default() -> Self {
        Self {
            disparity_sigma_px: 0.3,
            pixel_sigma_px: 0.5,
            focal_px: FOCAL_PX,
            baseline_m: STEREO_BASELINE_M,
        }
    }
}

impl StereoNoiseConfig {
    /// Depth error (1 σ) at `depth_m`: z² σ_d / (f B).
    ///
    /// ```
    /// use segloc::landmarks::stereo_noise::StereoNoiseConfig;
    /// let s = StereoNoiseConfig::default();
    /// // 5 m away: 25 · 0.3 / (914.015 · 0.162) ≈ 5 cm
    /// assert!((s.depth_sigma_m(5.0) - 0.0507).abs() < 1e-3);
    /// ```
    pub fn depth_sigma_m(&self, depth_m: f64) -> f64 {
        depth_m * depth_m * self.disparity_sigma_px / (self.focal_px * self.baseline_m)
    }

    /// Error across the viewing ray (1 σ, per axis) at `depth_m`: z σ_px / f.
    pub fn lateral_sigma_m(&self, depth_m: f64) -> f64 {
        depth_m * self.pixel_sigma_px / self.focal_px
    }

    /// A noisy measurement of `p_cam`, a point in a camera frame whose x axis is the
    /// optical axis (depth = x): the depth error moves the point along its ray, the pixel
    /// error moves it across (in y and z). Points at or behind the camera come back as is.
    pub fn perturb(&self, p_cam: &Vector3<f64>, rng: &mut impl Rng) -> Vector3<f64> {
        let depth = p_cam.x;
        if depth.is_nan() || depth <= 1e-6 {
            return *p_cam;
        }
        let n = |rng: &mut dyn rand::RngCore| -> f64 { StandardNormal.sample(rng) };
        let measured_depth = (depth + self.depth_sigma_m(depth) * n(rng)).max(1e-3);
        let lateral = self.lateral_sigma_m(depth);
        let mut p = p_cam * (measured_depth / depth);
        p.y += lateral * n(rng);
        p.z += lateral * n(rng);
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn depth_spread_matches_the_model() {
        let s = StereoNoiseConfig::default();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for depth in [2.0, 5.0] {
            let p = Vector3::new(depth, 0.5, -0.2);
            let errs: Vec<f64> = (0..20_000)
                .map(|_| s.perturb(&p, &mut rng).x - depth)
                .collect();
            let mean = errs.iter().sum::<f64>() / errs.len() as f64;
            let sd =
                (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / errs.len() as f64).sqrt();
            assert!(mean.abs() < 0.05 * s.depth_sigma_m(depth));
            assert!(
                (sd / s.depth_sigma_m(depth) - 1.0).abs() < 0.05,
                "{depth}: {sd}"
            );
        }
    }
}
