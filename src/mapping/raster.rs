//! A small RGB rasteriser for the map pictures: filled rectangles, lines, dots and a
//! 3 × 5 pixel font (digits, capital letters and a little punctuation; lower case is
//! drawn in capitals), encoded as PNG with the `image` crate and written atomically.

use std::path::Path;

use segloc_maps::{write_atomic, MapError};
use thiserror::Error;

/// An RGB colour.
pub type Rgb = [u8; 3];

/// Why a picture could not be written.
#[derive(Debug, Error)]
pub enum PictureError {
    /// PNG encoding failed.
    #[error("encoding PNG for {path}: {message}")]
    Encode {
        /// The file being written.
        path: String,
        /// The encoder's message.
        message: String,
    },
    /// Writing the file failed.
    #[error(transparent)]
    Write(#[from] MapError),
    /// The picture would be empty or absurdly large.
    #[error("picture of {width} × {height} pixels is not drawable")]
    Size {
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
    },
}

/// An RGB canvas, row-major, origin at the top left.
#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height × 3` bytes.
    pub pixels: Vec<u8>,
}

/// Largest side of a canvas, pixels.
pub const MAX_SIDE: usize = 16_384;

impl Canvas {
    /// A canvas filled with `background`.
    pub fn new(width: usize, height: usize, background: Rgb) -> Result<Self, PictureError> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(PictureError::Size { width, height });
        }
        let mut pixels = Vec::with_capacity(width * height * 3);
        for _ in 0..width * height {
            pixels.extend_from_slice(&background);
        }
        Ok(Canvas {
            width,
            height,
            pixels,
        })
    }

    /// Set one pixel (ignored outside the canvas).
    pub fn put(&mut self, x: i64, y: i64, c: Rgb) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            let k = (y as usize * self.width + x as usize) * 3;
            self.pixels[k..k + 3].copy_from_slice(&c);
        }
    }

    /// The colour at a pixel, if inside.
    pub fn get(&self, x: usize, y: usize) -> Option<Rgb> {
        (x < self.width && y < self.height).then(|| {
            let k = (y * self.width + x) * 3;
            [self.pixels[k], self.pixels[k + 1], self.pixels[k + 2]]
        })
    }

    /// Fill the rectangle with top-left (x, y) and size w × h (clipped).
    pub fn fill_rect(&mut self, x: i64, y: i64, w: i64, h: i64, c: Rgb) {
        let x0 = x.max(0);
        let y0 = y.max(0);
        let x1 = (x + w).min(self.width as i64);
        let y1 = (y + h).min(self.height as i64);
        for yy in y0..y1 {
            for xx in x0..x1 {
                self.put(xx, yy, c);
            }
        }
    }

    /// A filled disc of `radius` pixels at (x, y).
    pub fn dot(&mut self, x: f64, y: f64, radius: f64, c: Rgb) {
        if !(x.is_finite() && y.is_finite() && radius.is_finite()) {
            return;
        }
        let r = radius.max(0.5);
        let (x0, x1) = ((x - r).floor() as i64, (x + r).ceil() as i64);
        let (y0, y1) = ((y - r).floor() as i64, (y + r).ceil() as i64);
        for yy in y0..=y1 {
            for xx in x0..=x1 {
                let (dx, dy) = (xx as f64 + 0.5 - x, yy as f64 + 0.5 - y);
                if dx * dx + dy * dy <= r * r {
                    self.put(xx, yy, c);
                }
            }
        }
    }

    /// A line from (x0, y0) to (x1, y1), `width` pixels wide (dots along the segment).
    pub fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, width: f64, c: Rgb) {
        if ![x0, y0, x1, y1].iter().all(|v| v.is_finite()) {
            return;
        }
        let len = (x1 - x0).hypot(y1 - y0);
        if len > 4.0 * MAX_SIDE as f64 {
            return;
        }
        let steps = (len * 2.0).ceil().max(1.0) as usize;
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            self.dot(x0 + t * (x1 - x0), y0 + t * (y1 - y0), width / 2.0, c);
        }
    }

    /// Text in the 3 × 5 font scaled by `scale`, top-left at (x, y); returns the x after it.
    pub fn text(&mut self, x: i64, y: i64, text: &str, scale: i64, c: Rgb) -> i64 {
        crate::font::for_each_lit_pixel(text, |fx, fy| {
            self.fill_rect(x + fx * scale, y + fy * scale, scale, scale, c)
        });
        x + text.chars().count() as i64 * crate::font::ADVANCE * scale
    }

    /// A legend entry: a colour block then its label; returns the x after it.
    pub fn legend(&mut self, x: i64, y: i64, c: Rgb, label: &str, scale: i64) -> i64 {
        self.fill_rect(x, y, 5 * scale, 5 * scale, c);
        self.text(x + 7 * scale, y, label, scale, [20, 20, 20]) + 4 * scale
    }

    /// Encode as PNG and write atomically.
    pub fn write_png(&self, path: &Path) -> Result<(), PictureError> {
        let mut bytes = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut bytes);
        image::ImageEncoder::write_image(
            encoder,
            &self.pixels,
            self.width as u32,
            self.height as u32,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| PictureError::Encode {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        write_atomic(path, &bytes)?;
        Ok(())
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_and_clips() {
        let mut c = Canvas::new(20, 10, [255, 255, 255]).unwrap();
        c.fill_rect(-5, -5, 8, 8, [1, 2, 3]);
        assert_eq!(c.get(0, 0), Some([1, 2, 3]));
        assert_eq!(c.get(3, 3), Some([255, 255, 255]));
        c.line(0.0, 9.5, 19.0, 9.5, 1.0, [9, 9, 9]);
        assert_eq!(c.get(10, 9), Some([9, 9, 9]));
        c.dot(100.0, 100.0, 3.0, [0, 0, 0]); // off the canvas: nothing, no panic
        c.line(f64::NAN, 0.0, 1.0, 1.0, 1.0, [0, 0, 0]);
        let end = c.text(0, 0, "A1", 1, [0, 0, 0]);
        assert_eq!(end, 8);
        assert_eq!(c.get(1, 0), Some([0, 0, 0])); // top of the A
        assert!(Canvas::new(0, 5, [0; 3]).is_err());
    }

    #[test]
    fn writes_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.png");
        let c = Canvas::new(4, 3, [10, 20, 30]).unwrap();
        c.write_png(&p).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(c.write_png(&dir.path().join("no/such/dir/x.png")).is_err());
    }
}
