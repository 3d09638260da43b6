//! The renderer's configuration: image size, sun, reflectance, albedo texture, pebbles and the
//! camera's exposure and noise, validated with errors naming the field.

use serde::{Deserialize, Serialize};

/// Errors of the renderer.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RenderError {
    /// A configuration value is out of range; names the field (its TOML path under
    /// `[render]`).
    #[error("invalid render configuration: render.{field}: {message}")]
    InvalidConfig {
        /// The field's name.
        field: &'static str,
        /// What is wrong with it.
        message: String,
    },
}

/// Parameters of the renderer (TOML-loadable; every field has a default).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderConfig {
    /// Image scale relative to the IPEX cameras' 1280 × 720 (1.0 full, 0.5 half
    /// resolution: 640 × 360, the camera model scaled alike).
    pub resolution_scale: f64,
    /// Sun elevation above the horizon, degrees (5–30 on the LAC site).
    pub sun_elevation_deg: f64,
    /// Sun azimuth, degrees, counter-clockwise from the world's +x axis.
    pub sun_azimuth_deg: f64,
    /// Weight `L` of the Lommel–Seeliger term in the lunar-Lambert reflectance
    /// `2L·μ0/(μ0+μ) + (1−L)·μ0` (1: pure Lommel–Seeliger, 0: Lambert); with
    /// `phase_dependent_weight`, the weight at zero phase.
    pub lommel_seeliger_weight: f64,
    /// Let the Lommel–Seeliger weight fall with the phase angle α between the sun and the
    /// viewer, as fitted to the Moon by McEwen (1991): `L(α) = 1 − 0.019α + 2.42·10⁻⁴α²
    /// − 1.46·10⁻⁶α³` (α in degrees, clamped to [0, 1]), times `lommel_seeliger_weight`.
    /// Looking away from a low sun the ground is lit almost evenly (Lommel–Seeliger); looking
    /// across or into it, it shades like Lambert, and sun-facing rock faces outshine it.
    /// `false`: the fixed weight.
    pub phase_dependent_weight: bool,
    /// Light in shadows and on faces turned away from the sun, as a fraction of a
    /// sun-facing surface's (black sky: only a little scattered light).
    pub ambient: f64,
    /// Mean regolith albedo (relative units: 1 is the reference of `exposure_dn`).
    pub regolith_albedo: f64,
    /// Contrast of the multi-scale albedo texture (standard deviation of its logarithm).
    pub albedo_contrast: f64,
    /// Mean rock albedo relative to the regolith's; each rock draws its own within ±30 %.
    pub rock_albedo: f64,
    /// Pebbles (drawn, not in the ground truth's rocks) per square metre.
    pub pebbles_per_m2: f64,
    /// Largest pebble radius, metres (smallest: a quarter of it).
    pub pebble_radius_max_m: f64,
    /// Fixed exposure: grey level of a surface of albedo 1 whose reflectance is 1.
    pub exposure_dn: f64,
    /// Display gamma: the linear signal `s ∈ [0, 1]` is written as `255·s^(1/gamma)`.
    pub gamma: f64,
    /// Sensor gain, electrons per grey level (shot noise: `sqrt(electrons)`).
    pub electrons_per_dn: f64,
    /// Read noise, grey levels (1 σ).
    pub read_noise_dn: f64,
    /// Texel of the shadow map on flat ground, metres.
    pub shadow_texel_m: f64,
    /// Nearest drawn surface (near clipping plane), metres.
    pub near_m: f64,
    /// Seed of the noise of the images (the scene's textures come from the moon's seed).
    pub noise_seed: u64,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            resolution_scale: 1.0,
            sun_elevation_deg: 15.0,
            sun_azimuth_deg: 30.0,
            lommel_seeliger_weight: 1.0,
            phase_dependent_weight: true,
            ambient: 0.03,
            regolith_albedo: 1.0,
            albedo_contrast: 0.25,
            rock_albedo: 1.1,
            pebbles_per_m2: 3.0,
            pebble_radius_max_m: 0.04,
            exposure_dn: 250.0,
            gamma: 1.6,
            electrons_per_dn: 20.0,
            read_noise_dn: 1.5,
            shadow_texel_m: 0.02,
            near_m: 0.05,
            noise_seed: 0,
        }
    }
}

impl RenderConfig {
    /// Check every value is in range; the error names the field.
    pub fn validate(&self) -> Result<(), RenderError> {
        let bad = |field: &'static str, message: &str| {
            Err(RenderError::InvalidConfig {
                field,
                message: message.to_string(),
            })
        };
        let in_range = |v: f64, lo: f64, hi: f64| v.is_finite() && v >= lo && v <= hi;
        if !(self.resolution_scale.is_finite()
            && self.resolution_scale > 0.0
            && self.resolution_scale <= 2.0)
            || self.width() == 0
            || self.height() == 0
        {
            return bad(
                "resolution_scale",
                "must be within (0, 2] and give a non-empty image",
            );
        }
        if !in_range(self.sun_elevation_deg, 0.5, 90.0) {
            return bad(
                "sun_elevation_deg",
                "the sun must be above the horizon (0.5–90°)",
            );
        }
        if !self.sun_azimuth_deg.is_finite() {
            return bad("sun_azimuth_deg", "must be finite");
        }
        let fields = [
            ("lommel_seeliger_weight", self.lommel_seeliger_weight, 1.0),
            ("ambient", self.ambient, 1.0),
            ("albedo_contrast", self.albedo_contrast, 2.0),
            ("read_noise_dn", self.read_noise_dn, 100.0),
            ("pebbles_per_m2", self.pebbles_per_m2, 100.0),
        ];
        for (field, v, hi) in fields {
            if !in_range(v, 0.0, hi) {
                return bad(field, &format!("must be within [0, {hi}] (got {v})"));
            }
        }
        let positive = [
            ("regolith_albedo", self.regolith_albedo),
            ("rock_albedo", self.rock_albedo),
            ("pebble_radius_max_m", self.pebble_radius_max_m),
            ("exposure_dn", self.exposure_dn),
            ("gamma", self.gamma),
            ("electrons_per_dn", self.electrons_per_dn),
            ("shadow_texel_m", self.shadow_texel_m),
            ("near_m", self.near_m),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, &format!("must be positive (got {v})"));
            }
        }
        if self.shadow_texel_m < 0.005 || self.pebble_radius_max_m > 0.2 {
            return bad(
                "shadow_texel_m",
                "shadow_texel_m must be ≥ 0.005 m and pebble_radius_max_m ≤ 0.2 m",
            );
        }
        Ok(())
    }

    /// Image width, pixels.
    pub fn width(&self) -> usize {
        (crate::ipex::IMAGE_WIDTH_PX * self.resolution_scale).round() as usize
    }

    /// Image height, pixels.
    pub fn height(&self) -> usize {
        (crate::ipex::IMAGE_HEIGHT_PX * self.resolution_scale).round() as usize
    }

    /// Unit vector toward the sun, world frame.
    pub fn sun_direction(&self) -> nalgebra::Vector3<f64> {
        let (e, a) = (
            self.sun_elevation_deg.to_radians(),
            self.sun_azimuth_deg.to_radians(),
        );
        nalgebra::Vector3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_out_of_range_values_naming_the_field() {
        assert!(RenderConfig::default().validate().is_ok());
        let cases = [
            (
                RenderConfig {
                    sun_elevation_deg: -3.0,
                    ..Default::default()
                },
                "sun_elevation_deg",
            ),
            (
                RenderConfig {
                    resolution_scale: 0.0,
                    ..Default::default()
                },
                "resolution_scale",
            ),
            (
                RenderConfig {
                    read_noise_dn: -1.0,
                    ..Default::default()
                },
                "read_noise_dn",
            ),
        ];
        for (config, field) in cases {
            let e = config.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
