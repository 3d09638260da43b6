//! Session 1: start at a known pose, drive, and build the boulder map every later session
//! relocalizes against (in the optimised session frame, which is the world frame up to
//! drift since the start is known).

use super::boulder_adjustment::{adjust_in_place, BoulderAdjustmentReport};
use super::fix_gate::{agrees, Tolerance};
use super::lander_factor::add_lander_factors_optimized;
use super::odometry_bias::OdometryBias;
use super::progress::{MissionProgress, MissionStage};
use super::submap::{detections_with_poses, frame_nearest, landmark_positions};
use super::trajectory::TrajectoryGraph;
use super::view_bias::ViewBiasCalibration;
use super::{Attempt, MissionConfig, MissionError};
use crate::graph::{se3, RobustKernel};
use crate::landmarks::{fuse_detections, FusionConfig};
use crate::relocalize::Relocalizer;
use crate::sim::moon::Moon;
use crate::sim::session::{SessionConfig, SessionLog, SessionSim};
use nalgebra::Isometry3;
use segloc_maps::ObjectMap;

/// Frames whose lander factors are added before the graph is re-optimised.
const LANDER_CHUNK_FRAMES: usize = 30;

/// Passes over the whole session of the final viewpoint-bias estimate.
const FINAL_VIEW_BIAS_ITERATIONS: usize = 3;

/// What session 1 produced.
pub struct MappedSession {
    /// The simulation log.
    pub log: SessionLog,
    /// Optimised `world_from_rover` of every frame.
    pub poses: Vec<Isometry3<f64>>,
    /// The boulder map (world frame), the prior of later sessions.
    pub map: ObjectMap,
    /// Loop-closure attempts (recent submaps against the session's own earlier map).
    pub attempts: Vec<Attempt>,
    /// The odometry's biases as estimated at the end of the session.
    pub odometry_bias: OdometryBias,
    /// Position RMSE of the pose graph's poses (before the mission's terrain height
    /// alignment changes `poses`), metres.
    pub rmse_graph_m: f64,
    /// What the boulder adjustment did (`None`: off).
    pub adjustment: Option<BoulderAdjustmentReport>,
    /// Position RMSE of the pose graph's poses before the boulder adjustment, metres.
    pub rmse_before_adjustment_m: f64,
    /// The viewpoint-bias calibration at the end of the session from its short passes.
    pub view_bias: ViewBiasCalibration,
    /// The viewpoint-bias size fraction the boulder adjustment estimated from every pass,
    /// if it did: the map was fused with it (else with `view_bias`'s), and later sessions
    /// and the maps use it too.
    pub adjusted_view_bias: Option<f64>,
}

impl MappedSession {
    /// `config` with this session's calibrated fusion parameters, for the sessions and
    /// maps that follow.
    pub fn calibrated(&self, config: &MissionConfig) -> MissionConfig {
        let fusion = self.view_bias.fusion(&config.fusion);
        MissionConfig {
            fusion: FusionConfig {
                view_bias_size_fraction: self
                    .adjusted_view_bias
                    .unwrap_or(fusion.view_bias_size_fraction),
                ..fusion
            },
            ..config.clone()
        }
    }
}

/// Run session 1 from `start` for the mission's duration and build its map.
pub fn map_session(
    moon: &Moon,
    config: &MissionConfig,
    start: [f64; 3],
    seed: u64,
    progress: &dyn MissionProgress,
) -> Result<MappedSession, MissionError> {
    let session = SessionConfig {
        duration_s: config.seconds_per_session,
        start,
        initial_guess: None,
        ..config.session.clone()
    };
    let mut sim = SessionSim::new(moon, &session, seed)?;
    let mut online =
        (config.loop_closures && config.online_loop_closures).then(|| OnlineClosures::new(config));
    while sim.step() {
        progress.update(MissionStage::Driving {
            session: 1,
            time_s: sim.log().ticks.last().map_or(0.0, |t| t.time_s),
            duration_s: session.duration_s,
        });
        if let Some(online) = online.as_mut() {
            if let Some(planner_from_session) = online.advance(sim.log(), config)? {
                sim.reanchor_planner(&planner_from_session);
            }
        }
    }
    let log = sim.finish();
    let mut graph = TrajectoryGraph::new();
    graph.extend(&log, config)?;
    if config.lander_factors {
        // in time order, a chunk at a time, each placed with the estimate the earlier
        // chunks corrected (as the rover would online)
        let mut first = 0;
        while first < graph.frames {
            let end = (first + LANDER_CHUNK_FRAMES).min(graph.frames);
            add_lander_factors_optimized(&mut graph, &log, first..end, false, config)?;
            first = end;
        }
    }
    let before_closures = config.view_bias.reprocess.then(|| graph.clone());
    let mut view_bias = ViewBiasCalibration::new(&config.view_bias);
    let mut attempts = if config.loop_closures {
        loop_closures(&log, config, &mut graph, &mut view_bias)?
    } else {
        Vec::new()
    };
    graph.optimize()?;
    // the whole session, iterated (each pass clusters with the previous estimate)
    let end_s = log.frames.last().map_or(0.0, |f| f.time_s) + config.view_bias.stretch_s;
    let closed = graph.poses_in_prior();
    for _ in 0..FINAL_VIEW_BIAS_ITERATIONS {
        view_bias.update(&log, &closed, end_s, &config.fusion);
    }
    if let (true, Some(fraction), Some(fresh)) =
        (config.loop_closures, view_bias.fraction(), before_closures)
    {
        // the closures before the estimate existed were made with the bias left in: close
        // every loop again with the final estimate, as the session ends
        graph = fresh;
        let mut fixed = view_bias.fixed_at(fraction);
        attempts = loop_closures(&log, config, &mut graph, &mut fixed)?;
        graph.optimize()?;
    }
    let fusion = view_bias.fusion(&config.fusion);
    let rmse_before_adjustment_m = super::trajectory::rmse_m(&log, &graph.poses_in_prior());
    if config.boulder_adjustment.runs() {
        // the boulders are the evidence the loop closures summarised (fused with the
        // short-pass viewpoint bias): counted once, and a wrong closure cannot bend the
        // adjusted trajectory
        graph = graph.without_loop_closures(config)?;
    }
    let adjustment = adjust_in_place(&mut graph, &log, &fusion, &config.boulder_adjustment)?;
    // the adjustment's estimate of the viewpoint bias, from every pass, replaces the
    // short-pass one for the map and everything after it
    let adjusted_view_bias = adjustment.as_ref().and_then(|a| a.view_bias_size_fraction);
    let fusion = FusionConfig {
        view_bias_size_fraction: adjusted_view_bias.unwrap_or(fusion.view_bias_size_fraction),
        ..fusion
    };
    let poses = graph.poses_in_prior();
    let set = detections_with_poses(&log, &poses, 0..log.frames.len(), "session1", "world");
    let map = fuse_detections(&set, &fusion);
    let rmse_graph_m = super::trajectory::rmse_m(&log, &poses);
    Ok(MappedSession {
        log,
        poses,
        map,
        attempts,
        odometry_bias: graph.bias,
        rmse_graph_m,
        adjustment,
        rmse_before_adjustment_m,
        view_bias,
        adjusted_view_bias,
    })
}

/// Every `relocalize_period_s`, relocalize the submap of the last `submap_window_s` against
/// (1) the *start map*, the detections of the frames before the rover moved or turned much
/// (their poses are known almost exactly from the known start, so a match there fixes the
/// yaw the odometry lost while turning on the spot), and (2) the map of the frames older
/// than `loop_closure_gap_s` before the submap. Both maps are placed with the current
/// estimate (earlier closures applied, re-optimised after each). An accepted result becomes a
/// between factor from the earlier frame nearest the matched landmarks (frame 0 for the
/// start map) to the submap frame nearest its matched landmarks.
fn loop_closures(
    log: &SessionLog,
    config: &MissionConfig,
    graph: &mut TrajectoryGraph,
    view_bias: &mut ViewBiasCalibration,
) -> Result<Vec<Attempt>, MissionError> {
    let mut closer = LoopCloser::default();
    let end = log.frames.last().map_or(0.0, |f| f.time_s);
    let mut t = config.relocalize_period_s;
    while t <= end + 1e-9 {
        closer.close_at(t, log, config, graph, view_bias)?;
        t += config.relocalize_period_s;
    }
    Ok(closer.attempts)
}

/// The loop-closure state carried from one period to the next.
#[derive(Default)]
struct LoopCloser {
    attempts: Vec<Attempt>,
    gate: ClosureGate,
}

impl LoopCloser {
    /// The closures of the period ending at `now`: the submap of the frames up to `now`
    /// against the start map and the earlier map. Returns whether the graph changed.
    fn close_at(
        &mut self,
        now: f64,
        log: &SessionLog,
        config: &MissionConfig,
        graph: &mut TrajectoryGraph,
        view_bias: &mut ViewBiasCalibration,
    ) -> Result<bool, MissionError> {
        let frame_at = |t: f64| log.frames.iter().position(|f| f.time_s >= t);
        let Some(k) = log.frames.iter().rposition(|f| f.time_s <= now + 1e-9) else {
            return Ok(false);
        };
        let first = frame_at(now - config.submap_window_s).unwrap_or(0);
        let Some(old_end) = frame_at(now - config.submap_window_s - config.loop_closure_gap_s)
        else {
            return Ok(false);
        };
        if old_end < 10 {
            return Ok(false);
        }
        let start_end = start_frames(log, config);
        view_bias.update(log, &graph.poses_in_prior(), now, &config.fusion);
        let fusion = view_bias.fusion(&config.fusion);
        let mut references = Vec::with_capacity(2);
        if start_end > 0 && start_end < first {
            references.push(Reference {
                frames: 0..start_end,
                fixed_frame: Some(0),
                fusion: FusionConfig {
                    min_observations: 1,
                    ..fusion.clone()
                },
            });
        }
        references.push(Reference {
            frames: 0..old_end,
            fixed_frame: None,
            fusion,
        });
        let mut changed = false;
        for reference in &references {
            let closure = close_loop(
                log,
                config,
                graph,
                reference,
                first..k + 1,
                &mut self.attempts,
            )?;
            changed |= self
                .gate
                .submit(closure, &mut self.attempts, graph, config)?;
        }
        Ok(changed)
    }
}

/// Session 1's loop closures while it drives, for its planner: every period the graph is
/// extended with the new frames (and their lander factors), the loops are closed as after
/// the drive, and the latest pose's correction is the planner's frame.
struct OnlineClosures {
    graph: TrajectoryGraph,
    view_bias: ViewBiasCalibration,
    closer: LoopCloser,
    next_s: f64,
    lander_done: usize,
}

impl OnlineClosures {
    fn new(config: &MissionConfig) -> Self {
        Self {
            graph: TrajectoryGraph::new(),
            view_bias: ViewBiasCalibration::new(&config.view_bias),
            closer: LoopCloser::default(),
            next_s: config.relocalize_period_s,
            lander_done: 0,
        }
    }

    /// At the end of each period, when the graph changed: `planner_from_session` of every
    /// frame so far (its optimised pose composed with the inverse of its odometry pose).
    fn advance(
        &mut self,
        log: &SessionLog,
        config: &MissionConfig,
    ) -> Result<Option<Vec<Isometry3<f64>>>, MissionError> {
        let Some(last) = log.frames.last() else {
            return Ok(None);
        };
        if last.time_s + 1e-9 < self.next_s {
            return Ok(None);
        }
        let now = self.next_s;
        self.next_s += config.relocalize_period_s;
        self.graph.extend(log, config)?;
        let mut changed = false;
        if config.lander_factors {
            let frames = self.graph.frames;
            let range = self.lander_done..frames;
            self.lander_done = frames;
            changed = add_lander_factors_optimized(&mut self.graph, log, range, false, config)?;
        }
        changed |= self
            .closer
            .close_at(now, log, config, &mut self.graph, &mut self.view_bias)?;
        if !changed {
            return Ok(None);
        }
        let corrections = (0..self.graph.frames)
            .map_while(|k| self.graph.prior_from_session(log, k))
            .collect();
        Ok(Some(corrections))
    }
}

/// A loop closure the relocalizer accepted, before the gate has confirmed it.
struct Closure {
    /// The earlier frame.
    j: usize,
    /// The recent frame.
    k: usize,
    /// Measured pose of `k` in `j`.
    j_from_k: Isometry3<f64>,
    /// Information (right perturbation of `j_from_k`).
    information: nalgebra::Matrix6<f64>,
    /// Index of its record among the attempts.
    attempt: usize,
}

/// Session 1's consistency gate, as session 2's ([`super::fix_gate`]): a closure enters the
/// graph when the pose it implies for its recent frame agrees with the graph's estimate
/// (a small correction), or with the one implied by the previous closure carried over by
/// the graph's relative motion (two independent submaps asking for the same correction).
/// Single closures off by 1–2° of yaw (few inliers, a submap bent while turning) otherwise
/// entered the graph unchecked (seeds 13 and 17).
#[derive(Default)]
struct ClosureGate {
    pending: Option<Closure>,
}

impl ClosureGate {
    /// Gate a closure the relocalizer accepted, if any; admitted closures are added to the
    /// graph (their attempts in `attempts` marked accepted) and the graph re-optimised.
    /// Returns whether any was admitted.
    fn submit(
        &mut self,
        closure: Option<Closure>,
        attempts: &mut [Attempt],
        graph: &mut TrajectoryGraph,
        config: &MissionConfig,
    ) -> Result<bool, MissionError> {
        let Some(c) = closure else {
            return Ok(false);
        };
        let admitted = if config.gate_relocalizations {
            self.admit(c, graph, config)
        } else {
            vec![c]
        };
        if admitted.is_empty() {
            return Ok(false);
        }
        let kernel = RobustKernel::Cauchy {
            c: config.robust_scale,
        };
        for c in admitted {
            if let Some(record) = attempts.get_mut(c.attempt) {
                record.accepted = true;
                record.refusal = None;
            }
            graph.add_loop_closure(c.j, c.k, c.j_from_k, c.information, kernel)?;
        }
        graph.optimize()?;
        if config.calibrate_odometry {
            graph.calibrate(config, config.calibration_rounds)?;
        }
        Ok(true)
    }

    fn admit(
        &mut self,
        c: Closure,
        graph: &TrajectoryGraph,
        config: &MissionConfig,
    ) -> Vec<Closure> {
        let tolerance = Tolerance::of_gate(config);
        let pose = |k: usize| graph.pose_or_identity(k);
        let implied = |c: &Closure| pose(c.j) * c.j_from_k;
        if agrees(&pose(c.k), &implied(&c), &tolerance) {
            self.pending = None;
            return vec![c];
        }
        if let Some(p) = self.pending.take() {
            let carried = implied(&p) * pose(p.k).inverse() * pose(c.k);
            if agrees(&carried, &implied(&c), &tolerance) {
                return vec![p, c];
            }
        }
        self.pending = Some(c);
        Vec::new()
    }
}

/// The frames taken before the rover moved more than `start_map_max_motion_m` or turned more
/// than `start_map_max_turn_deg` from its
/// start (by odometry): their end index.
fn start_frames(log: &SessionLog, config: &MissionConfig) -> usize {
    let Some(first) = log.ticks.first() else {
        return 0;
    };
    let moved = |t: &crate::sim::session::TickRecord| {
        let d = first.session_from_rover.inverse() * t.session_from_rover;
        d.translation.vector.xy().norm() > config.start_map_max_motion_m
            || d.rotation.euler_angles().2.abs() > config.start_map_max_turn_deg.to_radians()
    };
    log.frames
        .iter()
        .position(|f| log.ticks.get(f.tick).is_none_or(moved))
        .unwrap_or(log.frames.len())
}

/// What a submap is relocalized against.
struct Reference {
    /// Frames whose detections make the map.
    frames: std::ops::Range<usize>,
    /// The earlier end of the factor, if fixed (otherwise nearest the matched landmarks).
    fixed_frame: Option<usize>,
    /// Fusion of this map (the submap's takes the mission's minimum observations).
    fusion: FusionConfig,
}

/// Relocalizes the recent frames' submap against `reference`'s map; records the attempt in
/// `attempts` and returns the closure when the relocalizer accepted it.
fn close_loop(
    log: &SessionLog,
    config: &MissionConfig,
    graph: &TrajectoryGraph,
    reference: &Reference,
    recent: std::ops::Range<usize>,
    attempts: &mut Vec<Attempt>,
) -> Result<Option<Closure>, MissionError> {
    let odometry = graph.poses_in_prior();
    let old = fuse_detections(
        &detections_with_poses(
            log,
            &odometry,
            reference.frames.clone(),
            "session1-old",
            "odom",
        ),
        &reference.fusion,
    );
    let query_fusion = FusionConfig {
        min_observations: config.fusion.min_observations,
        ..reference.fusion.clone()
    };
    let query = fuse_detections(
        &detections_with_poses(log, &odometry, recent.clone(), "session1-recent", "odom"),
        &query_fusion,
    );
    let last = recent.end.saturating_sub(1);
    let mut record = Attempt::pending(
        1,
        log.frames.get(last).map_or(0.0, |f| f.time_s),
        query.len(),
    );
    let reloc = match Relocalizer::new(old.clone(), config.relocalize.clone())
        .and_then(|r| r.relocalize(&query))
    {
        Ok(r) => r,
        Err(e) => {
            record.refusal = Some(format!("error: {e}"));
            attempts.push(record);
            return Ok(None);
        }
    };
    record.inliers = reloc.inliers.len();
    record.yaw_sigma_deg = Some(super::lost_session::yaw_sigma_deg(&reloc.information));
    let Some(old_from_recent) = reloc.prior_from_query else {
        record.refusal = Some(
            reloc
                .refusal
                .as_ref()
                .map_or_else(|| "refused".to_string(), |r| r.to_string()),
        );
        attempts.push(record);
        return Ok(None);
    };
    // the earlier frame nearest the matched landmarks of the old map, and the recent frame
    // nearest the matched landmarks of the submap (least drift relative to them)
    let matched_old = landmark_positions(&old, reloc.inliers.iter().map(|(p, _)| *p));
    let matched_new = landmark_positions(&query, reloc.inliers.iter().map(|(_, q)| *q));
    let j = reference
        .fixed_frame
        .unwrap_or_else(|| frame_nearest(&odometry, reference.frames.clone(), &matched_old));
    let k = frame_nearest(&odometry, recent, &matched_new);
    let j_from_k = odometry[j].inverse() * old_from_recent * odometry[k];
    let truth = log
        .true_motion_between(log.frames[j].tick, log.frames[k].tick)
        .unwrap_or_else(Isometry3::identity);
    let error = truth.inverse() * j_from_k;
    let (error_m, error_deg) = (
        error.translation.vector.norm(),
        error.rotation.angle().to_degrees(),
    );
    record.refusal = Some("not confirmed by the pose graph or the next loop closure".into());
    record.error_m = Some(error_m);
    record.error_deg = Some(error_deg);
    record.error_yaw_deg = Some(error.rotation.euler_angles().2.to_degrees());
    record.wrong = error_m > config.wrong_translation_m || error_deg > config.wrong_rotation_deg;
    let ad = se3::adjoint(&odometry[k]);
    let information =
        ad.transpose() * reloc.information * ad * config.relocalization_information_scale;
    attempts.push(record);
    Ok(Some(Closure {
        j,
        k,
        j_from_k,
        information,
        attempt: attempts.len() - 1,
    }))
}
