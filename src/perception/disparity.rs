//! Dense disparity maps and what can be read from them.

use super::StereoCamera;

/// A dense disparity map of the left image, possibly at a reduced resolution.
///
/// `data[y * width + x]` is the disparity in pixels *of this map's resolution*, NaN where
/// no reliable match was found. One map pixel covers `scale × scale` image pixels.
#[derive(Clone, Debug)]
pub struct DisparityMap {
    /// Width of the map.
    pub width: usize,
    /// Height of the map.
    pub height: usize,
    /// Disparities (map pixels), NaN = invalid.
    pub data: Vec<f32>,
    /// Image pixels per map pixel along each axis (1 = full resolution).
    pub scale: usize,
    /// The camera at the map's resolution.
    pub camera: StereoCamera,
}

impl DisparityMap {
    /// The disparity at map pixel `(x, y)`, if valid.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Option<f32> {
        let d = *self.data.get(y * self.width + x)?;
        d.is_finite().then_some(d)
    }

    /// The disparity at image pixel `(u, v)`, in image pixels, if valid.
    pub fn at_image_pixel(&self, u: usize, v: usize) -> Option<f64> {
        let (x, y) = (u / self.scale, v / self.scale);
        if x >= self.width || y >= self.height {
            return None;
        }
        self.get(x, y).map(|d| d as f64 * self.scale as f64)
    }

    /// Depth in metres at map pixel `(x, y)`, if valid.
    pub fn depth_m(&self, x: usize, y: usize) -> Option<f64> {
        self.get(x, y)
            .and_then(|d| self.camera.depth_from_disparity(d as f64))
    }

    /// Fraction of valid pixels.
    pub fn valid_fraction(&self) -> f64 {
        if self.data.is_empty() {
            return 0.0;
        }
        self.data.iter().filter(|d| d.is_finite()).count() as f64 / self.data.len() as f64
    }
}
