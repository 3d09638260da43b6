//! The camera's sensor: a fixed exposure turns radiance into grey levels, then shot noise
//! (Poisson, as a Gaussian of variance electrons), read noise, a display gamma and 8 bits.

use super::config::RenderConfig;
use super::hash_noise::gaussian;
use crate::perception::GrayImage;
use rayon::prelude::*;

/// The 8-bit image of a `width × height` radiance image (relative units, see
/// [`RenderConfig::exposure_dn`]); `noise_key` draws the noise.
pub fn expose(
    radiance: &[f32],
    width: usize,
    height: usize,
    config: &RenderConfig,
    noise_key: u64,
) -> GrayImage {
    let mut data = vec![0u8; width * height];
    let read_var = config.read_noise_dn * config.read_noise_dn;
    // grey level of a linear signal, in steps of 1/16 grey level
    let lut: Vec<u8> = (0..=255 * 16)
        .map(|k| (255.0 * (k as f64 / (255.0 * 16.0)).powf(1.0 / config.gamma)).round() as u8)
        .collect();
    data.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            let idx = y * width + x;
            let signal = config.exposure_dn * radiance[idx] as f64;
            let sigma = (signal.max(0.0) / config.electrons_per_dn + read_var).sqrt();
            let key = noise_key.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ idx as u64;
            let dn = signal + sigma * gaussian(key);
            *out = lut[(dn * 16.0).clamp(0.0, 255.0 * 16.0) as usize];
        }
    });
    GrayImage {
        width,
        height,
        data,
    }
}
