//! Lunar Autonomy Challenge maps: the height and rock layers of the 180 × 180 grid, their
//! score, and pictures of them.
//!
//! - [`HeightMapBuilder`] ([`height_map`]): ground points → per-cell medians, filled by
//!   natural-neighbour interpolation (nearest observed cell outside the convex hull);
//! - [`rock_grid`] ([`rock_footprint`]): fused landmarks → the cells their footprints cover;
//! - [`RockEvidence`] ([`rock_evidence`]): raw detections with the rover's views → cells
//!   detected far more often than their exposure explains (the real-data rock map), less
//!   the detections on the lander's own structure ([`lander_structure`]);
//! - [`traverse_views()`] ([`mod@traverse_views`]): a LunarLoc traverse's detection frames,
//!   with the heading the positions imply;
//! - [`score()`] ([`mod@score`]): the LAC points of a grid against the ground truth;
//! - [`pictures`]: PNGs of the height error, the rock map and trajectories, drawn with
//!   the small rasteriser in [`raster`].

pub mod height_map;
pub mod lander_structure;
pub mod pictures;
pub mod raster;
pub mod rock_evidence;
pub mod rock_footprint;
pub mod score;
pub mod traverse_views;
pub mod tune;

use crate::field_error::FieldError;

pub use height_map::HeightMapBuilder;
pub use lander_structure::LanderStructureConfig;
pub use rock_evidence::{RockEvidence, RockEvidenceConfig};
pub use rock_footprint::{rock_grid, RockGridConfig};
pub use score::{score, LacScore, ScoreError};
pub use traverse_views::traverse_views;
pub use tune::{cross_validate, sensitivity, CrossValidation, ThresholdResult};

/// Every named value is a finite number above 0 (`positive`) or at least 0: the first one
/// that is not, as an error naming it (for the configs' `validate`).
pub(crate) fn check_numbers(fields: &[(&str, f64)], positive: bool) -> Result<(), FieldError> {
    for &(name, v) in fields {
        let ok = v.is_finite() && if positive { v > 0.0 } else { v >= 0.0 };
        if !ok {
            let kind = if positive { "positive" } else { "non-negative" };
            return Err(FieldError::new(
                name,
                format!("must be a {kind} number, got {v}"),
            ));
        }
    }
    Ok(())
}
