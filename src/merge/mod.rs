//! Multi-agent map merging: several maps, each in its own frame, into one.
//!
//! Stages, each in its own module:
//! 1. [`pairwise`]: relocalize every pair of maps (a cheap test skips pairs that cannot
//!    yield an accepted transform), keeping accepted transforms with their information
//!    matrices and the refusal reasons;
//! 2. [`frames`]: one frame variable per map in a pose graph, accepted pairwise transforms
//!    as robust between factors, the reference frame fixed — so a wrong pairwise answer is
//!    out-voted by the consistent ones; maps not connected to the reference are reported;
//! 3. [`refine_frames`]: every frame re-aligned to all other maps' landmarks at once;
//! 4. [`fuse`]: landmarks that are the same boulder across maps are fused
//!    (covariance-weighted, observation counts summed, provenance kept).
//!
//! ```
//! use segloc::merge::{merge_maps, MergeConfig};
//! use segloc::relocalize::RelocalizeConfig;
//! use segloc::sim::boulder_field::{two_sessions, FieldConfig};
//! let (a, b, _) = two_sessions(&FieldConfig::default(), 3);
//! let report = merge_maps(&[a, b], 0, &RelocalizeConfig::default(), &MergeConfig::default()).unwrap();
//! assert!(report.maps.iter().all(|m| m.reference_from_map.is_some()));
//! assert!(report.fused > 10);
//! ```

pub mod frames;
pub mod fuse;
pub mod pairwise;
pub mod refine_frames;

use crate::relocalize::RelocalizeConfig;
use nalgebra::Isometry3;
use segloc_maps::ObjectMap;
use serde::{Deserialize, Serialize};
use std::time::Instant;

pub use pairwise::PairOutcome;

/// Parameters of the merge (pairwise relocalization uses the [`RelocalizeConfig`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MergeConfig {
    /// Cauchy scale (Mahalanobis distance) of the pairwise factors in the frame graph.
    pub factor_cauchy_scale: f64,
    /// A pairwise factor whose translation disagrees with the optimised frames by more
    /// than this (m, at the maps' landmarks) is reported as out-voted.
    pub outvoted_m: f64,
    /// Landmarks of different maps closer than this (m) in the reference frame are fused
    /// (mutual nearest neighbours).
    pub fuse_gate_m: f64,
    /// Sweeps of joint frame refinement against all other maps' landmarks (0: none).
    pub refine_sweeps: usize,
    /// An accepted pairwise transform with fewer inliers than this is a weak pair: the
    /// merge keeps it only if its inlier RMSE is at most `weak_pair_max_rmse_m`.
    pub weak_pair_inliers: usize,
    /// See `weak_pair_inliers` (m). True overlaps of the LunarLoc traverses with 6–9
    /// inliers fit to at most 1.7 cm, chance coincidences of 5–7 boulders (a traverse
    /// against a mirror image of itself) to 2.3–3.3 cm.
    pub weak_pair_max_rmse_m: f64,
}

impl Default for MergeConfig {
    fn default() -> Self {
        Self {
            factor_cauchy_scale: 3.0,
            outvoted_m: 0.10,
            fuse_gate_m: 0.10,
            refine_sweeps: 3,
            weak_pair_inliers: 10,
            weak_pair_max_rmse_m: 0.02,
        }
    }
}

/// Why a merge could not be attempted.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// Fewer than two maps, or a reference index out of range.
    #[error("{0}")]
    Usage(String),
    /// Maps of different gravity conventions with a 4-DOF motion model.
    #[error("map {index} ({session}) is {what} but map {reference} is not; merge them with dof 6")]
    MixedGravity {
        /// The offending map.
        index: usize,
        /// Its session.
        session: String,
        /// "gravity-aligned" or "not gravity-aligned".
        what: &'static str,
        /// The reference map.
        reference: usize,
    },
    /// The frame graph failed.
    #[error("frame graph: {0}")]
    Graph(#[from] crate::graph::GraphError),
    /// A relocalization failed on its input.
    #[error("relocalization: {0}")]
    Relocalize(#[from] crate::relocalize::RelocalizeError),
}

/// Whether a map joined the reference frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MapStatus {
    /// Placed in the reference frame.
    Merged,
    /// No chain of accepted pairwise transforms links it to the reference.
    Disconnected,
}

/// One input map's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct MapPlacement {
    /// Input index.
    pub index: usize,
    /// Session of the map.
    pub session: String,
    /// Merged or disconnected.
    pub status: MapStatus,
    /// The map's frame in the reference frame, when merged.
    #[serde(serialize_with = "crate::relocalize::result::serialize_option_isometry")]
    pub reference_from_map: Option<Isometry3<f64>>,
    /// Landmarks of the map.
    pub landmarks: usize,
    /// Accepted pairwise transforms involving this map.
    pub accepted_pairs: usize,
}

/// Everything a merge produced.
#[derive(Clone, Debug, Serialize)]
pub struct MergeReport {
    /// The merged map in the reference frame (merged maps only).
    #[serde(skip)]
    pub merged: ObjectMap,
    /// Per input map.
    pub maps: Vec<MapPlacement>,
    /// Per pair of maps.
    pub pairs: Vec<PairOutcome>,
    /// Landmarks in the merged map.
    pub landmarks: usize,
    /// Landmarks that were fused from two or more maps.
    pub fused: usize,
    /// Root-mean-square residual (m) of the pairwise factors' translations after the
    /// frame optimisation, over the factors that were not out-voted.
    pub frame_residual_rmse_m: f64,
    /// Time (ms): pairwise relocalization, frame graph, fusion, total.
    pub pairwise_ms: f64,
    /// See `pairwise_ms`.
    pub frames_ms: f64,
    /// See `pairwise_ms`.
    pub fuse_ms: f64,
    /// See `pairwise_ms`.
    pub time_ms: f64,
}

/// Merge `maps` into the frame of `maps[reference]`.
pub fn merge_maps(
    maps: &[ObjectMap],
    reference: usize,
    relocalize: &RelocalizeConfig,
    config: &MergeConfig,
) -> Result<MergeReport, MergeError> {
    let started = Instant::now();
    check_inputs(maps, reference, relocalize)?;

    let t = Instant::now();
    let mut pairs = pairwise::relocalize_pairs(maps, relocalize)?;
    for p in pairs.iter_mut() {
        reject_weak_pair(p, config);
    }
    let pairwise_ms = ms_since(t);

    let t = Instant::now();
    let centroids: Vec<_> = maps.iter().map(centroid).collect();
    let mut solved = frames::solve_frames(maps.len(), reference, &mut pairs, &centroids, config)?;
    let dof = relocalize
        .dof
        .unwrap_or(if maps[reference].gravity_aligned {
            crate::align::Dof::Four
        } else {
            crate::align::Dof::Six
        });
    refine_frames::refine_frames(
        maps,
        &mut solved.reference_from_map,
        reference,
        dof,
        &relocalize.refine,
        config.refine_sweeps,
        relocalize.verification.min_inliers,
    );
    let frames_ms = ms_since(t);

    let t = Instant::now();
    let merged = fuse::fuse_maps(maps, &solved.reference_from_map, reference, config);
    let fuse_ms = ms_since(t);

    let placements = maps
        .iter()
        .enumerate()
        .map(|(index, map)| MapPlacement {
            index,
            session: map.session.clone(),
            status: if solved.reference_from_map[index].is_some() {
                MapStatus::Merged
            } else {
                MapStatus::Disconnected
            },
            reference_from_map: solved.reference_from_map[index],
            landmarks: map.len(),
            accepted_pairs: pairs
                .iter()
                .filter(|p| p.accepted && (p.a == index || p.b == index))
                .count(),
        })
        .collect();
    Ok(MergeReport {
        landmarks: merged.map.len(),
        fused: merged.fused,
        merged: merged.map,
        maps: placements,
        pairs,
        frame_residual_rmse_m: solved.residual_rmse_m,
        pairwise_ms,
        frames_ms,
        fuse_ms,
        time_ms: ms_since(started),
    })
}

/// Refuse an accepted pair that is weak (few inliers) and fits loosely.
fn reject_weak_pair(pair: &mut PairOutcome, config: &MergeConfig) {
    if pair.accepted
        && pair.inliers < config.weak_pair_inliers
        && pair.rmse_m > config.weak_pair_max_rmse_m
    {
        pair.accepted = false;
        pair.a_from_b = None;
        pair.reason = Some(format!(
            "weak pair: {} inliers (< {}) with rmse {:.1} cm > {:.1} cm",
            pair.inliers,
            config.weak_pair_inliers,
            pair.rmse_m * 100.0,
            config.weak_pair_max_rmse_m * 100.0
        ));
    }
}

fn check_inputs(
    maps: &[ObjectMap],
    reference: usize,
    relocalize: &RelocalizeConfig,
) -> Result<(), MergeError> {
    if maps.len() < 2 {
        return Err(MergeError::Usage(format!(
            "merging needs at least two maps, got {}",
            maps.len()
        )));
    }
    if reference >= maps.len() {
        return Err(MergeError::Usage(format!(
            "reference index {reference} is out of range: {} maps (0-based)",
            maps.len()
        )));
    }
    if relocalize.dof != Some(crate::align::Dof::Six) {
        let want = maps[reference].gravity_aligned;
        if let Some((index, map)) = maps
            .iter()
            .enumerate()
            .find(|(_, m)| m.gravity_aligned != want)
        {
            return Err(MergeError::MixedGravity {
                index,
                session: map.session.clone(),
                what: if map.gravity_aligned {
                    "gravity-aligned"
                } else {
                    "not gravity-aligned"
                },
                reference,
            });
        }
    }
    Ok(())
}

fn centroid(map: &ObjectMap) -> nalgebra::Point3<f64> {
    let n = map.len().max(1) as f64;
    let sum = map
        .landmarks
        .iter()
        .fold(nalgebra::Vector3::zeros(), |acc, l| acc + l.position.coords);
    (sum / n).into()
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
