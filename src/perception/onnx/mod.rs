//! Segmentation with an ONNX model of the FastSAM / YOLOv8-seg output format.

pub mod yolo_seg;

pub use yolo_seg::{decode_yolo_seg, Letterbox, YoloSegConfig};
