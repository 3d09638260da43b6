//! The consistency graph of the candidate associations (see `segloc_clipper`).

use super::config::ConsistencyConfig;
use super::prepared::PreparedMap;
use crate::align::Dof;
use segloc_clipper::{
    Association, ClipperError, ConsistencyGraph, Invariant, PointVariances, ToleranceSummary,
};

/// The consistency graph of `associations`, each pair's tolerance from its landmarks'
/// covariances (at least the configured one), and the tolerances used.
pub fn build_graph(
    prior: &PreparedMap,
    query: &PreparedMap,
    associations: &[Association],
    dof: Dof,
    config: &ConsistencyConfig,
) -> Result<(ConsistencyGraph, ToleranceSummary), ClipperError> {
    let (prior_var, query_var) = match dof {
        Dof::Six => (&prior.var_3d, &query.var_3d),
        Dof::Four | Dof::Auto => (&prior.var_xy, &query.var_xy),
    };
    let variances = PointVariances {
        prior: prior_var,
        query: query_var,
        prior_z: &prior.var_z,
        query_z: &query.var_z,
        multiplier: config.sigma_multiplier,
        max_epsilon: config.max_epsilon_m,
        max_epsilon_z: config.max_epsilon_z_m,
    };
    ConsistencyGraph::build_with_variances(
        &prior.points,
        &query.points,
        associations,
        &invariant(dof, config),
        &variances,
    )
}

/// The rigid-motion invariant for the motion model.
pub fn invariant(dof: Dof, config: &ConsistencyConfig) -> Invariant {
    match dof {
        Dof::Six => Invariant::Distance {
            epsilon: config.epsilon_m,
            sigma: config.sigma_m,
        },
        Dof::Four | Dof::Auto => Invariant::GravityAligned {
            epsilon: config.epsilon_m,
            sigma: config.sigma_m,
            epsilon_z: config.epsilon_z_m,
            sigma_z: config.sigma_z_m,
        },
    }
}
