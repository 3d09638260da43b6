//! Typed errors of the pose-graph module.

use super::VarKey;
use std::path::PathBuf;

/// Everything that can go wrong while building, reading, writing or optimising a pose graph.
#[derive(Debug, thiserror::Error)]
pub enum GraphError {
    /// A line of a graph file could not be understood.
    #[error("{}:{line}: {message}", path.display())]
    Parse {
        /// File being read.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the line.
        message: String,
    },
    /// A file holds no vertex and no edge of either format.
    #[error("{}: no vertex or edge that segloc reads (g2o VERTEX_SE3:QUAT / EDGE_SE3:QUAT, TORO VERTEX3 / EDGE3); {detail}", path.display())]
    NothingRead {
        /// File read.
        path: PathBuf,
        /// What the file held instead.
        detail: String,
    },
    /// Reading or writing a file failed.
    #[error("cannot read or write {}", path.display())]
    Io {
        /// File being read or written.
        path: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A factor or call refers to a variable that was never added.
    #[error("unknown variable {0}")]
    UnknownVariable(VarKey),
    /// A variable was added twice.
    #[error("variable {0} already exists")]
    DuplicateVariable(VarKey),
    /// An information matrix is not symmetric positive definite.
    #[error("information matrix of {what} is not symmetric positive definite")]
    NotPositiveDefinite {
        /// The factor the matrix belongs to.
        what: String,
    },
    /// A pose, measurement or parameter contains NaN or infinity.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Where the value was found.
        what: String,
    },
    /// A factor connects a variable with itself.
    #[error("factor connects {0} with itself")]
    SelfLoop(VarKey),
    /// A solver parameter is out of range.
    #[error("invalid solver configuration: {0}")]
    InvalidConfig(String),
    /// The graph holds something the chosen file format cannot express.
    #[error("cannot write {what} in {format} format")]
    Unrepresentable {
        /// What could not be written.
        what: String,
        /// Target format.
        format: &'static str,
    },
    /// The sparse linear algebra failed for a reason other than a non-positive-definite system.
    #[error("sparse linear algebra failed: {0}")]
    LinearAlgebra(String),
}
