//! Evaluation on the real LunarLoc traverses (`../shared/data/lunarloc`).
//!
//! - [`lunarloc`]: relocalize pairs of traverses under random rigid transforms and compare
//!   with the truth (all traverses share one world frame);
//! - [`grid`]: global localization of traverses and submaps against the rock grid;
//! - [`merge`]: map merging with traverses as agents;
//! - [`landmark_quality`]: how well fused landmarks land on the ground-truth rock cells;
//! - [`segmenter_labels`]: a segmenter's recall and precision against hand labels of
//!   the real LAC pairs' rocks;
//! - [`render_front_end`]: the perception front end on rendered frames against their truth;
//!   [`render_breakdown`]: why it misses the rocks it misses;
//! - [`stream`]: traverses replayed frame by frame through the online localizer against
//!   another traverse's map;
//! - [`transform_error`]: the error measures.

pub mod grid;
pub mod landmark_quality;
pub mod lunarloc;
pub mod merge;
pub mod render_breakdown;
pub mod render_front_end;
pub mod segmenter_labels;
pub mod stream;

use nalgebra::{Isometry3, Point3};
use segloc_maps::DetectionSet;

/// A detection set mirrored in x (rover positions too): the statistics of a real map, but
/// no rigid motion maps it onto the original, so every alignment of the two is wrong.
pub fn mirrored_x(set: &DetectionSet) -> DetectionSet {
    let flip = |p: &Point3<f64>| Point3::new(-p.x, p.y, p.z);
    let mut out = set.clone();
    for d in &mut out.detections {
        d.p_world = flip(&d.p_world);
        d.rover_position = d.rover_position.as_ref().map(flip);
    }
    out
}

/// Translation error (m) and rotation error (degrees) of an estimate against the truth,
/// both `prior_from_query`: the error transform `estimate · truth⁻¹` acts in the prior
/// frame, so the translation error is how far the estimate moves the prior frame's origin
/// (on the LunarLoc data: the lander, within about 15 m of every boulder).
pub fn transform_error(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> (f64, f64) {
    let error = estimate * truth.inverse();
    (
        error.translation.vector.norm(),
        error.rotation.angle().to_degrees(),
    )
}

/// Path of traverse `n` under a data directory.
pub fn traverse_path(data: &std::path::Path, n: usize) -> std::path::PathBuf {
    data.join("lunarloc").join(format!("traverse_{n}.csv"))
}
