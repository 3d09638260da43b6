//! Loop closures of a mapping session: every period, the submap of the recent frames is
//! relocalized against (1) the *start map*, the detections of the frames before the rover
//! moved or turned much (their poses are known almost exactly from the start, so a match
//! there fixes the yaw the odometry lost while turning on the spot), and (2) the map of the
//! frames older than `loop_closures.gap_s` before the submap. Both maps are placed with the
//! current estimate (earlier closures applied, re-optimised after each). An accepted result
//! becomes a between factor from the earlier frame that saw the matched landmarks (frame 0
//! for the start map) to the submap frame that saw its matched landmarks
//! ([`super::submap::anchor_frame`]), once the gate has confirmed it.

use super::fix_gate::{agrees, Tolerance};
use super::frame_log::FrameLog;
use super::relocalization::accepted_answer;
use super::report::{AttemptRecord, AttemptStatus, Confirmation, Measurement};
use super::submap::{anchor_frame, landmark_positions};
use super::trajectory::TrajectoryGraph;
use super::view_bias::ViewBiasCalibration;
use super::{LocalizerConfig, LocalizerError};
use crate::graph::{se3, RobustKernel};
use crate::landmarks::{fuse_detections, FusionConfig};
use crate::relocalize::Relocalizer;
use nalgebra::Isometry3;

/// Every period's loop closures over a whole session, after the drive.
pub fn loop_closures(
    log: &FrameLog,
    config: &LocalizerConfig,
    graph: &mut TrajectoryGraph,
    view_bias: &mut ViewBiasCalibration,
) -> Result<Vec<AttemptRecord>, LocalizerError> {
    let mut closer = LoopCloser::default();
    let end = log.last_t();
    let period = config.schedule.relocalize_period_s;
    let mut t = period;
    while t <= end + 1e-9 {
        closer.close_at(t, log, config, graph, view_bias)?;
        t += period;
    }
    Ok(closer.attempts)
}

/// The loop-closure state carried from one period to the next.
#[derive(Default)]
pub struct LoopCloser {
    /// Every attempt so far.
    pub attempts: Vec<AttemptRecord>,
    gate: ClosureGate,
}

impl LoopCloser {
    /// The closures of the period ending at `now`: the submap of the frames up to `now`
    /// against the start map and the earlier map. Returns whether the graph changed.
    pub fn close_at(
        &mut self,
        now: f64,
        log: &FrameLog,
        config: &LocalizerConfig,
        graph: &mut TrajectoryGraph,
        view_bias: &mut ViewBiasCalibration,
    ) -> Result<bool, LocalizerError> {
        let frame_at = |t: f64| log.frames.iter().position(|f| f.t >= t);
        let Some(k) = log.frames.iter().rposition(|f| f.t <= now + 1e-9) else {
            return Ok(false);
        };
        let window_s = config.submap.window_s;
        let first = frame_at(now - window_s).unwrap_or(0);
        let Some(old_end) = frame_at(now - window_s - config.loop_closures.gap_s) else {
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
            );
            changed |= self
                .gate
                .submit(closure, &mut self.attempts, graph, config)?;
        }
        Ok(changed)
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
    /// Time of the last frame of its submap, s: closures of the same period share their
    /// submap, so they cannot confirm each other.
    submap_t: f64,
}

/// The mapping session's consistency gate, as against a prior map ([`super::fix_gate`]):
/// a closure enters the graph when the pose it implies for its recent frame agrees with the
/// graph's estimate (a small correction), or with the one implied by the previous closure
/// of an earlier period carried over by the graph's relative motion (two independent
/// submaps asking for the same correction). The closures of one period against the start
/// map and the earlier map share their submap, and with it the submap's own bend, so they
/// never confirm each other.
#[derive(Default)]
struct ClosureGate {
    pending: Option<Closure>,
}

impl ClosureGate {
    /// Gate a closure the relocalizer accepted, if any; admitted closures are added to the
    /// graph (their attempts marked accepted) and the graph updated and recalibrated
    /// (incrementally for an online graph). Returns whether any was admitted.
    fn submit(
        &mut self,
        closure: Option<Closure>,
        attempts: &mut [AttemptRecord],
        graph: &mut TrajectoryGraph,
        config: &LocalizerConfig,
    ) -> Result<bool, LocalizerError> {
        let Some(c) = closure else {
            return Ok(false);
        };
        let admitted = if config.gate.enabled {
            self.admit(c, graph, config)
        } else {
            vec![c]
        };
        if admitted.is_empty() {
            return Ok(false);
        }
        let kernel = RobustKernel::Cauchy {
            c: config.factors.robust_scale,
        };
        for c in admitted {
            if let Some(record) = attempts.get_mut(c.attempt) {
                record.status = AttemptStatus::Accepted;
            }
            graph.add_loop_closure(c.j, c.k, c.j_from_k, c.information, kernel)?;
        }
        graph.update()?;
        if config.calibration.enabled {
            graph.recalibrate(config)?;
        }
        Ok(true)
    }

    fn admit(
        &mut self,
        c: Closure,
        graph: &TrajectoryGraph,
        config: &LocalizerConfig,
    ) -> Vec<Closure> {
        let tolerance = Tolerance::of_gate(&config.gate);
        let pose = |k: usize| graph.pose_or_identity(k);
        let implied = |c: &Closure| pose(c.j) * c.j_from_k;
        if agrees(&pose(c.k), &implied(&c), &tolerance) {
            self.pending = None;
            return vec![c];
        }
        if let Some(p) = self.pending.take().filter(|p| p.submap_t < c.submap_t) {
            let carried = implied(&p) * pose(p.k).inverse() * pose(c.k);
            if agrees(&carried, &implied(&c), &tolerance) {
                return vec![p, c];
            }
        }
        self.pending = Some(c);
        Vec::new()
    }
}

/// The frames taken before the rover moved more than `start_map_max_motion_m` or turned
/// more than `start_map_max_turn_deg` from its first frame (by odometry): their end index.
pub fn start_frames(log: &FrameLog, config: &LocalizerConfig) -> usize {
    let Some(first) = log.frames.first() else {
        return 0;
    };
    let limits = &config.loop_closures;
    let moved = |pose: &Isometry3<f64>| {
        let d = first.odom_from_rover.inverse() * pose;
        d.translation.vector.xy().norm() > limits.start_map_max_motion_m
            || d.rotation.euler_angles().2.abs() > limits.start_map_max_turn_deg.to_radians()
    };
    log.frames
        .iter()
        .position(|f| moved(&f.odom_from_rover))
        .unwrap_or(log.frames.len())
}

/// What a submap is relocalized against.
struct Reference {
    /// Frames whose detections make the map.
    frames: std::ops::Range<usize>,
    /// The earlier end of the factor, if fixed (otherwise nearest the matched landmarks).
    fixed_frame: Option<usize>,
    /// Fusion of this map (the submap's takes the configured minimum observations).
    fusion: FusionConfig,
}

/// Relocalizes the recent frames' submap against `reference`'s map; records the attempt in
/// `attempts` and returns the closure when the relocalizer accepted it.
fn close_loop(
    log: &FrameLog,
    config: &LocalizerConfig,
    graph: &TrajectoryGraph,
    reference: &Reference,
    recent: std::ops::Range<usize>,
    attempts: &mut Vec<AttemptRecord>,
) -> Option<Closure> {
    let odometry = graph.poses_in_prior();
    let old_detections =
        log.detections_with_poses(&odometry, reference.frames.clone(), "old", "odom");
    let old = fuse_detections(&old_detections, &reference.fusion);
    let query_fusion = FusionConfig {
        min_observations: config.fusion.min_observations,
        ..reference.fusion.clone()
    };
    let query_detections = log.detections_with_poses(&odometry, recent.clone(), "recent", "odom");
    let query = fuse_detections(&query_detections, &query_fusion);
    let last = recent.end.saturating_sub(1);
    let t = log.frames.get(last).map_or(0.0, |f| f.t);
    let mut record = AttemptRecord::pending(t, last, query.len());
    let answer =
        Relocalizer::new(old.clone(), config.relocalize.clone()).and_then(|r| r.relocalize(&query));
    let Some(reloc) = accepted_answer(&mut record, answer) else {
        attempts.push(record);
        return None;
    };
    let old_from_recent = reloc.prior_from_query;
    // the earlier frame and the recent frame that saw the matched landmarks of the old map
    // and of the submap (least drift relative to them)
    let matched_old = landmark_positions(&old, reloc.inliers.iter().map(|(p, _)| *p));
    let matched_new = landmark_positions(&query, reloc.inliers.iter().map(|(_, q)| *q));
    let radius = query_fusion.cluster_radius_m;
    let j = reference.fixed_frame.unwrap_or_else(|| {
        let frames = reference.frames.clone();
        anchor_frame(&odometry, &old_detections, frames, &matched_old, radius)
    });
    let k = anchor_frame(&odometry, &query_detections, recent, &matched_new, radius);
    let j_from_k = odometry[j].inverse() * old_from_recent * odometry[k];
    record.status = AttemptStatus::Unconfirmed(Confirmation::NextLoopClosure);
    record.measurement = Some(Measurement::Closure { j, k, j_from_k });
    let ad = se3::adjoint(&odometry[k]);
    let information =
        ad.transpose() * reloc.information * ad * config.factors.relocalization_information_scale;
    attempts.push(record);
    Some(Closure {
        j,
        k,
        j_from_k,
        information,
        attempt: attempts.len() - 1,
        submap_t: t,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix6, Vector3};
    use segloc_maps::frames::StreamFrame;

    /// A graph of 20 frames standing still at the odometry's origin.
    fn still_graph(config: &LocalizerConfig) -> TrajectoryGraph {
        let mut log = FrameLog::default();
        for k in 0..20 {
            log.push(&StreamFrame::new(k as f64, Isometry3::identity()));
        }
        let mut graph = TrajectoryGraph::new();
        graph.extend(&log, config).unwrap();
        graph
    }

    /// A closure of frame 15 on frame 2 asking for a 1 m correction (the graph says 0).
    fn closure(attempt: usize, submap_t: f64) -> Closure {
        Closure {
            j: 2,
            k: 15,
            j_from_k: Isometry3::new(Vector3::new(1.0, 0.0, 0.0), Vector3::zeros()),
            information: Matrix6::identity(),
            attempt,
            submap_t,
        }
    }

    #[test]
    fn closures_of_one_submap_do_not_confirm_each_other() {
        let config = LocalizerConfig::default();
        let graph = still_graph(&config);
        // the start map's and the earlier map's closures of the same period
        let mut gate = ClosureGate::default();
        assert!(gate.admit(closure(0, 80.0), &graph, &config).is_empty());
        assert!(gate.admit(closure(1, 80.0), &graph, &config).is_empty());
        // the next period's submap asks for the same correction: it confirms the pending one
        let admitted = gate.admit(closure(2, 90.0), &graph, &config);
        let ids: Vec<usize> = admitted.iter().map(|c| c.attempt).collect();
        assert_eq!(ids, vec![1, 2]);
    }
}
