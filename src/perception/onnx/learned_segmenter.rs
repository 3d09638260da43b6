//! The learned [`Segmenter`]: segloc's own U-Net (`models/boulders.onnx`, trained on
//! rendered frames by `scripts/train_segmenter.py`), run by onnxruntime and decoded by
//! [`decode_unet`].

use std::path::{Path, PathBuf};

use ort::session::Session;
use ort::value::{Tensor, ValueType};

use super::runtime::load_session;
use crate::perception::segmenter::{SegmentInput, Segmenter};
use crate::perception::unet_decoder::{decode_unet, UnetDecoderConfig};
use crate::perception::{GrayImage, Mask, PerceptionError};

/// The file name of the shipped model.
pub const SHIPPED_MODEL: &str = "boulders.onnx";

/// Where the shipped model is looked for, in order: `$SEGLOC_MODELS/boulders.onnx`,
/// `models/boulders.onnx` beside the executable or up to three folders above it (a cargo
/// `target/<profile>/` binary finds the repository's), `models/boulders.onnx` of the
/// current directory, and of the source tree this binary was built from.
pub fn shipped_model_candidates() -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Some(dir) = std::env::var_os("SEGLOC_MODELS") {
        out.push(PathBuf::from(dir).join(SHIPPED_MODEL));
        return out;
    }
    if let Ok(exe) = std::env::current_exe() {
        for dir in exe.ancestors().skip(1).take(4) {
            out.push(dir.join("models").join(SHIPPED_MODEL));
        }
    }
    out.push(PathBuf::from("models").join(SHIPPED_MODEL));
    out.push(PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/models/boulders.onnx"
    )));
    out
}

/// The shipped model's path; the error lists where it was looked for.
pub fn shipped_model() -> Result<PathBuf, PerceptionError> {
    let candidates = shipped_model_candidates();
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .ok_or_else(|| {
            let looked: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
            PerceptionError::model(
                SHIPPED_MODEL,
                format!(
                "the learned segmenter's model was not found (looked in {}); set SEGLOC_MODELS \
                 to the folder holding {SHIPPED_MODEL}",
                looked.join(", ")
            ),
            )
        })
}

/// Runs the U-Net on the left image and decodes rock instances.
pub struct LearnedSegmenter {
    session: Session,
    path: PathBuf,
    input_width: usize,
    input_height: usize,
    config: UnetDecoderConfig,
}

impl LearnedSegmenter {
    /// Load a model with one input `[1, 1, H, W]` and one output `[1, 3, h, w]`. Errors
    /// name the file and say what was expected and found.
    pub fn load(path: &Path, config: UnetDecoderConfig) -> Result<Self, PerceptionError> {
        config.validate()?;
        let session = load_session(path)?;
        let found = |what: &str| {
            PerceptionError::model(
                path,
                format!(
                    "expected one input [1, 1, H, W] and one output [1, 3, h, w], found {what}"
                ),
            )
        };
        if session.inputs().len() != 1 || session.outputs().len() != 1 {
            return Err(found(&format!(
                "{} inputs and {} outputs",
                session.inputs().len(),
                session.outputs().len()
            )));
        }
        let dims = |t: &ValueType| match t {
            ValueType::Tensor { shape, .. } => Some(shape.iter().copied().collect::<Vec<i64>>()),
            _ => None,
        };
        let input = dims(session.inputs()[0].dtype());
        let output = dims(session.outputs()[0].dtype());
        let (input_height, input_width) = match (input.as_deref(), output.as_deref()) {
            (Some([1, 1, h, w]), Some([1, 3, _, _])) if *h > 0 && *w > 0 => {
                (*h as usize, *w as usize)
            }
            (i, o) => return Err(found(&format!("input {i:?} and output {o:?}"))),
        };
        Ok(LearnedSegmenter {
            session,
            path: path.to_path_buf(),
            input_width,
            input_height,
            config,
        })
    }

    /// The model's input size `(width, height)`.
    pub fn input_size(&self) -> (usize, usize) {
        (self.input_width, self.input_height)
    }

    /// Masks of one grayscale image (any size: it is resampled to the model's input).
    pub fn segment_image(&mut self, image: &GrayImage) -> Result<Vec<Mask>, PerceptionError> {
        let input = resample(image, self.input_width, self.input_height);
        let path = self.path.clone();
        let model_err = |m: String| PerceptionError::model(&path, m);
        let tensor = Tensor::from_array(([1usize, 1, self.input_height, self.input_width], input))
            .map_err(|e| model_err(format!("input tensor: {e}")))?;
        let outputs = self
            .session
            .run(ort::inputs![tensor])
            .map_err(|e| model_err(format!("inference failed: {e}")))?;
        let (shape, logits) = outputs[0]
            .try_extract_tensor::<f32>()
            .map_err(|e| model_err(format!("the output is not a float tensor: {e}")))?;
        let shape: Vec<usize> = shape.iter().map(|&d| d.max(0) as usize).collect();
        decode_unet(logits, &shape, image.width, image.height, &self.config)
            .map_err(|m| model_err(format!("unexpected output: {m}")))
    }
}

/// The image resampled (bilinear at pixel centres; a 2 × 2 box mean for an exact halving)
/// to `w × h`, grey levels / 255.
fn resample(image: &GrayImage, w: usize, h: usize) -> Vec<f32> {
    let (sx, sy) = (
        image.width as f64 / w as f64,
        image.height as f64 / h as f64,
    );
    let last = |n: usize| n.saturating_sub(1) as f64;
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        let fy = ((y as f64 + 0.5) * sy - 0.5).clamp(0.0, last(image.height));
        let (y0, ty) = (fy.floor() as usize, fy - fy.floor());
        let y1 = (y0 + 1).min(image.height - 1);
        for x in 0..w {
            let fx = ((x as f64 + 0.5) * sx - 0.5).clamp(0.0, last(image.width));
            let (x0, tx) = (fx.floor() as usize, fx - fx.floor());
            let x1 = (x0 + 1).min(image.width - 1);
            let g = |u: usize, v: usize| image.get(u, v) as f64;
            let top = g(x0, y0) * (1.0 - tx) + g(x1, y0) * tx;
            let bottom = g(x0, y1) * (1.0 - tx) + g(x1, y1) * tx;
            out.push(((top * (1.0 - ty) + bottom * ty) / 255.0) as f32);
        }
    }
    out
}

impl Segmenter for LearnedSegmenter {
    fn name(&self) -> &'static str {
        "learned"
    }

    fn segment(&mut self, input: &SegmentInput<'_>) -> Result<Vec<Mask>, PerceptionError> {
        self.segment_image(input.left)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halving_is_a_box_mean() {
        let image = GrayImage::new(4, 2, vec![0, 255, 10, 20, 255, 0, 30, 40]).unwrap();
        let out = resample(&image, 2, 1);
        assert!((out[0] - 0.5).abs() < 1e-6, "{out:?}");
        assert!((out[1] - 25.0 / 255.0).abs() < 1e-6, "{out:?}");
    }

    #[test]
    fn models_dir_from_the_environment_is_the_only_candidate() {
        // read-only check of the candidate list's shape (the variable is not set in tests)
        if std::env::var_os("SEGLOC_MODELS").is_none() {
            let c = shipped_model_candidates();
            assert!(c.iter().all(|p| p.ends_with("models/boulders.onnx")));
        }
    }
}
