//! What a relocalization returns: the transform with its evidence, or a refusal with its
//! reason — always with the diagnostics.

use nalgebra::{Isometry3, Matrix4, Matrix6};
use serde::Serialize;

/// Why a relocalization was refused.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Refusal {
    /// The query map has too few landmarks to fix a transform.
    TooFewLandmarks {
        /// Landmarks in the query map.
        landmarks: usize,
        /// The minimum.
        required: usize,
    },
    /// The consistency graph held no clique large enough to be a hypothesis.
    NoHypothesis {
        /// Size of the largest clique found.
        largest_clique: usize,
        /// The smallest size that makes a hypothesis.
        required: usize,
    },
    /// The best hypothesis has too few inliers.
    TooFewInliers {
        /// Inliers of the best hypothesis.
        inliers: usize,
        /// Required inliers.
        required: usize,
    },
    /// The inliers' residuals are too large.
    ResidualTooLarge {
        /// Root-mean-square residual (m).
        rmse_m: f64,
        /// Largest accepted (m).
        max_rmse_m: f64,
    },
    /// The inliers lie on a line or in a small patch: the yaw is not fixed.
    DegenerateGeometry {
        /// Standard deviation (m) along the inliers' minor horizontal axis.
        spread_m: f64,
        /// Smallest accepted (m).
        min_spread_m: f64,
    },
    /// Widened (grid) tolerances: the inliers' covariances leave the yaw too uncertain.
    YawUncertain {
        /// Standard deviation (degrees) of the yaw.
        yaw_sigma_deg: f64,
        /// Largest accepted (degrees).
        max_yaw_sigma_deg: f64,
    },
    /// A different transform is supported almost as well.
    Ambiguous {
        /// Inliers of the best hypothesis.
        best_inliers: usize,
        /// Inliers of the runner-up.
        runner_up_inliers: usize,
    },
}

impl Refusal {
    /// A stable machine-readable code, the same as the JSON's `kind`
    /// (`too_few_landmarks`, `no_hypothesis`, `too_few_inliers`, `residual_too_large`,
    /// `degenerate_geometry`, `yaw_uncertain`, `ambiguous`).
    pub fn code(&self) -> &'static str {
        match self {
            Refusal::TooFewLandmarks { .. } => "too_few_landmarks",
            Refusal::NoHypothesis { .. } => "no_hypothesis",
            Refusal::TooFewInliers { .. } => "too_few_inliers",
            Refusal::ResidualTooLarge { .. } => "residual_too_large",
            Refusal::DegenerateGeometry { .. } => "degenerate_geometry",
            Refusal::YawUncertain { .. } => "yaw_uncertain",
            Refusal::Ambiguous { .. } => "ambiguous",
        }
    }
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::TooFewLandmarks { landmarks, required } => write!(
                f,
                "query map has {landmarks} landmarks; relocalization needs at least {required}"
            ),
            Refusal::NoHypothesis { largest_clique, required } => write!(
                f,
                "no consistent set of associations: largest clique {largest_clique}, need {required}"
            ),
            Refusal::TooFewInliers { inliers, required } => {
                write!(f, "too few inliers: {inliers}, need {required}")
            }
            Refusal::ResidualTooLarge { rmse_m, max_rmse_m } => write!(
                f,
                "inlier residual too large: rmse {:.1} cm > {:.1} cm",
                rmse_m * 100.0,
                max_rmse_m * 100.0
            ),
            Refusal::DegenerateGeometry { spread_m, min_spread_m } => write!(
                f,
                "inliers collinear or clustered: minor-axis spread {:.2} m < {:.2} m",
                spread_m, min_spread_m
            ),
            Refusal::YawUncertain {
                yaw_sigma_deg,
                max_yaw_sigma_deg,
            } => write!(
                f,
                "yaw too uncertain: sigma {yaw_sigma_deg:.2} deg > {max_yaw_sigma_deg:.2} deg"
            ),
            Refusal::Ambiguous { best_inliers, runner_up_inliers } => write!(
                f,
                "ambiguous: best hypothesis has {best_inliers} inliers, a different one has {runner_up_inliers}"
            ),
        }
    }
}

/// One hypothesis: a clique's transform refined over all landmarks.
#[derive(Clone, Debug, Serialize)]
pub struct Hypothesis {
    /// Associations in the clique.
    pub clique_size: usize,
    /// The refined transform, as a 4 × 4 row-major matrix.
    #[serde(serialize_with = "serialize_isometry")]
    pub prior_from_query: Isometry3<f64>,
    /// Refined inliers: (prior landmark index, query landmark index).
    #[serde(skip)]
    pub inliers: Vec<(u32, u32)>,
    /// Query-frame positions of the inliers (where two hypotheses are compared).
    #[serde(skip)]
    pub support_query: Vec<nalgebra::Point3<f64>>,
    /// Number of refined inliers.
    pub inlier_count: usize,
    /// Root-mean-square residual (m) over the inliers.
    pub rmse_m: f64,
    /// Standard deviation (m) of the inliers along their minor horizontal axis.
    pub spread_m: f64,
    /// Motion model `auto` only: the tilt-aware alignment's last decision.
    pub tilt: Option<TiltDiagnostics>,
    /// The residual gate (m) for this hypothesis: the configured floor, or the RMS residual
    /// its inliers' covariances predict times the multiplier, whichever is larger.
    pub max_rmse_m: f64,
    /// Widened (grid) tolerances only: the standard deviation (degrees) of the yaw from the
    /// inliers' covariances (see `VerificationConfig::max_yaw_sigma_deg`).
    pub yaw_sigma_deg: Option<f64>,
    /// Widened (grid) tolerances only, on the best hypothesis and on those that could make
    /// it ambiguous: the fewest inliers it needs, raised to what a wrong transform collects
    /// by chance where this one puts the query (see [`super::verify::local_chance_inliers`]);
    /// `None`: the configuration's.
    pub min_inliers: Option<usize>,
}

/// The tolerances a relocalization used (they follow the landmarks' covariances).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Tolerances {
    /// Whether any association pair's tolerance exceeded the configured `epsilon_m` or
    /// `epsilon_z_m` (false: every pair used them).
    pub widened: bool,
    /// Largest horizontal (4-DOF) or distance (6-DOF) tolerance of any pair (m).
    pub epsilon_max_m: f64,
    /// Largest height tolerance of any pair (m; 4-DOF).
    pub epsilon_z_max_m: f64,
    /// The tolerance of a pair of two median associations (m).
    pub epsilon_median_m: f64,
    /// Factor applied to the refinement's gate, inlier threshold and kernel scale, to the
    /// same-hypothesis distance and to the fewest inliers: the median tolerance over
    /// `epsilon_m` (1 unless most pairs were widened).
    pub refine_scale: f64,
}

impl Tolerances {
    /// From the graph build's summary.
    pub fn from_summary(
        summary: &segloc_clipper::ToleranceSummary,
        config: &super::ConsistencyConfig,
    ) -> Self {
        Self {
            widened: summary.widened,
            epsilon_max_m: summary.epsilon_max,
            epsilon_z_max_m: summary.epsilon_z_max,
            epsilon_median_m: summary.epsilon_median,
            refine_scale: (summary.epsilon_median / config.epsilon_m).max(1.0),
        }
    }

    /// The configuration with the refinement's distances scaled by `refine_scale`, or
    /// `None` when the scale is 1 (the configuration is used as it is).
    pub fn scaled(&self, config: &super::RelocalizeConfig) -> Option<super::RelocalizeConfig> {
        let s = self.refine_scale;
        if s <= 1.0 {
            return None;
        }
        let mut out = config.clone();
        out.refine.gate_m *= s;
        out.refine.inlier_threshold_m *= s;
        // the kernel's scale: at least the RMS residual one median association's covariances
        // predict (the median tolerance over the multiplier: 6.3 cm against the 0.15 m grid).
        // A narrower kernel lets the few pairs that happen to sit within a centimetre pull the
        // yaw (traverse 8: 0.34° with 1.3 cm, see docs/design/covariance-tolerances.md)
        let predicted_m = if config.consistency.sigma_multiplier > 0.0 {
            self.epsilon_median_m / config.consistency.sigma_multiplier
        } else {
            0.0
        };
        out.refine.cauchy_scale_m = (config.refine.cauchy_scale_m * s).max(predicted_m);
        out.verification.same_hypothesis_m *= s;
        // a wider inlier gate lets more landmarks fall in it by chance (measured on mirrored
        // traverses against the 0.15 m grid: 5 of 340 accepted with 6 inliers); linear in the
        // scale refused most traverses at 0.45 m (28 inliers needed), so its square root
        out.verification.min_inliers =
            (config.verification.min_inliers as f64 * s.sqrt()).ceil() as usize;
        Some(out)
    }
}

/// What the tilt-aware alignment (motion model `auto`) decided for a hypothesis.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TiltDiagnostics {
    /// Whether the inliers determined the residual tilt (else the answer is yaw-only, the
    /// tilt known from gravity alone).
    pub determined: bool,
    /// Whether the answer includes the tilt (determined and not indistinguishable from
    /// level).
    pub applied: bool,
    /// The estimated tilt about the prior frame's x and y axes (degrees), applied or not.
    pub tilt_deg: [f64; 2],
    /// Worst-direction standard deviation of the tilt from the inliers alone (degrees;
    /// `null` when they do not fix it at all).
    pub sigma_deg: f64,
}

impl From<crate::align::TiltAlignment> for TiltDiagnostics {
    fn from(a: crate::align::TiltAlignment) -> Self {
        Self {
            determined: a.tilt_determined,
            applied: a.tilt_applied,
            tilt_deg: a.tilt_rad.map(f64::to_degrees),
            sigma_deg: a.tilt_sigma_rad.to_degrees(),
        }
    }
}

/// Timings of the stages, milliseconds.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Timings {
    /// Candidate associations.
    pub associations_ms: f64,
    /// Consistency graph build.
    pub graph_ms: f64,
    /// Clique solves (all hypotheses).
    pub clique_ms: f64,
    /// Alignment and refinement (all hypotheses).
    pub alignment_ms: f64,
    /// The whole relocalization.
    pub total_ms: f64,
}

/// Everything measured on the way, accepted or not.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Diagnostics {
    /// Landmarks in the prior map.
    pub prior_landmarks: usize,
    /// Landmarks in the query map.
    pub query_landmarks: usize,
    /// Candidate associations.
    pub associations: usize,
    /// Edges of the consistency graph.
    pub graph_edges: usize,
    /// Degrees of freedom of the association (4 or 6; 4 for `auto`).
    pub dof: u32,
    /// Whether the alignment was tilt-aware (motion model `auto`).
    pub tilt_aware: bool,
    /// The consistency tolerances used.
    pub tolerances: Tolerances,
    /// Hypotheses examined, best first.
    pub hypotheses: Vec<Hypothesis>,
    /// Stage timings.
    pub timings: Timings,
}

/// An accepted relocalization: the transform and its evidence.
#[derive(Clone, Debug)]
pub struct Accepted {
    /// The transform taking query-map coordinates into the prior map's frame.
    pub prior_from_query: Isometry3<f64>,
    /// Inliers (prior landmark id, query landmark id).
    pub inliers: Vec<(u32, u32)>,
    /// 6 × 6 information matrix of `prior_from_query` for the pose graph, tangent ordered
    /// (rotation, translation), right perturbation (GTSAM's `Pose3` convention).
    pub information: Matrix6<f64>,
}

/// The answer of one relocalization: accepted with its evidence, or refused with the
/// reason, and in both cases the diagnostics.
///
/// ```
/// # use segloc::relocalize::{Relocalization, Refusal};
/// # fn report(answer: &Relocalization) {
/// match &answer.outcome {
///     Ok(accepted) => println!("{} inliers", accepted.inliers.len()),
///     Err(refusal) => println!("refused ({}): {refusal}", refusal.code()),
/// }
/// # }
/// ```
#[derive(Clone, Debug)]
pub struct Relocalization {
    /// The accepted transform, or why it was refused.
    pub outcome: Result<Accepted, Refusal>,
    /// Root-mean-square residual (m) over the inliers of the best hypothesis (accepted or
    /// not; NaN without a hypothesis).
    pub rmse_m: f64,
    /// Diagnostics.
    pub diagnostics: Diagnostics,
}

impl Relocalization {
    /// Whether the transform was accepted.
    pub fn is_accepted(&self) -> bool {
        self.outcome.is_ok()
    }

    /// The accepted answer, if any.
    pub fn accepted(&self) -> Option<&Accepted> {
        self.outcome.as_ref().ok()
    }

    /// The accepted transform, if any.
    pub fn prior_from_query(&self) -> Option<Isometry3<f64>> {
        self.accepted().map(|a| a.prior_from_query)
    }

    /// Why it was refused, if it was.
    pub fn refusal(&self) -> Option<&Refusal> {
        self.outcome.as_ref().err()
    }

    /// The best hypothesis' transform, accepted or not (useful for diagnosis only).
    pub fn best_guess(&self) -> Option<Isometry3<f64>> {
        self.diagnostics
            .hypotheses
            .first()
            .map(|h| h.prior_from_query)
    }
}

impl Serialize for Relocalization {
    /// The flat JSON shape: `prior_from_query` (4 × 4 or null), `refusal` (an object with
    /// its `kind`, or null), `inliers`, `rmse_m`, `information` (zeros when refused),
    /// `diagnostics`.
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let accepted = self.accepted();
        let mut out = s.serialize_struct("Relocalization", 6)?;
        out.serialize_field(
            "prior_from_query",
            &accepted.map(|a| matrix_rows(&a.prior_from_query)),
        )?;
        out.serialize_field("refusal", &self.refusal())?;
        out.serialize_field("inliers", &accepted.map_or(&[][..], |a| &a.inliers[..]))?;
        out.serialize_field("rmse_m", &self.rmse_m)?;
        let information = accepted.map_or_else(Matrix6::zeros, |a| a.information);
        out.serialize_field("information", &matrix6_rows(&information))?;
        out.serialize_field("diagnostics", &self.diagnostics)?;
        out.end()
    }
}

/// A 4 × 4 homogeneous matrix as nested rows.
pub fn matrix_rows(transform: &Isometry3<f64>) -> [[f64; 4]; 4] {
    let m: Matrix4<f64> = transform.to_homogeneous();
    let mut rows = [[0.0; 4]; 4];
    for (r, row) in rows.iter_mut().enumerate() {
        for (c, value) in row.iter_mut().enumerate() {
            *value = m[(r, c)];
        }
    }
    rows
}

fn serialize_isometry<S: serde::Serializer>(t: &Isometry3<f64>, s: S) -> Result<S::Ok, S::Error> {
    matrix_rows(t).serialize(s)
}

pub(crate) fn serialize_option_isometry<S: serde::Serializer>(
    t: &Option<Isometry3<f64>>,
    s: S,
) -> Result<S::Ok, S::Error> {
    t.as_ref().map(matrix_rows).serialize(s)
}

/// A 6 × 6 matrix as nested rows.
pub fn matrix6_rows(m: &Matrix6<f64>) -> [[f64; 6]; 6] {
    let mut rows = [[0.0; 6]; 6];
    for (r, row) in rows.iter_mut().enumerate() {
        for (c, value) in row.iter_mut().enumerate() {
            *value = m[(r, c)];
        }
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::relocalize::RelocalizeConfig;

    #[test]
    fn scaled_kernel_follows_the_predicted_residual() {
        let config = RelocalizeConfig::default();
        let session = Tolerances {
            epsilon_median_m: 0.08,
            refine_scale: 1.0,
            ..Tolerances::default()
        };
        assert!(session.scaled(&config).is_none());
        // a 0.15 m grid: median tolerance 12.6 cm, k = 2 → one association's RMS residual 6.3 cm
        let grid = Tolerances {
            epsilon_median_m: 0.126,
            refine_scale: 0.126 / 0.08,
            ..Tolerances::default()
        };
        let scaled = grid.scaled(&config).unwrap();
        assert!((scaled.refine.cauchy_scale_m - 0.063).abs() < 1e-12);
        let gate = config.refine.gate_m * 0.126 / 0.08;
        assert!((scaled.refine.gate_m - gate).abs() < 1e-12);
    }
}
