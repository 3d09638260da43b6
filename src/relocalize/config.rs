//! The relocalizer's configuration: one struct per stage, all with documented defaults.
//!
//! The whole configuration prints and loads as TOML (`segloc config print`,
//! `--config FILE`), and every report records the configuration it ran with.

use crate::align::{Dof, RefineConfig};
use crate::landmarks::FusionConfig;
use serde::{Deserialize, Serialize};

/// Every stage's parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RelocalizeConfig {
    /// Motion model: `"4"` (yaw + translation), `"6"` (full rigid motion) or `"auto"`
    /// (gravity-aligned maps: 4-DOF association, then the tilt-aware alignment, which
    /// estimates a residual roll and pitch when the inliers determine it; see
    /// `refine.tilt`). Unset: `gravity_aligned_dof` when both maps are gravity-aligned,
    /// else 6.
    pub dof: Option<Dof>,
    /// The motion model when `dof` is unset and both maps are gravity-aligned: `"auto"`
    /// (the default) or `"4"`. The localizer's default is `"4"`: its submaps are placed by
    /// the frames' own IMU attitudes, which a constant IMU bias bends rather than tilts
    /// rigidly, and its pose graph holds every frame's tilt with gravity factors (measured
    /// with a 0.3° bias: `auto` accepted 3 session-1 loop closures 1.0–1.2° off, `4` none).
    pub gravity_aligned_dof: Dof,
    /// Detections → landmarks (used when an input is a detection file or a traverse).
    pub landmarks: FusionConfig,
    /// Landmarks → candidate associations.
    pub associations: AssociationConfig,
    /// Associations → consistency graph.
    pub consistency: ConsistencyConfig,
    /// Consistency graph → cliques (hypotheses).
    pub clique: CliqueConfig,
    /// Clique → refined alignment over all landmarks.
    pub refine: RefineConfig,
    /// Hypotheses → accept or refuse.
    pub verification: VerificationConfig,
}

impl Default for RelocalizeConfig {
    fn default() -> Self {
        Self {
            dof: None,
            gravity_aligned_dof: Dof::Auto,
            landmarks: FusionConfig::default(),
            associations: AssociationConfig::default(),
            consistency: ConsistencyConfig::default(),
            clique: CliqueConfig::default(),
            refine: RefineConfig::default(),
            verification: VerificationConfig::default(),
        }
    }
}

/// Parameters of the candidate-association stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AssociationConfig {
    /// When both landmarks have a size, associate them only if the larger is at most this
    /// many times the smaller. Sizes unknown: every pair is a candidate (all-to-all).
    pub max_size_ratio: f64,
    /// A map with more landmarks than this offers only its this-many most observed ones
    /// as association candidates (refinement and verification still use all of them).
    pub max_landmarks: usize,
    /// A survey prior (every landmark with 0 observations: a rock grid, an orbital map)
    /// offers all its landmarks, since no detection count ranks them; the query then offers
    /// its most observed `max_associations / prior landmarks` ones (within
    /// `min_query_landmarks..=max_landmarks`). Session maps never reach it (120 × 120).
    pub max_associations: usize,
    /// See `max_associations`.
    pub min_query_landmarks: usize,
}

impl Default for AssociationConfig {
    fn default() -> Self {
        Self {
            max_size_ratio: 2.0,
            max_landmarks: 120,
            max_associations: 14_400,
            min_query_landmarks: 16,
        }
    }
}

/// Parameters of the consistency graph (the rigid-motion invariant).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ConsistencyConfig {
    /// Largest difference (m) of the pairwise distance (6-DOF) or horizontal distance
    /// (4-DOF) for two associations to be consistent.
    pub epsilon_m: f64,
    /// Scale (m) of the Gaussian edge weight exp(−c²/2σ²).
    pub sigma_m: f64,
    /// 4-DOF only: largest difference (m) of the height difference.
    pub epsilon_z_m: f64,
    /// 4-DOF only: scale (m) of the height term of the weight.
    pub sigma_z_m: f64,
    /// Covariance-driven tolerances: a pair of associations is consistent within this many
    /// standard deviations of its residual (from its four landmarks' covariances), never
    /// less than `epsilon_m` / `epsilon_z_m` (see docs/design/covariance-tolerances.md).
    pub sigma_multiplier: f64,
    /// Cap (m) of a pair's covariance-driven horizontal-distance (or distance) tolerance:
    /// a few very uncertain landmarks must not make the whole graph dense.
    pub max_epsilon_m: f64,
    /// Cap (m) of a pair's covariance-driven height tolerance (4-DOF).
    pub max_epsilon_z_m: f64,
}

impl Default for ConsistencyConfig {
    fn default() -> Self {
        Self {
            epsilon_m: 0.08,
            sigma_m: 0.04,
            epsilon_z_m: 0.06,
            sigma_z_m: 0.03,
            sigma_multiplier: 2.0,
            max_epsilon_m: 0.5,
            max_epsilon_z_m: 0.12,
        }
    }
}

/// Parameters of the clique stage (hypothesis generation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CliqueConfig {
    /// Seed of the relaxation's random start (results are reproducible).
    pub seed: u64,
    /// Number of hypotheses to extract: after each clique, the associations consistent
    /// with its transform are removed and the graph solved again.
    pub hypotheses: usize,
    /// Cliques smaller than this are not worth a hypothesis.
    pub min_clique: usize,
    /// Use the exact maximum-clique solver when the core-pruned graph is at most this large
    /// (vertices).
    pub exact_max_vertices: usize,
    /// Branch-and-bound nodes after which the exact solver gives up.
    pub exact_max_nodes: u64,
    /// Relaxation: most penalty increases (outer iterations). A clear clique converges in
    /// one or two; a graph without one (the later hypothesis rounds) would otherwise spend
    /// hundreds proving it.
    pub max_outer_iterations: usize,
    /// Relaxation: most gradient steps per outer iteration.
    pub max_inner_iterations: usize,
    /// Most edges sampled by the edge-seeded clique search, which catches a true clique the
    /// relaxation misses in dense (6-DOF) graphs (it stops earlier once a larger clique
    /// would have been found with probability 0.999).
    pub seeded_samples: usize,
}

impl Default for CliqueConfig {
    fn default() -> Self {
        Self {
            seed: 7,
            hypotheses: 4,
            min_clique: 4,
            exact_max_vertices: 3000,
            exact_max_nodes: 200_000,
            max_outer_iterations: 20,
            max_inner_iterations: 50,
            seeded_samples: 40_000,
        }
    }
}

/// Parameters of the acceptance test. A wrong transform accepted is the worst failure:
/// every test must pass.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VerificationConfig {
    /// Fewest refined inliers (landmark pairs within the inlier threshold).
    pub min_inliers: usize,
    /// Largest root-mean-square residual (m) over the inliers: the floor of the gate, which
    /// is `rmse_multiplier` times the RMS residual the inliers' covariances predict.
    pub max_rmse_m: f64,
    /// The residual gate in predicted RMS residuals (see `max_rmse_m`).
    pub rmse_multiplier: f64,
    /// Smallest standard deviation (m) of the inliers' positions along their minor
    /// horizontal axis: collinear or clustered inliers do not fix a yaw.
    pub min_spread_m: f64,
    /// The runner-up hypothesis (a transform that differs from the best) may have at most
    /// this fraction of the best one's inliers.
    pub max_runner_up_ratio: f64,
    /// ... and at least this many fewer inliers.
    pub min_runner_up_margin: usize,
    /// Two hypotheses whose transforms differ by less than this (m, at the inliers) are
    /// the same hypothesis.
    pub same_hypothesis_m: f64,
    /// Widened (grid) tolerances only: the largest standard deviation (degrees) of the yaw
    /// the inliers' covariances leave (the 4-DOF marginal of the information matrix):
    /// half the 1° an answer counts as wrong at, so an accepted yaw is within it at 2σ. A
    /// few inliers of 4–6 cm quantisation over a metre fix the yaw to 0.5° at best
    /// (docs/design/grid-yaw-precision.md). Session maps (tolerances at their floor) are
    /// not tested: `min_spread_m` stands for it.
    pub max_yaw_sigma_deg: f64,
}

impl Default for VerificationConfig {
    fn default() -> Self {
        Self {
            min_inliers: 6,
            max_rmse_m: 0.03,
            rmse_multiplier: 1.0,
            min_spread_m: 0.3,
            max_runner_up_ratio: 0.6,
            min_runner_up_margin: 3,
            same_hypothesis_m: 0.25,
            max_yaw_sigma_deg: 0.5,
        }
    }
}
