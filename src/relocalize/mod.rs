//! Relocalization: the rigid transform between a query map and a prior map of boulders,
//! or an explicit refusal.
//!
//! The stages, each in its own module:
//! landmarks ([`PreparedMap`]) → candidate associations ([`associations`]) → consistency
//! graph ([`consistency`], built by `segloc_clipper`) → cliques as hypotheses, each aligned
//! and refined ([`hypotheses`]) → acceptance ([`verify`]) → [`Relocalization`].
//!
//! ```
//! use segloc::relocalize::{Relocalizer, RelocalizeConfig};
//! use segloc::sim::boulder_field::{two_sessions, FieldConfig};
//! let (prior, query, truth) = two_sessions(&FieldConfig::default(), 3);
//! let relocalizer = Relocalizer::new(prior, RelocalizeConfig::default()).unwrap();
//! let answer = relocalizer.relocalize(&query).unwrap();
//! let estimate = answer.prior_from_query().expect("accepted");
//! assert!((estimate.translation.vector - truth.translation.vector).norm() < 0.05);
//! ```

pub mod associations;
pub mod config;
pub mod consistency;
pub mod hypotheses;
pub mod prepared;
pub mod result;
pub mod verify;

pub use config::{
    AssociationConfig, CliqueConfig, ConsistencyConfig, RelocalizeConfig, VerificationConfig,
};
pub use prepared::{PreparedMap, MIN_LANDMARKS};
pub use result::{
    Accepted, Diagnostics, Hypothesis, Refusal, Relocalization, TiltDiagnostics, Timings,
    Tolerances,
};

use crate::align::{information_matrix, tilt_aware_information, Dof, WeightedPair};
use segloc_clipper::ClipperError;
use segloc_maps::{MapError, ObjectMap};
use std::time::Instant;

/// Why a relocalization could not even be attempted (bad input, not a refusal).
#[derive(Debug, thiserror::Error)]
pub enum RelocalizeError {
    /// A map failed validation.
    #[error("{role} map is invalid: {source}")]
    InvalidMap {
        /// "prior" or "query".
        role: &'static str,
        /// What is wrong.
        source: MapError,
    },
    /// A map has too few landmarks to fix a transform.
    #[error("{role} map has {count} landmarks; relocalization needs at least {required}")]
    TooFewLandmarks {
        /// "prior" or "query".
        role: &'static str,
        /// Landmarks in the map.
        count: usize,
        /// The minimum.
        required: usize,
    },
    /// 4-DOF (or auto) was asked for but a map is not gravity-aligned.
    #[error("--dof {dof} needs gravity-aligned maps, but the {role} map is not (use --dof 6)")]
    NotGravityAligned {
        /// "prior" or "query".
        role: &'static str,
        /// The motion model asked for (`4` or `auto`).
        dof: &'static str,
    },
    /// The association solver rejected its input.
    #[error("association failed: {0}")]
    Association(#[from] ClipperError),
}

/// Relocalize `query` against `prior` once. To relocalize many queries against one prior,
/// build a [`Relocalizer`] once instead.
pub fn relocalize(
    prior: &ObjectMap,
    query: &ObjectMap,
    config: &RelocalizeConfig,
) -> Result<Relocalization, RelocalizeError> {
    Relocalizer::new(prior.clone(), config.clone())?.relocalize(query)
}

/// A prior map prepared once, relocalized against many times (e.g. from a SLAM system's
/// loop closure).
#[derive(Clone, Debug)]
pub struct Relocalizer {
    prior: PreparedMap,
    config: RelocalizeConfig,
}

impl Relocalizer {
    /// Prepare `prior` for relocalization with `config`.
    pub fn new(prior: ObjectMap, config: RelocalizeConfig) -> Result<Self, RelocalizeError> {
        Ok(Self {
            prior: PreparedMap::new(&prior, "prior")?,
            config,
        })
    }

    /// The configuration this relocalizer runs with.
    pub fn config(&self) -> &RelocalizeConfig {
        &self.config
    }

    /// Find `prior_from_query` for `query`, or refuse with the reason.
    pub fn relocalize(&self, query: &ObjectMap) -> Result<Relocalization, RelocalizeError> {
        let started = Instant::now();
        let config = &self.config;
        let prior = &self.prior;
        let query = match PreparedMap::new(query, "query") {
            Err(RelocalizeError::TooFewLandmarks {
                count, required, ..
            }) => {
                return Ok(self.too_few_landmarks(count, required, started));
            }
            prepared => prepared?,
        };
        let dof = self.motion_model(&query)?;
        let mut timings = Timings::default();

        // Landmarks → candidate associations.
        let t = Instant::now();
        let associations =
            associations::candidate_associations(prior, &query, &config.associations);
        timings.associations_ms = ms_since(t);

        // Associations → consistency graph.
        let t = Instant::now();
        let (graph, summary) =
            consistency::build_graph(prior, &query, &associations, dof, &config.consistency)?;
        timings.graph_ms = ms_since(t);
        let tolerances = Tolerances::from_summary(&summary, &config.consistency);
        // grid priors: the configuration scaled to the widened tolerances (`None` for
        // session maps); the chance floors come per hypothesis below
        let scaled = tolerances.scaled(&self.config);
        let config = scaled.as_ref().unwrap_or(config);

        // Graph → cliques → aligned and refined hypotheses.
        let found =
            hypotheses::generate_hypotheses(&graph, &associations, prior, &query, dof, config);
        timings.clique_ms = found.clique_ms;
        timings.alignment_ms = found.alignment_ms;
        let mut hypotheses = found.hypotheses;
        if scaled.is_some() {
            // wide (grid) tolerances: a few coarse inliers may fix the yaw no better than
            // the 1° a wrong answer is (see `VerificationConfig::max_yaw_sigma_deg`), and
            // a wrong transform collects inliers by chance wherever it puts the query
            for h in &mut hypotheses {
                h.yaw_sigma_deg = Some(yaw_sigma_of(h, prior, &query));
            }
            chance_floors(&mut hypotheses, prior, &query, config);
        }

        // Hypotheses → verification → the accepted transform with its information.
        let no_hypothesis = Refusal::NoHypothesis {
            largest_clique: found.largest_clique,
            required: config.clique.min_clique,
        };
        let outcome = if hypotheses.is_empty() {
            Err(no_hypothesis)
        } else {
            verify::decide(&mut hypotheses, &config.verification).and_then(|()| {
                let best = hypotheses.first().ok_or(no_hypothesis)?;
                Ok(accept(best, prior, &query, dof, config))
            })
        };
        timings.total_ms = ms_since(started);
        Ok(Relocalization {
            outcome,
            rmse_m: hypotheses.first().map_or(f64::NAN, |b| b.rmse_m),
            diagnostics: Diagnostics {
                prior_landmarks: prior.len(),
                query_landmarks: query.len(),
                associations: associations.len(),
                graph_edges: graph.num_edges(),
                dof: dof.count(),
                tilt_aware: dof == Dof::Auto,
                tolerances,
                hypotheses,
                timings,
            },
        })
    }

    /// The refusal of a query map too small to fix a transform.
    fn too_few_landmarks(&self, count: usize, required: usize, started: Instant) -> Relocalization {
        Relocalization {
            outcome: Err(Refusal::TooFewLandmarks {
                landmarks: count,
                required,
            }),
            rmse_m: f64::NAN,
            diagnostics: Diagnostics {
                prior_landmarks: self.prior.len(),
                query_landmarks: count,
                timings: Timings {
                    total_ms: ms_since(started),
                    ..Timings::default()
                },
                ..Diagnostics::default()
            },
        }
    }

    /// The motion model: the configured one, else `gravity_aligned_dof` (by default `auto`:
    /// 4-DOF association, tilt-aware alignment) when both maps are gravity-aligned, else
    /// 6-DOF.
    fn motion_model(&self, query: &PreparedMap) -> Result<Dof, RelocalizeError> {
        match self.config.dof {
            Some(dof) if dof.needs_gravity() && !self.prior.gravity_aligned => {
                Err(RelocalizeError::NotGravityAligned {
                    role: "prior",
                    dof: dof.label(),
                })
            }
            Some(dof) if dof.needs_gravity() && !query.gravity_aligned => {
                Err(RelocalizeError::NotGravityAligned {
                    role: "query",
                    dof: dof.label(),
                })
            }
            Some(dof) => Ok(dof),
            None if self.prior.gravity_aligned && query.gravity_aligned => {
                Ok(self.config.gravity_aligned_dof)
            }
            None => Ok(Dof::Six),
        }
    }
}

/// The accepted answer of the best hypothesis: its transform, its inliers by landmark id
/// and the information matrix of the transform (tilt-aware for the motion model `auto`).
fn accept(
    best: &Hypothesis,
    prior: &PreparedMap,
    query: &PreparedMap,
    dof: Dof,
    config: &RelocalizeConfig,
) -> Accepted {
    let pairs = inlier_pairs(best, prior, query);
    let inliers = best
        .inliers
        .iter()
        .map(|&(i, j)| (prior.ids[i as usize], query.ids[j as usize]))
        .collect();
    let information = match best.tilt {
        Some(tilt) if dof == Dof::Auto => tilt_aware_information(
            &pairs,
            &best.prior_from_query,
            tilt.determined,
            config.refine.tilt.gravity_sigma_deg.to_radians(),
        ),
        _ => information_matrix(&pairs, &best.prior_from_query),
    };
    Accepted {
        prior_from_query: best.prior_from_query,
        inliers,
        information,
    }
}

/// Widened (grid) tolerances: the fewest inliers of the best hypothesis and of every one
/// that could make it ambiguous, each raised to what a wrong transform collects by chance
/// where it puts the query ([`verify::local_chance_inliers`]). A rival under its own chance
/// count is no rival ([`verify::decide`]); the others keep `min_inliers: None`.
fn chance_floors(
    hypotheses: &mut [Hypothesis],
    prior: &PreparedMap,
    query: &PreparedMap,
    config: &RelocalizeConfig,
) {
    verify::sort_best_first(hypotheses);
    let Some(best_inliers) = hypotheses.first().map(|h| h.inlier_count) else {
        return;
    };
    let verification = &config.verification;
    for (k, h) in hypotheses.iter_mut().enumerate() {
        if k == 0 || verify::is_rival(h.inlier_count, best_inliers, verification) {
            let chance = verify::local_chance_inliers(
                &prior.points,
                &query.points,
                &h.prior_from_query,
                config.refine.inlier_threshold_m,
            );
            h.min_inliers = Some(verification.min_inliers.max(chance));
        }
    }
}

/// [`verify::yaw_sigma_deg`] of a hypothesis' inliers.
fn yaw_sigma_of(h: &Hypothesis, prior: &PreparedMap, query: &PreparedMap) -> f64 {
    verify::yaw_sigma_deg(&inlier_pairs(h, prior, query), &h.prior_from_query)
}

/// The landmark pairs of a hypothesis' inliers.
fn inlier_pairs(h: &Hypothesis, prior: &PreparedMap, query: &PreparedMap) -> Vec<WeightedPair> {
    h.inliers
        .iter()
        .map(|&(i, j)| {
            let a = segloc_clipper::Association { prior: i, query: j };
            hypotheses::pair_of(&a, prior, query)
        })
        .collect()
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
