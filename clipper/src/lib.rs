//! Graph-theoretic data association for point landmarks.
//!
//! Given two maps of 3D points (a prior map and a query map) and putative associations
//! between them, this crate builds the *consistency graph* (one vertex per association, an
//! edge when two associations preserve a rigid-motion invariant) and finds the densest or
//! the largest clique in it: the mutually consistent set of associations.
//!
//! - [`ConsistencyGraph::build`]: the graph, in compressed sparse rows, without ever
//!   materialising the m × m pair table (pair-list join for dense association lists, a
//!   vectorised pairwise scan for sparse ones; parallel, thread-count independent).
//! - [`core_numbers`]: k-core decomposition.
//! - [`densest_clique`]: CLIPPER-class relaxation behind a graph-theoretic front (greedy
//!   clique, upper bounds, certification, core pruning).
//! - [`max_clique`]: exact maximum clique by bitset branch and bound, with limits.
//!
//! Pure math: no file or network I/O.
//!
//! ```
//! use nalgebra::{Point3, Rotation3, Vector3};
//! use segloc_clipper::*;
//! let prior: Vec<Point3<f64>> = (0..8)
//!     .map(|k| Point3::new((k * 7 % 5) as f64, (k * 3 % 8) as f64, 0.1 * k as f64))
//!     .collect();
//! let r = Rotation3::from_euler_angles(0.1, -0.2, 0.7);
//! let query: Vec<_> = prior.iter().map(|p| r * p + Vector3::new(3.0, 1.0, 0.5)).collect();
//! // all-to-all associations
//! let assoc: Vec<_> = (0..8).flat_map(|i| (0..8).map(move |j| Association::new(i, j))).collect();
//! let g = ConsistencyGraph::build(&prior, &query, &assoc,
//!     &Invariant::Distance { epsilon: 0.05, sigma: 0.02 }).unwrap();
//! let s = densest_clique(&g, &DensestCliqueConfig::default());
//! assert!(s.vertices.iter().all(|&v| assoc[v as usize].prior == assoc[v as usize].query));
//! assert_eq!(s.vertices.len(), 8);
//! ```
#![warn(missing_docs)]
#![warn(clippy::too_many_lines)]

mod association;
mod build;
mod core;
mod densest;
mod error;
mod exact;
mod front;
mod graph;
mod greedy;
mod loose_partners;
mod polish;
mod relaxation;
mod rng;
mod seeded;
#[cfg(test)]
mod testutil;
mod tolerance;

pub use association::{Association, Invariant};
pub use build::{choose_strategy, BuildStrategy};
pub use core::core_numbers;
pub use densest::{densest_clique, CliqueSolution, DensestCliqueConfig};
pub use error::ClipperError;
pub use exact::{max_clique, MaxCliqueLimits};
pub use graph::ConsistencyGraph;
pub use seeded::{edge_seeded_clique, edge_seeded_cliques, SeededSearch};
pub use tolerance::{PointVariances, ToleranceSummary};
