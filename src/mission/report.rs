//! The mission report (JSON) and its pictures.

use super::lost_session::LocalizedSession;
use super::mapping_session::MappedSession;
use super::maps::MissionMaps;
use super::stream::{odometry_in_world, rmse_from_m, rmse_m};
use super::MissionConfig;
use crate::localizer::boulder_adjustment::BoulderAdjustmentReport;
use crate::localizer::odometry_bias::OdometryBias;
use crate::localizer::AttemptStatus;
use crate::mapping::pictures::{height_error_png, rock_map_png, trajectory_png, Polyline};
use crate::mapping::LacScore;
use crate::sim::rendered_boulders::PerceptionSummary;
use crate::sim::rendered_odometry::ImageOdometryStats;
use crate::sim::session::SessionLog;
use crate::vo::{segment_drift, SegmentDrift};
use nalgebra::Isometry3;
use segloc_maps::LacGrid;
use serde::Serialize;
use std::path::Path;

/// One relocalization attempt.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Attempt {
    /// Session number (1-based).
    pub session: usize,
    /// Session time of the submap's last frame, seconds.
    pub time_s: f64,
    /// Landmarks in the submap.
    pub query_landmarks: usize,
    /// Whether the relocalizer accepted.
    pub accepted: bool,
    /// Why it did not enter the pose graph: in JSON `status`, a stable `code` and the
    /// `reason` as a sentence.
    pub refusal: Option<AttemptStatus>,
    /// Inlier associations.
    pub inliers: usize,
    /// Accepted: position error of the relocalized rover pose against the truth, metres.
    pub error_m: Option<f64>,
    /// Accepted: rotation error, degrees.
    pub error_deg: Option<f64>,
    /// Accepted: the yaw part of the rotation error, degrees.
    pub error_yaw_deg: Option<f64>,
    /// Accepted but off by more than the mission's thresholds.
    pub wrong: bool,
    /// The relocalizer's yaw standard deviation (from its information), degrees.
    pub yaw_sigma_deg: Option<f64>,
}

impl Attempt {
    /// An attempt not (yet) accepted: the outcome fields are filled in once the
    /// relocalizer has answered.
    pub fn pending(session: usize, time_s: f64, query_landmarks: usize) -> Self {
        Attempt {
            session,
            time_s,
            query_landmarks,
            accepted: false,
            refusal: None,
            inliers: 0,
            error_m: None,
            error_deg: None,
            error_yaw_deg: None,
            wrong: false,
            yaw_sigma_deg: None,
        }
    }
}

/// Relocalization counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RelocalizationCounts {
    /// Accepted attempts.
    pub accepted: usize,
    /// Refused attempts.
    pub refused: usize,
    /// Accepted but wrong (> 10 cm or > 1° off).
    pub wrong_accepted: usize,
}

impl RelocalizationCounts {
    fn of(attempts: &[Attempt]) -> Self {
        Self {
            accepted: attempts.iter().filter(|a| a.accepted).count(),
            refused: attempts.iter().filter(|a| !a.accepted).count(),
            wrong_accepted: attempts.iter().filter(|a| a.accepted && a.wrong).count(),
        }
    }
}

/// One session's figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SessionReport {
    /// Session number (1-based).
    pub session: usize,
    /// Simulated seconds.
    pub duration_s: f64,
    /// Distance driven, metres.
    pub distance_m: f64,
    /// Position RMSE over the frames with the global factors (and the terrain height
    /// alignment), metres.
    pub rmse_m: f64,
    /// Position RMSE of the pose graph's estimate, before the terrain height alignment
    /// ([`super::terrain_height`]), metres.
    pub rmse_graph_m: f64,
    /// Position RMSE of odometry alone, aligned at the true start, metres.
    pub rmse_without_global_m: f64,
    /// The odometry's translation drift over 10 m segments (KITTI's metric, mean), percent
    /// (`None`: a path shorter than 10 m).
    pub vo_drift_percent: Option<f64>,
    /// The odometry's drift over 10 m segments in full (`None`: a path shorter than 10 m).
    pub vo_drift: Option<SegmentDrift>,
    /// What the odometry from images did (absent: the drift model measured the steps).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image_odometry: Option<ImageOdometryStats>,
    /// Position RMSE of the pose graph's estimate before the boulder adjustment, metres.
    pub rmse_before_adjustment_m: f64,
    /// What the boulder adjustment did (`None`: off).
    pub boulder_adjustment: Option<BoulderAdjustmentReport>,
    /// The odometry's systematic errors: the localizer's calibration at the end, and the
    /// drift model's drawn ones when it measured the steps.
    pub odometry_bias: OdometryBiasReport,
    /// Distinct collision events.
    pub collisions: usize,
    /// Boulder detections.
    pub detections: usize,
    /// Relocalization attempts of this session.
    pub relocalizations: RelocalizationCounts,
    /// Wall-clock seconds simulating.
    pub simulation_wall_s: f64,
    /// A session that started lost: how it found itself (absent for a known start).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lost_start: Option<LostStartReport>,
}

/// The odometry's biases as calibrated against what the simulation drew.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OdometryBiasReport {
    /// The localizer's estimate at the end of the session.
    pub estimated: OdometryBias,
    /// The drift model's drawn biases (absent: the odometry came from images).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drawn: Option<OdometryBias>,
}

/// How a session that started lost found itself in its prior map.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LostStartReport {
    /// What it relocalized against: `"site rock grid"` or `"session 1 map"`.
    pub prior: String,
    /// Landmarks in that prior.
    pub prior_landmarks: usize,
    /// Session time of the first accepted fix, seconds (`None`: never placed).
    pub first_fix_s: Option<f64>,
    /// The relocalizations against that prior (wrong: accepted but off by more than the
    /// mission's thresholds).
    pub fixes: RelocalizationCounts,
    /// Position RMSE of the session's final poses from the first fix on, metres.
    pub rmse_after_first_fix_m: Option<f64>,
    /// Session 1: rocks of its map paired with the grid's by the end's horizontal fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub map_fit_pairs: Option<usize>,
    /// Session 1: ground points behind the end's height fit onto the grid's heights.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub height_fit_points: Option<usize>,
}

impl LostStartReport {
    fn of(
        prior: &str,
        prior_landmarks: usize,
        (log, poses): (&SessionLog, &[Isometry3<f64>]),
        attempts: &[Attempt],
        first_fix_frame: Option<usize>,
    ) -> Self {
        let first_fix_s = first_fix_frame
            .and_then(|k| log.frames.get(k))
            .map(|f| f.time_s);
        let rmse_after_first_fix_m = first_fix_frame.map(|k| rmse_from_m(log, poses, k));
        Self {
            prior: prior.to_string(),
            prior_landmarks,
            first_fix_s,
            fixes: RelocalizationCounts::of(attempts),
            rmse_after_first_fix_m,
            map_fit_pairs: None,
            height_fit_points: None,
        }
    }
}

/// The LAC score summary.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LacSummary {
    /// Geometric points (of 300).
    pub geometric: f64,
    /// Rock points (of 300).
    pub rocks: f64,
    /// Productivity points.
    pub productivity: f64,
    /// Total.
    pub total: f64,
    /// Rock precision.
    pub rock_precision: f64,
    /// Rock recall.
    pub rock_recall: f64,
    /// Boulders in the fused map of both sessions.
    pub landmarks: usize,
}

/// The whole report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MissionReport {
    /// Moon and mission seed.
    pub seed: u64,
    /// Per session.
    pub sessions: Vec<SessionReport>,
    /// LAC scores.
    pub lac: LacSummary,
    /// All relocalization attempts counted (session 1's loop closures, its relocalizations
    /// against the site's rock grid when it started lost, and session 2's relocalizations
    /// against session 1's map).
    pub relocalizations: RelocalizationCounts,
    /// Every attempt.
    pub attempts: Vec<Attempt>,
    /// Collisions of both sessions.
    pub collisions: usize,
    /// Simulated seconds per wall-clock second, whole mission.
    pub realtime_factor: f64,
    /// Wall-clock seconds of the whole mission.
    pub wall_s: f64,
    /// Boulders in session 1's map (the prior).
    pub prior_landmarks: usize,
    /// The viewpoint bias of the detections as session 1 calibrated it
    /// ([`crate::localizer::view_bias`]).
    pub view_bias: ViewBiasReport,
    /// The configuration (its fusion's `view_bias_size_fraction` is the one used).
    pub config: MissionConfig,
    /// The front end on the rendered frames (`perception.sensors = "rendered"`; absent with
    /// the sensor model).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub perception: Option<PerceptionSummary>,
}

/// The viewpoint-bias calibration's outcome.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ViewBiasReport {
    /// The size fraction estimated from session 1's passes (`None`: not enough evidence,
    /// or calibration off; the configured value was used).
    pub estimated_size_fraction: Option<f64>,
    /// Its standard error.
    pub standard_error: Option<f64>,
    /// Boulders seen from several directions within one pass.
    pub boulders: usize,
}

/// A session's true and estimated xy of every frame.
pub type TrajectoryPair = (Vec<(f64, f64)>, Vec<(f64, f64)>);

/// The report with what the pictures need.
pub struct MissionOutput {
    /// The report.
    pub report: MissionReport,
    /// The mission's grid (heights and rocks).
    pub grid: LacGrid,
    /// The ground truth.
    pub truth: LacGrid,
    /// The full score.
    pub score: LacScore,
    /// Per session: true and estimated xy of every frame.
    pub trajectories: Vec<TrajectoryPair>,
    /// The mission frame by frame, for playback (the Rerun recording).
    pub trace: super::MissionTrace,
}

/// What a session's pose graph and its boulder adjustment measured.
struct Adjusted<'a> {
    rmse_graph_m: f64,
    rmse_before_adjustment_m: f64,
    adjustment: &'a Option<BoulderAdjustmentReport>,
    odometry_bias: OdometryBias,
}

fn session_report(
    n: usize,
    log: &SessionLog,
    poses: &[Isometry3<f64>],
    adjusted: Adjusted,
    attempts: &[Attempt],
    lost_start: Option<LostStartReport>,
) -> SessionReport {
    let s = log.summary();
    let vo_drift = odometry_drift(log);
    SessionReport {
        session: n,
        duration_s: s.duration_s,
        distance_m: s.distance_m,
        rmse_m: rmse_m(log, poses),
        rmse_graph_m: adjusted.rmse_graph_m,
        rmse_without_global_m: rmse_m(log, &odometry_in_world(log)),
        vo_drift_percent: vo_drift.map(|d| d.translation_percent),
        vo_drift,
        image_odometry: log.image_odometry.clone(),
        rmse_before_adjustment_m: adjusted.rmse_before_adjustment_m,
        boulder_adjustment: adjusted.adjustment.clone(),
        odometry_bias: OdometryBiasReport {
            estimated: adjusted.odometry_bias,
            drawn: log.odometry_bias,
        },
        collisions: s.collisions,
        detections: s.detections,
        relocalizations: RelocalizationCounts::of(attempts),
        simulation_wall_s: log.wall_time_s,
        lost_start,
    }
}

/// The session's odometry (`session_from_rover`) against the truth over 10 m segments, at
/// the odometry's own rate when it ran on images (every tick with the drift model).
fn odometry_drift(log: &SessionLog) -> Option<SegmentDrift> {
    let every = log.image_odometry.as_ref().map_or(1, |o| o.period_ticks);
    let ticks = log.ticks.iter().step_by(every.max(1));
    let (estimate, truth): (Vec<_>, Vec<_>) = ticks
        .map(|t| (t.session_from_rover, t.world_from_rover))
        .unzip();
    segment_drift(&estimate, &truth, 10.0)
}

fn xy(poses: impl Iterator<Item = Isometry3<f64>>) -> Vec<(f64, f64)> {
    poses
        .map(|p| (p.translation.vector.x, p.translation.vector.y))
        .collect()
}

/// Put the report together.
pub(super) fn assemble(
    seed: u64,
    config: &MissionConfig,
    one: &MappedSession,
    two: &LocalizedSession,
    maps: MissionMaps,
    truth: LacGrid,
    wall_s: f64,
) -> MissionOutput {
    let grid_attempts = one.lost_start.as_ref().map_or(&[][..], |l| &l.attempts[..]);
    let one_attempts: Vec<Attempt> = one.attempts.iter().chain(grid_attempts).cloned().collect();
    let lost_1 = one.lost_start.as_ref().map(|l| LostStartReport {
        map_fit_pairs: l.map_fit_pairs,
        height_fit_points: l.height_fit_points,
        ..LostStartReport::of(
            "site rock grid",
            l.prior_landmarks,
            (&one.log, &one.poses),
            &l.attempts,
            l.first_fix_frame,
        )
    });
    let lost_2 = LostStartReport::of(
        "session 1 map",
        one.map.len(),
        (&two.log, &two.poses),
        &two.attempts,
        two.first_fix_frame,
    );
    let sessions = vec![
        session_report(
            1,
            &one.log,
            &one.poses,
            Adjusted {
                rmse_graph_m: one.rmse_graph_m,
                rmse_before_adjustment_m: one.rmse_before_adjustment_m,
                adjustment: &one.adjustment,
                odometry_bias: one.odometry_bias,
            },
            &one_attempts,
            lost_1,
        ),
        session_report(
            2,
            &two.log,
            &two.poses,
            Adjusted {
                rmse_graph_m: two.rmse_graph_m,
                rmse_before_adjustment_m: two.rmse_before_adjustment_m,
                adjustment: &two.adjustment,
                odometry_bias: two.odometry_bias,
            },
            &two.attempts,
            Some(lost_2),
        ),
    ];
    let collisions = sessions.iter().map(|s| s.collisions).sum();
    let simulated: f64 = sessions.iter().map(|s| s.duration_s).sum();
    let s = &maps.score;
    let attempts: Vec<Attempt> = one_attempts
        .into_iter()
        .chain(two.attempts.iter().cloned())
        .collect();
    let trajectories = [(&one.log, &one.poses), (&two.log, &two.poses)]
        .iter()
        .map(|(log, poses)| {
            let truth = xy(log
                .frames
                .iter()
                .filter_map(|f| log.ticks.get(f.tick))
                .map(|t| t.world_from_rover));
            (truth, xy(poses.iter().copied()))
        })
        .collect();
    MissionOutput {
        report: MissionReport {
            seed,
            sessions,
            lac: LacSummary {
                geometric: s.geometric,
                rocks: s.rocks,
                productivity: s.productivity,
                total: s.total,
                rock_precision: s.rock_precision,
                rock_recall: s.rock_recall,
                landmarks: maps.landmarks,
            },
            relocalizations: RelocalizationCounts::of(&attempts),
            attempts,
            collisions,
            realtime_factor: simulated / wall_s.max(1e-9),
            wall_s,
            prior_landmarks: one.map.len(),
            view_bias: ViewBiasReport {
                estimated_size_fraction: one.view_bias.fraction(),
                standard_error: one.view_bias.evidence().fraction_standard_error(),
                boulders: one.view_bias.evidence().boulders,
            },
            config: config.clone(),
            perception: None,
        },
        grid: maps.grid,
        truth,
        score: maps.score,
        trajectories,
        trace: super::MissionTrace::default(),
    }
}

/// Errors writing the outputs.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The directory could not be created.
    #[error("cannot create {path}: {message}")]
    Directory {
        /// The directory.
        path: String,
        /// Why.
        message: String,
    },
    /// A picture failed.
    #[error(transparent)]
    Picture(#[from] crate::mapping::raster::PictureError),
    /// The report failed.
    #[error(transparent)]
    Map(#[from] segloc_maps::MapError),
    /// The report could not be serialised.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// The Rerun recording failed.
    #[cfg(feature = "rerun")]
    #[error(transparent)]
    Recording(#[from] super::recording::RecordingError),
}

/// The image odometry's pairs as CSV: the VO's diagnostics, then the odometry's and the true
/// rover position and yaw (x, y, z m, yaw degrees), one line per pair.
fn vo_pairs_csv(pairs: &[crate::sim::rendered_odometry::PairRecord]) -> String {
    let pose = |p: &Isometry3<f64>| {
        let v = p.translation.vector;
        let yaw = p.rotation.euler_angles().2.to_degrees();
        format!("{:.4},{:.4},{:.4},{yaw:.3}", v.x, v.y, v.z)
    };
    let mut out = String::from(
        "time_s,tracked,inliers,features,lost,gyro_rotation,wheel_translation,vo_ms,\
         odom_x,odom_y,odom_z,odom_yaw_deg,true_x,true_y,true_z,true_yaw_deg\n",
    );
    for p in pairs {
        out += &format!(
            "{:.2},{},{},{},{},{},{},{:.1},{},{}\n",
            p.time_s,
            p.tracked,
            p.inliers,
            p.features,
            u8::from(p.lost),
            u8::from(p.gyro_rotation),
            u8::from(p.wheel_translation),
            p.vo_ms,
            pose(&p.odom_from_rover),
            pose(&p.world_from_rover)
        );
    }
    out
}

impl MissionOutput {
    /// Write `report.json`, `height_error.png`, `rock_map.png`, `trajectories.png`, the
    /// sessions' trajectories (`sessionN_{truth,estimate,odometry}.tum`) and, for sessions
    /// on images, their VO pairs (`sessionN_vo.csv`) into `dir` (created if missing), each
    /// file atomically; with the cargo feature `rerun`,
    /// also `mission.rrd`, a recording of the run for the Rerun viewer.
    pub fn write(&self, dir: &Path) -> Result<(), OutputError> {
        std::fs::create_dir_all(dir).map_err(|e| OutputError::Directory {
            path: dir.display().to_string(),
            message: e.to_string(),
        })?;
        let r = &self.report;
        height_error_png(
            &self.grid,
            &self.truth,
            &format!("HEIGHT SEED {} GEOMETRIC {:.0}", r.seed, r.lac.geometric),
            &dir.join("height_error.png"),
        )?;
        rock_map_png(
            &self.grid,
            &self.truth,
            &format!("ROCKS SEED {} SCORE {:.0}", r.seed, r.lac.rocks),
            &dir.join("rock_map.png"),
        )?;
        let colours = [
            ([40, 40, 40], [30, 120, 255]),
            ([120, 120, 120], [255, 140, 0]),
        ];
        let mut lines = Vec::new();
        for (k, ((truth, est), (ct, ce))) in self.trajectories.iter().zip(colours).enumerate() {
            lines.push(Polyline {
                label: format!("S{} TRUE", k + 1),
                colour: ct,
                points_xy: truth.clone(),
                width_px: 6.0,
            });
            lines.push(Polyline {
                label: format!("S{} EST", k + 1),
                colour: ce,
                points_xy: est.clone(),
                width_px: 2.0,
            });
        }
        trajectory_png(
            &self.truth,
            &lines,
            &format!("TRAJECTORIES SEED {}", r.seed),
            &dir.join("trajectories.png"),
        )?;
        #[cfg(feature = "rerun")]
        super::recording::write_recording(
            self,
            &dir.join("mission.rrd"),
            &[
                ("height_error", &dir.join("height_error.png")),
                ("rock_map", &dir.join("rock_map.png")),
                ("trajectories", &dir.join("trajectories.png")),
            ],
        )?;
        self.write_trajectories(dir)?;
        self.write_vo_pairs(dir)?;
        let json = serde_json::to_vec_pretty(r)?;
        segloc_maps::write_atomic(&dir.join("report.json"), &json)?;
        Ok(())
    }

    /// Each session's rover poses at its camera frames as TUM files (what `evo` reads):
    /// `sessionN_truth.tum`, `sessionN_estimate.tum` (the pose graph after the session) and
    /// `sessionN_odometry.tum` (odometry alone, aligned at the true start), world frame.
    fn write_trajectories(&self, dir: &Path) -> Result<(), OutputError> {
        type Pick = fn(&super::trace::TraceFrame) -> Isometry3<f64>;
        let kinds: [(&str, Pick); 3] = [
            ("truth", |f| f.world_from_rover_true),
            ("estimate", |f| f.world_from_rover_estimate),
            ("odometry", |f| f.world_from_rover_odometry),
        ];
        for session in &self.trace.sessions {
            for (kind, pick) in kinds {
                let poses: Vec<(f64, Isometry3<f64>)> =
                    session.frames.iter().map(|f| (f.time_s, pick(f))).collect();
                let path = dir.join(format!("session{}_{kind}.tum", session.session));
                segloc_maps::write_atomic(&path, crate::vo::tum::tum_text(&poses).as_bytes())?;
            }
        }
        Ok(())
    }

    /// Each session's image odometry pair by pair (`sessionN_vo.csv`, [`vo_pairs_csv`]);
    /// nothing for a session on the drift model.
    fn write_vo_pairs(&self, dir: &Path) -> Result<(), OutputError> {
        for (k, session) in self.report.sessions.iter().enumerate() {
            if let Some(odometry) = &session.image_odometry {
                let path = dir.join(format!("session{}_vo.csv", k + 1));
                segloc_maps::write_atomic(&path, vo_pairs_csv(&odometry.per_pair).as_bytes())?;
            }
        }
        Ok(())
    }
}
