//! The real LunarLoc traverses replayed as streams through the online
//! [`crate::localizer::Localizer`] (`segloc eval stream`).
//!
//! Each query traverse becomes a drive of [`StreamFrame`]s, one per frame with detections in
//! the traverse's cadence (every 20th simulator frame on most traverses, every 4th or 6th on
//! some), `t` = simulator frame / 20 s:
//!
//! - the true pose: the rover's position, its heading along the direction of travel over
//!   ±1 s of the 20 Hz positions (held while the rover stands or turns on the spot), roll and
//!   pitch 0 — the traverses give no orientation;
//! - the frame's detections, world-frame centroids, moved into that true rover frame;
//! - the odometry: the true relative motions with a scale error, a yaw drift per metre and a
//!   seeded yaw random walk ([`DriftConfig`]), chained from a seeded random pose;
//! - gravity (0, 0, −1.62) m/s², and no odometry path (the localizer derives it).
//!
//! Its prior is another traverse's map fused in the world frame as `segloc map build` fuses
//! a traverse: the LunarLoc world frame is the prior map's frame, so the localizer's
//! `prior_from_rover` is compared with the true `world_from_rover` directly.

use super::lunarloc::{common_landmarks, PAPER_PAIRS, TRAVERSES};
use super::{transform_error, traverse_path};
use crate::field_error::FieldError;
use crate::landmarks::{fuse_detections, FusionConfig};
use crate::localizer::odometry_bias::OdometryBias;
use crate::localizer::{Localizer, LocalizerConfig, LocalizerError, Measurement, SessionResult};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use segloc_maps::frames::{FrameDetection, StreamFrame};
use segloc_maps::{read_lunarloc_traverse, MapError, ObjectMap, Traverse};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The simulator's frame rate, Hz (a traverse row's time is its frame over this).
pub const SIM_HZ: f64 = 20.0;

/// Half the time span over which the direction of travel gives the heading, s.
pub const HEADING_HALF_SPAN_S: f64 = 1.0;

/// Horizontal motion over the heading's time span below which the rover counts as
/// stopped (the previous heading is held), m.
pub const STOPPED_M: f64 = 0.02;

/// Lunar gravity, m/s², as the IMU reports it (down, rover frame).
pub const LUNAR_GRAVITY_MPS2: f64 = 1.62;

/// An accepted fix farther than this from the true pose of its frame is wrong, m.
pub const WRONG_FIX_M: f64 = 0.10;
/// See [`WRONG_FIX_M`] (degrees).
pub const WRONG_FIX_DEG: f64 = 1.0;

/// A frame sees the prior map when one of its detections lies this close to one of the
/// prior map's landmarks (the fusion's default cluster radius), m.
pub const SEES_PRIOR_M: f64 = 0.2;

/// The odometry's errors in a replayed drive.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriftConfig {
    /// Yaw random walk, 1 σ, radians per √metre driven.
    pub yaw_walk_rad_per_sqrt_m: f64,
    /// Yaw drift, degrees per 10 m driven (counter-clockwise positive).
    pub yaw_drift_deg_per_10m: f64,
    /// Scale error of the distance driven, fraction (0.01: 1 % too long).
    pub scale_error: f64,
}

impl Default for DriftConfig {
    fn default() -> Self {
        Self {
            yaw_walk_rad_per_sqrt_m: 0.0005,
            yaw_drift_deg_per_10m: 1.0,
            scale_error: 0.01,
        }
    }
}

impl DriftConfig {
    /// Check the values are finite (and the walk non-negative, the scale above −1).
    pub fn validate(&self) -> Result<(), FieldError> {
        let bad = |field: &str, value: f64, rule: &str| {
            FieldError::new(field, format!("must be {rule}, got {value}")).within("drift")
        };
        let walk = self.yaw_walk_rad_per_sqrt_m;
        if !(walk.is_finite() && walk >= 0.0) {
            return Err(bad("yaw_walk_rad_per_sqrt_m", walk, "a finite number ≥ 0"));
        }
        if !self.yaw_drift_deg_per_10m.is_finite() {
            return Err(bad(
                "yaw_drift_deg_per_10m",
                self.yaw_drift_deg_per_10m,
                "a finite number",
            ));
        }
        if !(self.scale_error.is_finite() && self.scale_error > -1.0) {
            return Err(bad(
                "scale_error",
                self.scale_error,
                "a finite number above -1",
            ));
        }
        Ok(())
    }
}

/// A query traverse as the localizer's input, with the truth it is scored against.
#[derive(Clone, Debug)]
pub struct Drive {
    /// Traverse number.
    pub traverse: usize,
    /// The frames, in time order.
    pub frames: Vec<StreamFrame>,
    /// True `world_from_rover` of each frame.
    pub truth: Vec<Isometry3<f64>>,
    /// Simulator frames between two stream frames.
    pub frame_step: u64,
    /// Horizontal distance driven, m.
    pub distance_m: f64,
    /// The drive's odometry (`world_from_rover`, aligned with the truth at the first frame)
    /// with its deterministic drift removed (no yaw drift, no scale error), its random walk
    /// kept: what a perfect calibration of the odometry would leave.
    pub calibrated_odometry: Vec<Isometry3<f64>>,
}

/// The ten ordered pairs of the LunarLoc paper: each of [`PAPER_PAIRS`] with the first as
/// the prior and the second as the query, then the reverse direction.
pub fn paper_pairs_both_ways() -> Vec<(usize, usize)> {
    let forward = PAPER_PAIRS.iter().copied();
    forward
        .clone()
        .chain(forward.map(|(a, b)| (b, a)))
        .collect()
}

/// Every ordered pair (prior, query) of distinct traverses among `maps` (world-frame maps)
/// that share at least one boulder ([`common_landmarks`]).
pub fn sharing_pairs(maps: &BTreeMap<usize, ObjectMap>) -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    for (&a, map_a) in maps {
        for (&b, map_b) in maps.range(a + 1..) {
            if common_landmarks(map_a, map_b) > 0 {
                pairs.push((a, b));
                pairs.push((b, a));
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Simulator frames between consecutive detection frames: the smallest gap between two
/// frames with detections (20 when there are fewer than two).
pub fn detection_step(traverse: &Traverse) -> u64 {
    let with: Vec<u64> = traverse
        .frames
        .iter()
        .filter(|f| !f.boulders.is_empty())
        .map(|f| f.frame)
        .collect();
    with.windows(2)
        .map(|w| w[1].saturating_sub(w[0]))
        .filter(|&d| d > 0)
        .min()
        .unwrap_or(20)
}

/// Indices of the traverse's rows that become stream frames: every row in the detection
/// cadence ([`detection_step`], in phase with the first detection), from the first
/// detection to the end, with or without detections.
pub fn stream_rows(traverse: &Traverse) -> Vec<usize> {
    let step = detection_step(traverse);
    let Some(first) = traverse.frames.iter().position(|f| !f.boulders.is_empty()) else {
        return Vec::new();
    };
    let phase = traverse.frames[first].frame % step;
    (first..traverse.frames.len())
        .filter(|&i| traverse.frames[i].frame % step == phase)
        .collect()
}

/// The heading (yaw, radians) of the direction of travel at every row of `rows`: the
/// horizontal displacement over ±[`HEADING_HALF_SPAN_S`] of the 20 Hz positions; while the
/// rover moves less than [`STOPPED_M`] over that span the previous heading is held (before
/// the first motion: the first heading; a traverse that never moves: 0).
pub fn headings(traverse: &Traverse, rows: &[usize]) -> Vec<f64> {
    let frames = &traverse.frames;
    let span = (HEADING_HALF_SPAN_S * SIM_HZ).round() as u64;
    let row_at = |frame: u64| {
        frames
            .partition_point(|f| f.frame < frame)
            .min(frames.len().saturating_sub(1))
    };
    let raw: Vec<Option<f64>> = rows
        .iter()
        .map(|&i| {
            let f = frames[i].frame;
            let (a, b) = (row_at(f.saturating_sub(span)), row_at(f + span));
            let d = frames[b].rover_position - frames[a].rover_position;
            (d.xy().norm() >= STOPPED_M).then(|| d.y.atan2(d.x))
        })
        .collect();
    let mut held = raw.iter().flatten().next().copied().unwrap_or(0.0);
    raw.iter()
        .map(|h| {
            if let Some(h) = h {
                held = *h;
            }
            held
        })
        .collect()
}

/// The odometry of a drive: the true relative motions between consecutive `truth` poses,
/// each with the distance scaled by `1 + scale_error` and the yaw turned by the drift per
/// metre plus a random walk, chained from `start`.
pub fn drifted_odometry(
    truth: &[Isometry3<f64>],
    drift: &DriftConfig,
    start: Isometry3<f64>,
    rng: &mut ChaCha8Rng,
) -> Vec<Isometry3<f64>> {
    let drift_rad_per_m = drift.yaw_drift_deg_per_10m.to_radians() / 10.0;
    let mut odometry = Vec::with_capacity(truth.len());
    let mut pose = start;
    for (k, now) in truth.iter().enumerate() {
        if let Some(before) = k.checked_sub(1).map(|j| truth[j]) {
            let step = before.inverse() * now;
            let distance = step.translation.vector.norm();
            let noise: f64 = StandardNormal.sample(rng);
            let yaw_error = drift_rad_per_m * distance
                + drift.yaw_walk_rad_per_sqrt_m * distance.sqrt() * noise;
            let measured = Isometry3::from_parts(
                Translation3::from(step.translation.vector * (1.0 + drift.scale_error)),
                step.rotation * UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_error),
            );
            pose *= measured;
        }
        odometry.push(pose);
    }
    odometry
}

/// A random start of the odometry frame: any yaw, ±20 m in x and y, ±1 m in z (roll and
/// pitch 0: the odometry is gravity-aligned like the truth).
fn random_start(rng: &mut ChaCha8Rng) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(
            rng.random_range(-20.0..20.0),
            rng.random_range(-20.0..20.0),
            rng.random_range(-1.0..1.0),
        ),
        UnitQuaternion::from_euler_angles(
            0.0,
            0.0,
            rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
        ),
    )
}

/// Traverse `number` replayed as a drive (see the [module docs](self)); `seed` draws the
/// odometry's start and random walk.
pub fn drive_from_traverse(
    number: usize,
    traverse: &Traverse,
    drift: &DriftConfig,
    seed: u64,
) -> Drive {
    let rows = stream_rows(traverse);
    let yaws = headings(traverse, &rows);
    let truth: Vec<Isometry3<f64>> = rows
        .iter()
        .zip(&yaws)
        .map(|(&i, &yaw)| {
            Isometry3::from_parts(
                Translation3::from(traverse.frames[i].rover_position.coords),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            )
        })
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (number as u64).wrapping_mul(0x9E37_79B9));
    let start = random_start(&mut rng);
    let walk_only = DriftConfig {
        yaw_drift_deg_per_10m: 0.0,
        scale_error: 0.0,
        ..*drift
    };
    let calibrated_odometry = drifted_odometry(&truth, &walk_only, truth[0], &mut rng.clone());
    let odometry = drifted_odometry(&truth, drift, start, &mut rng);
    let frames = rows
        .iter()
        .zip(truth.iter().zip(&odometry))
        .map(|(&i, (world_from_rover, odom_from_rover))| {
            let row = &traverse.frames[i];
            let rover_from_world = world_from_rover.inverse();
            StreamFrame {
                detections: row
                    .boulders
                    .iter()
                    .map(|p: &Point3<f64>| FrameDetection {
                        p_rover: rover_from_world * p,
                        size_m: None,
                        cov_rover: None,
                    })
                    .collect(),
                gravity_rover: Some(Vector3::new(0.0, 0.0, -LUNAR_GRAVITY_MPS2)),
                ..StreamFrame::new(row.frame as f64 / SIM_HZ, *odom_from_rover)
            }
        })
        .collect();
    let distance_m = truth
        .windows(2)
        .map(|w| {
            (w[1].translation.vector - w[0].translation.vector)
                .xy()
                .norm()
        })
        .sum();
    Drive {
        traverse: number,
        frames,
        truth,
        frame_step: detection_step(traverse),
        distance_m,
        calibrated_odometry,
    }
}

/// An accepted fix: its measured pose against the truth of its frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FixScore {
    /// Index of the attempt.
    pub attempt: usize,
    /// The frame the fix is anchored at.
    pub frame: usize,
    /// Time of the attempt, s.
    pub t: f64,
    /// Inlier associations.
    pub inliers: usize,
    /// Yaw standard deviation the relocalizer's information matrix implies, degrees.
    pub yaw_sigma_deg: Option<f64>,
    /// Translation error, m.
    pub error_m: f64,
    /// Rotation error, degrees.
    pub error_deg: f64,
    /// Over [`WRONG_FIX_M`] or [`WRONG_FIX_DEG`].
    pub wrong: bool,
}

/// Position RMSE of the estimates over a set of frames, m (`None` without such frames).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Rmse {
    /// Frames in the set.
    pub frames: usize,
    /// The online `prior_from_rover` of `push_frame` (what the rover knew at the time).
    pub online_m: Option<f64>,
    /// The final smoothed poses (`SessionResult::poses`).
    pub smoothed_m: Option<f64>,
    /// The same before the boulder adjustment.
    pub before_adjustment_m: Option<f64>,
    /// The odometry alone, aligned with the truth at the first frame.
    pub odometry_m: Option<f64>,
    /// A fix oracle: every frame that sees the prior map placed exactly, the others carried
    /// from the latest such frame (or the first fix) by the odometry alone; what a perfect
    /// relocalizer without drift calibration would leave where the prior map is out of
    /// sight.
    pub oracle_m: Option<f64>,
    /// The fix oracle on perfectly calibrated odometry ([`Drive::calibrated_odometry`]:
    /// only the random walk left): a floor for any estimator that places the frames out of
    /// the prior's sight by the odometry.
    pub calibrated_oracle_m: Option<f64>,
}

/// Distances driven out of the prior map's sight ([`PairRow::unseen_path_m`]), m.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct UnseenPath {
    /// Root mean square over the frames.
    pub rms: f64,
    /// The longest.
    pub max: f64,
}

/// From frame `from` on, the path each frame has driven since the latest frame that sees
/// the prior map (zero on such frames).
fn unseen_path(truth: &[Isometry3<f64>], seeing: &[bool], from: usize) -> UnseenPath {
    let mut path = 0.0;
    let mut lengths = Vec::new();
    for k in from..truth.len() {
        path = if seeing[k] || k == 0 {
            0.0
        } else {
            path + (truth[k].translation.vector - truth[k - 1].translation.vector).norm()
        };
        lengths.push(path);
    }
    let n = lengths.len().max(1) as f64;
    UnseenPath {
        rms: (lengths.iter().map(|d| d * d).sum::<f64>() / n).sqrt(),
        max: lengths.iter().copied().fold(0.0, f64::max),
    }
}

/// Wall time of the localizer's frames, milliseconds.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameTimes {
    /// Median of the frames without a relocalization attempt.
    pub median_ms: f64,
    /// 99th percentile of the frames without an attempt.
    pub p99_ms: f64,
    /// Maximum of the frames without an attempt.
    pub max_ms: f64,
    /// Median of the frames with an attempt.
    pub attempt_median_ms: f64,
    /// Maximum of the frames with an attempt.
    pub attempt_max_ms: f64,
    /// `Localizer::finish`.
    pub finish_ms: f64,
}

/// One pair's outcome: the query traverse replayed against the prior traverse's map.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PairRow {
    /// Prior traverse number.
    pub prior: usize,
    /// Query traverse number.
    pub query: usize,
    /// Landmarks of the prior map.
    pub prior_landmarks: usize,
    /// Landmarks the two traverses' world-frame maps truly share.
    pub common_landmarks: usize,
    /// Frames of the drive.
    pub frames: usize,
    /// Simulator frames between two stream frames.
    pub frame_step: u64,
    /// Distance driven, m.
    pub distance_m: f64,
    /// Relocalization attempts.
    pub attempts: usize,
    /// Attempts that entered the pose graph.
    pub accepted: usize,
    /// Attempts that did not, by reason code (`AttemptStatus::code`).
    pub refused: BTreeMap<String, usize>,
    /// The first frame whose pose was known while driving.
    pub first_fix_frame: Option<usize>,
    /// Its time since the drive's first frame, s.
    pub time_to_first_fix_s: Option<f64>,
    /// Position RMSE over the frames from the first fix on (without a fix: the odometry's
    /// over the whole drive, the others `None`).
    pub rmse: Rmse,
    /// Position RMSE over the frames from the first fix on that see a boulder of the prior
    /// map (a detection within [`SEES_PRIOR_M`] of one of its landmarks): where the prior map
    /// can correct the rover at all.
    pub rmse_seeing_prior: Rmse,
    /// From the first fix on, the distance each frame has driven since it last saw the
    /// prior map (what only the odometry carries): root mean square and maximum, m.
    pub unseen_path_m: UnseenPath,
    /// The largest position error of an accepted fix, m.
    pub max_fix_error_m: Option<f64>,
    /// Every accepted fix, scored.
    pub fixes: Vec<FixScore>,
    /// The accepted fixes that are wrong ([`WRONG_FIX_M`], [`WRONG_FIX_DEG`]).
    pub wrong_fixes: Vec<FixScore>,
    /// The odometry's biases as the localizer estimated them at the end of the drive (to
    /// compare with the drift drawn, [`StreamReport::drift`]; what a later drive of the same
    /// rover can carry over as `[calibration.known]`).
    pub odometry_bias: OdometryBias,
    /// Wall time of the frames.
    pub time: FrameTimes,
}

/// Root-mean-square distance of the estimates' positions from the truth's (`None` when
/// there is no pair).
pub fn rmse_m<'a>(
    pairs: impl Iterator<Item = (&'a Isometry3<f64>, &'a Isometry3<f64>)>,
) -> Option<f64> {
    let (sum, n) = pairs.fold((0.0, 0usize), |(sum, n), (est, truth)| {
        let d = est.translation.vector - truth.translation.vector;
        (sum + d.norm_squared(), n + 1)
    });
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// The `q`-quantile (0..=1) of `values`, nearest rank (0 when empty).
pub fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let rank = (q.clamp(0.0, 1.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// The median of `values` (0 when empty).
pub fn median(values: &[f64]) -> f64 {
    quantile(values, 0.5)
}

/// What the localizer gave while the drive was replayed.
struct Replay {
    online: Vec<Option<Isometry3<f64>>>,
    plain_ms: Vec<f64>,
    attempt_ms: Vec<f64>,
    finish_ms: f64,
    session: SessionResult,
}

/// Feed every frame of `drive` to a localizer against `prior_map`, then finish it.
fn replay(
    prior_map: ObjectMap,
    drive: &Drive,
    config: &LocalizerConfig,
) -> Result<Replay, LocalizerError> {
    let mut localizer = Localizer::new(Some(prior_map), config.clone())?;
    let mut online = Vec::with_capacity(drive.frames.len());
    let (mut plain_ms, mut attempt_ms) = (Vec::new(), Vec::new());
    for frame in &drive.frames {
        let out = localizer.push_frame(frame)?;
        if out.attempted() {
            attempt_ms.push(out.time_ms);
        } else {
            plain_ms.push(out.time_ms);
        }
        online.push(out.prior_from_rover);
    }
    let started = std::time::Instant::now();
    let session = localizer.finish()?;
    Ok(Replay {
        online,
        plain_ms,
        attempt_ms,
        finish_ms: started.elapsed().as_secs_f64() * 1e3,
        session,
    })
}

/// Whether each frame of `drive` sees `prior_map` (see [`PairRow::rmse_seeing_prior`]).
pub fn frames_seeing(drive: &Drive, prior_map: &ObjectMap) -> Vec<bool> {
    let landmarks = prior_map.positions();
    drive
        .frames
        .iter()
        .zip(&drive.truth)
        .map(|(f, world_from_rover)| {
            f.detections.iter().any(|d| {
                let p = world_from_rover * d.p_rover;
                landmarks.iter().any(|l| (l - p).norm() <= SEES_PRIOR_M)
            })
        })
        .collect()
}

/// The [`Rmse`] over the frames where `mask` holds.
fn rmse_over(
    mask: &[bool],
    r: &Replay,
    truth: &[Isometry3<f64>],
    odometry: &[Isometry3<f64>],
    oracles: [&[Isometry3<f64>]; 2],
) -> Rmse {
    let over = |poses: &[Isometry3<f64>]| {
        rmse_m(
            mask.iter()
                .zip(poses.iter().zip(truth))
                .filter_map(|(m, pair)| m.then_some(pair)),
        )
    };
    let online: Vec<(&Isometry3<f64>, &Isometry3<f64>)> = mask
        .iter()
        .zip(r.online.iter().zip(truth))
        .filter_map(|(m, (e, t))| Some((e.as_ref().filter(|_| *m)?, t)))
        .collect();
    Rmse {
        frames: mask.iter().filter(|m| **m).count(),
        online_m: rmse_m(online.into_iter()),
        smoothed_m: over(&r.session.poses),
        before_adjustment_m: over(&r.session.poses_before_adjustment),
        odometry_m: over(odometry),
        oracle_m: over(oracles[0]),
        calibrated_oracle_m: over(oracles[1]),
    }
}

/// The fix oracle's poses ([`Rmse::oracle_m`]): from frame `from` on, each frame carried by
/// the odometry from the latest frame that sees the prior map (or from `from`), placed at
/// its true pose.
pub fn oracle_poses(
    truth: &[Isometry3<f64>],
    odometry: &[Isometry3<f64>],
    seeing: &[bool],
    from: usize,
) -> Vec<Isometry3<f64>> {
    let mut anchor = from;
    (0..truth.len())
        .map(|k| {
            if k < from {
                return truth[k];
            }
            if seeing[k] {
                anchor = k;
            }
            truth[anchor] * odometry[anchor].inverse() * odometry[k]
        })
        .collect()
}

/// Replay `drive` against `prior_map` (traverse `prior`'s map, in the world frame) and score
/// it against the drive's truth.
pub fn run_pair(
    prior: usize,
    prior_map: ObjectMap,
    common: usize,
    drive: &Drive,
    config: &LocalizerConfig,
) -> Result<PairRow, LocalizerError> {
    let prior_landmarks = prior_map.len();
    let seeing = frames_seeing(drive, &prior_map);
    let r = replay(prior_map, drive, config)?;
    let truth = &drive.truth;
    let first_fix = r.online.iter().position(Option::is_some);
    let from = first_fix.unwrap_or(0);
    let world_from_odom = truth[0] * drive.frames[0].odom_from_rover.inverse();
    let odometry: Vec<Isometry3<f64>> = drive
        .frames
        .iter()
        .map(|f| world_from_odom * f.odom_from_rover)
        .collect();
    let after: Vec<bool> = (0..truth.len()).map(|k| k >= from).collect();
    let after_seeing: Vec<bool> = after.iter().zip(&seeing).map(|(a, s)| *a && *s).collect();
    let oracle = oracle_poses(truth, &odometry, &seeing, from);
    let calibrated_oracle = oracle_poses(truth, &drive.calibrated_odometry, &seeing, from);
    let oracles = [oracle.as_slice(), calibrated_oracle.as_slice()];
    let attempts = &r.session.attempts;
    let mut refused = BTreeMap::new();
    for a in attempts.iter().filter(|a| !a.accepted()) {
        *refused.entry(a.status.code().to_string()).or_insert(0) += 1;
    }
    let fixes = score_fixes(&r.session, truth);
    Ok(PairRow {
        prior,
        query: drive.traverse,
        prior_landmarks,
        common_landmarks: common,
        frames: drive.frames.len(),
        frame_step: drive.frame_step,
        distance_m: drive.distance_m,
        attempts: attempts.len(),
        accepted: attempts.iter().filter(|a| a.accepted()).count(),
        refused,
        first_fix_frame: first_fix,
        time_to_first_fix_s: first_fix.map(|k| drive.frames[k].t - drive.frames[0].t),
        rmse: rmse_over(&after, &r, truth, &odometry, oracles),
        rmse_seeing_prior: rmse_over(&after_seeing, &r, truth, &odometry, oracles),
        unseen_path_m: unseen_path(truth, &seeing, from),
        max_fix_error_m: fixes.iter().map(|f| f.error_m).reduce(f64::max),
        wrong_fixes: fixes.iter().filter(|f| f.wrong).cloned().collect(),
        fixes,
        odometry_bias: r.session.odometry_bias,
        time: FrameTimes {
            median_ms: median(&r.plain_ms),
            p99_ms: quantile(&r.plain_ms, 0.99),
            max_ms: r.plain_ms.iter().copied().fold(0.0, f64::max),
            attempt_median_ms: median(&r.attempt_ms),
            attempt_max_ms: r.attempt_ms.iter().copied().fold(0.0, f64::max),
            finish_ms: r.finish_ms,
        },
    })
}

/// Every accepted fix of `session` against the truth of its frame.
fn score_fixes(session: &SessionResult, truth: &[Isometry3<f64>]) -> Vec<FixScore> {
    let mut fixes = Vec::new();
    for (attempt, record) in session.attempts.iter().enumerate() {
        let Some(Measurement::Prior {
            k,
            prior_from_rover,
        }) = record.measurement.filter(|_| record.accepted())
        else {
            continue;
        };
        let Some(true_pose) = truth.get(k) else {
            continue;
        };
        // both are world_from_rover: the error acts in the rover frame of frame k
        let (error_m, error_deg) = transform_error(
            &(true_pose.inverse() * prior_from_rover),
            &Isometry3::identity(),
        );
        fixes.push(FixScore {
            attempt,
            frame: k,
            t: record.t,
            inliers: record.inliers,
            yaw_sigma_deg: record.yaw_sigma_deg,
            error_m,
            error_deg,
            wrong: error_m > WRONG_FIX_M || error_deg > WRONG_FIX_DEG,
        });
    }
    fixes
}

/// The figures over all pairs.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Aggregate {
    /// Pairs run.
    pub pairs: usize,
    /// Pairs with a fix.
    pub pairs_with_fix: usize,
    /// Median of the pairs' online RMSE (pairs with a fix), m.
    pub median_rmse_online_m: f64,
    /// Maximum of the same, m.
    pub max_rmse_online_m: f64,
    /// Median of the pairs' smoothed RMSE (pairs with a fix), m.
    pub median_rmse_smoothed_m: f64,
    /// Maximum of the same, m.
    pub max_rmse_smoothed_m: f64,
    /// Median of the pairs' online RMSE over the frames that see the prior map, m.
    pub median_rmse_online_seeing_prior_m: f64,
    /// Maximum of the same, m.
    pub max_rmse_online_seeing_prior_m: f64,
    /// Accepted attempts over all pairs.
    pub accepted: usize,
    /// Wrong accepted fixes over all pairs.
    pub wrong_fixes: usize,
    /// Median time to the first fix (pairs with a fix), s.
    pub median_time_to_first_fix_s: f64,
    /// Median over all frames without an attempt of all pairs, ms.
    pub median_frame_ms: f64,
    /// Median over all frames with an attempt of all pairs (of the pairs' medians), ms.
    pub median_attempt_ms: f64,
}

impl Aggregate {
    /// The aggregate of `rows`.
    pub fn of(rows: &[PairRow]) -> Self {
        let fixed: Vec<&PairRow> = rows
            .iter()
            .filter(|r| r.first_fix_frame.is_some())
            .collect();
        let of = |f: fn(&PairRow) -> Option<f64>| fixed.iter().filter_map(|r| f(r)).collect();
        let online: Vec<f64> = of(|r| r.rmse.online_m);
        let smoothed: Vec<f64> = of(|r| r.rmse.smoothed_m);
        let seeing: Vec<f64> = of(|r| r.rmse_seeing_prior.online_m);
        let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        let times: Vec<f64> = rows.iter().map(|r| r.time.median_ms).collect();
        let attempt_times: Vec<f64> = rows
            .iter()
            .filter(|r| r.attempts > 0)
            .map(|r| r.time.attempt_median_ms)
            .collect();
        Self {
            pairs: rows.len(),
            pairs_with_fix: fixed.len(),
            median_rmse_online_m: median(&online),
            max_rmse_online_m: max(&online),
            median_rmse_smoothed_m: median(&smoothed),
            max_rmse_smoothed_m: max(&smoothed),
            median_rmse_online_seeing_prior_m: median(&seeing),
            max_rmse_online_seeing_prior_m: max(&seeing),
            accepted: rows.iter().map(|r| r.accepted).sum(),
            wrong_fixes: rows.iter().map(|r| r.wrong_fixes.len()).sum(),
            median_time_to_first_fix_s: median(&of(|r| r.time_to_first_fix_s)),
            median_frame_ms: median(&times),
            median_attempt_ms: median(&attempt_times),
        }
    }
}

/// What to evaluate.
#[derive(Clone, Debug)]
pub enum PairChoice {
    /// [`paper_pairs_both_ways`].
    Paper,
    /// [`sharing_pairs`] of all 17 traverses.
    All,
    /// These ordered pairs (prior, query).
    List(Vec<(usize, usize)>),
}

/// The whole evaluation.
#[derive(Clone, Debug, Serialize)]
pub struct StreamReport {
    /// Seed of the odometry's start and random walk.
    pub seed: u64,
    /// The odometry's errors.
    pub drift: DriftConfig,
    /// Per pair, in order.
    pub pairs: Vec<PairRow>,
    /// Over all pairs.
    pub aggregate: Aggregate,
    /// The fusion the prior maps were made with (as `segloc map build`).
    pub prior_fusion: FusionConfig,
    /// The localizer's configuration (with `[calibration.known]` as carried in, if it was).
    pub config: LocalizerConfig,
    /// The calibration drives run before the pairs, when their calibration was carried in
    /// (`segloc eval stream --carry-calibration`).
    pub carried_calibration: Option<CarriedCalibration>,
}

/// Errors of the stream evaluation.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// A traverse could not be read (the message names the file).
    #[error(transparent)]
    Data(#[from] MapError),
    /// A pair is not two distinct traverse numbers in 1..=17.
    #[error("pair ({0}, {1}): traverses are numbered 1 to {TRAVERSES} and must differ")]
    BadPair(usize, usize),
    /// The drift is out of range.
    #[error(transparent)]
    Drift(#[from] FieldError),
    /// No calibration drive to run: every traverse is evaluated.
    #[error(
        "no calibration drive: the evaluated pairs use every traverse (give the drives as a list)"
    )]
    NoCalibrationDrives,
    /// The localizer failed on a pair.
    #[error("pair ({prior}, {query}): {source}")]
    Localizer {
        /// Prior traverse.
        prior: usize,
        /// Query traverse.
        query: usize,
        /// What failed.
        source: LocalizerError,
    },
}

/// Run the evaluation on the traverses under `data` (the folder holding `lunarloc/`):
/// prior maps fused with `prior_fusion`, drives with `drift` and `seed`, the localizer with
/// `config`; `progress(done, total)` after each pair.
pub fn evaluate_stream(
    data: &Path,
    choice: &PairChoice,
    drift: &DriftConfig,
    seed: u64,
    prior_fusion: &FusionConfig,
    config: &LocalizerConfig,
    mut progress: impl FnMut(usize, usize),
) -> Result<StreamReport, StreamError> {
    drift.validate().map_err(StreamError::Drift)?;
    let needed: Vec<usize> = match choice {
        PairChoice::Paper | PairChoice::List(_) => pair_list(choice, &BTreeMap::new())?
            .iter()
            .flat_map(|&(a, b)| [a, b])
            .collect(),
        PairChoice::All => (1..=TRAVERSES).collect(),
    };
    let (traverses, maps) = load_traverses(data, needed, prior_fusion)?;
    let pairs = pair_list(choice, &maps)?;
    let mut drives: BTreeMap<usize, Drive> = BTreeMap::new();
    let mut rows = Vec::with_capacity(pairs.len());
    for (done, &(prior, query)) in pairs.iter().enumerate() {
        progress(done, pairs.len());
        let drive = drives
            .entry(query)
            .or_insert_with(|| drive_from_traverse(query, &traverses[&query], drift, seed));
        let common = common_landmarks(&maps[&prior], &maps[&query]);
        let row =
            run_pair(prior, maps[&prior].clone(), common, drive, config).map_err(|source| {
                StreamError::Localizer {
                    prior,
                    query,
                    source,
                }
            })?;
        rows.push(row);
    }
    progress(pairs.len(), pairs.len());
    Ok(StreamReport {
        seed,
        drift: drift.clone(),
        aggregate: Aggregate::of(&rows),
        pairs: rows,
        prior_fusion: prior_fusion.clone(),
        config: config.clone(),
        carried_calibration: None,
    })
}

/// The drives that calibrate the odometry before the evaluated pairs (see
/// [`carry_calibration`]).
#[derive(Clone, Debug)]
pub enum CalibrationDrives {
    /// Every ordered pair sharing a boulder among the traverses the evaluated pairs do not
    /// use (held out from them).
    OtherTraverses,
    /// These ordered pairs (prior, query), in this order.
    List(Vec<(usize, usize)>),
}

/// Added to the evaluation's seed for the calibration drives' random walks, so that they
/// never share one with an evaluated drive.
pub const CALIBRATION_SEED_OFFSET: u64 = 1000;

/// One calibration drive.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CalibrationDrive {
    /// Prior traverse number.
    pub prior: usize,
    /// Query traverse number.
    pub query: usize,
    /// Fixes that entered its pose graph (without one, its estimate is not carried on).
    pub accepted: usize,
    /// The biases estimated at its end.
    pub odometry_bias: OdometryBias,
}

/// An odometry calibration carried from drive to drive of the same rover, as a team
/// carries its rover's calibration from one session to the next.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CarriedCalibration {
    /// Seed of the calibration drives' random walks.
    pub seed: u64,
    /// The drives, in the order they ran.
    pub drives: Vec<CalibrationDrive>,
    /// The biases carried into the evaluated pairs (`[calibration.known]`): the median of
    /// the drives' estimates.
    pub known: OdometryBias,
    /// Their uncertainty (1 σ), the evaluated pairs' `[calibration] prior_*`: the standard
    /// error of the median.
    pub sigma: OdometryBias,
}

/// Replay the calibration `drives` (drift `drift`, random walks seeded by `seed` +
/// [`CALIBRATION_SEED_OFFSET`]) one after the other, each starting from the median of the
/// biases the earlier drives with a fix ended on (the first from `config`'s
/// `[calibration.known]`), and return the median of them all and its standard error, for
/// the pairs of `evaluated`.
pub fn carry_calibration(
    data: &Path,
    drives: &CalibrationDrives,
    evaluated: &PairChoice,
    drift: &DriftConfig,
    seed: u64,
    prior_fusion: &FusionConfig,
    config: &LocalizerConfig,
) -> Result<CarriedCalibration, StreamError> {
    drift.validate().map_err(StreamError::Drift)?;
    let (pairs, traverses, maps) = match drives {
        CalibrationDrives::List(list) => {
            let pairs = pair_list(&PairChoice::List(list.clone()), &BTreeMap::new())?;
            let needed = pairs.iter().flat_map(|&(a, b)| [a, b]);
            let (traverses, maps) = load_traverses(data, needed, prior_fusion)?;
            (pairs, traverses, maps)
        }
        CalibrationDrives::OtherTraverses => {
            let used: Vec<usize> = match evaluated {
                PairChoice::All => (1..=TRAVERSES).collect(),
                _ => pair_list(evaluated, &BTreeMap::new())?
                    .iter()
                    .flat_map(|&(a, b)| [a, b])
                    .collect(),
            };
            let others = (1..=TRAVERSES).filter(|n| !used.contains(n));
            let (traverses, maps) = load_traverses(data, others, prior_fusion)?;
            (sharing_pairs(&maps), traverses, maps)
        }
    };
    if pairs.is_empty() {
        return Err(StreamError::NoCalibrationDrives);
    }
    let seed = seed + CALIBRATION_SEED_OFFSET;
    let mut config = config.clone();
    let mut run = Vec::with_capacity(pairs.len());
    let mut calibrated = Vec::new();
    let mut by_query: BTreeMap<usize, Drive> = BTreeMap::new();
    for &(prior, query) in &pairs {
        let drive = by_query
            .entry(query)
            .or_insert_with(|| drive_from_traverse(query, &traverses[&query], drift, seed));
        let r = replay(maps[&prior].clone(), drive, &config).map_err(|source| {
            StreamError::Localizer {
                prior,
                query,
                source,
            }
        })?;
        let accepted = r.session.attempts.iter().filter(|a| a.accepted()).count();
        if accepted > 0 {
            calibrated.push(r.session.odometry_bias);
            config.calibration.known = median_bias(&calibrated);
        }
        run.push(CalibrationDrive {
            prior,
            query,
            accepted,
            odometry_bias: r.session.odometry_bias,
        });
    }
    Ok(CarriedCalibration {
        seed,
        drives: run,
        known: median_bias(&calibrated),
        sigma: median_sigma(&calibrated, &config.calibration.prior().sigma),
    })
}

/// The median of each bias over `biases` (zero when empty): robust to the drives whose few
/// fixes left their estimate wide of the others.
fn median_bias(biases: &[OdometryBias]) -> OdometryBias {
    bias_map(biases, median)
}

/// The standard error of [`median_bias`]: 1.2533 × 1.4826 × the median absolute deviation,
/// over √n, for each bias, but never under a hundredth of `prior_sigma`; `prior_sigma`
/// itself from fewer than [`MIN_DRIVES_FOR_SPREAD`] drives.
fn median_sigma(biases: &[OdometryBias], prior_sigma: &OdometryBias) -> OdometryBias {
    if biases.len() < MIN_DRIVES_FOR_SPREAD {
        return *prior_sigma;
    }
    let n = biases.len() as f64;
    let spread = bias_map(biases, |v| {
        let m = median(v);
        let deviations: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
        1.2533 * 1.4826 * median(&deviations) / n.sqrt()
    });
    let floor = 0.01 * prior_sigma.to_vector();
    OdometryBias::from_vector(&spread.to_vector().sup(&floor))
}

/// Fewest calibration drives with a fix whose spread gives the carried calibration's σ.
pub const MIN_DRIVES_FOR_SPREAD: usize = 5;

/// `statistic` of each bias over `biases`.
fn bias_map(biases: &[OdometryBias], statistic: impl Fn(&[f64]) -> f64) -> OdometryBias {
    let of = |i: usize| statistic(&biases.iter().map(|b| b.to_vector()[i]).collect::<Vec<_>>());
    OdometryBias::from_vector(&Vector3::new(of(0), of(1), of(2)))
}

/// The traverses numbered in `needed`, read from `data`, and their maps fused with
/// `prior_fusion` (world frame).
#[allow(clippy::type_complexity)]
fn load_traverses(
    data: &Path,
    needed: impl IntoIterator<Item = usize>,
    prior_fusion: &FusionConfig,
) -> Result<(BTreeMap<usize, Traverse>, BTreeMap<usize, ObjectMap>), StreamError> {
    let mut traverses = BTreeMap::new();
    for n in needed {
        if let std::collections::btree_map::Entry::Vacant(slot) = traverses.entry(n) {
            slot.insert(read_lunarloc_traverse(&traverse_path(data, n))?);
        }
    }
    let maps = traverses
        .iter()
        .map(|(&n, t)| (n, fuse_detections(&t.detections(), prior_fusion)))
        .collect();
    Ok((traverses, maps))
}

/// The ordered pairs of `choice`, checked (`maps`: every traverse's map, for
/// [`PairChoice::All`]).
fn pair_list(
    choice: &PairChoice,
    maps: &BTreeMap<usize, ObjectMap>,
) -> Result<Vec<(usize, usize)>, StreamError> {
    let pairs = match choice {
        PairChoice::Paper => paper_pairs_both_ways(),
        PairChoice::All => sharing_pairs(maps),
        PairChoice::List(list) => list.clone(),
    };
    let valid = |n: usize| (1..=TRAVERSES).contains(&n);
    match pairs
        .iter()
        .find(|(a, b)| a == b || !valid(*a) || !valid(*b))
    {
        Some(&(a, b)) => Err(StreamError::BadPair(a, b)),
        None => Ok(pairs),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use segloc_maps::TraverseFrame;

    /// A straight drive along +y at 0.2 m/s, 20 Hz rows, a detection every 20th frame.
    fn straight() -> Traverse {
        let frames = (1..=400u64)
            .map(|f| TraverseFrame {
                frame: f,
                rover_position: Point3::new(1.0, 0.01 * f as f64, 0.5),
                boulders: if f % 20 == 0 {
                    vec![Point3::new(3.0, 0.01 * f as f64 + 2.0, 0.4)]
                } else {
                    Vec::new()
                },
            })
            .collect();
        Traverse {
            name: "straight".into(),
            frames,
        }
    }

    #[test]
    fn drive_has_true_heading_and_rover_frame_detections() {
        let t = straight();
        let drive = drive_from_traverse(1, &t, &DriftConfig::default(), 1);
        assert_eq!(drive.frame_step, 20);
        assert_eq!(drive.frames.len(), 20);
        assert!((drive.frames[0].t - 1.0).abs() < 1e-12);
        for (f, truth) in drive.frames.iter().zip(&drive.truth) {
            let yaw = truth.rotation.euler_angles().2;
            assert!((yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
            // the boulder 2 m ahead and 2 m to the right
            let p = f.detections[0].p_rover;
            assert!((p - Point3::new(2.0, -2.0, -0.1)).norm() < 1e-9, "{p}");
        }
        assert!((drive.distance_m - 3.8).abs() < 1e-9);
    }

    #[test]
    fn calibrated_odometry_keeps_only_the_random_walk() {
        let t = straight();
        let no_walk = DriftConfig {
            yaw_walk_rad_per_sqrt_m: 0.0,
            ..DriftConfig::default()
        };
        let drive = drive_from_traverse(1, &t, &no_walk, 1);
        for (c, truth) in drive.calibrated_odometry.iter().zip(&drive.truth) {
            assert!((c.translation.vector - truth.translation.vector).norm() < 1e-9);
        }
        let walking = drive_from_traverse(1, &t, &DriftConfig::default(), 1);
        let end = walking
            .calibrated_odometry
            .last()
            .map(|p| p.translation.vector);
        let truth_end = walking.truth.last().map(|p| p.translation.vector);
        let gap = (end.unwrap_or_default() - truth_end.unwrap_or_default()).norm();
        assert!(gap > 0.0 && gap < 0.05, "{gap}");
    }

    #[test]
    fn odometry_drifts_by_the_configured_scale_and_yaw() {
        let truth: Vec<Isometry3<f64>> = (0..11)
            .map(|k| Isometry3::translation(k as f64, 0.0, 0.0))
            .collect();
        let drift = DriftConfig {
            yaw_walk_rad_per_sqrt_m: 0.0,
            yaw_drift_deg_per_10m: 1.0,
            scale_error: 0.01,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let odom = drifted_odometry(&truth, &drift, Isometry3::identity(), &mut rng);
        let end = odom[10];
        assert!((end.rotation.euler_angles().2.to_degrees() - 1.0).abs() < 1e-9);
        let length: f64 = odom
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum();
        assert!((length - 10.1).abs() < 1e-9);
    }

    #[test]
    fn paper_pairs_go_both_ways_and_bad_pairs_are_refused() {
        let pairs = paper_pairs_both_ways();
        assert_eq!(pairs.len(), 10);
        assert!(pairs.contains(&(3, 5)) && pairs.contains(&(5, 3)));
        let none = BTreeMap::new();
        assert!(pair_list(&PairChoice::List(vec![(3, 3)]), &none).is_err());
        assert!(pair_list(&PairChoice::List(vec![(0, 3)]), &none).is_err());
        assert!(pair_list(&PairChoice::List(vec![(3, 18)]), &none).is_err());
    }

    #[test]
    fn quantiles_by_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(&v, 0.99), 99.0);
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(quantile(&[], 0.5), 0.0);
    }

    #[test]
    fn the_oracle_is_exact_where_the_prior_is_seen_and_drifts_between() {
        let truth: Vec<Isometry3<f64>> = (0..6)
            .map(|k| Isometry3::translation(k as f64, 0.0, 0.0))
            .collect();
        // odometry 10 % long
        let odometry: Vec<Isometry3<f64>> = (0..6)
            .map(|k| Isometry3::translation(1.1 * k as f64, 0.0, 0.0))
            .collect();
        let seeing = [false, false, true, false, false, true];
        let oracle = oracle_poses(&truth, &odometry, &seeing, 1);
        let x: Vec<f64> = oracle.iter().map(|p| p.translation.x).collect();
        let expected = [0.0, 1.0, 2.0, 3.1, 4.2, 5.0];
        for (a, b) in x.iter().zip(expected) {
            assert!((a - b).abs() < 1e-12, "{x:?}");
        }
    }
}
