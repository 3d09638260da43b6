//! Filters around the matcher: which pixels have texture enough to match, and removal of
//! small isolated patches of disparity (speckles).

use super::GrayImage;
use crate::perception::gray_image::neighbours4;

/// Pixels whose 7 × 7 intensity standard deviation is at least `min_std`.
pub(super) fn texture_mask(image: &GrayImage, min_std: f32, out: &mut Vec<bool>) {
    let (w, h) = (image.width, image.height);
    let iw = w + 1;
    let mut s1 = vec![0u64; iw * (h + 1)];
    let mut s2 = vec![0u64; iw * (h + 1)];
    for y in 0..h {
        let (mut r1, mut r2) = (0u64, 0u64);
        for x in 0..w {
            let v = image.data[y * w + x] as u64;
            r1 += v;
            r2 += v * v;
            s1[(y + 1) * iw + x + 1] = s1[y * iw + x + 1] + r1;
            s2[(y + 1) * iw + x + 1] = s2[y * iw + x + 1] + r2;
        }
    }
    let min_var = (min_std * min_std) as f64;
    out.clear();
    out.resize(w * h, false);
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(3), (y + 4).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(3), (x + 4).min(w));
            let n = ((y1 - y0) * (x1 - x0)) as f64;
            let rect = |s: &[u64]| {
                (s[y1 * iw + x1] + s[y0 * iw + x0]) as f64
                    - (s[y0 * iw + x1] + s[y1 * iw + x0]) as f64
            };
            let mean = rect(&s1) / n;
            let var = rect(&s2) / n - mean * mean;
            out[y * w + x] = var >= min_var;
        }
    }
}

/// Invalidate connected patches (4-neighbours differing by at most `max_diff`) smaller than
/// `max_area` pixels.
pub(super) fn remove_speckles(
    data: &mut [f32],
    w: usize,
    h: usize,
    max_area: usize,
    max_diff: f32,
) {
    let mut label = vec![u32::MAX; w * h];
    let mut stack = Vec::new();
    let mut members = Vec::new();
    let mut next = 0u32;
    for start in 0..w * h {
        if label[start] != u32::MAX || !data[start].is_finite() {
            continue;
        }
        members.clear();
        stack.push(start);
        label[start] = next;
        while let Some(p) = stack.pop() {
            members.push(p);
            let dp = data[p];
            for q in neighbours4(p, w, h) {
                if label[q] == u32::MAX && data[q].is_finite() && (data[q] - dp).abs() <= max_diff {
                    label[q] = next;
                    stack.push(q);
                }
            }
        }
        if members.len() < max_area {
            for &p in &members {
                data[p] = f32::NAN;
            }
        }
        next += 1;
    }
}
