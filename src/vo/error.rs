//! Errors of the visual odometry.

use std::path::PathBuf;

/// What can go wrong between a stereo sequence on disk and a trajectory. Every variant
/// about a file names it.
#[derive(Debug, thiserror::Error)]
pub enum VoError {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A file has the wrong content.
    #[error("{}:{line}: {message}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line (0 when the problem is not on one line).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A sequence is incomplete or inconsistent (a missing right image, images of different
    /// sizes, no frames, timestamps out of order).
    #[error("{}: {message}", path.display())]
    Sequence {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A trajectory file could not be read (it names the file and line).
    #[error(transparent)]
    Trajectory(#[from] segloc_maps::MapError),
    /// An image could not be read.
    #[error(transparent)]
    Image(#[from] crate::perception::PerceptionError),
    /// A configuration value is out of range.
    #[error("invalid configuration: {0}")]
    Config(String),
}
