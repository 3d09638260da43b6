//! Inputs and outputs of the engine: loading a map from any supported file, association
//! benchmark problems, JSON reports.

pub mod association_problem;
pub mod inputs;

pub use association_problem::{read_ground_truth, read_problem, AssociationProblem, ProblemTruth};
pub use inputs::{load_map, InputKind};
