//! Instance masks: a bounding box and the pixels inside it that belong to the object.

/// One object's pixels in image coordinates, stored as a bit map over its bounding box.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    /// Left column of the bounding box.
    pub x0: usize,
    /// Top row of the bounding box.
    pub y0: usize,
    /// Width of the bounding box.
    pub width: usize,
    /// Height of the bounding box.
    pub height: usize,
    /// `bits[(y - y0) * width + (x - x0)]`: whether pixel (x, y) belongs to the object.
    pub bits: Vec<bool>,
    /// Segmenter confidence in [0, 1].
    pub score: f32,
}

impl Mask {
    /// The mask of a set of pixels `(x, y)`; `None` when empty.
    pub fn from_pixels(pixels: &[(usize, usize)], score: f32) -> Option<Mask> {
        let x0 = pixels.iter().map(|p| p.0).min()?;
        let y0 = pixels.iter().map(|p| p.1).min()?;
        let x1 = pixels.iter().map(|p| p.0).max()? + 1;
        let y1 = pixels.iter().map(|p| p.1).max()? + 1;
        let width = x1 - x0;
        let mut bits = vec![false; width * (y1 - y0)];
        for &(x, y) in pixels {
            bits[(y - y0) * width + (x - x0)] = true;
        }
        Some(Mask {
            x0,
            y0,
            width,
            height: y1 - y0,
            bits,
            score,
        })
    }

    /// A mask from a full-image boolean map (`map[y * image_width + x]`), `None` if empty.
    pub fn from_image_map(map: &[bool], image_width: usize, score: f32) -> Option<Mask> {
        let pixels: Vec<(usize, usize)> = map
            .iter()
            .enumerate()
            .filter(|(_, &b)| b)
            .map(|(i, _)| (i % image_width, i / image_width))
            .collect();
        Mask::from_pixels(&pixels, score)
    }

    /// Whether image pixel `(x, y)` belongs to the mask.
    #[inline]
    pub fn contains(&self, x: usize, y: usize) -> bool {
        x >= self.x0
            && y >= self.y0
            && x < self.x0 + self.width
            && y < self.y0 + self.height
            && self.bits[(y - self.y0) * self.width + (x - self.x0)]
    }

    /// Number of pixels in the mask.
    pub fn area(&self) -> usize {
        self.bits.iter().filter(|&&b| b).count()
    }

    /// The mask's pixels `(x, y)`, row by row.
    pub fn pixels(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.bits
            .iter()
            .enumerate()
            .filter(|(_, &b)| b)
            .map(|(i, _)| (self.x0 + i % self.width, self.y0 + i / self.width))
    }

    /// Bounding box `[x0, y0, x1, y1]`, with `x1`, `y1` exclusive.
    pub fn bbox(&self) -> [usize; 4] {
        [
            self.x0,
            self.y0,
            self.x0 + self.width,
            self.y0 + self.height,
        ]
    }

    /// Whether some pixel lies within `margin` pixels of the border of an image of
    /// `image_width × image_height`.
    pub fn touches_border(&self, image_width: usize, image_height: usize, margin: usize) -> bool {
        self.pixels().any(|(x, y)| {
            x < margin
                || y < margin
                || x + margin >= image_width.max(margin)
                || y + margin >= image_height.max(margin)
        })
    }

    /// The same mask on an image `factor` times larger (each pixel becomes a block).
    pub fn upscaled(&self, factor: usize) -> Mask {
        if factor <= 1 {
            return self.clone();
        }
        let (w, h) = (self.width * factor, self.height * factor);
        let mut bits = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                bits[y * w + x] = self.bits[(y / factor) * self.width + x / factor];
            }
        }
        Mask {
            x0: self.x0 * factor,
            y0: self.y0 * factor,
            width: w,
            height: h,
            bits,
            score: self.score,
        }
    }

    /// Intersection over union with another mask.
    pub fn iou(&self, other: &Mask) -> f64 {
        let inter = self.pixels().filter(|&(x, y)| other.contains(x, y)).count();
        let union = self.area() + other.area() - inter;
        if union == 0 {
            0.0
        } else {
            inter as f64 / union as f64
        }
    }

    /// Whether pixel `(x, y)` of the mask is on its outline (in the mask, with a 4-neighbour
    /// outside it).
    pub fn is_edge(&self, x: usize, y: usize) -> bool {
        self.contains(x, y)
            && (x == 0
                || y == 0
                || !self.contains(x - 1, y)
                || !self.contains(x + 1, y)
                || !self.contains(x, y - 1)
                || !self.contains(x, y + 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_round_trip_and_bbox() {
        let px = [(3, 4), (4, 4), (4, 5)];
        let m = Mask::from_pixels(&px, 1.0).unwrap();
        assert_eq!(m.bbox(), [3, 4, 5, 6]);
        assert_eq!(m.area(), 3);
        assert_eq!(m.pixels().collect::<Vec<_>>(), px.to_vec());
        assert!(!m.contains(3, 5));
        assert!(Mask::from_pixels(&[], 1.0).is_none());
    }

    #[test]
    fn border_and_upscale() {
        let m = Mask::from_pixels(&[(0, 3), (1, 3)], 1.0).unwrap();
        assert!(m.touches_border(10, 10, 1));
        let n = Mask::from_pixels(&[(4, 4)], 1.0).unwrap();
        assert!(!n.touches_border(10, 10, 2));
        let up = n.upscaled(2);
        assert_eq!(up.bbox(), [8, 8, 10, 10]);
        assert_eq!(up.area(), 4);
        assert!((n.iou(&n) - 1.0).abs() < 1e-12);
    }
}
