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
//! * stereo projection: a landmark `l` seen by a rectified stereo camera at pose `X` (the
//!   left camera's `world_from_camera`) at pixels `z = (u_left, u_right, v)`:
//!   `r = (ε · Log(R_l), π(Rᵀ (l − t)) − z)` with `π` the projection of
//!   [`StereoCalibration`], as GTSAM's `GenericStereoFactor`; a point behind the camera
//!   gives GTSAM's constant residual `2 f_x` per pixel and no gradient;
//!
//! Jacobians are taken with respect to right perturbations `X ← X · Exp(δ)`:
//! `∂r/∂δ_B = J_r⁻¹(r)` and `∂r/∂δ_A = −J_r⁻¹(r) · Ad(B⁻¹ A)`; for a prior
//! `∂r/∂δ_X = J_r⁻¹(r)`.

use super::robust::RobustKernel;
use super::se3;
use super::stereo::StereoCalibration;
use super::structure::FactorBlocks;
use super::{GraphError, VarKey};
use nalgebra::{Isometry3, Matrix3, Matrix6, SMatrix, Vector3, Vector6};
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
    /// A landmark seen by a rectified stereo camera: the measurement's translation holds
    /// the pixels `(u_left, u_right, v)`; residual `π(Rᵀ (l − t)) − z` (and the landmark's
    /// rotation held at the identity, as for [`FactorKind::Point`]).
    Stereo {
        /// Left camera pose variable (`world_from_camera`).
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
    /// The camera of a stereo projection factor.
    camera: Option<StereoCalibration>,
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
            camera: None,
        })
    }

    /// Attaches the camera of a stereo projection factor (after checking it).
    pub(crate) fn with_camera(mut self, camera: StereoCalibration) -> Result<Self, GraphError> {
        camera.validate().map_err(|e| {
            GraphError::InvalidConfig(format!("camera of {}: {e}", describe(&self.kind)))
        })?;
        self.camera = Some(camera);
        Ok(self)
    }

    /// The camera of a stereo projection factor.
    pub fn camera(&self) -> Option<&StereoCalibration> {
        self.camera.as_ref()
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
        if let Some(camera) = &self.camera {
            return self.stereo_parts(camera, poses).residual();
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

    /// The pieces of a stereo projection factor at the given estimate.
    fn stereo_parts(&self, camera: &StereoCalibration, poses: &[Isometry3<f64>]) -> StereoParts {
        let (pose, point) = (&poses[self.vars[0]], &poses[self.vars[1]]);
        let r_t = pose.rotation.inverse();
        let q = r_t * (point.translation.vector - pose.translation.vector);
        let hold = se3::log(&Isometry3::from_parts(
            nalgebra::Translation3::identity(),
            point.rotation,
        ))
        .fixed_rows::<3>(0)
        .into_owned();
        let hold_jacobian =
            se3::right_jacobian_inverse(&Vector6::new(hold.x, hold.y, hold.z, 0.0, 0.0, 0.0))
                .fixed_view::<3, 3>(0, 0)
                .into_owned();
        let Some(projected) = camera.project(&q) else {
            let fx2 = 2.0 * camera.fx;
            return StereoParts {
                hold: hold * POINT_ROTATION_HOLD,
                hold_jacobian: hold_jacobian * POINT_ROTATION_HOLD,
                error: Vector3::new(fx2, fx2, fx2),
                jac_pose: SMatrix::zeros(),
                jac_point: Matrix3::zeros(),
            };
        };
        let p = camera.projection_jacobian(&q);
        let mut jac_pose = SMatrix::<f64, 3, 6>::zeros();
        jac_pose
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(p * se3::hat(&q)));
        jac_pose.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-p));
        let r_rel = (r_t * point.rotation).to_rotation_matrix().into_inner();
        StereoParts {
            hold: hold * POINT_ROTATION_HOLD,
            hold_jacobian: hold_jacobian * POINT_ROTATION_HOLD,
            error: projected - self.measured.translation.vector,
            jac_pose,
            jac_point: p * r_rel,
        }
    }

    /// Cost and normal-equation blocks of a stereo projection factor, with 3-row products
    /// (the generic path would multiply 6 × 6 matrices that are mostly zero).
    fn stereo_blocks(&self, parts: &StereoParts, mu: f64) -> (f64, FactorBlocks<6>) {
        let omega = self.information.fixed_view::<3, 3>(3, 3).into_owned();
        let omega_hold = self.information.fixed_view::<3, 3>(0, 0).into_owned();
        let s =
            parts.error.dot(&(omega * parts.error)) + parts.hold.dot(&(omega_hold * parts.hold));
        let cost = 0.5 * self.kernel.rho(s, mu);
        let w = self.kernel.weight(s, mu);
        let w_omega = omega * w;
        let w_hold = omega_hold * w;
        let jt_wa = parts.jac_pose.transpose() * w_omega;
        let jt_wp = parts.jac_point.transpose() * w_omega;
        let jt_wh = parts.hold_jacobian.transpose() * w_hold;
        let mut hab = Matrix6::zeros();
        hab.fixed_view_mut::<6, 3>(0, 3)
            .copy_from(&(jt_wa * parts.jac_point));
        let mut hbb = Matrix6::zeros();
        hbb.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(jt_wh * parts.hold_jacobian));
        hbb.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(jt_wp * parts.jac_point));
        let mut gb = Vector6::zeros();
        gb.fixed_rows_mut::<3>(0).copy_from(&(jt_wh * parts.hold));
        gb.fixed_rows_mut::<3>(3).copy_from(&(jt_wp * parts.error));
        let blocks = FactorBlocks {
            haa: jt_wa * parts.jac_pose,
            hab,
            hbb,
            ga: jt_wa * parts.error,
            gb,
        };
        (cost, blocks)
    }

    /// Cost and the normal-equation blocks of a stereo projection factor on the pose and
    /// the point's translation alone (bundle adjustment; the landmark's rotation is held).
    /// A factor of another kind gives zeros.
    pub(crate) fn stereo_normal_blocks(&self, poses: &[Isometry3<f64>]) -> StereoBlocks {
        let Some(camera) = &self.camera else {
            return StereoBlocks::default();
        };
        let parts = self.stereo_parts(camera, poses);
        let omega = self.information.fixed_view::<3, 3>(3, 3).into_owned();
        let omega_hold = self.information.fixed_view::<3, 3>(0, 0).into_owned();
        let s =
            parts.error.dot(&(omega * parts.error)) + parts.hold.dot(&(omega_hold * parts.hold));
        let w_omega = omega * self.kernel.weight(s, 0.0);
        let jt_wa = parts.jac_pose.transpose() * w_omega;
        let jt_wp = parts.jac_point.transpose() * w_omega;
        StereoBlocks {
            cost: 0.5 * self.kernel.rho(s, 0.0),
            h_pose: jt_wa * parts.jac_pose,
            h_point: jt_wp * parts.jac_point,
            h_pose_point: jt_wa * parts.jac_point,
            g_pose: jt_wa * parts.error,
            g_point: jt_wp * parts.error,
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
        if let Some(camera) = &self.camera {
            return self.stereo_blocks(&self.stereo_parts(camera, poses), mu);
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
        if let Some(camera) = &self.camera {
            let (cost, blocks) = self.stereo_blocks(&self.stereo_parts(camera, poses), mu);
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
        if let Some(camera) = &self.camera {
            return self.stereo_parts(camera, poses).linearization();
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
        FactorKind::Stereo { pose, point } => {
            format!("stereo observation of {point} from {pose}")
        }
    }
}

/// The blocks of a stereo projection factor in a bundle adjustment (pose: right
/// perturbation; point: translation).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct StereoBlocks {
    /// `½ ρ(s)`.
    pub cost: f64,
    /// `J_poseᵀ W J_pose`.
    pub h_pose: Matrix6<f64>,
    /// `J_pointᵀ W J_point`.
    pub h_point: Matrix3<f64>,
    /// `J_poseᵀ W J_point`.
    pub h_pose_point: SMatrix<f64, 6, 3>,
    /// `J_poseᵀ W e`.
    pub g_pose: Vector6<f64>,
    /// `J_pointᵀ W e`.
    pub g_point: Vector3<f64>,
}

/// A stereo projection factor at one estimate: the landmark-rotation hold and the pixel
/// error with their Jacobians (pose: right perturbation (rotation, translation); point:
/// translation part of its right perturbation).
struct StereoParts {
    /// `ε · Log(R_l)`.
    hold: Vector3<f64>,
    /// `∂hold/∂ω_l`.
    hold_jacobian: Matrix3<f64>,
    /// `π(q) − z`, pixels.
    error: Vector3<f64>,
    /// `∂error/∂δ_pose`.
    jac_pose: SMatrix<f64, 3, 6>,
    /// `∂error/∂ν_l`.
    jac_point: Matrix3<f64>,
}

impl StereoParts {
    fn residual(&self) -> Vector6<f64> {
        let mut r = Vector6::zeros();
        r.fixed_rows_mut::<3>(0).copy_from(&self.hold);
        r.fixed_rows_mut::<3>(3).copy_from(&self.error);
        r
    }

    fn linearization(&self) -> Linearization {
        let mut jac_a = Matrix6::zeros();
        jac_a.fixed_view_mut::<3, 6>(3, 0).copy_from(&self.jac_pose);
        let mut jac_b = Matrix6::zeros();
        jac_b
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&self.hold_jacobian);
        jac_b
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&self.jac_point);
        Linearization {
            residual: self.residual(),
            jac_a,
            jac_b,
        }
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
    fn stereo_jacobians_match_finite_differences() {
        let camera = StereoCalibration {
            fx: 721.5,
            fy: 720.0,
            skew: 0.2,
            cx: 609.6,
            cy: 172.9,
            baseline_m: 0.537,
        };
        let world_from_camera = pose([0.1, -0.2, 0.05, 1.0, -0.5, 2.0]);
        let p_camera = Vector3::new(1.5, -0.7, 12.0);
        let landmark = Isometry3::from_parts(
            (world_from_camera * nalgebra::Point3::from(p_camera))
                .coords
                .into(),
            nalgebra::UnitQuaternion::from_euler_angles(0.01, -0.02, 0.03),
        );
        let poses = vec![world_from_camera, landmark];
        let uv = camera.project(&p_camera).unwrap() + Vector3::new(1.5, -2.0, 0.7);
        let z = Isometry3::from_parts(uv.into(), nalgebra::UnitQuaternion::identity());
        let mut info = Matrix6::identity();
        info.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&Matrix3::new(2.0, 0.3, 0.0, 0.3, 1.0, 0.1, 0.0, 0.1, 0.5));
        let kind = FactorKind::Stereo {
            pose: VarKey::Pose(0),
            point: VarKey::Point(0),
        };
        let f = Factor::new(kind, [0, 1], false, z, info, RobustKernel::Huber { k: 3.0 })
            .unwrap()
            .with_camera(camera)
            .unwrap();
        let lin = f.linearize(&poses);
        for (var, jac) in [(0, lin.jac_a), (1, lin.jac_b)] {
            let numeric = numeric_jacobian(&f, &poses, var, &lin.residual);
            let err = (numeric - jac).abs().max();
            assert!(err < 1e-4, "d/d var {var}: error {err}");
        }
        // the specialised blocks agree with the generic ones
        let (cost, fast) = f.normal_blocks(&poses, 0.0);
        let (cost_generic, slow) = f.blocks_of(&lin, 0.0);
        assert!((cost - cost_generic).abs() < 1e-9 * cost.max(1.0));
        assert!((fast.haa - slow.haa).abs().max() < 1e-6 * slow.haa.abs().max());
        assert!((fast.hab - slow.hab).abs().max() < 1e-6 * slow.haa.abs().max());
        assert!((fast.hbb - slow.hbb).abs().max() < 1e-6 * slow.haa.abs().max());
        assert!((fast.ga - slow.ga).abs().max() < 1e-6 * slow.ga.abs().max());
        assert!((fast.gb - slow.gb).abs().max() < 1e-6 * slow.ga.abs().max());
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
