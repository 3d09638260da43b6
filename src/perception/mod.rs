//! Perception: boulders from the rover's stereo images.
//!
//! The front end (LunarLoc's, with a training-free alternative to FastSAM):
//!
//! 1. [`sgm`]: dense disparity of the rectified pair by semi-global matching on census
//!    costs, with the [`StereoCamera`] model of the IPEX front pair;
//! 2. a [`Segmenter`] turns the left image (and the disparity) into instance masks:
//!    [`GeometricSegmenter`] finds what stands out of the local ground surface, the ONNX
//!    segmenter decodes a FastSAM / YOLOv8-seg model, and the learned segmenter runs
//!    segloc's own U-Net trained on rendered frames ([`unet_decoder`]);
//! 3. [`boulders`]: masks that touch the border, are too elongated or of an implausible
//!    physical size are dropped; the rest become boulders with a 3D centroid and a size.
//!    An image-only segmenter's masks are first split where they span two depths
//!    ([`depth_split`]), measured on their pixels that stand out of the ground and checked
//!    against the relief ([`relief_gate`]).
//!
//! [`FrontEnd`] runs the three steps on one stereo pair and times them.
#![allow(clippy::too_many_arguments)]

pub mod camera;
pub mod census;
pub mod depth_refine;
pub mod disparity;
pub mod error;
pub mod gray_image;
pub mod sgm;

pub use camera::{CameraMount, StereoCamera};
pub use disparity::DisparityMap;
pub use error::PerceptionError;
pub use gray_image::{read_gray_png, write_gray_png, GrayImage};
pub use sgm::{compute_disparity, compute_disparity_with, StereoConfig, StereoScratch};
pub mod boulders;
pub mod depth_split;
pub mod front_end;
pub mod geometric;
pub mod ground;
pub mod lac;
pub mod mask;
pub mod onnx;
pub mod overlay;
pub mod relief_gate;
pub mod render;
pub mod segmenter;
pub mod unet_decoder;

pub use boulders::{boulders_from_masks, Boulder, BoulderConfig, Rejection};
pub use front_end::{FrameResult, FrontEnd, FrontEndConfig, FrontEndTiming};
pub use geometric::{GeometricConfig, GeometricSegmenter, Region, RegionDrop};
pub use mask::Mask;
pub use segmenter::{SegmentInput, Segmenter};
pub use unet_decoder::{decode_unet, UnetDecoderConfig};
