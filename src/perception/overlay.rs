//! An overlay picture a person can check at a glance: the left image with each accepted
//! boulder tinted green, boxed, its centroid crossed and labelled "depth m / size m", and
//! each rejected mask outlined in red (orange when it only touched the border).

use std::path::Path;

use super::front_end::FrameResult;
use super::gray_image::encode_rgb_png;
use super::{GrayImage, PerceptionError};

const GREEN: [u8; 3] = [40, 230, 60];
const YELLOW: [u8; 3] = [255, 230, 0];
const RED: [u8; 3] = [235, 40, 40];
const ORANGE: [u8; 3] = [255, 150, 0];

/// The overlay as RGB pixels (`3 * width * height` bytes).
pub fn overlay_rgb(left: &GrayImage, result: &FrameResult) -> Vec<u8> {
    let (w, h) = (left.width, left.height);
    let mut rgb: Vec<u8> = left.data.iter().flat_map(|&v| [v, v, v]).collect();
    let put = |rgb: &mut Vec<u8>, x: isize, y: isize, c: [u8; 3]| {
        if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
            let i = 3 * (y as usize * w + x as usize);
            rgb[i..i + 3].copy_from_slice(&c);
        }
    };
    for (mask, verdict) in result.masks.iter().zip(&result.verdicts) {
        let colour = match verdict {
            Ok(_) => GREEN,
            Err(super::boulders::Rejection::Border) => ORANGE,
            Err(_) => RED,
        };
        for (x, y) in mask.pixels() {
            if mask.is_edge(x, y) {
                put(&mut rgb, x as isize, y as isize, colour);
            } else if verdict.is_ok() {
                let i = 3 * (y * w + x);
                for (k, &c) in GREEN.iter().enumerate() {
                    rgb[i + k] = ((rgb[i + k] as u16 * 5 + c as u16 * 3) / 8) as u8;
                }
            }
        }
    }
    for b in &result.boulders {
        let [x0, y0, x1, y1] = b.pixel_box.map(|v| v as isize);
        let (x0, y0, x1, y1) = (x0 - 3, y0 - 3, x1 + 2, y1 + 2);
        for x in x0..=x1 {
            put(&mut rgb, x, y0, GREEN);
            put(&mut rgb, x, y1, GREEN);
        }
        for y in y0..=y1 {
            put(&mut rgb, x0, y, GREEN);
            put(&mut rgb, x1, y, GREEN);
        }
        let (cu, cv) = (
            b.pixel_centroid[0].round() as isize,
            b.pixel_centroid[1].round() as isize,
        );
        for k in -5..=5 {
            put(&mut rgb, cu + k, cv, YELLOW);
            put(&mut rgb, cu, cv + k, YELLOW);
        }
        let label = format!("{:.1}m/{:.2}", b.depth_m, b.size_m);
        let ty = if y0 >= 14 { y0 - 13 } else { y1 + 3 };
        draw_text(&mut rgb, w, h, x0, ty, &label, YELLOW);
    }
    rgb
}

/// Write the overlay as an RGB PNG.
pub fn write_overlay(
    left: &GrayImage,
    result: &FrameResult,
    path: &Path,
) -> Result<(), PerceptionError> {
    let bytes = encode_rgb_png(&overlay_rgb(left, result), left.width, left.height)?;
    std::fs::write(path, bytes).map_err(|e| PerceptionError::io(path, e))
}

/// Text at (x, y) (top left), glyphs scaled ×2, on a dark backing for legibility.
fn draw_text(rgb: &mut [u8], w: usize, h: usize, x: isize, y: isize, text: &str, colour: [u8; 3]) {
    const S: isize = 2;
    let mut set = |px: isize, py: isize, c: [u8; 3]| {
        if px >= 0 && py >= 0 && (px as usize) < w && (py as usize) < h {
            let i = 3 * (py as usize * w + px as usize);
            rgb[i..i + 3].copy_from_slice(&c);
        }
    };
    let n = text.chars().count() as isize;
    for py in y - 1..y + 5 * S + 1 {
        for px in x - 1..x + n * 4 * S {
            set(px, py, [0, 0, 0]);
        }
    }
    crate::font::for_each_lit_pixel(text, |fx, fy| {
        for sy in 0..S {
            for sx in 0..S {
                set(x + fx as isize * S + sx, y + fy as isize * S + sy, colour);
            }
        }
    });
}
