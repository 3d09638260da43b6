//! Float image pyramids for tracking: level 0 is the image, each level above is the 2 × 2
//! mean of the one below; bilinear sampling with clamping at the border.

use crate::perception::GrayImage;

/// A float image, row-major.
#[derive(Clone, Debug)]
pub struct FloatImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Intensities, row-major.
    pub data: Vec<f32>,
}

impl FloatImage {
    /// The image of an 8-bit one.
    pub fn from_gray(image: &GrayImage) -> Self {
        Self {
            width: image.width,
            height: image.height,
            data: image.data.iter().map(|&v| v as f32).collect(),
        }
    }

    /// The value at integer coordinates (clamped to the image).
    #[inline]
    pub fn at(&self, x: isize, y: isize) -> f32 {
        let x = x.clamp(0, self.width as isize - 1) as usize;
        let y = y.clamp(0, self.height as isize - 1) as usize;
        self.data[y * self.width + x]
    }

    /// Bilinear sample at `(x, y)` (pixel centres at integers).
    #[inline]
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as isize, y0 as isize);
        let a = self.at(xi, yi);
        let b = self.at(xi + 1, yi);
        let c = self.at(xi, yi + 1);
        let d = self.at(xi + 1, yi + 1);
        (a + (b - a) * fx) + ((c + (d - c) * fx) - (a + (b - a) * fx)) * fy
    }

    /// Bilinear samples at `(x0 + i, y0 + j)` for `i < w`, `j < h`, row by row, into `out`.
    /// All samples share one pair of interpolation weights, so the interior is sampled
    /// without clamping or recomputing them.
    pub fn patch(&self, x0: f32, y0: f32, w: usize, h: usize, out: &mut Vec<f32>) {
        out.clear();
        let (fx0, fy0) = (x0.floor(), y0.floor());
        let (xi, yi) = (fx0 as isize, fy0 as isize);
        let inside =
            xi >= 0 && yi >= 0 && (xi as usize + w) < self.width && (yi as usize + h) < self.height;
        if !inside {
            for j in 0..h {
                for i in 0..w {
                    out.push(self.sample(x0 + i as f32, y0 + j as f32));
                }
            }
            return;
        }
        let (fx, fy) = (x0 - fx0, y0 - fy0);
        let (w00, w10, w01, w11) = (
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        );
        let (xi, yi) = (xi as usize, yi as usize);
        out.resize(w * h, 0.0);
        for (j, dst) in out.chunks_exact_mut(w).enumerate() {
            let r0 = &self.data[(yi + j) * self.width + xi..][..w + 1];
            let r1 = &self.data[(yi + j + 1) * self.width + xi..][..w + 1];
            for ((v, a), b) in dst.iter_mut().zip(r0.windows(2)).zip(r1.windows(2)) {
                *v = w00 * a[0] + w10 * a[1] + w01 * b[0] + w11 * b[1];
            }
        }
    }

    /// The image at half resolution (2 × 2 means).
    pub fn half(&self) -> Self {
        let (w, h) = (self.width / 2, self.height / 2);
        let mut data = Vec::with_capacity(w * h);
        for y in 0..h {
            let r0 = &self.data[2 * y * self.width..];
            let r1 = &self.data[(2 * y + 1) * self.width..];
            for x in 0..w {
                data.push(0.25 * (r0[2 * x] + r0[2 * x + 1] + r1[2 * x] + r1[2 * x + 1]));
            }
        }
        Self {
            width: w,
            height: h,
            data,
        }
    }
}

/// An image pyramid, finest level first.
#[derive(Clone, Debug)]
pub struct Pyramid {
    /// Levels, level `k` at `2^-k` resolution.
    pub levels: Vec<FloatImage>,
}

impl Pyramid {
    /// A pyramid of `levels` levels (at least one; levels stop above 16 pixels).
    pub fn new(image: &GrayImage, levels: usize) -> Self {
        let mut out = vec![FloatImage::from_gray(image)];
        while out.len() < levels.max(1) {
            let last = &out[out.len() - 1];
            if last.width < 32 || last.height < 32 {
                break;
            }
            out.push(last.half());
        }
        Self { levels: out }
    }

    /// The full-resolution image.
    pub fn base(&self) -> &FloatImage {
        &self.levels[0]
    }
}
