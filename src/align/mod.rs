//! Rigid alignment of associated landmarks: `prior_from_query` from point pairs.
//!
//! - [`arun`]: Arun / Umeyama SVD solution for a full rigid motion (6 degrees of freedom).
//! - [`yaw_only`]: the closed form for a rotation about gravity (z) plus a translation
//!   (4 degrees of freedom), for gravity-aligned maps.
//! - [`mod@refine`]: iteratively re-weighted least squares with a Cauchy kernel over
//!   re-associated nearest neighbours, which turns a clique's rough answer into a
//!   centimetre one.
//! - [`tilt`]: for gravity-aligned maps that are not quite aligned, the yaw-only answer
//!   corrected by the residual roll and pitch when the pairs determine them (a gravity
//!   prior otherwise): [`Dof::Auto`].
//! - [`information`]: the 6 × 6 information matrix of the estimate for the pose graph.
//!
//! All solvers take weighted pairs `(p_prior, p_query, weight)` and return the isometry
//! that maps query points onto prior points: `p_prior ≈ prior_from_query * p_query`.

pub mod arun;
pub mod information;
pub mod refine;
pub mod tilt;
pub mod yaw_only;

use nalgebra::{Isometry3, Point3};
use serde::{Deserialize, Serialize};

pub use arun::align_rigid;
pub use information::{information_matrix, tilt_aware_information};
pub use refine::{refine, RefineConfig, Refined};
pub use tilt::{align_tilt, TiltAlignment, TiltConfig};
pub use yaw_only::align_yaw;

/// Which motion model the alignment solves for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Dof {
    /// Yaw about gravity (z) plus a 3D translation: both maps are gravity-aligned.
    #[serde(rename = "4")]
    Four,
    /// A full rigid motion: rotation about any axis plus translation.
    #[serde(rename = "6")]
    Six,
    /// Gravity-aligned maps whose alignment may be off by a small roll and pitch: 4-DOF
    /// association, then the tilt-aware alignment ([`tilt`]), which estimates the residual
    /// tilt when the pairs determine it.
    #[serde(rename = "auto")]
    Auto,
}

impl Dof {
    /// The degrees of freedom of the association's invariant (4 or 6; `Auto` associates
    /// with the 4-DOF one).
    pub fn count(self) -> u32 {
        match self {
            Dof::Four | Dof::Auto => 4,
            Dof::Six => 6,
        }
    }

    /// Whether the model needs gravity-aligned maps.
    pub fn needs_gravity(self) -> bool {
        self != Dof::Six
    }

    /// The name used on the command line and in configurations: `4`, `6` or `auto`.
    pub fn label(self) -> &'static str {
        match self {
            Dof::Four => "4",
            Dof::Six => "6",
            Dof::Auto => "auto",
        }
    }
}

/// One associated pair of points with its weight (inverse variance, 1/m²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WeightedPair {
    /// The point in the prior frame.
    pub p_prior: Point3<f64>,
    /// The point in the query frame.
    pub p_query: Point3<f64>,
    /// Weight of the pair (larger is more certain); must be positive and finite.
    pub weight: f64,
}

/// Solve `prior_from_query` for the given motion model, or `None` when the pairs are
/// degenerate (fewer than 2 for yaw-only or 3 for a full rigid motion, or zero weight).
/// `Auto` runs with the default [`TiltConfig`]; see [`align_with`].
pub fn align(pairs: &[WeightedPair], dof: Dof) -> Option<Isometry3<f64>> {
    align_with(pairs, dof, &TiltConfig::default())
}

/// [`align`] with the tilt-aware alignment's parameters (used by `Dof::Auto` only).
pub fn align_with(pairs: &[WeightedPair], dof: Dof, tilt: &TiltConfig) -> Option<Isometry3<f64>> {
    match dof {
        Dof::Four => align_yaw(pairs),
        Dof::Six => align_rigid(pairs),
        Dof::Auto => align_tilt(pairs, tilt).map(|a| a.prior_from_query),
    }
}

/// Weighted centroids `(c_prior, c_query, total_weight)` of the pairs, or `None` when the
/// total weight is not positive.
pub(crate) fn weighted_centroids(
    pairs: &[WeightedPair],
) -> Option<(Point3<f64>, Point3<f64>, f64)> {
    let mut w_sum = 0.0;
    let mut c_prior = nalgebra::Vector3::zeros();
    let mut c_query = nalgebra::Vector3::zeros();
    for pair in pairs {
        w_sum += pair.weight;
        c_prior += pair.weight * pair.p_prior.coords;
        c_query += pair.weight * pair.p_query.coords;
    }
    if w_sum.is_nan() || w_sum <= 0.0 || !w_sum.is_finite() {
        return None;
    }
    Some((
        Point3::from(c_prior / w_sum),
        Point3::from(c_query / w_sum),
        w_sum,
    ))
}

/// Root-mean-square residual ‖p_prior − T p_query‖ over the pairs (unweighted), in metres.
pub fn rmse(pairs: &[WeightedPair], prior_from_query: &Isometry3<f64>) -> f64 {
    if pairs.is_empty() {
        return 0.0;
    }
    let sum: f64 = pairs
        .iter()
        .map(|p| (p.p_prior - prior_from_query * p.p_query).norm_squared())
        .sum();
    (sum / pairs.len() as f64).sqrt()
}

#[cfg(test)]
pub(crate) mod test_util {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// A deterministic scatter of points in a 20 x 20 x 1 m box.
    pub fn scatter(n: usize, seed: u64) -> Vec<Point3<f64>> {
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64) / ((1u64 << 53) as f64)
        };
        (0..n)
            .map(|_| Point3::new(20.0 * next() - 10.0, 20.0 * next() - 10.0, next()))
            .collect()
    }

    pub fn pairs_for(
        points: &[Point3<f64>],
        prior_from_query: &Isometry3<f64>,
    ) -> Vec<WeightedPair> {
        let query_from_prior = prior_from_query.inverse();
        points
            .iter()
            .map(|p| WeightedPair {
                p_prior: *p,
                p_query: query_from_prior * p,
                weight: 1.0,
            })
            .collect()
    }

    pub fn yaw_transform(yaw: f64, t: Vector3<f64>) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(t),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        )
    }
}
