//! The consistency graph of the candidate associations (see `segloc_clipper`).

use super::config::ConsistencyConfig;
use crate::align::Dof;
use segloc_clipper::Invariant;

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
