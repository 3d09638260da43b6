//! segloc: boulder-based global relocalization for lunar rovers.

#![warn(missing_docs)]

pub mod cli;
pub mod graph;
