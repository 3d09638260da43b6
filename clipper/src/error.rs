//! Error type of the association crate.

use thiserror::Error;

/// Errors returned by graph construction and the clique solvers.
///
/// Every error describes bad input or a refused computation; the crate never panics on
/// input it is given.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ClipperError {
    /// A point has a NaN or infinite coordinate.
    #[error("{map} point {index} has a non-finite coordinate")]
    NonFinitePoint {
        /// `"prior"` or `"query"`.
        map: &'static str,
        /// Index of the offending point.
        index: usize,
    },
    /// An association refers to a point that does not exist.
    #[error(
        "association {index} refers to {map} point {point}, but the {map} map has {len} points"
    )]
    IndexOutOfRange {
        /// Index of the association in the list.
        index: usize,
        /// `"prior"` or `"query"`.
        map: &'static str,
        /// The point index it refers to.
        point: u32,
        /// Number of points in that map.
        len: usize,
    },
    /// The same (prior, query) pair appears twice in the association list.
    #[error("association {index} duplicates association {first}")]
    DuplicateAssociation {
        /// Index of the later copy.
        index: usize,
        /// Index of the first copy.
        first: usize,
    },
    /// An invariant parameter (epsilon, sigma) is not a positive finite number.
    #[error("invariant parameter {name} must be positive and finite, got {value}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: f64,
    },
    /// An edge given to [`crate::ConsistencyGraph::from_edges`] is malformed.
    #[error("edge {index} ({u}, {v}) is invalid: {reason}")]
    InvalidEdge {
        /// Index of the edge in the list.
        index: usize,
        /// First endpoint.
        u: u32,
        /// Second endpoint.
        v: u32,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The problem is larger than this solver accepts.
    #[error("problem too large: {what} is {size}, limit {limit}")]
    TooLarge {
        /// What was counted.
        what: &'static str,
        /// Its size.
        size: usize,
        /// The limit.
        limit: usize,
    },
    /// The exact search exceeded its node budget before proving optimality.
    #[error("maximum-clique search exceeded its budget of {max_nodes} nodes (best clique so far: {best_size})")]
    BudgetExceeded {
        /// The node budget.
        max_nodes: u64,
        /// Size of the best clique found before stopping.
        best_size: usize,
    },
    /// Point variances do not match the points, or one is negative or not finite.
    #[error("{map} variances: {reason}")]
    InvalidVariances {
        /// "prior" or "query".
        map: &'static str,
        /// What is wrong.
        reason: String,
    },
}
