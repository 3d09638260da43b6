//! Segmentation with ONNX models through the `ort` crate with a dynamically loaded
//! onnxruntime ([`runtime`]): a FastSAM / YOLOv8-seg model of the user's
//! ([`OnnxSegmenter`]) or segloc's own U-Net trained on rendered frames
//! ([`LearnedSegmenter`]).

pub mod learned_segmenter;
pub mod onnx_segmenter;
pub mod runtime;
pub mod yolo_seg;

pub use learned_segmenter::{shipped_model, LearnedSegmenter, SHIPPED_MODEL};
pub use onnx_segmenter::OnnxSegmenter;
pub use runtime::{onnxruntime_library, runtime_available, ONNXRUNTIME_VERSION};
pub use yolo_seg::{decode_yolo_seg, Letterbox, YoloOutputError, YoloSegConfig};
