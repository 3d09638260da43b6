//! The [`Segmenter`] backed by an ONNX model of the FastSAM / YOLOv8-seg format.

use std::path::{Path, PathBuf};

use ort::session::Session;
use ort::value::{Tensor, ValueType};

use super::runtime::load_session;
use super::yolo_seg::{decode_yolo_seg, Letterbox, YoloSegConfig};
use crate::perception::segmenter::{SegmentInput, Segmenter};
use crate::perception::{GrayImage, Mask, PerceptionError};

/// Runs a FastSAM / YOLOv8-seg ONNX model on the left image and decodes its masks.
pub struct OnnxSegmenter {
    session: Session,
    path: PathBuf,
    input_size: usize,
    config: YoloSegConfig,
}

impl OnnxSegmenter {
    /// Load a model. Errors name the file: missing, not an ONNX model, or with inputs and
    /// outputs that do not fit the format (one image input `[1, 3, S, S]`, two outputs).
    pub fn load(path: &Path, config: YoloSegConfig) -> Result<Self, PerceptionError> {
        let session = load_session(path)?;
        if session.inputs().len() != 1 || session.outputs().len() < 2 {
            return Err(PerceptionError::model(
                path,
                format!(
                    "expected 1 input and 2 outputs (detections, prototypes), found {} and {}",
                    session.inputs().len(),
                    session.outputs().len()
                ),
            ));
        }
        let input_size = match session.inputs()[0].dtype() {
            ValueType::Tensor { shape, .. } => {
                let dims: Vec<i64> = shape.iter().copied().collect();
                match dims.as_slice() {
                    [_, 3, h, w] if h == w && *h > 0 => *h as usize,
                    [_, 3, -1, -1] => 640,
                    other => {
                        return Err(PerceptionError::model(
                            path,
                            format!("input shape {other:?} is not [1, 3, S, S]"),
                        ))
                    }
                }
            }
            other => {
                return Err(PerceptionError::model(
                    path,
                    format!("the input is not a tensor ({other:?})"),
                ))
            }
        };
        Ok(OnnxSegmenter {
            session,
            path: path.to_path_buf(),
            input_size,
            config,
        })
    }

    /// The model's square input side.
    pub fn input_size(&self) -> usize {
        self.input_size
    }

    /// Masks of one grayscale image.
    pub fn segment_image(&mut self, image: &GrayImage) -> Result<Vec<Mask>, PerceptionError> {
        let s = self.input_size;
        let lb = Letterbox::new(image.width, image.height, s);
        let mut input = vec![114.0f32 / 255.0; 3 * s * s];
        for y in 0..s {
            for x in 0..s {
                let (u, v) = lb.to_image(x as f64 + 0.5, y as f64 + 0.5);
                if u < 0.0 || v < 0.0 || u >= image.width as f64 || v >= image.height as f64 {
                    continue;
                }
                let value = image.get(u as usize, v as usize) as f32 / 255.0;
                for c in 0..3 {
                    input[(c * s + y) * s + x] = value;
                }
            }
        }
        let path = self.path.clone();
        let model_err = |m: String| PerceptionError::model(&path, m);
        let tensor = Tensor::from_array(([1usize, 3, s, s], input))
            .map_err(|e| model_err(format!("input tensor: {e}")))?;
        let outputs = self
            .session
            .run(ort::inputs![tensor])
            .map_err(|e| model_err(format!("inference failed: {e}")))?;
        let extract = |k: usize| -> Result<(Vec<usize>, Vec<f32>), PerceptionError> {
            let (shape, data) = outputs[k]
                .try_extract_tensor::<f32>()
                .map_err(|e| model_err(format!("output {k} is not a float tensor: {e}")))?;
            Ok((
                shape.iter().map(|&d| d.max(0) as usize).collect(),
                data.to_vec(),
            ))
        };
        let (pred_shape, preds) = extract(0)?;
        let (proto_shape, protos) = extract(1)?;
        decode_yolo_seg(
            &preds,
            &pred_shape,
            &protos,
            &proto_shape,
            &lb,
            &self.config,
        )
        .map_err(|m| model_err(format!("unexpected outputs: {m}")))
    }
}

impl Segmenter for OnnxSegmenter {
    fn name(&self) -> &'static str {
        "onnx"
    }

    fn segment(&mut self, input: &SegmentInput<'_>) -> Result<Vec<Mask>, PerceptionError> {
        self.segment_image(input.left)
    }
}
