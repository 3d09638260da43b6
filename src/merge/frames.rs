//! One frame per map: accepted pairwise transforms as robust factors in a pose graph.
//!
//! Frame variable k is `reference_from_map_k`; an accepted pair (a, b) measures
//! `a_from_b = X_a⁻¹ · X_b`. Initial values come from a spanning tree of the accepted pairs
//! grown from the reference, strongest pairs (most inliers) first, so a weak wrong pair is
//! not chained into the start. The reference frame is fixed; Cauchy kernels let the
//! consistent majority out-vote a wrong pair. A pair that still disagrees with the solution
//! is marked out-voted; a map left with only out-voted pairs is disconnected.

use super::pairwise::PairOutcome;
use super::{MergeConfig, MergeError};
use crate::graph::{PoseGraph, RobustKernel, SolverConfig, VarKey};
use nalgebra::{Isometry3, Point3};

/// The solved frames.
pub struct SolvedFrames {
    /// `reference_from_map` per input map; `None` when disconnected.
    pub reference_from_map: Vec<Option<Isometry3<f64>>>,
    /// RMS translation disagreement (m) of the kept pairwise factors at the map centroids.
    pub residual_rmse_m: f64,
}

/// Solve the frames of `count` maps; marks out-voted pairs in `pairs`. `centroids[k]` is
/// the centroid of map k's landmarks in its own frame (where disagreement is measured).
pub fn solve_frames(
    count: usize,
    reference: usize,
    pairs: &mut [PairOutcome],
    centroids: &[Point3<f64>],
    config: &MergeConfig,
) -> Result<SolvedFrames, MergeError> {
    let mut placed = spanning_tree(count, reference, pairs);
    let members: Vec<usize> = (0..count).filter(|&k| placed[k].is_some()).collect();
    if members.len() > 1 {
        let mut graph = PoseGraph::new();
        for &k in &members {
            graph.add_frame(k as u64, placed[k].unwrap_or_else(Isometry3::identity))?;
        }
        graph.fix(VarKey::Frame(reference as u64))?;
        for p in pairs.iter().filter(|p| p.accepted) {
            if let (Some(z), true, true) =
                (p.a_from_b, placed[p.a].is_some(), placed[p.b].is_some())
            {
                graph.add_between_keys(
                    VarKey::Frame(p.a as u64),
                    VarKey::Frame(p.b as u64),
                    z,
                    p.information,
                    RobustKernel::Cauchy {
                        c: config.factor_cauchy_scale,
                    },
                )?;
            }
        }
        graph.optimize(&SolverConfig::default())?;
        for &k in &members {
            placed[k] = graph.frame(k as u64);
        }
    }
    // Out-voted pairs, and maps that only out-voted pairs connect.
    let mut squared = Vec::new();
    let mut support = vec![0usize; count];
    support[reference] = 1;
    for p in pairs.iter_mut().filter(|p| p.accepted) {
        let (Some(xa), Some(xb), Some(z)) = (placed[p.a], placed[p.b], p.a_from_b) else {
            continue;
        };
        let c = centroids[p.b];
        let disagreement = ((xa.inverse() * xb) * c - z * c).norm();
        if disagreement > config.outvoted_m {
            p.outvoted = true;
        } else {
            squared.push(disagreement * disagreement);
            support[p.a] += 1;
            support[p.b] += 1;
        }
    }
    for k in 0..count {
        if support[k] == 0 {
            placed[k] = None;
        }
    }
    let residual_rmse_m = if squared.is_empty() {
        0.0
    } else {
        (squared.iter().sum::<f64>() / squared.len() as f64).sqrt()
    };
    Ok(SolvedFrames {
        reference_from_map: placed,
        residual_rmse_m,
    })
}

/// Initial frames from the reference by the strongest accepted pairs (Prim's algorithm on
/// inlier counts); maps it cannot reach stay `None`.
fn spanning_tree(
    count: usize,
    reference: usize,
    pairs: &[PairOutcome],
) -> Vec<Option<Isometry3<f64>>> {
    let mut placed: Vec<Option<Isometry3<f64>>> = vec![None; count];
    placed[reference] = Some(Isometry3::identity());
    loop {
        let next = pairs
            .iter()
            .filter(|p| p.accepted && placed[p.a].is_some() != placed[p.b].is_some())
            .max_by_key(|p| (p.inliers, std::cmp::Reverse((p.a, p.b))));
        let Some(p) = next else { break };
        let Some(a_from_b) = p.a_from_b else { break };
        match (placed[p.a], placed[p.b]) {
            (Some(xa), None) => placed[p.b] = Some(xa * a_from_b),
            (None, Some(xb)) => placed[p.a] = Some(xb * a_from_b.inverse()),
            _ => break,
        }
    }
    placed
}
