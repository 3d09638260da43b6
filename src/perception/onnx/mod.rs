//! Segmentation with an ONNX model of the FastSAM / YOLOv8-seg output format, through
//! the `ort` crate with a dynamically loaded onnxruntime ([`runtime`]).

pub mod onnx_segmenter;
pub mod runtime;
pub mod yolo_seg;

pub use onnx_segmenter::OnnxSegmenter;
pub use runtime::{onnxruntime_library, runtime_available, ONNXRUNTIME_VERSION};
pub use yolo_seg::{decode_yolo_seg, Letterbox, YoloOutputError, YoloSegConfig};
