//! The segmenter interface: what turns an image into instance masks.

use super::{DisparityMap, GrayImage, Mask, PerceptionError, StereoCamera};

/// What a segmenter may look at for one stereo frame.
#[derive(Clone, Copy, Debug)]
pub struct SegmentInput<'a> {
    /// The left image at full resolution.
    pub left: &'a GrayImage,
    /// The left image's disparity (possibly at a reduced resolution).
    pub disparity: &'a DisparityMap,
    /// The camera at the left image's resolution.
    pub camera: &'a StereoCamera,
}

/// Turns a frame into instance masks in left-image pixel coordinates. Implementations:
/// [`GeometricSegmenter`](super::GeometricSegmenter) (training-free, from the depth) and
/// [`OnnxSegmenter`](super::onnx::OnnxSegmenter) (a FastSAM / YOLOv8-seg model) and
/// [`LearnedSegmenter`](super::onnx::LearnedSegmenter) (segloc's U-Net).
pub trait Segmenter: Send {
    /// A short name for reports ("geometric", "onnx", "learned").
    fn name(&self) -> &'static str;

    /// Whether its masks stand out of the ground by construction (the geometric segmenter's
    /// do); the front end checks the relief of the others' (see
    /// [`relief_gate`](super::relief_gate)).
    fn checks_relief(&self) -> bool {
        false
    }

    /// The masks of the objects in this frame, with a confidence each.
    fn segment(&mut self, input: &SegmentInput<'_>) -> Result<Vec<Mask>, PerceptionError>;
}
