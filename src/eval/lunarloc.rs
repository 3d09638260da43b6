//! Relocalization between pairs of real LunarLoc traverses under random rigid transforms.
//!
//! For each pair (prior, query) and trial, the query traverse — rover positions and every
//! detection — is moved by a random rigid transform (any yaw, ±20 m in x and y, ±1 m in z;
//! for 6-DOF also roll and pitch up to ±10°; for the gravity-aligned models, with
//! [`EvalOptions::tilt_deg`], a residual roll and pitch within ±`tilt_deg` that the maps do
//! not declare, as from an IMU's error), fused into landmarks in its moved frame,
//! and relocalized against the prior traverse's map. The traverses share one world frame,
//! so the truth is the applied transform, and the truly common landmarks are the mutual
//! nearest neighbours within 10 cm between the two maps fused in the world frame.
//!
//! With [`EvalOptions::negatives`] the query traverse is mirrored in x before it is moved
//! ([`super::mirrored_x`]): it keeps a real map's density and spacing, but no rigid motion
//! aligns it with any traverse, its own original included, so every accepted answer is a
//! false accept. This measures how often the relocalizer is fooled by chance geometry.
//! Negatives need the 4-DOF model: in 6-DOF a mirrored boulder field, nearly planar, is
//! close to the original turned upside down (a rotation of 180° about y), a rigid motion
//! that gravity alone rules out.

use super::{transform_error, traverse_path};
use crate::align::refine::mutual_nearest;
use crate::align::Dof;
use crate::landmarks::fuse_detections;
use crate::relocalize::{RelocalizeConfig, Relocalizer};
use crate::spatial::GridIndex;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use segloc_maps::{read_lunarloc_traverse, MapError, ObjectMap, Traverse};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The five pairs of the LunarLoc paper's headline table.
pub const PAPER_PAIRS: [(usize, usize); 5] = [(3, 5), (3, 7), (5, 7), (5, 12), (7, 12)];

/// Number of LunarLoc traverses.
pub const TRAVERSES: usize = 17;

/// Distance (m) within which two landmarks of different traverses are the same boulder.
pub const COMMON_LANDMARK_M: f64 = 0.10;

/// An accepted answer off by more than these is a false accept.
pub const FALSE_ACCEPT_M: f64 = 0.10;
/// See [`FALSE_ACCEPT_M`] (degrees).
pub const FALSE_ACCEPT_DEG: f64 = 1.0;

/// What to evaluate.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    /// Pairs (prior, query) of traverse numbers.
    pub pairs: Vec<(usize, usize)>,
    /// Random transforms per pair.
    pub trials: usize,
    /// Seed of the transforms.
    pub seed: u64,
    /// Motion model.
    pub dof: Dof,
    /// Mirror every query in x: no answer is right, every acceptance a false accept.
    pub negatives: bool,
    /// Gravity-aligned models: the query is also tilted by a random roll and pitch, each
    /// uniform within ± this (degrees), while still claiming to be gravity-aligned. 0: none.
    pub tilt_deg: f64,
}

/// One trial's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct Trial {
    /// Whether the relocalizer accepted a transform.
    pub accepted: bool,
    /// Accepted and within the false-accept bounds.
    pub correct: bool,
    /// Translation error (m), when accepted.
    pub translation_error_m: Option<f64>,
    /// Rotation error (degrees), when accepted.
    pub rotation_error_deg: Option<f64>,
    /// Refined inliers of the best hypothesis.
    pub inliers: usize,
    /// Refusal reason, when refused.
    pub refusal: Option<String>,
    /// Motion model `auto`: the tilt-aware alignment's decision for the best hypothesis.
    pub tilt: Option<crate::relocalize::TiltDiagnostics>,
    /// Landmarks of the moved query map.
    pub query_landmarks: usize,
    /// Candidate associations.
    pub associations: usize,
    /// Relocalization time (ms), query map given.
    pub time_ms: f64,
}

/// One pair's outcome over its trials.
#[derive(Clone, Debug, Serialize)]
pub struct PairReport {
    /// Prior traverse number.
    pub prior: usize,
    /// Query traverse number.
    pub query: usize,
    /// Landmarks of the prior map.
    pub prior_landmarks: usize,
    /// Landmarks of the query map (in the world frame).
    pub query_landmarks: usize,
    /// Truly common landmarks.
    pub true_common: usize,
    /// Trials accepted and correct.
    pub successes: usize,
    /// Trials accepted but wrong.
    pub false_accepts: usize,
    /// The trials.
    pub trials: Vec<Trial>,
}

/// Totals over all pairs.
#[derive(Clone, Debug, Serialize)]
pub struct Totals {
    /// Trials run.
    pub trials: usize,
    /// Accepted and correct.
    pub successes: usize,
    /// Accepted but wrong.
    pub false_accepts: usize,
    /// successes / trials.
    pub success_rate: f64,
    /// Accepted with a translation error of at most 2 cm.
    pub accepted_within_2cm: usize,
    /// Accepted with a translation error over 10 cm.
    pub accepted_over_10cm: usize,
    /// Trials on pairs with at least 8 truly common landmarks, and their successes.
    pub trials_with_8_common: usize,
    /// Successes among those.
    pub successes_with_8_common: usize,
    /// Translation error (m) over correct answers: mean, median, max.
    pub translation_error_m: Stats,
    /// Rotation error (degrees) over correct answers: mean, median, max.
    pub rotation_error_deg: Stats,
    /// Relocalization time (ms): mean, median, max.
    pub time_ms: Stats,
}

/// Mean, median and maximum of a sample.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Stats {
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// Maximum.
    pub max: f64,
}

impl Stats {
    /// Statistics of `values` (zeros when empty).
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let mut sorted = values.to_vec();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let n = sorted.len();
        let median = if n % 2 == 1 {
            sorted[n / 2]
        } else {
            0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
        };
        Self {
            mean: sorted.iter().sum::<f64>() / n as f64,
            median,
            max: sorted[n - 1],
        }
    }
}

/// The whole evaluation.
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    /// Degrees of freedom of the association (4 or 6).
    pub dof: u32,
    /// Motion model: `4`, `6` or `auto`.
    pub motion_model: &'static str,
    /// Largest residual roll and pitch of the queries (degrees; gravity-aligned models).
    pub tilt_deg: f64,
    /// Trials per pair.
    pub trials_per_pair: usize,
    /// Seed.
    pub seed: u64,
    /// Whether the queries were mirrored ([`EvalOptions::negatives`]).
    pub negatives: bool,
    /// Per pair.
    pub pairs: Vec<PairReport>,
    /// Totals.
    pub totals: Totals,
    /// The configuration it ran with.
    pub config: RelocalizeConfig,
}

/// Every traverse against the mirror image of itself: the 17 pairs (n, n), the hardest
/// negatives (the same boulder statistics and extent).
pub fn self_pairs() -> Vec<(usize, usize)> {
    (1..=TRAVERSES).map(|n| (n, n)).collect()
}

/// All pairs (a, b) with a < b of the 17 traverses: 136 pairs.
pub fn all_pairs() -> Vec<(usize, usize)> {
    (1..=TRAVERSES)
        .flat_map(|a| ((a + 1)..=TRAVERSES).map(move |b| (a, b)))
        .collect()
}

/// A random rigid transform for a trial: any yaw, ±20 m in x and y, ±1 m in z, and for
/// 6-DOF roll and pitch within ±10°.
pub fn random_transform(rng: &mut ChaCha8Rng, dof: Dof) -> Isometry3<f64> {
    random_tilted_transform(rng, dof, 0.0)
}

/// [`random_transform`], and for the gravity-aligned models a roll and pitch each within
/// ±`tilt_deg` (drawn after the rest, so that the yaw and translation of every trial are
/// those of the untilted evaluation with the same seed).
pub fn random_tilted_transform(rng: &mut ChaCha8Rng, dof: Dof, tilt_deg: f64) -> Isometry3<f64> {
    let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let (mut roll, mut pitch) = match dof {
        Dof::Four | Dof::Auto => (0.0, 0.0),
        Dof::Six => (
            rng.random_range(-10f64..10.0).to_radians(),
            rng.random_range(-10f64..10.0).to_radians(),
        ),
    };
    let translation = Translation3::new(
        rng.random_range(-20.0..20.0),
        rng.random_range(-20.0..20.0),
        rng.random_range(-1.0..1.0),
    );
    if dof.needs_gravity() && tilt_deg > 0.0 {
        roll = rng.random_range(-tilt_deg..tilt_deg).to_radians();
        pitch = rng.random_range(-tilt_deg..tilt_deg).to_radians();
    }
    Isometry3::from_parts(
        translation,
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

/// Run the evaluation on the traverses under `data` (the folder holding `lunarloc/`).
pub fn evaluate(
    data: &Path,
    options: &EvalOptions,
    config: &RelocalizeConfig,
    mut progress: impl FnMut(usize, usize),
) -> Result<EvalReport, MapError> {
    if !(options.tilt_deg.is_finite() && (0.0..=10.0).contains(&options.tilt_deg)) {
        return Err(MapError::InvalidData {
            what: "evaluation",
            message: format!(
                "tilt must be within 0..=10 degrees, got {}",
                options.tilt_deg
            ),
        });
    }
    if options.negatives && !options.dof.needs_gravity() {
        return Err(MapError::InvalidData {
            what: "evaluation",
            message: "mirrored negatives need the 4-DOF model: in 6-DOF a mirrored, nearly \
                      planar boulder field is the original turned upside down"
                .into(),
        });
    }
    let mut traverses: BTreeMap<usize, Traverse> = BTreeMap::new();
    for &(a, b) in &options.pairs {
        for n in [a, b] {
            if let std::collections::btree_map::Entry::Vacant(slot) = traverses.entry(n) {
                slot.insert(read_lunarloc_traverse(&traverse_path(data, n))?);
            }
        }
    }
    let world_maps: BTreeMap<usize, ObjectMap> = traverses
        .iter()
        .map(|(&n, t)| (n, fuse_detections(&t.detections(), &config.landmarks)))
        .collect();
    let mut reports = Vec::new();
    for (k, &(a, b)) in options.pairs.iter().enumerate() {
        progress(k, options.pairs.len());
        let mut prior_map = world_maps[&a].clone();
        prior_map.gravity_aligned = options.dof.needs_gravity();
        let relocalizer = Relocalizer::new(prior_map.clone(), config.clone()).map_err(|e| {
            MapError::InvalidData {
                what: "map",
                message: format!("traverse {a}: {e}"),
            }
        })?;
        let mut rng = ChaCha8Rng::seed_from_u64(options.seed ^ ((a as u64) << 32 | b as u64));
        let trials = (0..options.trials)
            .map(|_| {
                let truth = random_tilted_transform(&mut rng, options.dof, options.tilt_deg);
                run_trial(&relocalizer, &traverses[&b], &truth, options, config)
            })
            .collect::<Vec<_>>();
        reports.push(PairReport {
            prior: a,
            query: b,
            prior_landmarks: world_maps[&a].len(),
            query_landmarks: world_maps[&b].len(),
            true_common: if options.negatives {
                0
            } else {
                common_landmarks(&world_maps[&a], &world_maps[&b])
            },
            successes: trials.iter().filter(|t| t.correct).count(),
            false_accepts: trials.iter().filter(|t| t.accepted && !t.correct).count(),
            trials,
        });
    }
    progress(options.pairs.len(), options.pairs.len());
    Ok(EvalReport {
        dof: options.dof.count(),
        motion_model: options.dof.label(),
        tilt_deg: options.tilt_deg,
        trials_per_pair: options.trials,
        seed: options.seed,
        negatives: options.negatives,
        totals: totals(&reports),
        pairs: reports,
        config: config.clone(),
    })
}

/// One trial: move the query traverse by `truth⁻¹` (so that `prior_from_query = truth`;
/// mirrored first for negatives), fuse it, relocalize, compare.
fn run_trial(
    relocalizer: &Relocalizer,
    query_traverse: &Traverse,
    truth: &Isometry3<f64>,
    options: &EvalOptions,
    config: &RelocalizeConfig,
) -> Trial {
    let mut world = query_traverse.detections();
    if options.negatives {
        world = super::mirrored_x(&world);
    }
    let mut detections = world.transformed(&truth.inverse(), "query");
    detections.gravity_aligned = options.dof.needs_gravity();
    let query_map = fuse_detections(&detections, &config.landmarks);
    let started = std::time::Instant::now();
    let outcome = relocalizer.relocalize(&query_map);
    let time_ms = started.elapsed().as_secs_f64() * 1e3;
    match outcome {
        Ok(answer) => {
            let errors = answer
                .prior_from_query()
                .map(|t| transform_error(&t, truth));
            let correct = !options.negatives
                && errors.is_some_and(|(t, r)| t <= FALSE_ACCEPT_M && r <= FALSE_ACCEPT_DEG);
            Trial {
                accepted: answer.is_accepted(),
                correct,
                translation_error_m: errors.map(|e| e.0),
                rotation_error_deg: errors.map(|e| e.1),
                inliers: answer
                    .diagnostics
                    .hypotheses
                    .first()
                    .map_or(0, |h| h.inlier_count),
                refusal: answer.refusal().map(|r| r.to_string()),
                tilt: answer.diagnostics.hypotheses.first().and_then(|h| h.tilt),
                query_landmarks: answer.diagnostics.query_landmarks,
                associations: answer.diagnostics.associations,
                time_ms,
            }
        }
        Err(e) => Trial {
            accepted: false,
            correct: false,
            translation_error_m: None,
            rotation_error_deg: None,
            inliers: 0,
            refusal: Some(e.to_string()),
            tilt: None,
            query_landmarks: query_map.len(),
            associations: 0,
            time_ms,
        },
    }
}

/// Truly common landmarks: mutual nearest neighbours within [`COMMON_LANDMARK_M`] of two
/// maps in one frame.
pub fn common_landmarks(a: &ObjectMap, b: &ObjectMap) -> usize {
    let (pa, pb) = (a.positions(), b.positions());
    let index = GridIndex::from_points(&pa, COMMON_LANDMARK_M);
    mutual_nearest(&pa, &index, &pb, &Isometry3::identity(), COMMON_LANDMARK_M).len()
}

fn totals(reports: &[PairReport]) -> Totals {
    let all: Vec<&Trial> = reports.iter().flat_map(|r| r.trials.iter()).collect();
    let correct: Vec<&&Trial> = all.iter().filter(|t| t.correct).collect();
    let with_8: Vec<&PairReport> = reports.iter().filter(|r| r.true_common >= 8).collect();
    let successes = correct.len();
    Totals {
        trials: all.len(),
        successes,
        false_accepts: all.iter().filter(|t| t.accepted && !t.correct).count(),
        accepted_within_2cm: all
            .iter()
            .filter(|t| t.accepted && t.translation_error_m.is_some_and(|e| e <= 0.02))
            .count(),
        accepted_over_10cm: all
            .iter()
            .filter(|t| t.accepted && t.translation_error_m.is_some_and(|e| e > 0.10))
            .count(),
        success_rate: if all.is_empty() {
            0.0
        } else {
            successes as f64 / all.len() as f64
        },
        trials_with_8_common: with_8.iter().map(|r| r.trials.len()).sum(),
        successes_with_8_common: with_8.iter().map(|r| r.successes).sum(),
        translation_error_m: Stats::of(
            &correct
                .iter()
                .filter_map(|t| t.translation_error_m)
                .collect::<Vec<_>>(),
        ),
        rotation_error_deg: Stats::of(
            &correct
                .iter()
                .filter_map(|t| t.rotation_error_deg)
                .collect::<Vec<_>>(),
        ),
        time_ms: Stats::of(&all.iter().map(|t| t.time_ms).collect::<Vec<_>>()),
    }
}
