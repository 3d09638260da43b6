//! segloc: tells a lunar rover where it is by recognising boulders seen before.
//!
//! The engine composes two crates: `segloc_maps` (object maps and file formats) and
//! `segloc_clipper` (consistency graphs and clique solvers). Its stages:
//!
//! - [`landmarks`]: a session's boulder detections fused into an object map;
//! - [`relocalize`]: associations → consistency graph → cliques → alignment ([`align`]) →
//!   verification → `prior_from_query` or a refusal;
//! - [`graph`]: the SE(3) pose graph that relocalizations anchor;
//! - [`merge`]: several agents' maps merged into one frame;
//! - [`eval`]: evaluation on the real LunarLoc traverses;
//! - [`sim`]: generated boulder fields for tests and the demo.
#![warn(missing_docs)]
#![warn(clippy::too_many_lines)]

pub mod align;
pub mod eval;
pub mod field_error;
pub mod font;
pub mod graph;
pub mod image_stream;
pub mod io;
pub mod ipex;
pub mod landmarks;
pub mod localizer;
pub mod mapping;
pub mod memory;
pub mod merge;
pub mod mission;
pub mod perception;
pub mod planning;
pub mod relocalize;
pub mod sim;
pub mod spatial;
pub mod vo;

pub use segloc_clipper as clipper;
pub use segloc_maps as maps;
