//! The camera's sensor: a fixed exposure turns radiance into grey levels, then shot noise
//! (Poisson, as a Gaussian of variance electrons), read noise, a display gamma and 8 bits.
//!
//! [`Sensor::grey`] exposes one pixel, so that the renderer can expose each pixel as it is
//! shaded (no radiance image in memory); [`expose`] does a whole radiance image.

use super::config::RenderConfig;
use super::hash_noise::gaussian;
use crate::perception::GrayImage;
use rayon::prelude::*;

/// The sensor's constants, prepared once per renderer.
#[derive(Clone, Debug)]
pub struct Sensor {
    exposure_dn: f64,
    inv_electrons_per_dn: f64,
    read_var: f64,
    /// Grey level of a linear signal, in steps of 1/16 grey level.
    lut: Vec<u8>,
}

impl Sensor {
    /// The sensor of `config`.
    pub fn new(config: &RenderConfig) -> Sensor {
        let lut = (0..=255 * 16)
            .map(|k| (255.0 * (k as f64 / (255.0 * 16.0)).powf(1.0 / config.gamma)).round() as u8)
            .collect();
        Sensor {
            exposure_dn: config.exposure_dn,
            inv_electrons_per_dn: 1.0 / config.electrons_per_dn,
            read_var: config.read_noise_dn * config.read_noise_dn,
            lut,
        }
    }

    /// The noisy 8-bit grey level of pixel `idx` (row-major) receiving `radiance`
    /// (relative units, see [`RenderConfig::exposure_dn`]); `noise_key` is the image's.
    #[inline]
    pub fn grey(&self, radiance: f64, noise_key: u64, idx: usize) -> u8 {
        let signal = self.exposure_dn * radiance;
        let sigma = (signal.max(0.0) * self.inv_electrons_per_dn + self.read_var).sqrt();
        let key = noise_key.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ idx as u64;
        let dn = signal + sigma * gaussian(key);
        self.lut[(dn * 16.0).clamp(0.0, 255.0 * 16.0) as usize]
    }
}

/// The 8-bit image of a `width × height` radiance image (relative units, see
/// [`RenderConfig::exposure_dn`]); `noise_key` draws the noise.
pub fn expose(
    radiance: &[f32],
    width: usize,
    height: usize,
    config: &RenderConfig,
    noise_key: u64,
) -> GrayImage {
    let sensor = Sensor::new(config);
    let mut data = vec![0u8; width * height];
    data.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            let idx = y * width + x;
            *out = sensor.grey(radiance[idx] as f64, noise_key, idx);
        }
    });
    GrayImage {
        width,
        height,
        data,
    }
}
