//! Instance masks from the learned segmenter's output: three logits per output pixel
//! (background, rock, rock boundary), decoded by connected components of the rock class.
//!
//! 1. each output pixel takes its most likely class;
//! 2. 4-connected components of the `rock` pixels are the instances (the `boundary` class,
//!    trained on the pixels where two rocks touch, keeps touching rocks apart);
//! 3. each boundary pixel joins the instance it touches most (8-neighbourhood), so that
//!    masks reach the rock's outline again;
//! 4. instances smaller than [`UnetDecoderConfig::min_area_px`] output pixels, or with a
//!    mean rock probability under [`UnetDecoderConfig::min_score`], are dropped;
//! 5. masks are mapped to image pixels (each output pixel covers a block of the image).

use serde::{Deserialize, Serialize};

use super::{Mask, PerceptionError};
use crate::perception::gray_image::neighbours4;

/// Settings of the decoder.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UnetDecoderConfig {
    /// Smallest instance kept, in output pixels (one output pixel is 4 × 4 pixels of a
    /// 1280 × 720 image for the shipped model).
    pub min_area_px: usize,
    /// Smallest mean probability of rock (rock + boundary) over an instance's pixels.
    pub min_score: f32,
}

impl Default for UnetDecoderConfig {
    fn default() -> Self {
        UnetDecoderConfig {
            min_area_px: 3,
            min_score: 0.5,
        }
    }
}

impl UnetDecoderConfig {
    /// Checks the ranges; errors name the TOML path (`learned.*`).
    pub fn validate(&self) -> Result<(), PerceptionError> {
        if self.min_area_px == 0 {
            return Err(PerceptionError::Config(
                "learned.min_area_px must be at least 1".into(),
            ));
        }
        if !(0.0..=1.0).contains(&self.min_score) {
            return Err(PerceptionError::Config(format!(
                "learned.min_score must be in [0, 1], found {}",
                self.min_score
            )));
        }
        Ok(())
    }
}

const BACKGROUND: u8 = 0;
const ROCK: u8 = 1;
const BOUNDARY: u8 = 2;

/// Decode logits of shape `[1, 3, h, w]` into masks on an image of
/// `image_width × image_height` (which the `h × w` output covers uniformly). Errors
/// describe a shape that does not fit.
pub fn decode_unet(
    logits: &[f32],
    shape: &[usize],
    image_width: usize,
    image_height: usize,
    config: &UnetDecoderConfig,
) -> Result<Vec<Mask>, String> {
    let (h, w) = match shape {
        [1, 3, h, w] if *h > 0 && *w > 0 => (*h, *w),
        other => {
            return Err(format!(
                "expected logits of shape [1, 3, H, W], found {other:?}"
            ))
        }
    };
    if logits.len() != 3 * h * w {
        return Err(format!(
            "logits hold {} values, the shape {shape:?} needs {}",
            logits.len(),
            3 * h * w
        ));
    }
    let (classes, p_rock) = classify(logits, h * w);
    let mut label = components(&classes, w, h);
    attach_boundaries(&classes, &mut label, w, h);
    let count = label.iter().copied().max().unwrap_or(0) as usize;
    let mut pixels: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (i, &l) in label.iter().enumerate() {
        if l > 0 {
            pixels[l as usize - 1].push(i);
        }
    }
    let masks = pixels
        .into_iter()
        .filter(|p| p.len() >= config.min_area_px)
        .filter_map(|p| {
            let score = p.iter().map(|&i| p_rock[i]).sum::<f32>() / p.len() as f32;
            if score < config.min_score {
                return None;
            }
            to_image_mask(&p, w, h, image_width, image_height, score)
        })
        .collect();
    Ok(masks)
}

/// Per pixel: the most likely class and the probability of rock or boundary.
fn classify(logits: &[f32], n: usize) -> (Vec<u8>, Vec<f32>) {
    let mut classes = vec![BACKGROUND; n];
    let mut p_rock = vec![0.0f32; n];
    for i in 0..n {
        let l = [logits[i], logits[n + i], logits[2 * n + i]];
        let m = l.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let e = l.map(|x| (x - m).exp());
        let sum: f32 = e.iter().sum();
        p_rock[i] = (e[1] + e[2]) / sum;
        classes[i] = if l[1] >= l[0] && l[1] >= l[2] {
            ROCK
        } else if l[2] > l[0] && l[2] > l[1] {
            BOUNDARY
        } else {
            BACKGROUND
        };
    }
    (classes, p_rock)
}

/// 4-connected components of the rock pixels: 0 elsewhere, 1.. per component.
fn components(classes: &[u8], w: usize, h: usize) -> Vec<u32> {
    let mut label = vec![0u32; w * h];
    let mut next = 0u32;
    let mut stack = Vec::new();
    for start in 0..w * h {
        if classes[start] != ROCK || label[start] != 0 {
            continue;
        }
        next += 1;
        label[start] = next;
        stack.push(start);
        while let Some(i) = stack.pop() {
            for j in neighbours4(i, w, h) {
                if classes[j] == ROCK && label[j] == 0 {
                    label[j] = next;
                    stack.push(j);
                }
            }
        }
    }
    label
}

/// Each boundary pixel joins the component that holds most of its 8 neighbours.
fn attach_boundaries(classes: &[u8], label: &mut [u32], w: usize, h: usize) {
    let cores = label.to_vec();
    for i in (0..w * h).filter(|&i| classes[i] == BOUNDARY) {
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        let mut votes: Vec<(u32, u32)> = Vec::new();
        for dy in -1..=1i64 {
            for dx in -1..=1i64 {
                let (nx, ny) = (x + dx, y + dy);
                if (dx, dy) == (0, 0) || nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    continue;
                }
                let l = cores[ny as usize * w + nx as usize];
                if l == 0 {
                    continue;
                }
                match votes.iter_mut().find(|v| v.0 == l) {
                    Some(v) => v.1 += 1,
                    None => votes.push((l, 1)),
                }
            }
        }
        if let Some(&(l, _)) = votes.iter().max_by_key(|v| (v.1, std::cmp::Reverse(v.0))) {
            label[i] = l;
        }
    }
}

/// An output-resolution component as a mask over the image pixels it covers.
fn to_image_mask(
    pixels: &[usize],
    w: usize,
    h: usize,
    image_width: usize,
    image_height: usize,
    score: f32,
) -> Option<Mask> {
    let (sx, sy) = (
        image_width as f64 / w as f64,
        image_height as f64 / h as f64,
    );
    let span = |k: usize, s: f64, limit: usize| {
        let a = ((k as f64 * s).round() as usize).min(limit);
        let b = (((k + 1) as f64 * s).round() as usize).min(limit);
        a..b.max(a)
    };
    let mut image_pixels = Vec::new();
    for &i in pixels {
        let (x, y) = (i % w, i / w);
        for v in span(y, sy, image_height) {
            for u in span(x, sx, image_width) {
                image_pixels.push((u, v));
            }
        }
    }
    Mask::from_pixels(&image_pixels, score)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Logits of a class map: 4 for the class, 0 for the others.
    fn logits_of(classes: &[&str]) -> (Vec<f32>, Vec<usize>) {
        let (h, w) = (classes.len(), classes[0].len());
        let n = h * w;
        let mut l = vec![0.0f32; 3 * n];
        for (y, row) in classes.iter().enumerate() {
            for (x, c) in row.chars().enumerate() {
                let k = match c {
                    'r' => 1,
                    'b' => 2,
                    _ => 0,
                };
                l[k * n + y * w + x] = 4.0;
            }
        }
        (l, vec![1, 3, h, w])
    }

    #[test]
    fn touching_rocks_are_cut_by_the_boundary_and_keep_it() {
        let (l, shape) = logits_of(&[
            "........", //
            ".rrbrr..", //
            ".rrbrr..", //
            "......r.", // a single pixel: below min_area
            "........",
        ]);
        let mut masks = decode_unet(&l, &shape, 32, 20, &UnetDecoderConfig::default()).unwrap();
        assert_eq!(masks.len(), 2);
        masks.sort_by_key(|m| m.x0);
        // each output pixel is 4 × 4 image pixels; the boundary column joins the left rock
        // (equal votes: the lower label) and the right one keeps its two columns
        assert_eq!(masks[0].bbox(), [4, 4, 16, 12]);
        assert_eq!(masks[0].area(), 3 * 2 * 16);
        assert_eq!(masks[1].bbox(), [16, 4, 24, 12]);
        assert!(masks[0].score > 0.9);
    }

    #[test]
    fn low_scores_and_bad_shapes() {
        let (mut l, shape) = logits_of(&["rr", "rr"]);
        // rock barely wins: p(rock) ≈ 0.52, under a threshold of 0.6
        for i in 0..4 {
            l[i] = 3.9;
            l[4 + i] = 4.0;
            l[8 + i] = 0.0;
        }
        let strict = UnetDecoderConfig {
            min_area_px: 1,
            min_score: 0.6,
        };
        assert!(decode_unet(&l, &shape, 8, 8, &strict).unwrap().is_empty());
        let lax = UnetDecoderConfig {
            min_score: 0.5,
            ..strict
        };
        assert_eq!(decode_unet(&l, &shape, 8, 8, &lax).unwrap().len(), 1);
        assert!(decode_unet(&l, &[1, 2, 2, 2], 8, 8, &Default::default()).is_err());
        assert!(decode_unet(&l[..11], &shape, 8, 8, &Default::default()).is_err());
    }
}
