//! Left–right matching along the rectified rows: the disparity of a left-image point by
//! the sum of absolute differences over a window, refined to a fraction of a pixel by a
//! parabola through the best cost and its neighbours, kept when it is clearly the best.

use super::pyramid::FloatImage;
use serde::{Deserialize, Serialize};

/// Matching settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StereoMatchConfig {
    /// Half-size of the square window, pixels.
    pub half_window_px: usize,
    /// Smallest disparity searched, pixels (sets the farthest point).
    pub min_disparity_px: f32,
    /// Largest disparity searched, pixels (sets the nearest point).
    pub max_disparity_px: f32,
    /// The best cost must be below this fraction of the best one at least 2 px away.
    pub uniqueness: f32,
    /// Largest mean absolute difference per pixel at the best disparity.
    pub max_cost: f32,
}

impl Default for StereoMatchConfig {
    fn default() -> Self {
        Self {
            half_window_px: 4,
            min_disparity_px: 1.0,
            max_disparity_px: 160.0,
            uniqueness: 0.85,
            max_cost: 18.0,
        }
    }
}

/// The disparity `u_left − u_right` of the left point `(x, y)`, or `None`.
pub fn match_point(
    left: &FloatImage,
    right: &FloatImage,
    x: f32,
    y: f32,
    config: &StereoMatchConfig,
) -> Option<f32> {
    let hw = config.half_window_px as isize;
    let side = (2 * hw + 1) as usize;
    let d_min = config.min_disparity_px.floor().max(0.0) as isize;
    let d_max = (config.max_disparity_px.ceil() as isize).min(x as isize - hw - 1);
    if d_max <= d_min + 2 || y < hw as f32 + 1.0 || y > (left.height as isize - hw - 2) as f32 {
        return None;
    }
    let mut template = Vec::with_capacity(side * side);
    left.patch(x - hw as f32, y - hw as f32, side, side, &mut template);
    // Right rows at the same sub-pixel offsets, from x − d_max − hw to x − d_min + hw.
    let span = (d_max - d_min) as usize + side;
    let x0 = x - (d_max + hw) as f32;
    let mut strip = Vec::with_capacity(side * span);
    right.patch(x0, y - hw as f32, span, side, &mut strip);
    let count = (d_max - d_min + 1) as usize;
    // costs[k] is the window at disparity d = d_max − k, starting at column k of the strip.
    // Each cost takes its terms in the window's row-major order, one template pixel at a
    // time over all disparities: the sums are those of a window-by-window loop, bit for
    // bit, and the inner loop runs over contiguous columns (vectorised).
    let mut costs = vec![0.0f32; count];
    for r in 0..side {
        for c in 0..side {
            let t = template[r * side + c];
            let row = &strip[r * span + c..][..count];
            for (cost, a) in costs.iter_mut().zip(row) {
                *cost += (a - t).abs();
            }
        }
    }
    let (best_k, &best) = costs.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    let second = costs
        .iter()
        .enumerate()
        .filter(|(k, _)| (*k as isize - best_k as isize).abs() >= 2)
        .map(|(_, c)| *c)
        .fold(f32::INFINITY, f32::min);
    let n = (side * side) as f32;
    if best / n > config.max_cost || best > config.uniqueness * second {
        return None;
    }
    if best_k == 0 || best_k + 1 >= count {
        return None;
    }
    let (cm, cp) = (costs[best_k - 1], costs[best_k + 1]);
    let denom = cm - 2.0 * best + cp;
    let offset = if denom > 0.0 {
        0.5 * (cm - cp) / denom
    } else {
        0.0
    };
    // k grows as the disparity shrinks
    let disparity = (d_max - best_k as isize) as f32 - offset;
    (disparity >= config.min_disparity_px).then_some(disparity)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(shift: f32) -> FloatImage {
        let (w, h) = (200, 60);
        let mut data = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let u = x as f32 + shift;
                data.push(
                    128.0
                        + 50.0 * (u * 0.31).sin() * (y as f32 * 0.23).cos()
                        + 30.0 * (u * 0.047 + y as f32 * 0.11).sin(),
                );
            }
        }
        FloatImage {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn a_known_disparity_is_found() {
        let left = image(0.0);
        let right = image(17.4);
        let d = match_point(&left, &right, 120.0, 30.0, &StereoMatchConfig::default()).unwrap();
        assert!((d - 17.4).abs() < 0.25, "{d}");
    }
}
