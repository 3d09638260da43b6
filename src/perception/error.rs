//! Errors of the perception front end.

use std::path::PathBuf;

/// What can go wrong between image files and boulders. Every variant that concerns a file
/// names it, so a user can tell which input to fix.
#[derive(Debug, thiserror::Error)]
pub enum PerceptionError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// An image file could not be decoded or encoded.
    #[error("{path}: not a readable PNG image: {message}")]
    ImageFormat {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// An image has the wrong pixel type (for example 16-bit or colour where 8-bit grayscale
    /// is expected).
    #[error("{path}: expected an 8-bit grayscale image, found {found}")]
    PixelType {
        /// The file.
        path: PathBuf,
        /// The pixel type found.
        found: String,
    },
    /// An image has a size the camera model or the other image does not allow.
    #[error("{path}: {message}")]
    ImageSize {
        /// The file (or a description of the image).
        path: PathBuf,
        /// What is wrong with the size.
        message: String,
    },
    /// A configuration value is out of its valid range.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// A segmentation model is missing, corrupt or produced unexpected outputs.
    #[error("{path}: {message}")]
    Model {
        /// The model file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The ONNX Runtime library is missing or of the wrong version.
    #[error("ONNX Runtime: {0}")]
    Runtime(String),
    /// A `.lac` archive is truncated, corrupt or misses a required part.
    #[error("{path}: {message}")]
    Archive {
        /// The archive.
        path: PathBuf,
        /// What is wrong (names the member where it applies).
        message: String,
    },
}

impl PerceptionError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        PerceptionError::Io {
            path: path.into(),
            source,
        }
    }

    /// An archive error on `path`.
    pub fn archive(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        PerceptionError::Archive {
            path: path.into(),
            message: message.into(),
        }
    }

    /// A model error on `path`.
    pub fn model(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        PerceptionError::Model {
            path: path.into(),
            message: message.into(),
        }
    }
}
