//! `segloc vo` and `segloc eval vo`: stereo visual odometry on a sequence.
//!
//! Exit codes: 0 success, 2 bad input (a missing or inconsistent sequence, a bad
//! calibration, an unwritable output), 1 anything else.

use clap::Args;
use nalgebra::Isometry3;
use segloc::graph::file::write_atomic;
use segloc::vo::{
    run_sequence, segment_drift, tum, FrameResult, SegmentDrift, StageTimes, StereoSequence,
    VoConfig, VoError,
};
use serde::Serialize;
use std::path::PathBuf;

/// Where a stereo sequence comes from: exactly one of the three.
#[derive(Args, Debug)]
#[group(required = true, multiple = false)]
pub struct SequenceArgs {
    /// A KITTI-layout folder: image_l/, image_r/, calib.txt (P0, P1); t = 0.1·frame.
    #[arg(long)]
    pub kitti: Option<PathBuf>,
    /// A `segloc sim render` folder: NNNNNN_0.png / NNNNNN_1.png, calibration.json and
    /// truth.tum.
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// A `.lac` recording (FrontLeft / FrontRight grayscale images, the IPEX calibration).
    #[arg(long)]
    pub lac: Option<PathBuf>,
}

impl SequenceArgs {
    /// Reads the sequence; returns it with the path that names it.
    pub fn read(&self) -> Result<(StereoSequence, PathBuf), VoError> {
        match (&self.kitti, &self.images, &self.lac) {
            (Some(dir), _, _) => Ok((StereoSequence::read_kitti(dir)?, dir.clone())),
            (_, Some(dir), _) => Ok((StereoSequence::read_rendered(dir)?, dir.clone())),
            (_, _, Some(path)) => Ok((StereoSequence::read_lac(path)?, path.clone())),
            _ => Err(VoError::Config(
                "give a sequence: --kitti DIR, --images DIR or --lac FILE".into(),
            )),
        }
    }
}

/// Arguments of `segloc vo`.
#[derive(Args, Debug)]
pub struct VoArgs {
    /// The stereo sequence.
    #[command(flatten)]
    pub sequence: SequenceArgs,
    /// Output trajectory (TUM: t tx ty tz qx qy qz qw), the left camera in the first left
    /// camera's frame.
    #[arg(short, long)]
    pub output: PathBuf,
    /// VO configuration (TOML, fields of `VoConfig`).
    #[arg(long, value_name = "FILE")]
    pub vo_config: Option<PathBuf>,
    /// Also write one CSV row a frame:
    /// `t,tracked,inliers,features,lost,gyro_rotation,rotation_sigma_deg,time_ms`.
    #[arg(long, value_name = "CSV")]
    pub per_frame: Option<PathBuf>,
    /// Print one JSON object with the results.
    #[arg(long)]
    pub json: bool,
}

/// One CSV row a frame, with a header: what the odometry did on each frame.
fn per_frame_csv(results: &[FrameResult]) -> String {
    let mut text =
        String::from("t,tracked,inliers,features,lost,gyro_rotation,rotation_sigma_deg,time_ms\n");
    for r in results {
        text.push_str(&format!(
            "{:.3},{},{},{},{},{},{:.4},{:.2}\n",
            r.time_s,
            r.tracked,
            r.inliers,
            r.features,
            r.lost as u8,
            r.gyro_rotation as u8,
            r.rotation_sigma_deg,
            r.time_ms
        ));
    }
    text
}

/// Arguments of `segloc eval vo`.
#[derive(Args, Debug)]
pub struct EvalVoArgs {
    /// The stereo sequence, with its ground truth (KITTI poses.txt, a render folder's
    /// truth.tum, or a `.lac` recording's rover poses).
    #[command(flatten)]
    pub sequence: SequenceArgs,
    /// VO configuration (TOML, fields of `VoConfig`).
    #[arg(long, value_name = "FILE")]
    pub vo_config: Option<PathBuf>,
    /// Also score the motion from this frame to the last one (estimate and truth both taken
    /// relative to this frame): `from_frame_*` in the output. The KITTI excerpt's truth is a
    /// constant-rate interpolation over frames 0–11 (docs/design/vo-kitti-truth.md).
    #[arg(long, value_name = "N")]
    pub from_frame: Option<usize>,
    /// Also write one CSV row a frame, as `segloc vo --per-frame` does (which frames were
    /// lost: `scripts/vo_lost_frames.py` says why).
    #[arg(long, value_name = "CSV")]
    pub per_frame: Option<PathBuf>,
    /// Print one JSON object with the results.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Timing {
    median: f64,
    p90: f64,
    p99: f64,
    max: f64,
}

#[derive(Serialize)]
struct VoOutput<'a> {
    frames: usize,
    tracked_features: f64,
    inliers: f64,
    lost_frames: usize,
    /// Frames whose rotation is the gyro's (the image motion failed or disagreed with it).
    gyro_rotation_frames: usize,
    keyframes: usize,
    per_frame_ms: Timing,
    /// Median time of each stage over the frames, milliseconds.
    stage_ms_median: StageTimes,
    config: &'a VoConfig,
}

fn config_of(path: &Option<PathBuf>) -> Result<VoConfig, VoError> {
    let Some(p) = path else {
        return Ok(VoConfig::default());
    };
    let text = std::fs::read_to_string(p).map_err(|source| VoError::Io {
        path: p.clone(),
        source,
    })?;
    let config: VoConfig = toml::from_str(&text).map_err(|e| VoError::Parse {
        path: p.clone(),
        line: 0,
        message: e.to_string(),
    })?;
    config.validate().map_err(|e| VoError::Parse {
        path: p.clone(),
        line: 0,
        message: e.to_string(),
    })?;
    Ok(config)
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn summary<'a>(results: &[FrameResult], config: &'a VoConfig) -> VoOutput<'a> {
    let mut ms: Vec<f64> = results.iter().map(|r| r.time_ms).collect();
    ms.sort_by(f64::total_cmp);
    let mut tracked: Vec<f64> = results.iter().skip(1).map(|r| r.tracked as f64).collect();
    tracked.sort_by(f64::total_cmp);
    let mut inliers: Vec<f64> = results.iter().skip(1).map(|r| r.inliers as f64).collect();
    inliers.sort_by(f64::total_cmp);
    VoOutput {
        frames: results.len(),
        tracked_features: percentile(&tracked, 0.5),
        inliers: percentile(&inliers, 0.5),
        lost_frames: results.iter().filter(|r| r.lost).count(),
        gyro_rotation_frames: results.iter().filter(|r| r.gyro_rotation).count(),
        keyframes: results.len(),
        per_frame_ms: Timing {
            median: percentile(&ms, 0.5),
            p90: percentile(&ms, 0.9),
            p99: percentile(&ms, 0.99),
            max: ms.last().copied().unwrap_or(0.0),
        },
        stage_ms_median: stage_medians(results),
        config,
    }
}

/// The median of each stage's time over the frames.
fn stage_medians(results: &[FrameResult]) -> StageTimes {
    let median = |f: fn(&StageTimes) -> f64| {
        let mut v: Vec<f64> = results.iter().map(|r| f(&r.stages)).collect();
        v.sort_by(f64::total_cmp);
        percentile(&v, 0.5)
    };
    StageTimes {
        pyramid_ms: median(|s| s.pyramid_ms),
        track_ms: median(|s| s.track_ms),
        stereo_ms: median(|s| s.stereo_ms),
        motion_ms: median(|s| s.motion_ms),
        corners_ms: median(|s| s.corners_ms),
        window_ms: median(|s| s.window_ms),
    }
}

/// One line of the stages' median times.
fn stage_line(stages: &StageTimes) -> String {
    let parts: Vec<String> = stages
        .named()
        .iter()
        .map(|(name, ms)| format!("{name} {ms:.1}"))
        .collect();
    format!("median ms per stage: {}", parts.join(", "))
}

/// Bad input is exit 2 with the message; other failures propagate.
fn exit_code(result: anyhow::Result<()>) -> anyhow::Result<i32> {
    match result {
        Ok(()) => Ok(0),
        Err(e)
            if e.downcast_ref::<VoError>().is_some()
                || e.downcast_ref::<segloc::graph::GraphError>().is_some() =>
        {
            eprintln!("error: {e:#}");
            Ok(2)
        }
        Err(e) => Err(e),
    }
}

/// Runs `segloc vo`.
pub fn run(a: &VoArgs) -> anyhow::Result<i32> {
    exit_code((|| {
        let config = config_of(&a.vo_config)?;
        let (sequence, _) = a.sequence.read()?;
        let results = run_sequence(&sequence, &config)?;
        let poses: Vec<_> = results.iter().map(|r| (r.time_s, r.pose)).collect();
        write_atomic(&a.output, tum::tum_text(&poses).as_bytes())?;
        if let Some(path) = &a.per_frame {
            write_atomic(path, per_frame_csv(&results).as_bytes())?;
        }
        let out = summary(&results, &config);
        if a.json {
            super::print_json(&out)?;
        } else {
            println!("{} frames, {} lost, median {:.0} tracked, {:.1} ms per frame (median), {:.1} ms p99 -> {}", out.frames, out.lost_frames, out.tracked_features, out.per_frame_ms.median, out.per_frame_ms.p99, a.output.display());
            println!("{}", stage_line(&out.stage_ms_median));
        }
        Ok(())
    })())
}

#[derive(Serialize)]
struct EvalOutput<'a> {
    distance_m: f64,
    translation_error_m: f64,
    translation_error_percent: f64,
    rotation_error_deg: f64,
    /// The same errors for the motion from `--from-frame` to the last frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    from_frame: Option<EndPointErrors>,
    /// KITTI's metric over 10 m segments; null when the drive is shorter.
    drift_10m: Option<SegmentDrift>,
    #[serde(flatten)]
    vo: VoOutput<'a>,
}

/// End-point errors of the motion from one frame to the last.
#[derive(Serialize)]
struct EndPointErrors {
    /// The first frame of the motion scored.
    frame: usize,
    /// Distance along the truth from that frame to the last, metres.
    distance_m: f64,
    /// End-point translation error, metres.
    translation_error_m: f64,
    /// The same as a percentage of the distance.
    translation_error_percent: f64,
    /// Angle of the end-point rotation error, degrees.
    rotation_error_deg: f64,
}

/// The end-point errors of the estimate's motion from `from` to the last frame against the
/// truth's (both expressed in frame `from`'s camera frame); `None` when `from` is not
/// before the last frame of both.
fn end_point_errors(
    estimate_first_from_camera: &[Isometry3<f64>],
    truth_first_from_camera: &[Isometry3<f64>],
    from: usize,
) -> Option<EndPointErrors> {
    let last = estimate_first_from_camera
        .len()
        .min(truth_first_from_camera.len())
        .checked_sub(1)?;
    if from >= last {
        return None;
    }
    let relative = |poses: &[Isometry3<f64>]| poses[from].inverse() * poses[last];
    let (estimate, truth) = (
        relative(estimate_first_from_camera),
        relative(truth_first_from_camera),
    );
    let distance_m: f64 = truth_first_from_camera[from..=last]
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum();
    let translation_error_m = (estimate.translation.vector - truth.translation.vector).norm();
    Some(EndPointErrors {
        frame: from,
        distance_m,
        translation_error_m,
        translation_error_percent: 100.0 * translation_error_m / distance_m.max(1e-9),
        rotation_error_deg: (truth.inverse() * estimate).rotation.angle().to_degrees(),
    })
}

/// Runs `segloc eval vo`.
pub fn eval(a: &EvalVoArgs) -> anyhow::Result<i32> {
    exit_code((|| {
        let config = config_of(&a.vo_config)?;
        let (sequence, source) = a.sequence.read()?;
        let Some(truth) = sequence.truth.clone() else {
            return Err(VoError::Sequence {
                path: source,
                message: "the sequence has no ground truth (poses.txt, truth.tum or recorded \
                          rover poses)"
                    .into(),
            }
            .into());
        };
        let results = run_sequence(&sequence, &config)?;
        if let Some(path) = &a.per_frame {
            write_atomic(path, per_frame_csv(&results).as_bytes())?;
        }
        let poses: Vec<Isometry3<f64>> = results.iter().map(|r| r.pose).collect();
        let from_frame = match a.from_frame {
            Some(n) => {
                Some(
                    end_point_errors(&poses, &truth, n).ok_or_else(|| VoError::Sequence {
                        path: source.clone(),
                        message: format!("--from-frame {n}: not before the last frame"),
                    })?,
                )
            }
            None => None,
        };
        let distance_m: f64 = truth
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum();
        let (Some(end), Some(end_truth)) = (results.last(), truth.last()) else {
            return Err(VoError::Sequence {
                path: source,
                message: "no frames".into(),
            }
            .into());
        };
        let err = end_truth.inverse() * end.pose;
        let translation_error_m =
            (end.pose.translation.vector - end_truth.translation.vector).norm();
        let out = EvalOutput {
            distance_m,
            translation_error_m,
            translation_error_percent: 100.0 * translation_error_m / distance_m.max(1e-9),
            rotation_error_deg: err.rotation.angle().to_degrees(),
            from_frame,
            drift_10m: segment_drift(&poses, &truth, 10.0),
            vo: summary(&results, &config),
        };
        if a.json {
            super::print_json(&out)?;
        } else {
            println!(
                "{} frames over {:.2} m: end-point translation error {:.3} m ({:.2} %), rotation error {:.3}°; {:.1} ms per frame median, {:.1} ms p99, {} lost",
                out.vo.frames, out.distance_m, out.translation_error_m, out.translation_error_percent, out.rotation_error_deg, out.vo.per_frame_ms.median, out.vo.per_frame_ms.p99, out.vo.lost_frames
            );
            println!("{}", stage_line(&out.vo.stage_ms_median));
            if let Some(e) = &out.from_frame {
                println!(
                    "from frame {} ({:.2} m): end-point translation error {:.3} m ({:.2} %), rotation error {:.3}°",
                    e.frame, e.distance_m, e.translation_error_m, e.translation_error_percent, e.rotation_error_deg
                );
            }
            if let Some(d) = &out.drift_10m {
                println!(
                    "over {} segments of 10 m: translation drift {:.2} % (p90 {:.2} %), rotation {:.3}° per 10 m",
                    d.segments, d.translation_percent, d.translation_percent_p90, d.rotation_deg_per_10m
                );
            }
        }
        Ok(())
    })())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    #[test]
    fn errors_from_a_frame_ignore_the_error_made_before_it() {
        let step = |yaw: f64| {
            Isometry3::from_parts(
                Translation3::new(0.0, 0.0, 1.0),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), yaw),
            )
        };
        let mut truth = vec![Isometry3::identity()];
        let mut estimate = vec![Isometry3::identity()];
        for k in 0..6 {
            // the estimate turns 1° too far on the first step only
            let extra = if k == 0 { 1f64.to_radians() } else { 0.0 };
            truth.push(truth[k] * step(0.01));
            estimate.push(estimate[k] * step(0.01 + extra));
        }
        let all = end_point_errors(&estimate, &truth, 0).unwrap();
        assert!(
            (all.rotation_error_deg - 1.0).abs() < 1e-9,
            "{}",
            all.rotation_error_deg
        );
        let later = end_point_errors(&estimate, &truth, 1).unwrap();
        assert!(later.rotation_error_deg < 1e-9 && later.translation_error_m < 1e-9);
        assert!((later.distance_m - 5.0).abs() < 1e-9);
        assert!(end_point_errors(&estimate, &truth, 6).is_none());
    }
}
