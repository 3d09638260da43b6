//! A simulated session as the localizer's input, and the truth it is scored against: each
//! camera frame of a [`SessionLog`] becomes a [`StreamFrame`] (the odometry pose, whose roll
//! and pitch already come from the IMU's gravity, the odometry's path since the previous
//! frame, the detections and the lander points); the true poses stay here.

use crate::localizer::{AttemptRecord, Localizer, LocalizerError, LocalizerEvent, Measurement};
use crate::sim::session::SessionLog;
use nalgebra::Isometry3;
use segloc_maps::frames::{FrameDetection, FramePath, StreamFrame};
use segloc_maps::DetectionSet;

use super::Attempt;

/// Frame `k` of `log` as the localizer's input, with `gravity` the IMU's gravity (the
/// mission leaves it out: its odometry pose carries the IMU's roll and pitch already).
pub fn frame_input(log: &SessionLog, k: usize, gravity: bool) -> Option<StreamFrame> {
    let f = log.frames.get(k)?;
    let tick = log.ticks.get(f.tick)?;
    let path = k
        .checked_sub(1)
        .and_then(|j| log.frames.get(j))
        .map(|prev| path_between(log, prev.tick, f.tick));
    Some(StreamFrame {
        t: f.time_s,
        odom_from_rover: tick.session_from_rover,
        gravity_rover: gravity.then_some(tick.gravity_rover),
        detections: f
            .boulders
            .iter()
            .map(|b| FrameDetection {
                p_rover: b.p_rover,
                size_m: Some(2.0 * b.radius_m),
                cov_rover: None,
            })
            .collect(),
        lander_points_rover: f.lander_points_rover.clone(),
        path,
        step_cov: None,
    })
}

/// The odometry's path between two ticks: per-tick sums of the measured increments.
fn path_between(log: &SessionLog, a: usize, b: usize) -> FramePath {
    let mut path = FramePath {
        distance_m: 0.0,
        turned_rad: 0.0,
        turned_abs_rad: 0.0,
    };
    for t in (a..b).filter_map(|k| log.ticks.get(k + 1)) {
        let yaw = t.vo_prev_from_cur.rotation.euler_angles().2;
        path.distance_m += t.vo_prev_from_cur.translation.vector.norm();
        path.turned_rad += yaw;
        path.turned_abs_rad += yaw.abs();
    }
    path
}

/// The boulder detections of frames `frames` placed with `poses` (one per frame of the
/// log, `x_from_rover`), as a detection set in frame `frame_name`.
pub fn detections_with_poses(
    log: &SessionLog,
    poses: &[Isometry3<f64>],
    frames: std::ops::Range<usize>,
    session: &str,
    frame_name: &str,
) -> DetectionSet {
    let mut set = DetectionSet::new(session, frame_name, true);
    for k in frames {
        let (Some(f), Some(pose)) = (log.frames.get(k), poses.get(k)) else {
            continue;
        };
        set.detections.extend(f.detections(pose));
    }
    set
}

/// Root-mean-square position error of `world_from_rover` estimates (one per frame)
/// against the truth.
pub fn rmse_m(log: &SessionLog, world_from_rover: &[Isometry3<f64>]) -> f64 {
    rmse_from_m(log, world_from_rover, 0)
}

/// [`rmse_m`] over the frames from `first` on.
pub fn rmse_from_m(log: &SessionLog, world_from_rover: &[Isometry3<f64>], first: usize) -> f64 {
    let mut sum = 0.0;
    let mut n = 0usize;
    for (f, est) in log.frames.iter().zip(world_from_rover).skip(first) {
        if let Some(t) = log.ticks.get(f.tick) {
            sum += (est.translation.vector - t.world_from_rover.translation.vector).norm_squared();
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

/// The odometry-only estimate of every frame, aligned with the true start
/// (`world_from_session` at the start applied to the session frame).
pub fn odometry_in_world(log: &SessionLog) -> Vec<Isometry3<f64>> {
    let world_from_session = log.world_from_session();
    log.frames
        .iter()
        .filter_map(|f| log.ticks.get(f.tick))
        .map(|t| world_from_session * t.session_from_rover)
        .collect()
}

/// Feed `localizer` the frames of `log` from `*pushed` on; whether it re-optimised.
pub fn push_new_frames(
    localizer: &mut Localizer,
    log: &SessionLog,
    pushed: &mut usize,
) -> Result<bool, LocalizerError> {
    let mut reoptimized = false;
    while let Some(frame) = frame_input(log, *pushed, false) {
        let out = localizer.push_frame(&frame)?;
        reoptimized |= out.events.contains(&LocalizerEvent::Reoptimized);
        *pushed += 1;
    }
    Ok(reoptimized)
}

/// Every attempt of session `session` scored against the truth of `log`.
pub fn scored_attempts(
    session: usize,
    records: &[AttemptRecord],
    log: &SessionLog,
    config: &super::MissionConfig,
) -> Vec<Attempt> {
    let wrong = (config.wrong_translation_m, config.wrong_rotation_deg);
    records
        .iter()
        .map(|a| scored_attempt(session, a, log, wrong))
        .collect()
}

/// A localizer's attempt scored against the truth of `log`: the error of what it measured
/// (a fix's pose in the world, or a loop closure's relative motion), and whether it is
/// wrong by the mission's thresholds.
pub fn scored_attempt(
    session: usize,
    record: &AttemptRecord,
    log: &SessionLog,
    wrong: (f64, f64),
) -> Attempt {
    let mut attempt = Attempt::pending(session, record.t, record.query_landmarks);
    attempt.accepted = record.accepted();
    attempt.refusal = record.refusal().cloned();
    attempt.inliers = record.inliers;
    attempt.yaw_sigma_deg = record.yaw_sigma_deg;
    let truth_of = |k: usize| log.frames.get(k).and_then(|f| log.ticks.get(f.tick));
    let error = match record.measurement {
        Some(Measurement::Prior {
            k,
            prior_from_rover,
        }) => truth_of(k).map(|t| t.world_from_rover.inverse() * prior_from_rover),
        Some(Measurement::Closure { j, k, j_from_k }) => {
            let truth = match (log.frames.get(j), log.frames.get(k)) {
                (Some(a), Some(b)) => log.true_motion_between(a.tick, b.tick),
                _ => None,
            };
            Some(truth.unwrap_or_else(Isometry3::identity).inverse() * j_from_k)
        }
        None => None,
    };
    if let Some(error) = error {
        let error_m = error.translation.vector.norm();
        let error_deg = error.rotation.angle().to_degrees();
        attempt.error_m = Some(error_m);
        attempt.error_deg = Some(error_deg);
        attempt.error_yaw_deg = Some(error.rotation.euler_angles().2.to_degrees());
        attempt.wrong = error_m > wrong.0 || error_deg > wrong.1;
    }
    attempt
}
