//! A session's trajectory as a pose graph: one pose per camera frame (1 Hz), tied by the
//! visual odometry between consecutive frames, anchored at the first frame; relocalization
//! and loop-closure factors are added by the stages that find them.

use super::config::OdometryNoiseConfig;
use super::frame_log::FrameLog;
use super::odometry_bias::{
    anderson_step, estimate_bias, stale_correction_sigma, OdometryBias, OdometryStep, StepWeight,
};
use super::LocalizerConfig;
use crate::graph::{
    gravity_information, GraphError, IncrementalConfig, IncrementalGraph, PoseGraph, RobustKernel,
    SolverConfig, UpdateMethod,
};
use nalgebra::{Isometry3, Matrix6};
use serde::Serialize;
use std::time::Instant;

/// Frame id of the prior map (session 1's map) in a session's graph.
pub const PRIOR_FRAME: u64 = 0;

/// Information of one odometry step between frames (rotation, translation order): the
/// gravity fixes roll and pitch well; yaw drifts with the distance driven and the angle
/// turned, translation with the distance.
pub fn odometry_information(
    distance_m: f64,
    turned_rad: f64,
    config: &OdometryNoiseConfig,
) -> Matrix6<f64> {
    let d = distance_m.max(0.05);
    let sigma_t = config.translation_sigma_m_per_m * d + 1e-3;
    let sigma_yaw =
        config.yaw_sigma_rad_per_m * d + config.yaw_sigma_per_rad_turned * turned_rad.abs() + 1e-4;
    let sigma_tilt = 2e-3;
    let mut info = Matrix6::zeros();
    info[(0, 0)] = 1.0 / (sigma_tilt * sigma_tilt);
    info[(1, 1)] = 1.0 / (sigma_tilt * sigma_tilt);
    info[(2, 2)] = 1.0 / (sigma_yaw * sigma_yaw);
    for i in 3..6 {
        info[(i, i)] = 1.0 / (sigma_t * sigma_t);
    }
    info
}

/// Information of one odometry step: the inverse of the covariance the odometry reported
/// with it (`step_cov` of the frames file, times `reported_covariance_scale`), else the
/// noise model of [`odometry_information`].
pub fn step_information(step: &OdometryStep, config: &OdometryNoiseConfig) -> Matrix6<f64> {
    step.reported_cov
        .filter(|_| config.reported_covariance_scale > 0.0)
        .and_then(|c| (c * config.reported_covariance_scale).try_inverse())
        .unwrap_or_else(|| odometry_information(step.distance_m, step.turned_abs_rad, config))
}

/// A factor other than odometry, kept so that the graph can be rebuilt with re-corrected
/// odometry.
#[derive(Clone, Debug)]
enum ExtraFactor {
    /// Relocalization of frame `k` against the prior map.
    Relocalization {
        k: usize,
        prior_from_rover: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    },
    /// Absolute prior on frame `k` in the graph's own frame (e.g. from the lander).
    Prior {
        k: usize,
        odom_from_rover: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    },
    /// Loop closure `j_from_k` between two frames.
    Between {
        j: usize,
        k: usize,
        j_from_k: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    },
}

/// What the online solves of a graph did ([`TrajectoryGraph::update`],
/// [`TrajectoryGraph::recalibrate`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct OnlineSolveCounts {
    /// Updates whose new factors left the optimum where it was.
    pub skipped: usize,
    /// Updates solved on the window of recent poses.
    pub incremental: usize,
    /// Updates that linearised the settled poses again (no batch).
    pub relinearized: usize,
    /// Updates that re-solved the whole graph (the first, and the incremental graph's
    /// fallback).
    pub batch: usize,
    /// Bias estimates that re-corrected every odometry factor (each a batch re-solve).
    pub recalibrations: usize,
    /// Bias estimates applied to the new steps only.
    pub bias_updates: usize,
    /// Wall time of each update and each bias estimate: the largest, milliseconds.
    pub time_ms_max: f64,
    /// The same, summed.
    pub time_ms_total: f64,
}

impl OnlineSolveCounts {
    /// Count the wall time of one update or recalibration started at `started`.
    fn time(&mut self, started: Instant) {
        let ms = started.elapsed().as_secs_f64() * 1e3;
        self.time_ms_max = self.time_ms_max.max(ms);
        self.time_ms_total += ms;
    }
}

/// The growing pose graph of one session; the graph's world is the session's odometry
/// frame (`odom`), pose ids are frame indices into [`FrameLog::frames`]. The odometry
/// factors carry the measurements with an estimate of the odometry's biases taken out
/// ([`TrajectoryGraph::calibrate`]). An online graph ([`TrajectoryGraph::online`]) is solved
/// incrementally while driving ([`TrajectoryGraph::update`]).
pub struct TrajectoryGraph {
    /// The graph (poses `odom_from_rover`, frame [`PRIOR_FRAME`] = `odom_from_prior`) and
    /// its incremental solver's state.
    inc: IncrementalGraph,
    /// Whether [`TrajectoryGraph::update`] and [`TrajectoryGraph::recalibrate`] are
    /// incremental and bounded (else batch, as [`TrajectoryGraph::optimize`]).
    online: bool,
    /// What the online solves did.
    pub counts: OnlineSolveCounts,
    /// Frames added so far.
    pub frames: usize,
    /// Whether the prior map's frame variable exists.
    pub has_prior_frame: bool,
    /// The current estimate of the odometry's biases.
    pub bias: OdometryBias,
    /// Raw odometry of every step (`steps[k - 1]`: frame k − 1 to frame k).
    steps: Vec<OdometryStep>,
    /// The bias correction each step's factor carries.
    applied: Vec<OdometryBias>,
    /// Relocalizations and loop closures, in the order added.
    extra: Vec<ExtraFactor>,
    /// Gravity factors: frame, the IMU's attitude, information.
    gravity: Vec<(usize, Isometry3<f64>, Matrix6<f64>)>,
}

/// The solver of every batch solve of a trajectory graph.
fn batch_solver() -> SolverConfig {
    SolverConfig {
        log_iterations: false,
        ..SolverConfig::default()
    }
}

/// The incremental solver of an online graph: its fallback batch is [`batch_solver`].
fn incremental_config() -> IncrementalConfig {
    IncrementalConfig {
        solver: batch_solver(),
        ..IncrementalConfig::default()
    }
}

impl Clone for TrajectoryGraph {
    /// A copy at the same estimates; its next incremental update starts with a batch solve.
    fn clone(&self) -> Self {
        Self {
            inc: IncrementalGraph::new(self.inc.graph().clone(), incremental_config()),
            online: self.online,
            counts: self.counts,
            frames: self.frames,
            has_prior_frame: self.has_prior_frame,
            bias: self.bias,
            steps: self.steps.clone(),
            applied: self.applied.clone(),
            extra: self.extra.clone(),
            gravity: self.gravity.clone(),
        }
    }
}

impl TrajectoryGraph {
    /// Estimate of frame `k`'s pose `odom_from_rover` (identity for a frame not in the graph).
    pub fn pose_or_identity(&self, k: usize) -> Isometry3<f64> {
        self.graph()
            .pose(k as u64)
            .unwrap_or_else(Isometry3::identity)
    }

    /// An empty graph, solved in batch.
    pub fn new() -> Self {
        Self {
            inc: IncrementalGraph::new(PoseGraph::new(), incremental_config()),
            online: false,
            counts: OnlineSolveCounts::default(),
            frames: 0,
            has_prior_frame: false,
            bias: OdometryBias::default(),
            steps: Vec::new(),
            applied: Vec::new(),
            extra: Vec::new(),
            gravity: Vec::new(),
        }
    }

    /// An empty graph solved in batch, its odometry corrected from the first step on by the
    /// calibration carried over (`config.calibration.known`).
    pub fn batch(config: &LocalizerConfig) -> Self {
        Self {
            bias: config.calibration.known,
            ..Self::new()
        }
    }

    /// [`TrajectoryGraph::batch`], solved as `config.online_graph` says while driving.
    pub fn online(config: &LocalizerConfig) -> Self {
        Self {
            online: config.online_graph.incremental,
            ..Self::batch(config)
        }
    }

    /// The pose graph.
    pub fn graph(&self) -> &PoseGraph {
        self.inc.graph()
    }

    /// The pose graph to change; the next incremental update re-solves it in batch (its
    /// estimates may have been changed).
    pub fn graph_mut(&mut self) -> &mut PoseGraph {
        self.inc.invalidate();
        self.inc.graph_mut()
    }

    /// Add the frames of `log` not yet in the graph, with odometry factors (and gravity
    /// factors on their attitude); the first is fixed at its attitude: its odometry position
    /// and heading, with the IMU's roll and pitch when it has them (an odometry whose frame
    /// is the first rover frame, as a VO's is, starts tilted by the ground's slope; fixed
    /// there, the gravity factors of the later frames would bend the chain towards level).
    pub fn extend(&mut self, log: &FrameLog, config: &LocalizerConfig) -> Result<(), GraphError> {
        while self.frames < log.len() {
            let k = self.frames;
            let f = &log.frames[k];
            // appended variables and factors leave the incremental state valid
            let graph = self.inc.graph_mut();
            if k == 0 {
                graph.add_pose(0, f.attitude)?;
                graph.fix(0)?;
            } else {
                let step = f.step;
                let z = self.bias.correct(&step);
                // chain on the optimised previous pose
                let prev = graph.pose(k as u64 - 1).unwrap_or_else(Isometry3::identity);
                graph.add_pose(k as u64, prev * z)?;
                let info = step_information(&step, &config.odometry);
                graph.add_between(k as u64 - 1, k as u64, z, info, RobustKernel::None)?;
                self.steps.push(step);
                self.applied.push(self.bias);
                let sigma = config.factors.gravity_sigma_rad;
                if sigma > 0.0 {
                    // the attitude's roll and pitch are the IMU's gravity direction
                    let information = gravity_information(&f.attitude, sigma);
                    graph.add_prior(k as u64, f.attitude, information)?;
                    self.gravity.push((k, f.attitude, information));
                }
            }
            self.frames += 1;
        }
        Ok(())
    }

    /// Add a relocalization of frame `k` against the prior map: `prior_from_rover`
    /// measured, with its information and robust kernel (the prior frame variable is
    /// created on first use, initialised from this measurement); returns the factor index.
    pub fn add_relocalization(
        &mut self,
        k: usize,
        prior_from_rover: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        let odom_from_rover = self.pose_or_identity(k);
        let graph = self.inc.graph_mut();
        if !self.has_prior_frame {
            graph.add_frame(PRIOR_FRAME, odom_from_rover * prior_from_rover.inverse())?;
            self.has_prior_frame = true;
        }
        let index =
            graph.add_relocalization(k as u64, PRIOR_FRAME, prior_from_rover, information)?;
        // a new factor's kernel: the incremental state stays valid
        graph.set_factor_kernel(index, kernel)?;
        self.extra.push(ExtraFactor::Relocalization {
            k,
            prior_from_rover,
            information,
            kernel,
        });
        Ok(index)
    }

    /// Add a loop closure: frame `k` measured from frame `j` (`j_from_k`); returns the
    /// factor index.
    pub fn add_loop_closure(
        &mut self,
        j: usize,
        k: usize,
        j_from_k: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        let index =
            self.inc
                .graph_mut()
                .add_between(j as u64, k as u64, j_from_k, information, kernel)?;
        self.extra.push(ExtraFactor::Between {
            j,
            k,
            j_from_k,
            information,
            kernel,
        });
        Ok(index)
    }

    /// Add an absolute prior on frame `k` in the graph's own (odometry) frame, e.g. a pose
    /// measured from the lander when the odometry frame is the world frame; returns the
    /// factor index.
    pub fn add_pose_prior(
        &mut self,
        k: usize,
        odom_from_rover: Isometry3<f64>,
        information: Matrix6<f64>,
        kernel: RobustKernel,
    ) -> Result<usize, GraphError> {
        let index = self.inc.graph_mut().add_prior_key(
            crate::graph::VarKey::Pose(k as u64),
            odom_from_rover,
            information,
            kernel,
        )?;
        self.extra.push(ExtraFactor::Prior {
            k,
            odom_from_rover,
            information,
            kernel,
        });
        Ok(index)
    }

    /// Relocalizations, loop closures and pose priors added so far.
    pub fn num_fixes(&self) -> usize {
        self.extra.len()
    }

    /// Optimise the whole graph (batch, warm started at the current estimates).
    pub fn optimize(&mut self) -> Result<(), GraphError> {
        self.inc.graph_mut().optimize(&batch_solver())?;
        self.inc.invalidate();
        Ok(())
    }

    /// Bring the estimate to the optimum after new factors: an online graph incrementally
    /// ([`IncrementalGraph::update`]: milliseconds, a batch only as its fallback), else
    /// [`TrajectoryGraph::optimize`].
    pub fn update(&mut self) -> Result<(), GraphError> {
        if !self.online {
            return self.optimize();
        }
        let started = Instant::now();
        let report = self.inc.update()?;
        self.counts.time(started);
        let counter = match report.method {
            UpdateMethod::Skipped => &mut self.counts.skipped,
            UpdateMethod::Incremental => &mut self.counts.incremental,
            UpdateMethod::Relinearized => &mut self.counts.relinearized,
            UpdateMethod::Batch => &mut self.counts.batch,
        };
        *counter += 1;
        Ok(())
    }

    /// The bias calibration after new factors, once [`TrajectoryGraph::update`] has run: a
    /// graph solved in batch calibrates fully ([`TrajectoryGraph::calibrate`]); an online one
    /// estimates the bias from its current estimate and re-corrects every odometry factor
    /// (a batch) only when the factors' corrections are more than
    /// `online_graph.recalibrate_sigma` from it, else corrects the steps added from now on.
    pub fn recalibrate(&mut self, config: &LocalizerConfig) -> Result<(), GraphError> {
        if !self.online {
            return self.calibrate(config, config.calibration.rounds);
        }
        let started = Instant::now();
        let weights = self.step_weights(config);
        let estimate = self.estimate_bias(config, &weights);
        let change = stale_correction_sigma(
            &self.steps,
            &self.applied,
            &weights,
            &estimate,
            &self.fix_frames(),
        );
        self.bias = estimate;
        // the re-solves below are timed as updates
        self.counts.time(started);
        if change > config.online_graph.recalibrate_sigma {
            self.counts.recalibrations += 1;
            self.rebuild(config)?;
            self.update()?;
            // the remaining rounds as in the batch calibration, plain: an update is a step
            // towards the solution, not the solution Anderson's step needs
            for _ in 1..config.calibration.rounds {
                self.bias = self.estimate_bias(config, &weights);
                self.rebuild(config)?;
                self.update()?;
            }
        } else {
            self.counts.bias_updates += 1;
        }
        Ok(())
    }

    /// The frames that a relocalization, a pose prior or a loop closure ties down.
    fn fix_frames(&self) -> Vec<usize> {
        self.extra
            .iter()
            .flat_map(|f| match f {
                ExtraFactor::Relocalization { k, .. } | ExtraFactor::Prior { k, .. } => {
                    vec![*k]
                }
                ExtraFactor::Between { j, k, .. } => vec![*j, *k],
            })
            .collect()
    }

    /// Each step's weight in the bias estimate: its odometry factor's information.
    fn step_weights(&self, config: &LocalizerConfig) -> Vec<StepWeight> {
        self.steps
            .iter()
            .map(|s| {
                let info = step_information(s, &config.odometry);
                StepWeight {
                    yaw: info[(2, 2)],
                    translation: info[(3, 3)],
                }
            })
            .collect()
    }

    /// The odometry's biases from the current estimate: the poses were optimised with the
    /// factors' corrections, so the estimate is of the total bias seen from the raw steps.
    fn estimate_bias(&self, config: &LocalizerConfig, weights: &[StepWeight]) -> OdometryBias {
        let poses: Vec<Isometry3<f64>> =
            (0..self.frames).map(|k| self.pose_or_identity(k)).collect();
        estimate_bias(&self.steps, &poses, weights, &config.calibration.prior())
    }

    /// Estimate the odometry's biases from the optimised trajectory, rebuild the graph with
    /// the odometry corrected by them and re-optimise; `rounds` times (the estimate and the
    /// trajectory are solved in turn). Call after [`TrajectoryGraph::optimize`].
    pub fn calibrate(&mut self, config: &LocalizerConfig, rounds: usize) -> Result<(), GraphError> {
        let weights = self.step_weights(config);
        let (mut applied, mut estimated) = (Vec::new(), Vec::new());
        for _ in 0..rounds {
            self.next_round(config, &weights, &mut applied, &mut estimated);
            self.rebuild(config)?;
            self.optimize()?;
        }
        Ok(())
    }

    /// One round of the calibration: the bias estimated from the trajectory solved with the
    /// current one, then the bias to solve with next (the estimate, or with
    /// `calibration.anderson_depth` > 0 Anderson's step, [`anderson_step`]).
    fn next_round(
        &mut self,
        config: &LocalizerConfig,
        weights: &[StepWeight],
        applied: &mut Vec<OdometryBias>,
        estimated: &mut Vec<OdometryBias>,
    ) {
        applied.push(self.bias);
        estimated.push(self.estimate_bias(config, weights));
        let c = &config.calibration;
        self.bias = anderson_step(applied, estimated, &c.prior(), c.anderson_depth);
    }

    /// A copy without the loop closures (the relocalizations and pose priors kept), at the
    /// current estimates: for a bundle adjustment, whose boulder observations are what the
    /// closures summarised ([`super::boulder_adjustment`]).
    pub fn without_loop_closures(
        &self,
        config: &LocalizerConfig,
    ) -> Result<TrajectoryGraph, GraphError> {
        let mut copy = self.clone();
        copy.extra
            .retain(|f| !matches!(f, ExtraFactor::Between { .. }));
        copy.rebuild(config)?;
        Ok(copy)
    }

    /// A new graph with the same variables (current estimates), the odometry corrected with
    /// the current bias, and the same relocalizations and loop closures.
    fn rebuild(&mut self, config: &LocalizerConfig) -> Result<(), GraphError> {
        let mut graph = PoseGraph::new();
        self.applied = vec![self.bias; self.steps.len()];
        for k in 0..self.frames {
            let pose = self.pose_or_identity(k);
            graph.add_pose(k as u64, pose)?;
        }
        graph.fix(0)?;
        if let Some(frame) = self.odom_from_prior() {
            graph.add_frame(PRIOR_FRAME, frame)?;
        }
        for (i, step) in self.steps.iter().enumerate() {
            let info = step_information(step, &config.odometry);
            let z = self.bias.correct(step);
            graph.add_between(i as u64, i as u64 + 1, z, info, RobustKernel::None)?;
        }
        for (k, attitude, information) in &self.gravity {
            graph.add_prior(*k as u64, *attitude, *information)?;
        }
        for f in &self.extra {
            match f {
                ExtraFactor::Relocalization {
                    k,
                    prior_from_rover,
                    information,
                    kernel,
                } => {
                    let index = graph.add_relocalization(
                        *k as u64,
                        PRIOR_FRAME,
                        *prior_from_rover,
                        *information,
                    )?;
                    graph.set_factor_kernel(index, *kernel)?;
                }
                ExtraFactor::Prior {
                    k,
                    odom_from_rover,
                    information,
                    kernel,
                } => {
                    graph.add_prior_key(
                        crate::graph::VarKey::Pose(*k as u64),
                        *odom_from_rover,
                        *information,
                        *kernel,
                    )?;
                }
                ExtraFactor::Between {
                    j,
                    k,
                    j_from_k,
                    information,
                    kernel,
                } => {
                    graph.add_between(*j as u64, *k as u64, *j_from_k, *information, *kernel)?;
                }
            }
        }
        self.inc = IncrementalGraph::new(graph, incremental_config());
        Ok(())
    }

    /// The odometry chain of `frames` with the current bias correction, starting at the
    /// identity (relative shape only: what a submap is built from). Index `i` of the result
    /// is frame `frames.start + i`.
    pub fn corrected_odometry(&self, frames: std::ops::Range<usize>) -> Vec<Isometry3<f64>> {
        let mut pose = Isometry3::identity();
        let mut out = Vec::with_capacity(frames.len());
        for k in frames {
            if !out.is_empty() {
                if let Some(step) = k.checked_sub(1).and_then(|i| self.steps.get(i)) {
                    pose *= self.bias.correct(step);
                }
            }
            out.push(pose);
        }
        out
    }

    /// One-σ uncertainty the odometry accumulates between frames `a` and `b` (either
    /// order), from the odometry factors' noise model: (horizontal position m, yaw rad). The
    /// position includes the lever of the yaw uncertainty over the distance driven.
    pub fn odometry_sigma(&self, a: usize, b: usize, config: &OdometryNoiseConfig) -> (f64, f64) {
        let (from, to) = (a.min(b), a.max(b));
        let (mut var_t, mut var_yaw, mut path) = (0.0, 0.0, 0.0);
        for step in self.steps.iter().take(to).skip(from) {
            let info = step_information(step, config);
            var_t += 1.0 / info[(3, 3)];
            var_yaw += 1.0 / info[(2, 2)];
            path += step.distance_m;
        }
        let sigma_yaw = var_yaw.sqrt();
        (var_t.sqrt() + sigma_yaw * path, sigma_yaw)
    }

    /// `odom_from_prior` if known.
    pub fn odom_from_prior(&self) -> Option<Isometry3<f64>> {
        self.has_prior_frame
            .then(|| self.graph().frame(PRIOR_FRAME))
            .flatten()
    }

    /// Frame `k`'s drift correction `prior_from_session`: its optimised pose, in the prior
    /// map's frame when it is known (the odometry frame otherwise), composed with the
    /// inverse of its odometry pose in `log`. `None` for a frame the graph or `log` lacks.
    pub fn prior_from_session(&self, log: &FrameLog, k: usize) -> Option<Isometry3<f64>> {
        let prior_from_odom = self
            .odom_from_prior()
            .map_or_else(Isometry3::identity, |f| f.inverse());
        let odom_from_rover = self.graph().pose(k as u64)?;
        let session_from_rover = log.frames.get(k)?.odom_from_rover;
        Some(prior_from_odom * odom_from_rover * session_from_rover.inverse())
    }

    /// Optimised poses of all frames, in the prior map's frame when it is known (the odometry
    /// frame otherwise).
    pub fn poses_in_prior(&self) -> Vec<Isometry3<f64>> {
        let prior_from_odom = self
            .odom_from_prior()
            .map_or_else(Isometry3::identity, |f| f.inverse());
        (0..self.frames)
            .map(|k| prior_from_odom * self.pose_or_identity(k))
            .collect()
    }
}

impl Default for TrajectoryGraph {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::localizer::config::OnlineGraphConfig;
    use segloc_maps::frames::StreamFrame;

    #[test]
    fn a_reported_step_covariance_replaces_the_noise_model() {
        let mut step = OdometryStep {
            measured: Isometry3::translation(0.4, 0.0, 0.0),
            distance_m: 0.4,
            turned_rad: 0.0,
            turned_abs_rad: 0.0,
            reported_cov: None,
        };
        let mut config = OdometryNoiseConfig::default();
        let model = step_information(&step, &config);
        assert_eq!(model, odometry_information(0.4, 0.0, &config));
        let cov =
            Matrix6::from_diagonal(&nalgebra::Vector6::new(1e-8, 1e-8, 4e-8, 1e-6, 1e-6, 4e-6));
        step.reported_cov = Some(cov);
        let reported = step_information(&step, &config);
        assert!((reported[(2, 2)] - 2.5e7).abs() < 1e-3);
        assert!((reported[(3, 3)] - 1e6).abs() < 1e-6);
        config.reported_covariance_scale = 4.0;
        assert!((step_information(&step, &config)[(3, 3)] - 2.5e5).abs() < 1e-6);
        // 0: the frames' covariances are ignored
        config.reported_covariance_scale = 0.0;
        assert_eq!(step_information(&step, &config), model);
    }

    #[test]
    fn odometry_weight_falls_with_distance_and_turning() {
        let c = OdometryNoiseConfig::default();
        let still = odometry_information(0.0, 0.0, &c);
        let driven = odometry_information(1.0, 0.0, &c);
        let turned = odometry_information(0.0, 1.5, &c);
        assert!(driven[(3, 3)] < still[(3, 3)]);
        assert!(driven[(2, 2)] < still[(2, 2)]);
        assert!(turned[(2, 2)] < still[(2, 2)]);
        assert_eq!(turned[(3, 3)], still[(3, 3)]);
    }

    /// 300 frames on a 12 m circle, 0.4 m apart, the odometry 2 % long and turning
    /// 0.003 rad per metre too far, with the IMU's gravity; and the truth in the prior map,
    /// whose frame is the odometry frame moved.
    fn drifting_drive() -> (FrameLog, Vec<Isometry3<f64>>) {
        let truth_at = |k: usize| {
            let a = 0.4 * k as f64 / 12.0;
            Isometry3::new(
                nalgebra::Vector3::new(12.0 * a.sin(), 12.0 * (1.0 - a.cos()), 0.0),
                nalgebra::Vector3::z() * a,
            )
        };
        let mut log = FrameLog::default();
        let mut odom = Isometry3::identity();
        for k in 0..300 {
            if k > 0 {
                let step = truth_at(k - 1).inverse() * truth_at(k);
                let d = step.translation.vector.norm();
                let yaw = nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.003 * d);
                odom *= Isometry3::from_parts(
                    (step.translation.vector * 1.02).into(),
                    step.rotation * yaw,
                );
            }
            let mut frame = StreamFrame::new(k as f64, odom);
            frame.gravity_rover = Some(nalgebra::Vector3::new(0.0, 0.0, -1.62));
            log.push(&frame);
        }
        let prior_from_world = Isometry3::new(
            nalgebra::Vector3::new(3.0, -2.0, 0.0),
            nalgebra::Vector3::z() * 0.4,
        );
        (
            log,
            (0..300).map(|k| prior_from_world * truth_at(k)).collect(),
        )
    }

    /// The drive's graph up to frame `end` with a fix (1 cm, 0.1° noise-free information)
    /// every 10 frames up to it, updated online after each fix, and recalibrated.
    fn drive_online(
        config: &LocalizerConfig,
        log: &FrameLog,
        truth: &[Isometry3<f64>],
    ) -> TrajectoryGraph {
        let mut graph = TrajectoryGraph::online(config);
        let mut info = Matrix6::identity() * 1e4;
        for i in 0..3 {
            info[(i, i)] = 3e5;
        }
        let kernel = RobustKernel::Cauchy { c: 3.0 };
        for end in (10..log.len()).step_by(10) {
            let mut part = FrameLog::default();
            for f in &log.frames[..=end] {
                let mut frame = StreamFrame::new(f.t, f.odom_from_rover);
                frame.gravity_rover = Some(nalgebra::Vector3::new(0.0, 0.0, -1.62));
                part.push(&frame);
            }
            graph.extend(&part, config).unwrap();
            graph
                .add_relocalization(end, truth[end], info, kernel)
                .unwrap();
            graph.update().unwrap();
            graph.recalibrate(config).unwrap();
        }
        graph
    }

    /// The largest position difference between two graphs' poses in the prior map, metres.
    fn largest_difference(a: &TrajectoryGraph, b: &TrajectoryGraph) -> f64 {
        let (pa, pb) = (a.poses_in_prior(), b.poses_in_prior());
        pa.iter()
            .zip(&pb)
            .map(|(x, y)| (x.translation.vector - y.translation.vector).norm())
            .fold(0.0, f64::max)
    }

    #[test]
    fn the_incremental_estimate_is_the_batch_optimum() {
        let (log, truth) = drifting_drive();
        // the bias re-estimated at every fix but never re-applied to the old factors: the
        // online graph and a batch solve of the same factors must agree
        let config = LocalizerConfig {
            online_graph: OnlineGraphConfig {
                recalibrate_sigma: 1e9,
                ..OnlineGraphConfig::fast()
            },
            ..LocalizerConfig::default()
        };
        let online = drive_online(&config, &log, &truth);
        assert!(
            online.counts.incremental + online.counts.relinearized >= 20,
            "{:?}",
            online.counts
        );
        assert!(online.counts.batch <= 2, "{:?}", online.counts);
        let mut batch = online.clone();
        batch.optimize().unwrap();
        let gap = largest_difference(&online, &batch);
        // one Gauss-Newton step per update on the window, the settled poses on their last
        // linearisation: 6.5 mm measured
        assert!(gap < 0.01, "incremental vs batch: {gap} m");
    }

    #[test]
    fn a_stale_correction_is_reapplied_past_the_threshold() {
        let (log, truth) = drifting_drive();
        let mut config = LocalizerConfig {
            online_graph: OnlineGraphConfig {
                recalibrate_sigma: 0.0,
                ..OnlineGraphConfig::fast()
            },
            ..LocalizerConfig::default()
        };
        let always = drive_online(&config, &log, &truth);
        assert!(always.counts.recalibrations >= 25, "{:?}", always.counts);
        config.online_graph.recalibrate_sigma = OnlineGraphConfig::fast().recalibrate_sigma;
        let bounded = drive_online(&config, &log, &truth);
        // the 2 % scale error is learnt in a few recalibrations, then only refined
        assert!(
            bounded.counts.recalibrations < always.counts.recalibrations / 2,
            "{:?}",
            bounded.counts
        );
        assert!(bounded.counts.bias_updates > 0);
        assert!(
            (bounded.bias.scale_error - 0.02).abs() < 0.005,
            "{:?}",
            bounded.bias
        );
        assert!(largest_difference(&always, &bounded) < 0.01);
    }

    #[test]
    fn chain_of_odometry_and_a_relocalization() {
        // 20 frames 0.4 m apart, the odometry 2 % long
        let mut log = FrameLog::default();
        for k in 0..20 {
            let x = 0.4 * 1.02 * k as f64;
            log.push(&StreamFrame::new(
                k as f64,
                Isometry3::translation(x, 0.0, 0.0),
            ));
        }
        let config = LocalizerConfig::default();
        let mut graph = TrajectoryGraph::new();
        graph.extend(&log, &config).unwrap();
        assert_eq!(graph.frames, 20);
        graph.optimize().unwrap();
        // odometry alone: the graph reproduces it
        let poses = graph.poses_in_prior();
        assert!((poses[19].translation.x - 0.4 * 1.02 * 19.0).abs() < 1e-6);
        // a perfect relocalization of the last frame pulls it onto the truth
        let truth = Isometry3::translation(0.4 * 19.0, 0.0, 0.0);
        let info = Matrix6::identity() * 1e6;
        graph
            .add_relocalization(19, truth, info, RobustKernel::None)
            .unwrap();
        graph.optimize().unwrap();
        let poses = graph.poses_in_prior();
        assert!((poses[19].translation.vector - truth.translation.vector).norm() < 0.01);
    }
}
