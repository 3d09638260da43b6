//! Pyramidal Lucas–Kanade tracking (Bouguet's formulation) with a forward–backward check.

use super::pyramid::{FloatImage, Pyramid};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Tracking settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct KltConfig {
    /// Half-size of the square window, pixels (window `2 h + 1`).
    pub half_window_px: usize,
    /// Gauss–Newton iterations per pyramid level.
    pub iterations: usize,
    /// A track is kept when tracking it back lands within this distance of where it
    /// started, pixels.
    pub forward_backward_px: f32,
    /// Largest mean absolute intensity difference over the window after convergence.
    pub max_residual: f32,
}

impl Default for KltConfig {
    fn default() -> Self {
        Self {
            half_window_px: 6,
            iterations: 12,
            forward_backward_px: 0.5,
            max_residual: 20.0,
        }
    }
}

/// Tracks one point from `from` to `to`, starting at `guess` (both full-resolution
/// coordinates); `None` when it leaves the image, the window has no texture or the fit is poor.
fn track_point(
    from: &Pyramid,
    to: &Pyramid,
    p: (f32, f32),
    guess: (f32, f32),
    config: &KltConfig,
) -> Option<(f32, f32)> {
    let levels = from.levels.len().min(to.levels.len());
    let top = (levels - 1) as i32;
    let scale = 0.5f32.powi(top);
    let mut d = ((guess.0 - p.0) * scale, (guess.1 - p.1) * scale);
    let mut residual = 0.0;
    for level in (0..levels).rev() {
        let s = 0.5f32.powi(level as i32);
        let (a, b) = (&from.levels[level], &to.levels[level]);
        let (px, py) = (p.0 * s, p.1 * s);
        let (step, r) = track_level(a, b, (px, py), d, config)?;
        d = step;
        residual = r;
        if level > 0 {
            d = (d.0 * 2.0, d.1 * 2.0);
        }
    }
    if residual > config.max_residual {
        return None;
    }
    let q = (p.0 + d.0, p.1 + d.1);
    let (w, h) = (to.base().width as f32, to.base().height as f32);
    (q.0 >= 1.0 && q.1 >= 1.0 && q.0 < w - 2.0 && q.1 < h - 2.0).then_some(q)
}

/// One level: the displacement `d` of the window around `p` of `a` in `b`, and the mean
/// absolute residual.
fn track_level(
    a: &FloatImage,
    b: &FloatImage,
    p: (f32, f32),
    d0: (f32, f32),
    config: &KltConfig,
) -> Option<((f32, f32), f32)> {
    let hw = config.half_window_px;
    let side = 2 * hw + 1;
    let n = side * side;
    // The template with a one-pixel border, for central-difference gradients.
    let mut big = Vec::with_capacity((side + 2) * (side + 2));
    a.patch(
        p.0 - hw as f32 - 1.0,
        p.1 - hw as f32 - 1.0,
        side + 2,
        side + 2,
        &mut big,
    );
    let stride = side + 2;
    let mut template = Vec::with_capacity(n);
    let mut grads = Vec::with_capacity(n);
    let (mut gxx, mut gxy, mut gyy) = (0.0f32, 0.0f32, 0.0f32);
    for j in 1..=side {
        for i in 1..=side {
            let k = j * stride + i;
            let gx = 0.5 * (big[k + 1] - big[k - 1]);
            let gy = 0.5 * (big[k + stride] - big[k - stride]);
            template.push(big[k]);
            grads.push((gx, gy));
            gxx += gx * gx;
            gxy += gx * gy;
            gyy += gy * gy;
        }
    }
    let det = gxx * gyy - gxy * gxy;
    let min_eig = 0.5 * (gxx + gyy) - (0.25 * (gxx - gyy) * (gxx - gyy) + gxy * gxy).sqrt();
    if det.abs() < 1e-6 || min_eig / (n as f32) < 1e-3 {
        return None;
    }
    let mut d = d0;
    let mut residual = 0.0;
    let mut window = Vec::with_capacity(n);
    for _ in 0..config.iterations {
        b.patch(
            p.0 + d.0 - hw as f32,
            p.1 + d.1 - hw as f32,
            side,
            side,
            &mut window,
        );
        let (mut ex, mut ey, mut abs_sum) = (0.0f32, 0.0f32, 0.0f32);
        for k in 0..n {
            let diff = window[k] - template[k];
            ex += diff * grads[k].0;
            ey += diff * grads[k].1;
            abs_sum += diff.abs();
        }
        residual = abs_sum / n as f32;
        let step = ((gyy * ex - gxy * ey) / det, (gxx * ey - gxy * ex) / det);
        d = (d.0 - step.0, d.1 - step.1);
        if !(d.0.is_finite() && d.1.is_finite()) {
            return None;
        }
        if step.0 * step.0 + step.1 * step.1 < 1e-4 {
            break;
        }
    }
    Some((d, residual))
}

/// Tracks `points` from `from` to `to`, each checked by tracking back; `None` for a lost
/// point.
///
/// `predicted` holds, per point, where the motion prior expects it in `to` (or `None`):
/// the search starts there and falls back to the point's own position when that fails,
/// so a steady turn of tens of pixels a frame stays within the pyramid's reach while a
/// sudden stop is still found. Points are tracked in parallel (rayon); each point's result
/// depends on it alone, so any number of threads gives the same tracks.
pub fn track(
    from: &Pyramid,
    to: &Pyramid,
    points: &[(f32, f32)],
    predicted: &[Option<(f32, f32)>],
    config: &KltConfig,
) -> Vec<Option<(f32, f32)>> {
    points
        .par_iter()
        .enumerate()
        .with_min_len(8)
        .map(|(i, &p)| {
            let guess = predicted.get(i).copied().flatten();
            guess
                .and_then(|g| track_checked(from, to, p, g, config))
                .or_else(|| track_checked(from, to, p, p, config))
        })
        .collect()
}

/// One point tracked from `guess` and checked by tracking it back to `p`.
fn track_checked(
    from: &Pyramid,
    to: &Pyramid,
    p: (f32, f32),
    guess: (f32, f32),
    config: &KltConfig,
) -> Option<(f32, f32)> {
    let q = track_point(from, to, p, guess, config)?;
    let back = track_point(to, from, q, p, config)?;
    let err = ((back.0 - p.0).powi(2) + (back.1 - p.1).powi(2)).sqrt();
    (err <= config.forward_backward_px).then_some(q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::GrayImage;

    fn textured(shift_x: f32, shift_y: f32) -> GrayImage {
        let (w, h) = (160, 120);
        let mut data = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (u, v) = (x as f32 - shift_x, y as f32 - shift_y);
                let value = 128.0
                    + 60.0 * (u * 0.21).sin() * (v * 0.17).cos()
                    + 40.0 * ((u + 2.0 * v) * 0.07).sin();
                data.push(value.clamp(0.0, 255.0) as u8);
            }
        }
        GrayImage::new(w, h, data).unwrap()
    }

    #[test]
    fn a_shifted_image_is_tracked() {
        let a = Pyramid::new(&textured(0.0, 0.0), 3);
        let b = Pyramid::new(&textured(4.3, -2.6), 3);
        let points = [(60.0, 50.0), (90.0, 70.0), (40.0, 80.0)];
        let tracked = track(&a, &b, &points, &[], &KltConfig::default());
        for (p, q) in points.iter().zip(&tracked) {
            let q = q.expect("lost");
            assert!(
                (q.0 - p.0 - 4.3).abs() < 0.2 && (q.1 - p.1 + 2.6).abs() < 0.2,
                "{p:?} -> {q:?}"
            );
        }
    }

    #[test]
    fn a_shift_beyond_the_pyramid_is_tracked_from_the_prediction() {
        let a = Pyramid::new(&textured(0.0, 0.0), 2);
        let b = Pyramid::new(&textured(23.4, 1.7), 2);
        let points = [(50.0, 50.0), (70.0, 60.0)];
        let config = KltConfig::default();
        let predicted: Vec<_> = points
            .iter()
            .map(|p| Some((p.0 + 22.0, p.1 + 2.0)))
            .collect();
        let tracked = track(&a, &b, &points, &predicted, &config);
        for (p, q) in points.iter().zip(&tracked) {
            let q = q.expect("lost with the prediction");
            assert!(
                (q.0 - p.0 - 23.4).abs() < 0.2 && (q.1 - p.1 - 1.7).abs() < 0.2,
                "{p:?} -> {q:?}"
            );
        }
        // A wrong prediction falls back to the zero-motion start.
        let small = Pyramid::new(&textured(2.0, -1.0), 2);
        let wrong: Vec<_> = points.iter().map(|p| Some((p.0 + 40.0, p.1))).collect();
        for (p, q) in points
            .iter()
            .zip(track(&a, &small, &points, &wrong, &config))
        {
            let q = q.expect("lost after a wrong prediction");
            assert!((q.0 - p.0 - 2.0).abs() < 0.2, "{p:?} -> {q:?}");
        }
    }
}
