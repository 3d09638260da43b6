//! A session's trajectory as a pose graph: one pose per camera frame (1 Hz), tied by the
//! visual odometry between consecutive frames, anchored at the first frame; relocalization
//! and loop-closure factors are added by the stages that find them.

use super::config::OdometryNoiseConfig;
use super::frame_log::FrameLog;
use super::odometry_bias::{estimate_bias, BiasPrior, OdometryBias, OdometryStep, StepWeight};
use super::LocalizerConfig;
use crate::graph::{gravity_information, GraphError, PoseGraph, RobustKernel, SolverConfig};
use nalgebra::{Isometry3, Matrix6};

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

/// The growing pose graph of one session; the graph's world is the session's odometry
/// frame (`odom`), pose ids are frame indices into [`FrameLog::frames`]. The odometry
/// factors carry the measurements with the current estimate of the odometry's biases taken
/// out ([`TrajectoryGraph::calibrate`]).
#[derive(Clone)]
pub struct TrajectoryGraph {
    /// The graph (poses `odom_from_rover`, frame [`PRIOR_FRAME`] = `odom_from_prior`).
    pub graph: PoseGraph,
    /// Frames added so far.
    pub frames: usize,
    /// Whether the prior map's frame variable exists.
    pub has_prior_frame: bool,
    /// The current estimate of the odometry's biases.
    pub bias: OdometryBias,
    /// Raw odometry of every step (`steps[k - 1]`: frame k − 1 to frame k).
    steps: Vec<OdometryStep>,
    /// Relocalizations and loop closures, in the order added.
    extra: Vec<ExtraFactor>,
    /// Gravity factors: frame, the IMU's attitude, information.
    gravity: Vec<(usize, Isometry3<f64>, Matrix6<f64>)>,
}

impl TrajectoryGraph {
    /// Estimate of frame `k`'s pose `odom_from_rover` (identity for a frame not in the graph).
    pub fn pose_or_identity(&self, k: usize) -> Isometry3<f64> {
        self.graph
            .pose(k as u64)
            .unwrap_or_else(Isometry3::identity)
    }

    /// An empty graph.
    pub fn new() -> Self {
        Self {
            graph: PoseGraph::new(),
            frames: 0,
            has_prior_frame: false,
            bias: OdometryBias::default(),
            steps: Vec::new(),
            extra: Vec::new(),
            gravity: Vec::new(),
        }
    }

    /// Add the frames of `log` not yet in the graph, with odometry factors (and gravity
    /// factors on their attitude); the first is fixed at its odometry pose.
    pub fn extend(&mut self, log: &FrameLog, config: &LocalizerConfig) -> Result<(), GraphError> {
        while self.frames < log.len() {
            let k = self.frames;
            let f = &log.frames[k];
            if k == 0 {
                self.graph.add_pose(0, f.odom_from_rover)?;
                self.graph.fix(0)?;
            } else {
                let step = f.step;
                let z = self.bias.correct(&step);
                // chain on the optimised previous pose
                let prev = self
                    .graph
                    .pose(k as u64 - 1)
                    .unwrap_or_else(Isometry3::identity);
                self.graph.add_pose(k as u64, prev * z)?;
                let info =
                    odometry_information(step.distance_m, step.turned_abs_rad, &config.odometry);
                self.graph
                    .add_between(k as u64 - 1, k as u64, z, info, RobustKernel::None)?;
                self.steps.push(step);
                let sigma = config.factors.gravity_sigma_rad;
                if sigma > 0.0 {
                    // the attitude's roll and pitch are the IMU's gravity direction
                    let information = gravity_information(&f.attitude, sigma);
                    self.graph.add_prior(k as u64, f.attitude, information)?;
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
        if !self.has_prior_frame {
            let odom_from_rover = self.pose_or_identity(k);
            self.graph
                .add_frame(PRIOR_FRAME, odom_from_rover * prior_from_rover.inverse())?;
            self.has_prior_frame = true;
        }
        let index =
            self.graph
                .add_relocalization(k as u64, PRIOR_FRAME, prior_from_rover, information)?;
        self.graph.set_factor_kernel(index, kernel)?;
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
        let index = self
            .graph
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
        let index = self.graph.add_prior_key(
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

    /// Optimise.
    pub fn optimize(&mut self) -> Result<(), GraphError> {
        let config = SolverConfig {
            log_iterations: false,
            ..SolverConfig::default()
        };
        self.graph.optimize(&config)?;
        Ok(())
    }

    /// Estimate the odometry's biases from the optimised trajectory, rebuild the graph with
    /// the odometry corrected by them and re-optimise; `rounds` times (the estimate and the
    /// trajectory are solved in turn). Call after [`TrajectoryGraph::optimize`].
    pub fn calibrate(&mut self, config: &LocalizerConfig, rounds: usize) -> Result<(), GraphError> {
        let prior = BiasPrior {
            scale_error: config.calibration.prior_scale,
            yaw_drift_rad_per_m: config.calibration.prior_yaw_drift_rad_per_m,
            yaw_scale_error: config.calibration.prior_yaw_scale,
        };
        let weights: Vec<StepWeight> = self
            .steps
            .iter()
            .map(|s| {
                let info = odometry_information(s.distance_m, s.turned_abs_rad, &config.odometry);
                StepWeight {
                    yaw: info[(2, 2)],
                    translation: info[(3, 3)],
                }
            })
            .collect();
        for _ in 0..rounds {
            // the poses were optimised with the current correction: the estimate is of the
            // total bias seen from the raw measurements
            let poses: Vec<Isometry3<f64>> =
                (0..self.frames).map(|k| self.pose_or_identity(k)).collect();
            self.bias = estimate_bias(&self.steps, &poses, &weights, &prior);
            self.rebuild(config)?;
            self.optimize()?;
        }
        Ok(())
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
        for k in 0..self.frames {
            let pose = self.pose_or_identity(k);
            graph.add_pose(k as u64, pose)?;
        }
        graph.fix(0)?;
        if let Some(frame) = self.odom_from_prior() {
            graph.add_frame(PRIOR_FRAME, frame)?;
        }
        for (i, step) in self.steps.iter().enumerate() {
            let info = odometry_information(step.distance_m, step.turned_abs_rad, &config.odometry);
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
        self.graph = graph;
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
            let info = odometry_information(step.distance_m, step.turned_abs_rad, config);
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
            .then(|| self.graph.frame(PRIOR_FRAME))
            .flatten()
    }

    /// Frame `k`'s drift correction `prior_from_session`: its optimised pose, in the prior
    /// map's frame when it is known (the odometry frame otherwise), composed with the
    /// inverse of its odometry pose in `log`. `None` for a frame the graph or `log` lacks.
    pub fn prior_from_session(&self, log: &FrameLog, k: usize) -> Option<Isometry3<f64>> {
        let prior_from_odom = self
            .odom_from_prior()
            .map_or_else(Isometry3::identity, |f| f.inverse());
        let odom_from_rover = self.graph.pose(k as u64)?;
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
    use segloc_maps::frames::StreamFrame;

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
