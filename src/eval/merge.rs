//! Map merging evaluated on the real LunarLoc traverses used as agents.
//!
//! Each trial draws K traverses, moves each by its own random rigid transform (4-DOF: any
//! yaw, ±20 m, ±1 m), fuses each into a map in its moved frame, merges them into the
//! first one's frame, and compares every recovered `reference_from_map` with the truth.
//! Decoy agents — traverses mirrored in x, which have the statistics of a real map but
//! share no boulder with anything (a reflection is not a rigid motion) — must never be
//! placed.

use super::lunarloc::{random_transform, Stats, TRAVERSES};
use super::{transform_error, traverse_path};
use crate::align::Dof;
use crate::landmarks::fuse_detections;
use crate::merge::{merge_maps, MapStatus, MergeConfig};
use crate::relocalize::RelocalizeConfig;
use nalgebra::Isometry3;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use segloc_maps::{read_lunarloc_traverse, DetectionSet, MapError, ObjectMap};
use serde::Serialize;
use std::path::Path;

/// What to evaluate.
#[derive(Clone, Debug)]
pub struct MergeEvalOptions {
    /// Agents (traverses) per trial.
    pub agents: usize,
    /// Decoy agents (mirrored traverses) added to each trial.
    pub decoys: usize,
    /// Trials.
    pub trials: usize,
    /// Seed.
    pub seed: u64,
    /// Viewpoint-bias correction (m) used when fusing each agent's detections
    /// ([`crate::landmarks::FusionConfig::view_bias_m`]); 0 = none.
    pub view_bias_m: f64,
    /// Boulder-to-boulder spread of that bias (m) in the landmark covariances
    /// ([`crate::landmarks::FusionConfig::view_bias_sigma_m`]); 0 = not modelled.
    pub view_bias_sigma_m: f64,
}

/// One agent's outcome in a trial.
#[derive(Clone, Debug, Serialize)]
pub struct AgentOutcome {
    /// Traverse number.
    pub traverse: usize,
    /// A mirrored decoy.
    pub decoy: bool,
    /// Placed in the reference frame.
    pub merged: bool,
    /// Translation error (m) of its placement, when placed.
    pub translation_error_m: Option<f64>,
    /// Rotation error (degrees), when placed.
    pub rotation_error_deg: Option<f64>,
}

/// One trial.
#[derive(Clone, Debug, Serialize)]
pub struct MergeTrial {
    /// The agents, the reference first.
    pub agents: Vec<AgentOutcome>,
    /// Merge time (ms).
    pub time_ms: f64,
    /// Landmarks of the merged map.
    pub landmarks: usize,
    /// Fused landmarks.
    pub fused: usize,
}

/// The evaluation.
#[derive(Clone, Debug, Serialize)]
pub struct MergeEvalReport {
    /// The trials.
    pub trials: Vec<MergeTrial>,
    /// Real agents placed / real agents.
    pub placed: usize,
    /// Real agents in all trials (reference excluded).
    pub agents: usize,
    /// Real agents placed worse than 1 cm or 0.1°.
    pub placed_outside_1cm_0p1deg: usize,
    /// Decoys placed (must be 0).
    pub decoys_placed: usize,
    /// Decoys in all trials.
    pub decoys: usize,
    /// Translation error (m) of placed real agents.
    pub translation_error_m: Stats,
    /// Rotation error (degrees) of placed real agents.
    pub rotation_error_deg: Stats,
    /// Merge time (ms).
    pub time_ms: Stats,
}

/// Run the merge evaluation on the traverses under `data`.
pub fn evaluate_merge(
    data: &Path,
    options: &MergeEvalOptions,
    config: &RelocalizeConfig,
    mut progress: impl FnMut(usize, usize),
) -> Result<MergeEvalReport, MapError> {
    let mut fusion = config.landmarks.clone();
    fusion.view_bias_m = options.view_bias_m;
    fusion.view_bias_sigma_m = options.view_bias_sigma_m;
    let detections: Vec<DetectionSet> = (1..=TRAVERSES)
        .map(|n| read_lunarloc_traverse(&traverse_path(data, n)).map(|t| t.detections()))
        .collect::<Result<_, _>>()?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut trials = Vec::new();
    for trial in 0..options.trials {
        progress(trial, options.trials);
        let mut numbers: Vec<usize> = (1..=TRAVERSES).collect();
        numbers.shuffle(&mut rng);
        let chosen: Vec<(usize, bool)> = numbers[..options.agents.min(TRAVERSES)]
            .iter()
            .map(|&n| (n, false))
            .chain(
                numbers[..options.decoys.min(TRAVERSES)]
                    .iter()
                    .map(|&n| (n, true)),
            )
            .collect();
        let mut maps = Vec::new();
        let mut world_from_map = Vec::new();
        for &(n, decoy) in &chosen {
            let truth = random_transform(&mut rng, Dof::Four);
            let mut set = detections[n - 1].clone();
            if decoy {
                set = super::mirrored_x(&set);
                set.session = format!("decoy_{n}");
            }
            let moved = set.transformed(&truth.inverse(), "agent");
            maps.push(fuse_detections(&moved, &fusion));
            world_from_map.push(truth);
        }
        let report = merge_maps(&maps, 0, config, &MergeConfig::default()).map_err(|e| {
            MapError::InvalidData {
                what: "merge",
                message: e.to_string(),
            }
        })?;
        let agents = chosen
            .iter()
            .zip(&report.maps)
            .enumerate()
            .map(|(k, (&(traverse, decoy), placement))| {
                let errors = placement.reference_from_map.map(|estimate| {
                    // world_from_map estimated = world_from_reference (truth) · estimate.
                    transform_error(&(world_from_map[0] * estimate), &world_from_map[k])
                });
                AgentOutcome {
                    traverse,
                    decoy,
                    merged: placement.status == MapStatus::Merged,
                    translation_error_m: errors.map(|e| e.0),
                    rotation_error_deg: errors.map(|e| e.1),
                }
            })
            .collect();
        trials.push(MergeTrial {
            agents,
            time_ms: report.time_ms,
            landmarks: report.landmarks,
            fused: report.fused,
        });
    }
    progress(options.trials, options.trials);
    Ok(summarise(trials))
}

fn summarise(trials: Vec<MergeTrial>) -> MergeEvalReport {
    let real: Vec<&AgentOutcome> = trials
        .iter()
        .flat_map(|t| t.agents.iter().skip(1))
        .filter(|a| !a.decoy)
        .collect();
    let placed: Vec<&&AgentOutcome> = real.iter().filter(|a| a.merged).collect();
    let decoys: Vec<&AgentOutcome> = trials
        .iter()
        .flat_map(|t| t.agents.iter())
        .filter(|a| a.decoy)
        .collect();
    let t_err: Vec<f64> = placed
        .iter()
        .filter_map(|a| a.translation_error_m)
        .collect();
    let r_err: Vec<f64> = placed.iter().filter_map(|a| a.rotation_error_deg).collect();
    MergeEvalReport {
        placed: placed.len(),
        agents: real.len(),
        placed_outside_1cm_0p1deg: placed
            .iter()
            .filter(|a| {
                a.translation_error_m.unwrap_or(f64::INFINITY) > 0.01
                    || a.rotation_error_deg.unwrap_or(f64::INFINITY) > 0.1
            })
            .count(),
        decoys_placed: decoys.iter().filter(|a| a.merged).count(),
        decoys: decoys.len(),
        translation_error_m: Stats::of(&t_err),
        rotation_error_deg: Stats::of(&r_err),
        time_ms: Stats::of(&trials.iter().map(|t| t.time_ms).collect::<Vec<_>>()),
        trials,
    }
}

/// All 17 traverses, each in its own random frame, merged once: (report, merged map in
/// the world frame) — for the speed figure and the rock-map comparison.
pub fn merge_all(
    data: &Path,
    seed: u64,
    fusion: &crate::landmarks::FusionConfig,
    config: &RelocalizeConfig,
) -> Result<(crate::merge::MergeReport, ObjectMap), MapError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut maps = Vec::new();
    let mut reference_truth = Isometry3::identity();
    for n in 1..=TRAVERSES {
        let set = read_lunarloc_traverse(&traverse_path(data, n))?.detections();
        let truth = random_transform(&mut rng, Dof::Four);
        if n == 1 {
            reference_truth = truth;
        }
        maps.push(fuse_detections(
            &set.transformed(&truth.inverse(), "agent"),
            fusion,
        ));
    }
    let report = merge_maps(&maps, 0, config, &MergeConfig::default()).map_err(|e| {
        MapError::InvalidData {
            what: "merge",
            message: e.to_string(),
        }
    })?;
    let in_world = report.merged.transformed(&reference_truth, "world");
    Ok((report, in_world))
}

/// The rock map of the merged 17-traverse map against those of the single traverses, all
/// made the same way (`mapping::rock_grid` from landmarks) and scored against the LAC
/// ground truth.
#[derive(Clone, Debug, Serialize)]
pub struct RockMapComparison {
    /// Rock-map F1 of the merged map.
    pub merged_f1: f64,
    /// Its precision.
    pub merged_precision: f64,
    /// Its recall.
    pub merged_recall: f64,
    /// F1 of each single traverse's map: (traverse, F1).
    pub single_f1: Vec<(usize, f64)>,
    /// The best single traverse and its F1.
    pub best_single: (usize, f64),
}

/// Merge all 17 traverses (each in its own random frame), turn the merged map into a rock
/// grid, and compare its F1 with every single traverse's.
pub fn merged_rock_map(
    data: &Path,
    seed: u64,
    fusion: &crate::landmarks::FusionConfig,
    config: &RelocalizeConfig,
) -> Result<RockMapComparison, MapError> {
    use crate::mapping::{rock_grid, score, RockGridConfig};
    let truth = segloc_maps::read_grid_csv(&data.join("lac-groundtruth/moon_map_01_preset_1.csv"))?;
    let grid_config = RockGridConfig::default();
    let f1_of = |map: &ObjectMap| -> Result<(f64, f64, f64), MapError> {
        let grid = rock_grid(&map.landmarks, &truth, &grid_config);
        let s = score(&grid, &truth, None).map_err(|e| MapError::InvalidData {
            what: "grid",
            message: e.to_string(),
        })?;
        Ok((s.rock_f1, s.rock_precision, s.rock_recall))
    };
    let (_, merged_world) = merge_all(data, seed, fusion, config)?;
    let (merged_f1, merged_precision, merged_recall) = f1_of(&merged_world)?;
    let mut single_f1 = Vec::new();
    for n in 1..=TRAVERSES {
        let set = read_lunarloc_traverse(&traverse_path(data, n))?.detections();
        single_f1.push((n, f1_of(&fuse_detections(&set, fusion))?.0));
    }
    let best_single = single_f1
        .iter()
        .copied()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, 0.0));
    Ok(RockMapComparison {
        merged_f1,
        merged_precision,
        merged_recall,
        single_f1,
        best_single,
    })
}
