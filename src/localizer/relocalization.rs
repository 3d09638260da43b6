//! Relocalization against a prior map while driving: every period, the submap of the
//! recent detections (placed by the bias-corrected odometry) is relocalized against the
//! prior map; an accepted result is anchored at the frame nearest the landmarks it matched
//! and waits for the consistency gate ([`super::fix_gate`]) to confirm it.

use super::fix_gate::{agrees, Tolerance};
use super::frame_log::FrameLog;
use super::report::{AttemptRecord, AttemptRefusal, AttemptStatus, Confirmation, Measurement};
use super::submap::{anchor_frame, landmark_positions};
use super::trajectory::TrajectoryGraph;
use super::LocalizerConfig;
use crate::graph::se3;
use crate::landmarks::{fuse_detections, FusionConfig};
use crate::relocalize::{Accepted, Relocalization, RelocalizeError, Relocalizer};
use nalgebra::{Isometry3, Matrix6};

/// A relocalization the relocalizer accepted, before the gate has confirmed it.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// The frame it is anchored at.
    pub k: usize,
    /// Its measured pose in the prior map.
    pub prior_from_rover: Isometry3<f64>,
    /// Information of the measurement (right perturbation of `prior_from_rover`).
    pub information: Matrix6<f64>,
    /// Index of its record among the attempts.
    pub attempt: usize,
}

/// The state of the consistency gate of relocalizations against a prior map.
#[derive(Debug, Default)]
pub struct PriorGate {
    /// The last result that was not confirmed, waiting for the next one.
    pending: Option<Candidate>,
    /// The latest frame with a relocalization in the graph.
    pub last_fix_frame: Option<usize>,
}

impl PriorGate {
    /// The candidates to add to the graph now (none, this one, or the pending one and this
    /// one).
    pub fn admit(
        &mut self,
        c: Candidate,
        graph: &TrajectoryGraph,
        config: &LocalizerConfig,
    ) -> Vec<Candidate> {
        if !config.gate.enabled {
            return vec![c];
        }
        let tolerance = Tolerance::of_gate(&config.gate);
        let pose = |k: usize| graph.pose_or_identity(k);
        let mut informed = false;
        if let (Some(odom_from_prior), Some(last)) = (graph.odom_from_prior(), self.last_fix_frame)
        {
            let predicted = odom_from_prior.inverse() * pose(c.k);
            let (sigma_m, sigma_yaw) = graph.odometry_sigma(last, c.k, &config.odometry);
            let widened = tolerance.widened(sigma_m, sigma_yaw, 3.0);
            informed = widened.yaw_rad <= config.gate.max_prediction_yaw_deg.to_radians();
            if informed && agrees(&predicted, &c.prior_from_rover, &widened) {
                self.pending = None;
                return vec![c];
            }
        }
        if let Some(p) = self.pending.take() {
            let carried = p.prior_from_rover * pose(p.k).inverse() * pose(c.k);
            let (sigma_m, sigma_yaw) = graph.odometry_sigma(p.k, c.k, &config.odometry);
            // with no fix yet the odometry between the two is still uncalibrated (its
            // yaw-rate error bends both submaps alike while the rover turns on the spot); with
            // no informative prediction the pair alone vouches for itself: either way the pair
            // must agree more tightly than when it overrules the graph
            let n_sigma = if informed {
                3.0
            } else {
                config.gate.bootstrap_sigmas
            };
            if agrees(
                &carried,
                &c.prior_from_rover,
                &tolerance.widened(sigma_m, sigma_yaw, n_sigma),
            ) {
                return vec![p, c];
            }
        }
        self.pending = Some(c);
        Vec::new()
    }
}

/// The first frame of the submap ending at frame `k`: `window_s` back, but stopping once
/// the rover turned `max_turn_deg` in it (and spanning at least `min_window_s`).
fn submap_start(log: &FrameLog, k: usize, config: &LocalizerConfig) -> usize {
    let now_s = log.frames[k].t;
    let first = log
        .frames
        .iter()
        .position(|f| f.t >= now_s - config.submap.window_s)
        .unwrap_or(0);
    // odometry's yaw error grows with the angle turned
    let mut turned = 0.0;
    let mut j = k;
    while j > first {
        turned += log.frames[j].step.turned_abs_rad;
        if turned > config.submap.max_turn_deg.to_radians()
            && now_s - log.frames[j].t >= config.submap.min_window_s
        {
            break;
        }
        j -= 1;
    }
    j
}

/// The submap's poses in the odometry frame: the odometry chain of `first..=k` with the
/// current bias estimate taken out, placed at the first frame's odometry pose (only the
/// shape matters to the relocalizer); roll and pitch stay the frames' own, which the IMU's
/// gravity fixes (composing the odometry's tilt would let it drift). Index `i` is frame
/// `i` (frames before `first` hold the identity).
fn submap_poses(
    log: &FrameLog,
    graph: &TrajectoryGraph,
    first: usize,
    k: usize,
) -> Vec<Isometry3<f64>> {
    let start = log.frames[first].odom_from_rover;
    let mut odometry = vec![Isometry3::identity(); first];
    for (i, p) in graph
        .corrected_odometry(first..k + 1)
        .into_iter()
        .enumerate()
    {
        let p = start * p;
        let (roll, pitch, _) = se3::rpy_from_rotation(&log.frames[first + i].attitude.rotation);
        let (_, _, yaw) = se3::rpy_from_rotation(&p.rotation);
        odometry.push(Isometry3::from_parts(
            p.translation,
            se3::rotation_from_rpy(roll, pitch, yaw),
        ));
    }
    odometry
}

/// One relocalization of the submap ending at the latest frame against the prior map;
/// records the attempt in `attempts` and returns the result when the relocalizer accepted
/// it (recorded as awaiting confirmation by the gate).
pub fn attempt(
    log: &FrameLog,
    config: &LocalizerConfig,
    relocalizer: &Relocalizer,
    graph: &TrajectoryGraph,
    attempts: &mut Vec<AttemptRecord>,
) -> Option<Candidate> {
    let k = log.len().checked_sub(1)?;
    let first = submap_start(log, k, config);
    let odometry = submap_poses(log, graph, first, k);
    let set = log.detections_with_poses(&odometry, first..k + 1, "query", "odom");
    // placed by a barely calibrated odometry: the pose error, not the stereo's, dominates
    let fusion = FusionConfig {
        pose_sigma_m: config.submap.pose_sigma_m,
        ..config.fusion.clone()
    };
    let query = fuse_detections(&set, &fusion);
    let mut record = AttemptRecord::pending(log.frames[k].t, k, query.len());
    let answer = relocalizer.relocalize(&query);
    let Some(reloc) = accepted_answer(&mut record, answer) else {
        attempts.push(record);
        return None;
    };
    // the submap was built in the session's odometry frame
    let prior_from_odom = reloc.prior_from_query;
    if let Some(reason) = undetermined_yaw(&record, config) {
        record.status = AttemptStatus::Refused(reason);
        attempts.push(record);
        return None;
    }
    // anchor: a frame that saw the matched landmarks, near them (least drift relative to them)
    let matched = landmark_positions(&query, reloc.inliers.iter().map(|(_, q)| *q));
    let k = anchor_frame(
        &odometry,
        &set,
        first..k + 1,
        &matched,
        fusion.cluster_radius_m,
    );
    let odom_from_rover = odometry[k];
    let prior_from_rover = prior_from_odom * odom_from_rover;
    record.status = AttemptStatus::Unconfirmed(Confirmation::NextRelocalization);
    record.measurement = Some(Measurement::Prior {
        k,
        prior_from_rover,
    });
    attempts.push(record);
    // information on the right perturbation of prior_from_odom → of prior_from_rover
    let ad = se3::adjoint(&odom_from_rover);
    let information =
        ad.transpose() * reloc.information * ad * config.factors.relocalization_information_scale;
    Some(Candidate {
        k,
        prior_from_rover,
        information,
        attempt: attempts.len() - 1,
    })
}

/// Why an accepted relocalization cannot be trusted to the degree in yaw (its yaw σ over
/// the gate's `max_yaw_sigma_deg`), when the gate is on.
fn undetermined_yaw(record: &AttemptRecord, config: &LocalizerConfig) -> Option<AttemptRefusal> {
    let sigma_deg = record.yaw_sigma_deg.unwrap_or(f64::INFINITY);
    (config.gate.enabled && sigma_deg > config.gate.max_yaw_sigma_deg).then_some(
        AttemptRefusal::YawUndetermined {
            sigma_deg,
            max_deg: config.gate.max_yaw_sigma_deg,
        },
    )
}

/// The relocalizer's answer recorded in `record` (inliers, yaw σ, and the refusal when it
/// refused or failed); the accepted answer when it accepted.
pub fn accepted_answer(
    record: &mut AttemptRecord,
    answer: Result<Relocalization, RelocalizeError>,
) -> Option<Accepted> {
    let reloc = match answer {
        Ok(r) => r,
        Err(e) => {
            record.status = AttemptStatus::Refused(AttemptRefusal::Error(e.to_string()));
            return None;
        }
    };
    match reloc.outcome {
        Ok(accepted) => {
            record.inliers = accepted.inliers.len();
            record.yaw_sigma_deg = Some(yaw_sigma_deg(&accepted.information));
            Some(accepted)
        }
        Err(refusal) => {
            record.inliers = 0;
            // a refusal carries no information: its yaw is unknown
            record.yaw_sigma_deg = Some(f64::INFINITY);
            record.status = AttemptStatus::Refused(AttemptRefusal::Relocalizer(refusal));
            None
        }
    }
}

/// Standard deviation of the yaw (rotation about z, tangent index 2) implied by an
/// information matrix, degrees (infinite when it is singular).
pub fn yaw_sigma_deg(information: &Matrix6<f64>) -> f64 {
    information
        .try_inverse()
        .map(|c| c[(2, 2)])
        .filter(|v| v.is_finite() && *v >= 0.0)
        .map_or(f64::INFINITY, |v| v.sqrt().to_degrees())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::localizer::frame_log::FrameLog;
    use nalgebra::Vector3;
    use segloc_maps::frames::StreamFrame;

    fn pose(x: f64, y: f64, yaw_deg: f64) -> Isometry3<f64> {
        Isometry3::new(Vector3::new(x, y, 0.0), Vector3::z() * yaw_deg.to_radians())
    }

    fn candidate(k: usize, prior_from_rover: Isometry3<f64>) -> Candidate {
        Candidate {
            k,
            prior_from_rover,
            information: Matrix6::identity() * 1e4,
            attempt: k,
        }
    }

    #[test]
    fn the_gate_stops_a_wrong_fix_and_admits_two_that_agree() {
        let config = LocalizerConfig {
            online_graph: crate::localizer::config::OnlineGraphConfig::fast(),
            ..LocalizerConfig::default()
        };
        // the batch graph, and the online one updated incrementally
        gate_stops_a_wrong_fix(TrajectoryGraph::new());
        gate_stops_a_wrong_fix(TrajectoryGraph::online(&config));
    }

    fn gate_stops_a_wrong_fix(mut graph: TrajectoryGraph) {
        // 40 frames straight along x, 0.3 m apart; the prior frame is the odometry frame
        // moved by (2, 1) m
        let mut log = FrameLog::default();
        for k in 0..40 {
            log.push(&StreamFrame::new(k as f64, pose(0.3 * k as f64, 0.0, 0.0)));
        }
        let config = LocalizerConfig::default();
        graph.extend(&log, &config).unwrap();
        let prior_from_odom = pose(2.0, 1.0, 0.0);
        let truth = |k: usize| prior_from_odom * log.frames[k].odom_from_rover;
        let mut gate = PriorGate::default();
        // a first result waits for confirmation; the next one agrees: both enter
        assert!(gate
            .admit(candidate(10, truth(10)), &graph, &config)
            .is_empty());
        let admitted = gate.admit(candidate(20, truth(20)), &graph, &config);
        assert_eq!(admitted.len(), 2);
        for c in admitted {
            graph
                .add_relocalization(
                    c.k,
                    c.prior_from_rover,
                    c.information,
                    crate::graph::RobustKernel::None,
                )
                .unwrap();
        }
        gate.last_fix_frame = Some(20);
        graph.update().unwrap();
        graph.recalibrate(&config).unwrap();
        // a result 30 cm and 2° off the graph's prediction is held back
        let wrong = pose(0.3, 0.0, 2.0) * truth(30);
        assert!(gate.admit(candidate(30, wrong), &graph, &config).is_empty());
        // a good one is admitted alone
        assert_eq!(
            gate.admit(candidate(31, truth(31)), &graph, &config).len(),
            1
        );
    }

    #[test]
    fn a_loose_prediction_cannot_confirm_a_fix_alone() {
        // one fix at frame 10, then 400 frames of driving: the odometry's yaw σ since then
        // widens the prediction's tolerance past `max_prediction_yaw_deg`
        let mut log = FrameLog::default();
        for k in 0..420 {
            log.push(&StreamFrame::new(k as f64, pose(0.3 * k as f64, 0.0, 0.0)));
        }
        let mut config = LocalizerConfig::default();
        // a cap the 390 frames since the fix exceed
        config.gate.max_prediction_yaw_deg = 1.0;
        let mut graph = TrajectoryGraph::new();
        graph.extend(&log, &config).unwrap();
        let truth = |k: usize| pose(2.0, 1.0, 0.0) * log.frames[k].odom_from_rover;
        graph
            .add_relocalization(
                10,
                truth(10),
                Matrix6::identity() * 1e4,
                crate::graph::RobustKernel::None,
            )
            .unwrap();
        graph.optimize().unwrap();
        let mut gate = PriorGate {
            last_fix_frame: Some(10),
            ..PriorGate::default()
        };
        let (_, sigma_yaw) = graph.odometry_sigma(10, 400, &config.odometry);
        assert!(
            config.gate.yaw_deg + 3.0 * sigma_yaw.to_degrees() > config.gate.max_prediction_yaw_deg
        );
        // even an exact fix waits for a second one, which must agree tightly
        assert!(gate
            .admit(candidate(400, truth(400)), &graph, &config)
            .is_empty());
        let off = pose(0.0, 0.0, 0.8) * truth(410);
        assert!(gate.admit(candidate(410, off), &graph, &config).is_empty());
        assert!(gate
            .admit(candidate(415, truth(415)), &graph, &config)
            .is_empty());
        assert_eq!(
            gate.admit(candidate(419, truth(419)), &graph, &config)
                .len(),
            2
        );
    }

    #[test]
    fn a_fix_whose_yaw_the_submap_cannot_tell_is_refused() {
        let config = LocalizerConfig::default();
        let mut record = AttemptRecord::pending(0.0, 0, 10);
        record.yaw_sigma_deg = Some(config.gate.max_yaw_sigma_deg * 0.9);
        assert_eq!(undetermined_yaw(&record, &config), None);
        record.yaw_sigma_deg = Some(config.gate.max_yaw_sigma_deg * 1.1);
        let reason = undetermined_yaw(&record, &config).unwrap();
        assert_eq!(AttemptStatus::Refused(reason).code(), "yaw_undetermined");
        record.yaw_sigma_deg = None;
        assert!(undetermined_yaw(&record, &config).is_some());
    }
}
