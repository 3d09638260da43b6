//! Bundle adjustment: Levenberg–Marquardt on a graph of camera poses, landmark points and
//! stereo projection factors, with the points eliminated by the Schur complement.
//!
//! The normal equations of bundle adjustment are `[U W; Wᵀ V]` with `V` block diagonal
//! (one 3 × 3 block per point, the point's translation). Each iteration forms the reduced
//! camera system `S = U − W V⁻¹ Wᵀ` (dense, 6 per free pose), solves it by Cholesky and
//! back-substitutes the points: the work grows with the observations, not with the cube of
//! the variables, which is what makes a sliding-window VO back end cheap. The damping,
//! acceptance rule and stopping rule are those of [`SolverConfig`] (GTSAM's
//! Levenberg–Marquardt: `H + λ I`, a step is taken when the cost does not increase).
//!
//! The landmark's rotation (which nothing constrains) is held where it is; its cost term is
//! kept in the cost so that costs compare with [`PoseGraph::cost`].

use super::factors::{Factor, FactorKind};
use super::pose_graph::PoseGraph;
use super::se3;
use super::solver::{OptimizationReport, Profile, SolverConfig, Termination};
use super::{GraphError, VarKey};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Matrix6, SMatrix, Vector3, Vector6};
use std::time::Instant;

/// A step: `δ` per free pose, then per free point.
type Step = (Vec<Vector6<f64>>, Vec<Vector3<f64>>);

/// One stereo factor's place in the reduced system.
struct Observation {
    factor: usize,
    /// Free-pose slot, if the pose is free.
    pose: Option<usize>,
    /// Free-point slot, if the point is free.
    point: Option<usize>,
}

/// The linearised system of one iteration.
struct Linearized {
    cost: f64,
    /// `U_p` per free pose.
    u: Vec<Matrix6<f64>>,
    /// `V_l` per free point.
    v: Vec<Matrix3<f64>>,
    /// `W` per observation (6 × 3), zero when either side is held.
    w: Vec<SMatrix<f64, 6, 3>>,
    /// Gradient per free pose.
    g_pose: Vec<Vector6<f64>>,
    /// Gradient per free point.
    g_point: Vec<Vector3<f64>>,
}

/// The layout of a bundle-adjustment problem: slots of the free variables and the
/// observations of each free point.
struct Layout {
    pose_slots: Vec<usize>,
    point_slots: Vec<usize>,
    observations: Vec<Observation>,
    /// Observation indices by free point.
    by_point: Vec<Vec<usize>>,
}

impl Layout {
    fn new(graph: &PoseGraph) -> Result<Self, GraphError> {
        let fixed = graph.fixed_flags();
        let mut slot = vec![usize::MAX; graph.keys().len()];
        let (mut pose_slots, mut point_slots) = (Vec::new(), Vec::new());
        for (i, key) in graph.keys().iter().enumerate() {
            if fixed[i] {
                continue;
            }
            match key {
                VarKey::Pose(_) => {
                    slot[i] = pose_slots.len();
                    pose_slots.push(i);
                }
                VarKey::Point(_) => {
                    slot[i] = point_slots.len();
                    point_slots.push(i);
                }
                VarKey::Frame(_) => {
                    return Err(GraphError::InvalidConfig(
                        "bundle adjustment takes camera poses and points only".into(),
                    ))
                }
            }
        }
        let mut observations = Vec::new();
        let mut by_point = vec![Vec::new(); point_slots.len()];
        for (k, f) in graph.factors.iter().enumerate() {
            if !matches!(f.kind(), FactorKind::Stereo { .. }) {
                return Err(GraphError::InvalidConfig(format!(
                    "bundle adjustment takes stereo factors only, factor {k} is a {}",
                    super::factors::describe(&f.kind())
                )));
            }
            let [a, b] = f.vars();
            let free = |i: usize| (slot[i] != usize::MAX).then_some(slot[i]);
            let point = free(b);
            if let Some(l) = point {
                by_point[l].push(observations.len());
            }
            observations.push(Observation {
                factor: k,
                pose: free(a),
                point,
            });
        }
        Ok(Self {
            pose_slots,
            point_slots,
            observations,
            by_point,
        })
    }

    fn linearize(&self, factors: &[Factor], poses: &[Isometry3<f64>]) -> Linearized {
        let mut lin = Linearized {
            cost: 0.0,
            u: vec![Matrix6::zeros(); self.pose_slots.len()],
            v: vec![Matrix3::zeros(); self.point_slots.len()],
            w: vec![SMatrix::zeros(); self.observations.len()],
            g_pose: vec![Vector6::zeros(); self.pose_slots.len()],
            g_point: vec![Vector3::zeros(); self.point_slots.len()],
        };
        for (k, o) in self.observations.iter().enumerate() {
            let s = factors[o.factor].stereo_normal_blocks(poses);
            lin.cost += s.cost;
            if let Some(p) = o.pose {
                lin.u[p] += s.h_pose;
                lin.g_pose[p] += s.g_pose;
            }
            if let Some(l) = o.point {
                lin.v[l] += s.h_point;
                lin.g_point[l] += s.g_point;
            }
            if o.pose.is_some() && o.point.is_some() {
                lin.w[k] = s.h_pose_point;
            }
        }
        lin
    }

    /// The damped step `(δ_pose, δ_point)`, or `None` if the reduced system is not positive
    /// definite.
    fn solve(&self, lin: &Linearized, lambda: f64) -> Option<Step> {
        let n = 6 * self.pose_slots.len();
        let mut s = DMatrix::<f64>::zeros(n, n);
        let mut b = DVector::<f64>::zeros(n);
        for (p, u) in lin.u.iter().enumerate() {
            let damped = u + Matrix6::identity() * lambda;
            s.view_mut((6 * p, 6 * p), (6, 6)).copy_from(&damped);
            b.rows_mut(6 * p, 6).copy_from(&(-lin.g_pose[p]));
        }
        let mut v_inv = Vec::with_capacity(self.point_slots.len());
        for (l, obs) in self.by_point.iter().enumerate() {
            let vi = (lin.v[l] + Matrix3::identity() * lambda).try_inverse()?;
            let gl = lin.g_point[l];
            for &i in obs {
                let Some(p) = self.observations[i].pose else {
                    continue;
                };
                let wv = lin.w[i] * vi;
                let mut rows = b.rows_mut(6 * p, 6);
                rows += wv * gl;
                for &j in obs {
                    let Some(q) = self.observations[j].pose else {
                        continue;
                    };
                    let block = wv * lin.w[j].transpose();
                    let mut view = s.view_mut((6 * p, 6 * q), (6, 6));
                    view -= block;
                }
            }
            v_inv.push(vi);
        }
        let d_pose_flat = if n > 0 { s.cholesky()?.solve(&b) } else { b };
        let d_pose: Vec<Vector6<f64>> = (0..self.pose_slots.len())
            .map(|p| Vector6::from_iterator(d_pose_flat.rows(6 * p, 6).iter().copied()))
            .collect();
        let mut d_point = Vec::with_capacity(self.point_slots.len());
        for (l, obs) in self.by_point.iter().enumerate() {
            let mut rhs = -lin.g_point[l];
            for &i in obs {
                if let Some(p) = self.observations[i].pose {
                    rhs -= lin.w[i].transpose() * d_pose[p];
                }
            }
            d_point.push(v_inv[l] * rhs);
        }
        Some((d_pose, d_point))
    }

    /// The estimate after a step; returns the largest step entry too.
    fn retract(&self, poses: &[Isometry3<f64>], step: &Step, out: &mut Vec<Isometry3<f64>>) -> f64 {
        out.clear();
        out.extend_from_slice(poses);
        let mut step_max: f64 = 0.0;
        for (p, &i) in self.pose_slots.iter().enumerate() {
            out[i] = se3::retract(&poses[i], &step.0[p]);
            step_max = step_max.max(step.0[p].amax());
        }
        for (l, &i) in self.point_slots.iter().enumerate() {
            out[i].translation.vector += poses[i].rotation * step.1[l];
            step_max = step_max.max(step.1[l].amax());
        }
        step_max
    }
}

fn total_cost(factors: &[Factor], poses: &[Isometry3<f64>]) -> f64 {
    factors.iter().map(|f| f.cost(poses, 0.0)).sum()
}

impl PoseGraph {
    /// Bundle adjustment of a graph that holds camera poses, landmark points and stereo
    /// projection factors only (see the notes of `graph/bundle.rs`), by Levenberg–
    /// Marquardt on the Schur complement. Fixed variables are held; the graph needs at
    /// least one fixed pose (or enough fixed points) for its gauge, or the damping alone
    /// holds it.
    pub fn optimize_bundle(
        &mut self,
        config: &SolverConfig,
    ) -> Result<OptimizationReport, GraphError> {
        config.validate()?;
        let start = Instant::now();
        let layout = Layout::new(self)?;
        let initial_cost = total_cost(&self.factors, &self.poses);
        let mut lambda = config.lambda_initial;
        let mut candidate = Vec::with_capacity(self.poses.len());
        let (mut iterations, mut factorizations) = (0, 0);
        let mut previous_decrease: Option<f64> = None;
        let mut termination = Termination::MaxIterations;
        if layout.pose_slots.is_empty() && layout.point_slots.is_empty() {
            termination = Termination::NoFreeVariables;
        }
        while termination == Termination::MaxIterations && iterations < config.max_iterations {
            let lin = layout.linearize(&self.factors, &self.poses);
            if lin.cost <= 0.0 {
                termination = Termination::ZeroCost;
                break;
            }
            iterations += 1;
            let accepted = loop {
                factorizations += 1;
                if let Some(step) = layout.solve(&lin, lambda) {
                    let step_max = layout.retract(&self.poses, &step, &mut candidate);
                    let cost = total_cost(&self.factors, &candidate);
                    if cost <= lin.cost {
                        lambda = (lambda / config.lambda_factor).max(config.lambda_min);
                        break Some((cost, step_max));
                    }
                }
                lambda *= config.lambda_factor;
                if lambda > config.lambda_max {
                    break None;
                }
            };
            let Some((cost, step_max)) = accepted else {
                termination = Termination::LambdaLimit;
                break;
            };
            std::mem::swap(&mut self.poses, &mut candidate);
            let decrease = lin.cost - cost;
            let extrapolated = match previous_decrease {
                Some(p) if p > 0.0 && decrease < p => {
                    let rho = decrease / p;
                    decrease * rho / (1.0 - rho)
                }
                Some(_) => f64::INFINITY,
                None => f64::INFINITY,
            };
            if cost <= 0.0 {
                termination = Termination::ZeroCost;
            } else if step_max <= config.step_tolerance {
                termination = Termination::SmallStep;
            } else if decrease <= config.relative_tolerance * lin.cost
                && extrapolated <= config.extrapolated_tolerance * lin.cost
            {
                termination = Termination::RelativeDecrease;
            } else if decrease <= config.absolute_tolerance {
                termination = Termination::AbsoluteDecrease;
            }
            previous_decrease = Some(decrease);
        }
        let final_cost = total_cost(&self.factors, &self.poses);
        Ok(OptimizationReport {
            poses: self.num_poses(),
            variables: self.num_variables(),
            factors: self.num_factors(),
            initial_cost,
            final_cost,
            iterations,
            factorizations,
            single_precision_factorizations: 0,
            time_ms: start.elapsed().as_secs_f64() * 1e3,
            analysis_reused: false,
            converged: termination.converged(),
            termination,
            components: Vec::new(),
            factor_nnz: 0,
            gnc_stages: 0,
            profile: Profile::default(),
            log: Vec::new(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::{RobustKernel, StereoCalibration};
    use nalgebra::Point3;

    #[test]
    fn bundle_adjustment_matches_the_general_solver() {
        let camera = StereoCalibration {
            fx: 500.0,
            fy: 500.0,
            skew: 0.0,
            cx: 320.0,
            cy: 240.0,
            baseline_m: 0.4,
        };
        let truth: Vec<Isometry3<f64>> = (0..4)
            .map(|i| {
                se3::exp(&Vector6::new(
                    0.0,
                    0.02 * i as f64,
                    0.0,
                    0.1 * i as f64,
                    0.0,
                    0.8 * i as f64,
                ))
            })
            .collect();
        let mut graph = PoseGraph::new();
        for (i, t) in truth.iter().enumerate() {
            let noise = se3::exp(&Vector6::new(0.01, -0.01, 0.005, 0.05, -0.03, 0.04));
            let start = if i == 0 { *t } else { t * noise };
            graph.add_pose(i as u64, start).unwrap();
        }
        graph.fix(0).unwrap();
        let info = Matrix3::identity();
        for l in 0..40u64 {
            let p = Point3::new(
                (l % 8) as f64 - 3.5,
                (l / 8) as f64 - 2.0,
                10.0 + (l % 5) as f64,
            );
            graph
                .add_point(l, p + Vector3::new(0.1, -0.1, 0.2))
                .unwrap();
            for (i, t) in truth.iter().enumerate() {
                let q = t.inverse() * p;
                let mut uv = camera.project(&q.coords).unwrap();
                uv.x += 0.3 * ((l * 7 + i as u64) % 5) as f64 - 0.6;
                graph
                    .add_stereo_observation(i as u64, l, uv, camera, info, RobustKernel::None)
                    .unwrap();
            }
        }
        let mut general = graph.clone();
        let config = SolverConfig {
            relative_tolerance: 1e-10,
            extrapolated_tolerance: 1e-12,
            ..SolverConfig::default()
        };
        let bundle = graph.optimize_bundle(&config).unwrap();
        let reference = general.optimize(&config).unwrap();
        assert!(bundle.converged, "{:?}", bundle.termination);
        let rel = (bundle.final_cost - reference.final_cost).abs() / reference.final_cost;
        assert!(
            rel < 1e-8,
            "bundle {} general {}",
            bundle.final_cost,
            reference.final_cost
        );
        for i in 1..4u64 {
            let d = graph.pose(i).unwrap().inv_mul(&general.pose(i).unwrap());
            assert!(se3::log(&d).norm() < 1e-6);
        }
    }
}
