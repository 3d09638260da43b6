//! Factors of the pose graph: residuals and their Jacobians.
//!
//! Every factor measures a pose `Z` and has a 6×6 information matrix `Ω` in the GTSAM
//! tangent order **(rotation, translation)**. Residuals:
//!
//! * unary (prior):  `r = Log(Z⁻¹ · X)`
//! * binary (between, relocalization): `r = Log(Z⁻¹ · A⁻¹ · B)`
//! * point observation: a landmark `l` (a [`VarKey::Point`]) measured at `z` in the frame of
//!   pose `X = (R, t)`: `r = (ε · Log(R_l), Rᵀ (l − t) − z)`, whose information is the 3 × 3
//!   translation block (the rotation block is the identity and only holds the landmark's
//!   meaningless rotation, with the small weight `ε` = [`POINT_ROTATION_HOLD`]);
//!
//! Jacobians are taken with respect to right perturbations `X ← X · Exp(δ)`:
//! `∂r/∂δ_B = J_r⁻¹(r)` and `∂r/∂δ_A = −J_r⁻¹(r) · Ad(B⁻¹ A)`; for a prior
//! `∂r/∂δ_X = J_r⁻¹(r)`.

use super::robust::RobustKernel;
use super::se3;
use super::structure::FactorBlocks;
use super::{GraphError, VarKey};
use nalgebra::{Isometry3, Matrix6, Vector6};
use serde::{Deserialize, Serialize};

/// What a factor stands for; the variables it connects, by key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum FactorKind {
    /// Relative pose `from_T_to` between two variables (odometry or loop closure),
    /// residual `Log(Z⁻¹ · X_from⁻¹ · X_to)`.
    Between {
        /// The variable the measurement is expressed in.
        from: VarKey,
        /// The variable measured.
        to: VarKey,
    },
    /// Absolute pose of one variable, residual `Log(Z⁻¹ · X)`.
    Prior {
        /// The variable constrained.
        var: VarKey,
    },
    /// A relocalization: the relocalizer's `prior_from_query`, where the query frame is the
    /// rover body at `pose` and `frame` is the prior map's frame variable
    /// (`world_from_prior`). Residual `Log(Z⁻¹ · F⁻¹ · X)` with `F` the frame, `X` the pose.
    Relocalization {
        /// Rover pose variable (`world_from_rover`).
        pose: VarKey,
        /// Prior map frame variable (`world_from_prior`).
        frame: VarKey,
    },
    /// A landmark seen from a pose: the measured point is the translation of the factor's
    /// measurement, in the pose's (rover) frame; residual `Rᵀ (l − t) − z` (and the
    /// landmark's rotation held at the identity, see the module's notes).
    Point {
        /// Rover pose variable (`world_from_rover`).
        pose: VarKey,
        /// Landmark variable ([`VarKey::Point`]).
        point: VarKey,
    },
}

/// Weight `ε` of the term of a point observation that holds its landmark's rotation (which
/// nothing else constrains) at the identity.
pub const POINT_ROTATION_HOLD: f64 = 1e-3;

/// One factor: measurement, information matrix (rotation, translation order) and kernel.
#[derive(Clone, Debug)]
pub struct Factor {
    kind: FactorKind,
    /// Variable indices `[a, b]`; for unary factors only `a` is meaningful.
    vars: [usize; 2],
    unary: bool,
    measured: Isometry3<f64>,
    measured_inv: Isometry3<f64>,
    information: Matrix6<f64>,
    kernel: RobustKernel,
}

/// A factor's residual and Jacobians at the current estimate.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Linearization {
    /// Residual `r`.
    pub residual: Vector6<f64>,
    /// `∂r/∂δ_a`.
    pub jac_a: Matrix6<f64>,
    /// `∂r/∂δ_b` (zero for unary factors).
    pub jac_b: Matrix6<f64>,
}

impl Factor {
    /// Builds a factor after checking the measurement and information matrix.
    pub(crate) fn new(
        kind: FactorKind,
        vars: [usize; 2],
        unary: bool,
        measured: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    ) -> Result<Self, GraphError> {
        let what = describe(&kind);
        if !is_finite_pose(&measured) {
            return Err(GraphError::NonFinite {
                what: format!("measurement of {what}"),
            });
        }
        check_information(&information).map_err(|e| match e {
            InformationProblem::NonFinite => GraphError::NonFinite {
                what: format!("information matrix of {what}"),
            },
            InformationProblem::NotPositiveDefinite => {
                GraphError::NotPositiveDefinite { what: what.clone() }
            }
        })?;
        if kernel.is_invalid() {
            return Err(GraphError::InvalidConfig(format!(
                "robust kernel {kernel:?} of {what} needs a positive finite scale"
            )));
        }
        let mut measured = measured;
        measured.rotation.renormalize();
        Ok(Self {
            kind,
            vars,
            unary,
            measured_inv: measured.inverse(),
            measured,
            information: (information + information.transpose()) * 0.5,
            kernel,
        })
    }

    /// What the factor stands for.
    pub fn kind(&self) -> FactorKind {
        self.kind
    }

    /// The measured pose `Z`.
    pub fn measured(&self) -> &Isometry3<f64> {
        &self.measured
    }

    /// Information matrix, (rotation, translation) order.
    pub fn information(&self) -> &Matrix6<f64> {
        &self.information
    }

    /// Robust kernel.
    pub fn kernel(&self) -> RobustKernel {
        self.kernel
    }

    /// Replaces the robust kernel.
    pub(crate) fn set_kernel(&mut self, kernel: RobustKernel) {
        self.kernel = kernel;
    }

    /// Variable indices; the second is meaningless for unary factors.
    pub(crate) fn vars(&self) -> [usize; 2] {
        self.vars
    }

    /// True for factors on one variable.
    pub(crate) fn is_unary(&self) -> bool {
        self.unary
    }

    /// The pose the factor predicts for its measurement: `X` or `A⁻¹ · B`.
    pub(crate) fn predicted(&self, poses: &[Isometry3<f64>]) -> Isometry3<f64> {
        if self.unary {
            poses[self.vars[0]]
        } else {
            poses[self.vars[0]].inv_mul(&poses[self.vars[1]])
        }
    }

    /// Residual `r` at the given estimate.
    pub fn residual(&self, poses: &[Isometry3<f64>]) -> Vector6<f64> {
        if self.is_point() {
            return self.point_linearization(poses).residual;
        }
        se3::log(&(self.measured_inv * self.predicted(poses)))
    }

    /// True for a point observation.
    fn is_point(&self) -> bool {
        matches!(self.kind, FactorKind::Point { .. })
    }

    /// Residual and Jacobians of a point observation (see the module's notes): with
    /// `q = Rᵀ (l − t)`, `∂e/∂ω = [q]×`, `∂e/∂ν = −I` for the pose's right perturbation and
    /// `∂e/∂ν_l = Rᵀ R_l` for the landmark's.
    fn point_linearization(&self, poses: &[Isometry3<f64>]) -> Linearization {
        let (pose, point) = (&poses[self.vars[0]], &poses[self.vars[1]]);
        let r_t = pose.rotation.inverse();
        let q = r_t * (point.translation.vector - pose.translation.vector);
        let e = q - self.measured.translation.vector;
        let hold = se3::log(&Isometry3::from_parts(
            nalgebra::Translation3::identity(),
            point.rotation,
        ));
        let mut residual = Vector6::zeros();
        residual
            .fixed_rows_mut::<3>(0)
            .copy_from(&(hold.fixed_rows::<3>(0) * POINT_ROTATION_HOLD));
        residual.fixed_rows_mut::<3>(3).copy_from(&e);
        let mut jac_a = Matrix6::zeros();
        jac_a.fixed_view_mut::<3, 3>(3, 0).copy_from(&se3::hat(&q));
        jac_a
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(-nalgebra::Matrix3::identity()));
        let mut jac_b = Matrix6::zeros();
        let hold_jacobian = se3::right_jacobian_inverse(&hold);
        jac_b
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(hold_jacobian.fixed_view::<3, 3>(0, 0) * POINT_ROTATION_HOLD));
        jac_b
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(r_t * point.rotation).to_rotation_matrix().into_inner());
        Linearization {
            residual,
            jac_a,
            jac_b,
        }
    }

    /// Cost and normal-equation blocks from a linearization (any binary factor).
    fn blocks_of(&self, lin: &Linearization, mu: f64) -> (f64, FactorBlocks<6>) {
        let s = self.mahalanobis2(&lin.residual);
        let cost = 0.5 * self.kernel.rho(s, mu);
        let w_info = self.information * self.kernel.weight(s, mu);
        let jt_wa = lin.jac_a.transpose() * w_info;
        let jt_wb = lin.jac_b.transpose() * w_info;
        let blocks = FactorBlocks {
            haa: jt_wa * lin.jac_a,
            hab: jt_wa * lin.jac_b,
            hbb: jt_wb * lin.jac_b,
            ga: jt_wa * lin.residual,
            gb: jt_wb * lin.residual,
        };
        (cost, blocks)
    }

    /// Squared Mahalanobis distance `s = rᵀ Ω r`.
    pub(crate) fn mahalanobis2(&self, r: &Vector6<f64>) -> f64 {
        r.dot(&(self.information * r))
    }

    /// Robust cost `½ ρ(s)` at the given estimate.
    pub(crate) fn cost(&self, poses: &[Isometry3<f64>], mu: f64) -> f64 {
        let r = self.residual(poses);
        0.5 * self.kernel.rho(self.mahalanobis2(&r), mu)
    }

    /// Residual, robust cost `½ ρ(s)` and the blocks of the normal equations with the IRLS
    /// weight `ρ'(s)`, at the given estimate.
    ///
    /// Uses `J_a = −J_b · Ad(B⁻¹A)` so that `H_ab = −Adᵀ H_bb`, `H_aa = −H_ab · Ad` and
    /// `g_a = −Adᵀ g_b`, which saves a third of the 6×6 products of the plain form.
    pub(crate) fn normal_blocks(
        &self,
        poses: &[Isometry3<f64>],
        mu: f64,
    ) -> (f64, FactorBlocks<6>) {
        if self.is_point() {
            return self.blocks_of(&self.point_linearization(poses), mu);
        }
        let between = self.predicted(poses);
        let residual = se3::log(&(self.measured_inv * between));
        let s = self.mahalanobis2(&residual);
        let cost = 0.5 * self.kernel.rho(s, mu);
        let w = self.kernel.weight(s, mu);
        let jr_inv = se3::right_jacobian_inverse(&residual);
        let jt_w = jr_inv.transpose() * (self.information * w);
        let h = jt_w * jr_inv;
        let g = jt_w * residual;
        if self.unary {
            let zero = Matrix6::zeros();
            let blocks = FactorBlocks {
                haa: h,
                hab: zero,
                hbb: zero,
                ga: g,
                gb: Vector6::zeros(),
            };
            return (cost, blocks);
        }
        let ad = se3::adjoint(&between.inverse());
        let ad_t = ad.transpose();
        let hab = -(ad_t * h);
        let blocks = FactorBlocks {
            haa: -(hab * ad),
            hab,
            hbb: h,
            ga: -(ad_t * g),
            gb: g,
        };
        (cost, blocks)
    }

    /// Robust cost and the gradient blocks `(g_a, g_b)` of [`Factor::normal_blocks`] alone,
    /// for steps that reuse an earlier factorisation of the Hessian.
    pub(crate) fn gradient_blocks(
        &self,
        poses: &[Isometry3<f64>],
        mu: f64,
    ) -> (f64, Vector6<f64>, Vector6<f64>) {
        if self.is_point() {
            let (cost, blocks) = self.blocks_of(&self.point_linearization(poses), mu);
            return (cost, blocks.ga, blocks.gb);
        }
        let between = self.predicted(poses);
        let residual = se3::log(&(self.measured_inv * between));
        let s = self.mahalanobis2(&residual);
        let cost = 0.5 * self.kernel.rho(s, mu);
        let wr = self.information * residual * self.kernel.weight(s, mu);
        let g = se3::right_jacobian_inverse(&residual).transpose() * wr;
        if self.unary {
            return (cost, g, Vector6::zeros());
        }
        let ad = se3::adjoint(&between.inverse());
        (cost, -(ad.transpose() * g), g)
    }

    /// Residual and Jacobians at the given estimate.
    pub(crate) fn linearize(&self, poses: &[Isometry3<f64>]) -> Linearization {
        if self.is_point() {
            return self.point_linearization(poses);
        }
        let between = self.predicted(poses);
        let residual = se3::log(&(self.measured_inv * between));
        let jr_inv = se3::right_jacobian_inverse(&residual);
        if self.unary {
            Linearization {
                residual,
                jac_a: jr_inv,
                jac_b: Matrix6::zeros(),
            }
        } else {
            let jac_a = -(jr_inv * se3::adjoint(&between.inverse()));
            Linearization {
                residual,
                jac_a,
                jac_b: jr_inv,
            }
        }
    }
}

/// Human-readable name of a factor for error messages.
pub(crate) fn describe(kind: &FactorKind) -> String {
    match kind {
        FactorKind::Between { from, to } => format!("between factor {from} -> {to}"),
        FactorKind::Prior { var } => format!("prior on {var}"),
        FactorKind::Relocalization { pose, frame } => {
            format!("relocalization of {pose} in {frame}")
        }
        FactorKind::Point { pose, point } => format!("observation of {point} from {pose}"),
    }
}

/// True when translation and rotation are finite.
pub(crate) fn is_finite_pose(p: &Isometry3<f64>) -> bool {
    p.translation.vector.iter().all(|v| v.is_finite())
        && p.rotation.coords.iter().all(|v| v.is_finite())
}

/// Why an information matrix was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum InformationProblem {
    /// NaN or infinity.
    NonFinite,
    /// Not symmetric or not positive definite.
    NotPositiveDefinite,
}

/// Checks that an information matrix is finite, symmetric and positive definite.
pub(crate) fn check_information(m: &Matrix6<f64>) -> Result<(), InformationProblem> {
    if !m.iter().all(|v| v.is_finite()) {
        return Err(InformationProblem::NonFinite);
    }
    let scale = m.abs().max().max(f64::MIN_POSITIVE);
    if (m - m.transpose()).abs().max() > 1e-9 * scale {
        return Err(InformationProblem::NotPositiveDefinite);
    }
    match m.cholesky() {
        Some(ch) => {
            let d = ch.l_dirty().diagonal();
            if d.iter().all(|v| *v > 0.0 && v.is_finite()) {
                Ok(())
            } else {
                Err(InformationProblem::NotPositiveDefinite)
            }
        }
        None => Err(InformationProblem::NotPositiveDefinite),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(xi: [f64; 6]) -> Isometry3<f64> {
        se3::exp(&Vector6::from_row_slice(&xi))
    }

    fn numeric_jacobian(
        f: &Factor,
        poses: &[Isometry3<f64>],
        var: usize,
        residual: &Vector6<f64>,
    ) -> Matrix6<f64> {
        let h = 1e-7;
        let mut out = Matrix6::zeros();
        for k in 0..6 {
            let mut d = Vector6::zeros();
            d[k] = h;
            let mut plus = poses.to_vec();
            plus[var] = poses[var] * se3::exp(&d);
            let mut minus = poses.to_vec();
            minus[var] = poses[var] * se3::exp(&(-d));
            let col = (f.residual(&plus) - f.residual(&minus)) / (2.0 * h);
            out.set_column(k, &col);
        }
        let _ = residual;
        out
    }

    fn kinds() -> Vec<(FactorKind, bool)> {
        vec![
            (
                FactorKind::Between {
                    from: VarKey::Pose(0),
                    to: VarKey::Pose(1),
                },
                false,
            ),
            (
                FactorKind::Relocalization {
                    pose: VarKey::Pose(1),
                    frame: VarKey::Frame(0),
                },
                false,
            ),
            (
                FactorKind::Prior {
                    var: VarKey::Pose(0),
                },
                true,
            ),
            (
                FactorKind::Point {
                    pose: VarKey::Pose(0),
                    point: VarKey::Point(0),
                },
                false,
            ),
        ]
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let poses = vec![
            pose([0.3, -0.5, 1.1, 2.0, -1.0, 0.5]),
            pose([-0.7, 0.2, 0.4, -3.0, 1.0, 2.5]),
        ];
        let measurements = [
            pose([0.1, 0.2, -0.3, 0.5, 0.5, 0.5]),
            pose([1.5, -0.4, 0.9, -2.0, 4.0, 1.0]),
            pose([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        ];
        for (kind, unary) in kinds() {
            for z in &measurements {
                let f = Factor::new(
                    kind,
                    [0, 1],
                    unary,
                    *z,
                    Matrix6::identity(),
                    RobustKernel::None,
                )
                .unwrap();
                let lin = f.linearize(&poses);
                let na = numeric_jacobian(&f, &poses, 0, &lin.residual);
                let err_a = (na - lin.jac_a).abs().max();
                assert!(err_a < 1e-6, "{kind:?}: d/da error {err_a}");
                if !unary {
                    let nb = numeric_jacobian(&f, &poses, 1, &lin.residual);
                    let err_b = (nb - lin.jac_b).abs().max();
                    assert!(err_b < 1e-6, "{kind:?}: d/db error {err_b}");
                }
            }
        }
    }

    #[test]
    fn residual_is_zero_at_measurement() {
        let a = pose([0.3, -0.5, 1.1, 2.0, -1.0, 0.5]);
        let z = pose([0.1, 0.2, -0.3, 0.5, 0.5, 0.5]);
        let f = Factor::new(
            kinds()[0].0,
            [0, 1],
            false,
            z,
            Matrix6::identity(),
            RobustKernel::None,
        )
        .unwrap();
        assert!(f.residual(&[a, a * z]).norm() < 1e-12);
    }

    #[test]
    fn bad_information_is_refused() {
        let z = Isometry3::identity();
        let mut m = Matrix6::identity();
        m[(2, 2)] = -1.0;
        let e = Factor::new(kinds()[2].0, [0, 0], true, z, m, RobustKernel::None);
        assert!(matches!(e, Err(GraphError::NotPositiveDefinite { .. })));
        let mut m = Matrix6::identity();
        m[(0, 1)] = f64::NAN;
        let e = Factor::new(kinds()[2].0, [0, 0], true, z, m, RobustKernel::None);
        assert!(matches!(e, Err(GraphError::NonFinite { .. })));
        let mut m = Matrix6::identity();
        m[(0, 1)] = 0.5;
        let e = Factor::new(kinds()[2].0, [0, 0], true, z, m, RobustKernel::None);
        assert!(matches!(e, Err(GraphError::NotPositiveDefinite { .. })));
    }
}
