//! The pose graph container: variables, factors and their bookkeeping.

use super::factors::{describe, is_finite_pose, Factor, FactorKind};
use super::robust::RobustKernel;
use super::solver::{self, OptimizationReport, SolverConfig};
use super::stereo::StereoCalibration;
use super::structure::NormalEquations;
use super::{ComponentInfo, GraphError, VarKey};
use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3};
use std::collections::HashMap;

/// An SE(3) pose graph: rover poses, prior-map frames and the factors between them.
///
/// Information matrices are 6×6 in GTSAM's tangent order **(rotation, translation)**.
/// See the [module documentation](super) for the conventions and an example.
#[derive(Default)]
pub struct PoseGraph {
    keys: Vec<VarKey>,
    index: HashMap<VarKey, usize>,
    pub(crate) poses: Vec<Isometry3<f64>>,
    fixed: Vec<bool>,
    pub(crate) factors: Vec<Factor>,
    /// Structure analysed for some version of the variables, factors and fixed set. A stale
    /// one is kept until the next optimisation replaces it, so that growing the graph does
    /// not pay for freeing it.
    pub(crate) cache: Option<StructureCache>,
    /// Incremented by every change of variables, factors or fixed flags.
    pub(crate) structure_version: u64,
}

/// A symbolic analysis kept between optimisations while the structure is unchanged.
pub(crate) struct StructureCache {
    /// The `structure_version` the analysis was made for.
    pub version: u64,
    /// Connected components and their anchors.
    pub components: Vec<ComponentInfo>,
    /// Variables held constant (user-fixed and auto-fixed).
    pub held: Vec<bool>,
    /// Normal equations with the symbolic factorisation.
    pub system: NormalEquations<6>,
}

/// A copy of the variables, estimates, fixed flags and factors; the cached symbolic analysis
/// is not copied (the copy analyses again on its first optimisation).
impl Clone for PoseGraph {
    fn clone(&self) -> Self {
        Self {
            keys: self.keys.clone(),
            index: self.index.clone(),
            poses: self.poses.clone(),
            fixed: self.fixed.clone(),
            factors: self.factors.clone(),
            cache: None,
            structure_version: self.structure_version,
        }
    }
}

impl std::fmt::Debug for PoseGraph {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PoseGraph")
            .field("variables", &self.keys.len())
            .field("factors", &self.factors.len())
            .finish()
    }
}

impl PoseGraph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a rover pose `world_from_rover` with its initial estimate.
    pub fn add_pose(&mut self, id: u64, initial: Isometry3<f64>) -> Result<(), GraphError> {
        self.add_variable(VarKey::Pose(id), initial)
    }

    /// Adds the frame variable `world_from_prior` of a prior map or session.
    pub fn add_frame(&mut self, id: u64, initial: Isometry3<f64>) -> Result<(), GraphError> {
        self.add_variable(VarKey::Frame(id), initial)
    }

    /// Adds a variable of either kind.
    pub fn add_variable(&mut self, key: VarKey, initial: Isometry3<f64>) -> Result<(), GraphError> {
        if self.index.contains_key(&key) {
            return Err(GraphError::DuplicateVariable(key));
        }
        if !is_finite_pose(&initial) {
            return Err(GraphError::NonFinite {
                what: format!("initial estimate of {key}"),
            });
        }
        let mut initial = initial;
        initial.rotation.renormalize();
        self.index.insert(key, self.keys.len());
        self.keys.push(key);
        self.poses.push(initial);
        self.fixed.push(false);
        self.structure_version += 1;
        Ok(())
    }

    /// Adds a between factor (odometry or loop closure) on poses `i` and `j` measuring
    /// `i_from_j = z_ij`: residual `Log(z_ij⁻¹ · X_i⁻¹ · X_j)`. Returns the factor index.
    pub fn add_between(
        &mut self,
        i: u64,
        j: u64,
        z_ij: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        self.add_between_keys(VarKey::Pose(i), VarKey::Pose(j), z_ij, information, kernel)
    }

    /// Between factor on any two variables (poses or frames), see [`PoseGraph::add_between`].
    pub fn add_between_keys(
        &mut self,
        from: VarKey,
        to: VarKey,
        z: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        let kind = FactorKind::Between { from, to };
        self.push_binary(kind, from, to, z, information, kernel)
    }

    /// Adds an absolute prior `X_i ≈ z` on pose `i`: residual `Log(z⁻¹ · X_i)`.
    pub fn add_prior(
        &mut self,
        i: u64,
        z: Isometry3<f64>,
        information: Matrix6<f64>,
    ) -> Result<usize, GraphError> {
        self.add_prior_key(VarKey::Pose(i), z, information, RobustKernel::None)
    }

    /// Prior on any variable with a robust kernel, see [`PoseGraph::add_prior`].
    pub fn add_prior_key(
        &mut self,
        var: VarKey,
        z: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        let a = self.var_index(var)?;
        let f = Factor::new(
            FactorKind::Prior { var },
            [a, a],
            true,
            z,
            information,
            kernel,
        )?;
        self.factors.push(f);
        self.structure_version += 1;
        Ok(self.factors.len() - 1)
    }

    /// Adds a landmark point `p_world` ([`VarKey::Point`]) with its initial estimate.
    pub fn add_point(&mut self, id: u64, p_world: Point3<f64>) -> Result<(), GraphError> {
        self.add_variable(
            VarKey::Point(id),
            Isometry3::from_parts(
                Translation3::from(p_world.coords),
                UnitQuaternion::identity(),
            ),
        )
    }

    /// Current estimate of landmark point `id`.
    pub fn point(&self, id: u64) -> Option<Point3<f64>> {
        self.value(VarKey::Point(id))
            .map(|p| Point3::from(p.translation.vector))
    }

    /// Adds an observation of landmark `point_id` from pose `pose_id`: `p_rover` measured in
    /// the rover frame with the 3 × 3 `information` (m⁻², rover axes); residual
    /// `Rᵀ (l − t) − p_rover` for the pose `(R, t)` and the landmark `l`. Returns the factor
    /// index.
    ///
    /// ```
    /// use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
    /// use segloc::graph::{PoseGraph, RobustKernel, SolverConfig};
    ///
    /// // two poses 1 m apart see the same boulder; the second pose is found from it
    /// let mut graph = PoseGraph::new();
    /// graph.add_pose(0, Isometry3::identity())?;
    /// graph.add_pose(1, Isometry3::translation(0.9, 0.1, 0.0))?;
    /// graph.fix(0)?;
    /// graph.add_point(0, Point3::new(3.0, 0.0, 0.0))?;
    /// let info = Matrix3::identity() * 1e4;
    /// let kernel = RobustKernel::None;
    /// graph.add_point_observation(0, 0, Point3::new(3.0, 1.0, 0.0), info, kernel)?;
    /// graph.add_point(1, Point3::new(0.0, 2.0, 0.5))?;
    /// graph.add_point_observation(0, 1, Point3::new(0.0, 2.0, 0.5), info, kernel)?;
    /// graph.add_point(2, Point3::new(5.0, -2.0, 0.0))?;
    /// graph.add_point_observation(0, 2, Point3::new(5.0, -2.0, 0.0), info, kernel)?;
    /// for (id, p) in [(0, [2.0, 1.0, 0.0]), (1, [-1.0, 2.0, 0.5]), (2, [4.0, -2.0, 0.0])] {
    ///     graph.add_point_observation(1, id, Point3::from(p), info, kernel)?;
    /// }
    /// graph.optimize(&SolverConfig::default())?;
    /// let moved = graph.pose(1).unwrap().translation.vector - Vector3::new(1.0, 0.0, 0.0);
    /// assert!(moved.norm() < 1e-6);
    /// # Ok::<(), segloc::graph::GraphError>(())
    /// ```
    pub fn add_point_observation(
        &mut self,
        pose_id: u64,
        point_id: u64,
        p_rover: Point3<f64>,
        information: Matrix3<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        let pose = VarKey::Pose(pose_id);
        let point = VarKey::Point(point_id);
        let mut info6 = Matrix6::identity();
        info6.fixed_view_mut::<3, 3>(3, 3).copy_from(&information);
        let z = Isometry3::from_parts(
            Translation3::from(p_rover.coords),
            UnitQuaternion::identity(),
        );
        let kind = FactorKind::Point { pose, point };
        self.push_binary(kind, pose, point, z, info6, kernel)
    }

    /// Adds a stereo observation of landmark `point_id` from the camera pose `pose_id`
    /// (`world_from_camera`, the left camera; x right, y down, z forward): the pixels
    /// `uv = (u_left, u_right, v)` with the 3 × 3 `information` (px⁻²); residual
    /// `π(Rᵀ (l − t)) − uv`, as GTSAM's `GenericStereoFactor`. Returns the factor index.
    pub fn add_stereo_observation(
        &mut self,
        pose_id: u64,
        point_id: u64,
        uv: Vector3<f64>,
        camera: StereoCalibration,
        information: Matrix3<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        let pose = VarKey::Pose(pose_id);
        let point = VarKey::Point(point_id);
        let ia = self.var_index(pose)?;
        let ib = self.var_index(point)?;
        let mut info6 = Matrix6::identity();
        info6.fixed_view_mut::<3, 3>(3, 3).copy_from(&information);
        let z = Isometry3::from_parts(Translation3::from(uv), UnitQuaternion::identity());
        let kind = FactorKind::Stereo { pose, point };
        let f = Factor::new(kind, [ia, ib], false, z, info6, kernel)?.with_camera(camera)?;
        self.factors.push(f);
        self.structure_version += 1;
        Ok(self.factors.len() - 1)
    }

    /// Adds a relocalization of pose `pose_id` in the prior map whose frame variable is
    /// `frame_id`.
    ///
    /// `prior_from_query` maps points of the query frame into the prior map frame,
    /// `p_prior = prior_from_query · p_query`, where the **query frame is the rover body at
    /// pose `pose_id`**. With the frame variable `F = world_from_prior` and the pose
    /// `X = world_from_rover`, the prediction is `F⁻¹ · X` and the residual
    /// `Log(prior_from_query⁻¹ · F⁻¹ · X)`. If the relocalizer's query map is expressed in
    /// another frame attached to the rover (e.g. the session's odometry frame `odom`),
    /// compose first: `prior_from_rover = prior_from_odom · odom_from_rover`.
    ///
    /// `information` is in (rotation, translation) order on the right perturbation of the
    /// measured `prior_from_query`. The factor has no robust kernel; set one with
    /// [`PoseGraph::set_factor_kernel`]. Returns the factor index.
    pub fn add_relocalization(
        &mut self,
        pose_id: u64,
        frame_id: u64,
        prior_from_query: Isometry3<f64>,
        information: Matrix6<f64>,
    ) -> Result<usize, GraphError> {
        let pose = VarKey::Pose(pose_id);
        let frame = VarKey::Frame(frame_id);
        let kind = FactorKind::Relocalization { pose, frame };
        self.push_binary(
            kind,
            frame,
            pose,
            prior_from_query,
            information,
            RobustKernel::None,
        )
    }

    fn push_binary(
        &mut self,
        kind: FactorKind,
        a: VarKey,
        b: VarKey,
        z: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        let ia = self.var_index(a)?;
        let ib = self.var_index(b)?;
        if ia == ib {
            return Err(GraphError::SelfLoop(a));
        }
        let f = Factor::new(kind, [ia, ib], false, z, information, kernel)?;
        self.factors.push(f);
        self.structure_version += 1;
        Ok(self.factors.len() - 1)
    }

    /// Replaces the robust kernel of factor `index` (kept structure, so no re-analysis).
    pub fn set_factor_kernel(
        &mut self,
        index: usize,
        kernel: RobustKernel,
    ) -> Result<(), GraphError> {
        if kernel.is_invalid() {
            return Err(GraphError::InvalidConfig(format!(
                "robust kernel {kernel:?} needs a positive finite scale"
            )));
        }
        let n = self.factors.len();
        let f = self.factors.get_mut(index).ok_or_else(|| {
            GraphError::InvalidConfig(format!("factor {index} does not exist ({n} factors)"))
        })?;
        f.set_kernel(kernel);
        Ok(())
    }

    /// Holds a variable at its current estimate (removes the gauge freedom). A bare `u64`
    /// is a pose id.
    pub fn fix(&mut self, key: impl Into<VarKey>) -> Result<(), GraphError> {
        self.set_fixed(key.into(), true)
    }

    /// Lets a fixed variable move again.
    pub fn unfix(&mut self, key: impl Into<VarKey>) -> Result<(), GraphError> {
        self.set_fixed(key.into(), false)
    }

    fn set_fixed(&mut self, key: VarKey, fixed: bool) -> Result<(), GraphError> {
        let i = self.var_index(key)?;
        if self.fixed[i] != fixed {
            self.fixed[i] = fixed;
            self.structure_version += 1;
        }
        Ok(())
    }

    /// True when the variable is fixed by the user.
    pub fn is_fixed(&self, key: impl Into<VarKey>) -> bool {
        self.index.get(&key.into()).is_some_and(|&i| self.fixed[i])
    }

    /// Current estimate of pose `id`.
    pub fn pose(&self, id: u64) -> Option<Isometry3<f64>> {
        self.value(VarKey::Pose(id))
    }

    /// Current estimate of frame `id` (`world_from_prior`).
    pub fn frame(&self, id: u64) -> Option<Isometry3<f64>> {
        self.value(VarKey::Frame(id))
    }

    /// Current estimate of any variable.
    pub fn value(&self, key: VarKey) -> Option<Isometry3<f64>> {
        self.index.get(&key).map(|&i| self.poses[i])
    }

    /// Overwrites the estimate of a variable (warm start); the structure is kept.
    pub fn set_value(&mut self, key: VarKey, pose: Isometry3<f64>) -> Result<(), GraphError> {
        if !is_finite_pose(&pose) {
            return Err(GraphError::NonFinite {
                what: format!("estimate of {key}"),
            });
        }
        let i = self.var_index(key)?;
        let mut pose = pose;
        pose.rotation.renormalize();
        self.poses[i] = pose;
        Ok(())
    }

    /// True when the variable exists.
    pub fn contains(&self, key: impl Into<VarKey>) -> bool {
        self.index.contains_key(&key.into())
    }

    /// Variables in insertion order.
    pub fn keys(&self) -> &[VarKey] {
        &self.keys
    }

    /// Number of variables (poses and frames).
    pub fn num_variables(&self) -> usize {
        self.keys.len()
    }

    /// Number of pose variables.
    pub fn num_poses(&self) -> usize {
        self.keys
            .iter()
            .filter(|k| matches!(k, VarKey::Pose(_)))
            .count()
    }

    /// Number of factors.
    pub fn num_factors(&self) -> usize {
        self.factors.len()
    }

    /// The factors in insertion order.
    pub fn factors(&self) -> &[Factor] {
        &self.factors
    }

    /// Total cost `½ Σ ρ(rᵀ Ω r)` at the current estimate (GNC kernels as the truncated
    /// quadratic they end on).
    pub fn cost(&self) -> f64 {
        self.factors
            .iter()
            .fold(0.0, |acc, f| acc + f.cost(&self.poses, 0.0))
    }

    /// Plain least-squares cost `½ Σ rᵀ Ω r`, ignoring robust kernels.
    pub fn quadratic_cost(&self) -> f64 {
        self.factors.iter().fold(0.0, |acc, f| {
            let r = f.residual(&self.poses);
            acc + 0.5 * f.mahalanobis2(&r)
        })
    }

    /// Optimises the estimates in place and reports what happened.
    ///
    /// The symbolic analysis (ordering and symbolic Cholesky) is cached in the graph and
    /// reused by later calls until a variable, factor or fixed flag is added or changed.
    pub fn optimize(&mut self, config: &SolverConfig) -> Result<OptimizationReport, GraphError> {
        solver::optimize(self, config)
    }

    /// Index of a variable.
    pub(crate) fn var_index(&self, key: VarKey) -> Result<usize, GraphError> {
        self.index
            .get(&key)
            .copied()
            .ok_or(GraphError::UnknownVariable(key))
    }

    /// User-fixed flags by variable index.
    pub(crate) fn fixed_flags(&self) -> &[bool] {
        &self.fixed
    }

    /// Description of factor `i` for messages.
    pub fn describe_factor(&self, i: usize) -> Option<String> {
        self.factors.get(i).map(|f| describe(&f.kind()))
    }
}
