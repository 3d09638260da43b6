//! Decoding the output of a FastSAM / YOLOv8-seg ONNX export into instance masks.
//!
//! The model sees the image letterboxed into an `S × S` square (scaled by
//! `r = min(S / W, S / H)`, centred, padded with gray). It returns
//!
//! - `output0`, shape `[1, 4 + C + K, N]`: for each of N candidates the box (centre x,
//!   centre y, width, height, in input pixels), C class scores and K mask coefficients
//!   (K = 32 for FastSAM and YOLOv8-seg);
//! - `output1`, shape `[1, K, Hp, Wp]`: K prototype masks at 1/4 of the input resolution.
//!
//! Decoding: keep candidates whose best class score passes the threshold, non-maximum
//! suppression by box IoU, then each mask is `sigmoid(coefficients · prototypes) > 0.5`
//! inside its box, mapped back to the original image. Optionally (as LunarLoc does with
//! FastSAM's "everything" mode) only masks hit by a uniform G × G grid of point prompts
//! are kept.

use serde::{Deserialize, Serialize};

use crate::perception::Mask;

/// Decoder settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct YoloSegConfig {
    /// Smallest class score kept.
    pub score_threshold: f32,
    /// Boxes overlapping a better one by more than this IoU are suppressed.
    pub iou_threshold: f32,
    /// At most this many masks after suppression.
    pub max_detections: usize,
    /// Keep only masks containing a point of a uniform grid of this many points per side
    /// (0 = keep all). LunarLoc uses 32.
    pub point_grid: usize,
}

impl Default for YoloSegConfig {
    fn default() -> Self {
        YoloSegConfig {
            score_threshold: 0.4,
            iou_threshold: 0.7,
            max_detections: 100,
            point_grid: 32,
        }
    }
}

/// How the image was placed in the model's square input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Letterbox {
    /// Original image width.
    pub image_width: usize,
    /// Original image height.
    pub image_height: usize,
    /// Model input side S.
    pub input_size: usize,
    /// Scale r from image to input pixels.
    pub scale: f64,
    /// Horizontal padding (input pixels) left of the image.
    pub pad_x: f64,
    /// Vertical padding (input pixels) above the image.
    pub pad_y: f64,
}

impl Letterbox {
    /// The letterbox of a `width × height` image into an `input_size` square.
    pub fn new(width: usize, height: usize, input_size: usize) -> Self {
        let scale = (input_size as f64 / width as f64).min(input_size as f64 / height as f64);
        Letterbox {
            image_width: width,
            image_height: height,
            input_size,
            scale,
            pad_x: (input_size as f64 - width as f64 * scale) / 2.0,
            pad_y: (input_size as f64 - height as f64 * scale) / 2.0,
        }
    }

    /// Image pixel → input pixel.
    pub fn to_input(&self, u: f64, v: f64) -> (f64, f64) {
        (u * self.scale + self.pad_x, v * self.scale + self.pad_y)
    }

    /// Input pixel → image pixel.
    pub fn to_image(&self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.pad_x) / self.scale, (y - self.pad_y) / self.scale)
    }
}

/// Outputs that do not fit the YOLOv8-seg format.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum YoloOutputError {
    /// `output0` is not `[1, rows, candidates]`.
    #[error("output0 has shape {0:?}, expected [1, 4 + classes + k, candidates]")]
    PredictionShape(Vec<usize>),
    /// `output1` is not `[1, k, height, width]`.
    #[error("output1 has shape {0:?}, expected [1, k, height, width]")]
    PrototypeShape(Vec<usize>),
    /// `output0` has too few rows for a box, a class and the `k` mask coefficients.
    #[error("output0 has {rows} rows per candidate, but 4 box values + at least one class + {k} mask coefficients are needed")]
    TooFewRows {
        /// Rows per candidate.
        rows: usize,
        /// Mask coefficients (prototypes).
        k: usize,
    },
    /// The data lengths differ from the shapes' products.
    #[error("output sizes do not match their shapes")]
    SizeMismatch,
}

/// The dimensions of the two outputs.
struct OutputLayout {
    /// Candidates.
    n: usize,
    /// Class scores per candidate.
    classes: usize,
    /// Mask coefficients per candidate (prototype masks).
    k: usize,
    /// Prototype height and width.
    ph: usize,
    pw: usize,
}

impl OutputLayout {
    /// The layout of `output0` / `output1`, checked against their lengths.
    fn of(
        preds: &[f32],
        pred_shape: &[usize],
        protos: &[f32],
        proto_shape: &[usize],
    ) -> Result<Self, YoloOutputError> {
        let [1, rows, n] = *pred_shape else {
            return Err(YoloOutputError::PredictionShape(pred_shape.to_vec()));
        };
        let [1, k, ph, pw] = *proto_shape else {
            return Err(YoloOutputError::PrototypeShape(proto_shape.to_vec()));
        };
        if rows < 4 + 1 + k || k == 0 {
            return Err(YoloOutputError::TooFewRows { rows, k });
        }
        if preds.len() != rows * n || protos.len() != k * ph * pw {
            return Err(YoloOutputError::SizeMismatch);
        }
        Ok(OutputLayout {
            n,
            classes: rows - 4 - k,
            k,
            ph,
            pw,
        })
    }
}

/// A candidate: best class score, box (x0, y0, x1, y1, input pixels) and column.
type Candidate = (f32, [f64; 4], usize);

/// Decode the two outputs. `preds` / `pred_shape` are `output0`, `protos` / `proto_shape`
/// `output1`. Errors describe shapes that do not fit the format.
pub fn decode_yolo_seg(
    preds: &[f32],
    pred_shape: &[usize],
    protos: &[f32],
    proto_shape: &[usize],
    letterbox: &Letterbox,
    config: &YoloSegConfig,
) -> Result<Vec<Mask>, YoloOutputError> {
    let layout = OutputLayout::of(preds, pred_shape, protos, proto_shape)?;
    let at = |r: usize, i: usize| preds[r * layout.n + i];
    let mut masks = Vec::new();
    for (score, b, i) in suppress_overlaps(candidates(preds, &layout, config), config) {
        let coeffs: Vec<f32> = (0..layout.k)
            .map(|j| at(4 + layout.classes + j, i))
            .collect();
        let Some(pixels) = mask_pixels(&coeffs, protos, &layout, &b, letterbox) else {
            continue;
        };
        let Some(mask) = Mask::from_pixels(&pixels, score) else {
            continue;
        };
        if config.point_grid > 0 && !hit_by_grid(&mask, letterbox, config.point_grid) {
            continue;
        }
        masks.push(mask);
    }
    Ok(masks)
}

/// The candidates whose best class score passes the threshold and whose box is finite.
fn candidates(preds: &[f32], layout: &OutputLayout, config: &YoloSegConfig) -> Vec<Candidate> {
    let at = |r: usize, i: usize| preds[r * layout.n + i];
    (0..layout.n)
        .filter_map(|i| {
            let score = (0..layout.classes)
                .map(|c| at(4 + c, i))
                .fold(f32::MIN, f32::max);
            if score.is_nan() || score < config.score_threshold {
                return None;
            }
            let (cx, cy, w, h) = (
                at(0, i) as f64,
                at(1, i) as f64,
                at(2, i) as f64,
                at(3, i) as f64,
            );
            let b = [cx - w / 2.0, cy - h / 2.0, cx + w / 2.0, cy + h / 2.0];
            b.iter().all(|v| v.is_finite()).then_some((score, b, i))
        })
        .collect()
}

/// Non-maximum suppression: the best-scoring candidates, none overlapping a better one by
/// more than the IoU threshold, at most `max_detections`.
fn suppress_overlaps(mut cand: Vec<Candidate>, config: &YoloSegConfig) -> Vec<Candidate> {
    cand.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut kept: Vec<Candidate> = Vec::new();
    for c in cand {
        if kept.len() >= config.max_detections {
            break;
        }
        if kept
            .iter()
            .all(|k| box_iou(&k.1, &c.1) <= config.iou_threshold as f64)
        {
            kept.push(c);
        }
    }
    kept
}

/// The image pixels inside box `b` (input pixels) where the mask's logit (the prototypes
/// weighted by `coeffs`, sampled bilinearly) is positive; `None` when the box is empty in
/// the image.
fn mask_pixels(
    coeffs: &[f32],
    protos: &[f32],
    layout: &OutputLayout,
    b: &[f64; 4],
    letterbox: &Letterbox,
) -> Option<Vec<(usize, usize)>> {
    let (k, ph, pw) = (layout.k, layout.ph, layout.pw);
    let s = letterbox.input_size as f64;
    let (sx, sy) = (pw as f64 / s, ph as f64 / s);
    // the box in image pixels, clamped
    let (u0, v0) = letterbox.to_image(b[0], b[1]);
    let (u1, v1) = letterbox.to_image(b[2], b[3]);
    let u0 = u0.floor().max(0.0) as usize;
    let v0 = v0.floor().max(0.0) as usize;
    let u1 = (u1.ceil().max(0.0) as usize).min(letterbox.image_width);
    let v1 = (v1.ceil().max(0.0) as usize).min(letterbox.image_height);
    if u1 <= u0 || v1 <= v0 {
        return None;
    }
    let logit = |px: usize, py: usize| -> f32 {
        (0..k)
            .map(|j| coeffs[j] * protos[(j * ph + py) * pw + px])
            .sum()
    };
    let mut cache = std::collections::HashMap::new();
    let mut pixels = Vec::new();
    for v in v0..v1 {
        for u in u0..u1 {
            let (x, y) = letterbox.to_input(u as f64, v as f64);
            // bilinear sample of the prototype-resolution logit (pixel centres)
            let (fx, fy) = ((x * sx - 0.5).max(0.0), (y * sy - 0.5).max(0.0));
            let (x0, y0) = ((fx as usize).min(pw - 1), (fy as usize).min(ph - 1));
            let (x1, y1) = ((x0 + 1).min(pw - 1), (y0 + 1).min(ph - 1));
            let (ax, ay) = ((fx - x0 as f64) as f32, (fy - y0 as f64) as f32);
            let mut g = |px, py| *cache.entry((px, py)).or_insert_with(|| logit(px, py));
            let top = g(x0, y0) * (1.0 - ax) + g(x1, y0) * ax;
            let bottom = g(x0, y1) * (1.0 - ax) + g(x1, y1) * ax;
            if top * (1.0 - ay) + bottom * ay > 0.0 {
                pixels.push((u, v));
            }
        }
    }
    Some(pixels)
}

/// Whether a point of the uniform G × G grid over the image falls in the mask.
fn hit_by_grid(mask: &Mask, lb: &Letterbox, g: usize) -> bool {
    (0..g).any(|j| {
        (0..g).any(|i| {
            let u = ((i as f64 + 0.5) * lb.image_width as f64 / g as f64) as usize;
            let v = ((j as f64 + 0.5) * lb.image_height as f64 / g as f64) as usize;
            mask.contains(u, v)
        })
    })
}

fn box_iou(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let iw = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let ih = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = iw * ih;
    let area = |r: &[f64; 4]| (r[2] - r[0]).max(0.0) * (r[3] - r[1]).max(0.0);
    let union = area(a) + area(b) - inter;
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One class, K = 2 prototypes of 16 × 16 for a 64 × 64 input: prototype 0 is +1 in
    /// the left half, prototype 1 is +1 in the top half; both −1 elsewhere.
    fn protos() -> Vec<f32> {
        let mut p = vec![0f32; 2 * 16 * 16];
        for y in 0..16 {
            for x in 0..16 {
                p[y * 16 + x] = if x < 8 { 1.0 } else { -1.0 };
                p[256 + y * 16 + x] = if y < 8 { 1.0 } else { -1.0 };
            }
        }
        p
    }

    #[test]
    fn decodes_nms_and_maps_back_to_the_image() {
        // image 128 × 64 -> input 64: scale 0.5, pad_y 16
        let lb = Letterbox::new(128, 64, 64);
        assert_eq!((lb.scale, lb.pad_x, lb.pad_y), (0.5, 0.0, 16.0));
        // candidates: 0 (score .9) box over the left half with coeffs (1, 0) -> left half;
        // 1 (score .8) nearly the same box -> suppressed; 2 (score .1) -> below threshold
        let n = 3;
        let rows = 4 + 1 + 2;
        let mut preds = vec![0f32; rows * n];
        let set = |p: &mut Vec<f32>, r: usize, i: usize, v: f32| p[r * n + i] = v;
        for (i, (cx, score, c0)) in [(16.0, 0.9, 1.0), (17.0, 0.8, 1.0), (48.0, 0.1, 1.0)]
            .into_iter()
            .enumerate()
        {
            set(&mut preds, 0, i, cx);
            set(&mut preds, 1, i, 32.0);
            set(&mut preds, 2, i, 32.0);
            set(&mut preds, 3, i, 32.0);
            set(&mut preds, 4, i, score);
            set(&mut preds, 5, i, c0);
        }
        let config = YoloSegConfig {
            point_grid: 0,
            ..Default::default()
        };
        let masks = decode_yolo_seg(
            &preds,
            &[1, rows, n],
            &protos(),
            &[1, 2, 16, 16],
            &lb,
            &config,
        )
        .unwrap();
        assert_eq!(masks.len(), 1);
        let m = &masks[0];
        assert!((m.score - 0.9).abs() < 1e-6);
        // the box spans input x 0..32 -> image 0..64, y 16..48 -> image 0..64; the mask is
        // the left half of the input = image columns < 64
        assert!(m.contains(10, 30) && m.contains(60, 5));
        assert!(!m.contains(70, 30));
        assert!(m.area() > 60 * 60);
    }

    #[test]
    fn unexpected_shapes_are_reported() {
        let lb = Letterbox::new(64, 64, 64);
        let c = YoloSegConfig::default();
        assert!(decode_yolo_seg(&[0.0; 6], &[1, 6], &protos(), &[1, 2, 16, 16], &lb, &c).is_err());
        assert!(
            decode_yolo_seg(&[0.0; 6], &[1, 6, 1], &protos(), &[1, 2, 16, 16], &lb, &c)
                .unwrap_err()
                .to_string()
                .contains("rows")
        );
    }
}
