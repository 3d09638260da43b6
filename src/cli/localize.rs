//! `segloc localize`: a recorded drive through the online localizer, against a prior
//! session's map or, without one, as a mapping session; writes the trajectory as a TUM file
//! and, with `--map-out`, the session's boulder map. The drive is a frames file, or stereo
//! images (`--lac`, `--images`) that the visual odometry and the perception front end turn
//! into frames first ([`segloc::image_stream`]).

use super::detect::{make_segmenter, SegmenterKind};
use anyhow::{bail, Context, Result};
use clap::Args;
use segloc::image_stream::{stream_sequence, ImageStreamConfig, StreamOutput};
use segloc::io::inputs::load_map;
use segloc::localizer::{FrameInput, FrameOutput, Localizer, LocalizerConfig, SessionResult};
use segloc::vo::StereoSequence;
use segloc_maps::frames::{read_frames, write_frames};
use segloc_maps::tum::write_tum;
use serde_json::json;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Arguments of `segloc localize`.
#[derive(Args, Debug)]
pub struct LocalizeArgs {
    /// The drive: a frames file (JSON Lines, maps/FORMAT.md "Frames file").
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present_any = ["print_config", "lac", "images"],
        conflicts_with_all = ["lac", "images"]
    )]
    frames: Option<PathBuf>,
    /// The drive as a `.lac` recording: its front stereo pairs through the visual odometry
    /// and the perception front end, with the recorded IMU's gravity.
    #[arg(long, value_name = "FILE", conflicts_with = "images")]
    lac: Option<PathBuf>,
    /// The drive as a `segloc sim render` folder (stereo pairs, calibration, imu.csv).
    #[arg(long, value_name = "DIR")]
    images: Option<PathBuf>,
    /// With `--lac` or `--images`: the segmenter of the front end.
    #[arg(long, value_enum, default_value = "geometric")]
    segmenter: SegmenterKind,
    /// With `--segmenter onnx` (or another model for `learned`): the ONNX model.
    #[arg(long, value_name = "ONNX")]
    model: Option<PathBuf>,
    /// With `--lac` or `--images`: the image stream's settings (TOML: `detect_period_s`,
    /// `min_range_m`, `max_range_m`, `[vo]`, `[front_end]`).
    #[arg(long, value_name = "FILE")]
    stream_config: Option<PathBuf>,
    /// With `--lac` or `--images`: also write the frames the images gave (a frames file).
    #[arg(long, value_name = "FILE")]
    frames_out: Option<PathBuf>,
    /// The prior session's map (map file, detections CSV or LunarLoc traverse CSV); without
    /// it the drive is a mapping session anchored at its first frame.
    #[arg(long, value_name = "MAP")]
    prior: Option<PathBuf>,
    /// Where to write the trajectory `prior_from_rover` (TUM: `t tx ty tz qx qy qz qw`).
    #[arg(
        short,
        long,
        value_name = "FILE",
        required_unless_present = "print_config"
    )]
    output: Option<PathBuf>,
    /// Also write the session's boulder map (in the prior's frame when there is a prior).
    #[arg(long, value_name = "FILE")]
    map_out: Option<PathBuf>,
    /// Write every frame, also those before the first fix (placed by the final solve).
    #[arg(long)]
    all_frames: bool,
    /// Write the estimates the localizer gave while driving, not the final solve's (the
    /// final solve's for frames before the first fix, with `--all-frames`).
    #[arg(long)]
    online: bool,
    /// The localizer's configuration (TOML, as `--print-config` prints it).
    #[arg(long, value_name = "FILE")]
    localizer_config: Option<PathBuf>,
    /// Print the localizer's configuration (TOML) and exit.
    #[arg(long)]
    print_config: bool,
    /// Print one JSON summary object.
    #[arg(long)]
    json: bool,
}

/// Run `segloc localize`: 0 success, 1 no fix against the prior map, 2 bad input.
pub fn run(args: &LocalizeArgs) -> Result<i32> {
    let config = super::load_toml(
        args.localizer_config.as_deref(),
        "localizer config",
        LocalizerConfig::validate,
    )?;
    if args.print_config {
        print!("{}", toml::to_string_pretty(&config)?);
        return Ok(0);
    }
    let Some(output) = &args.output else {
        bail!("--output is required");
    };
    let drive = read_drive(args)?;
    let frames_path = &drive.source;
    let prior = match &args.prior {
        Some(path) => Some(
            load_map(path, &config.fusion)
                .with_context(|| format!("prior map {}", path.display()))?
                .0,
        ),
        None => None,
    };
    let mapping = prior.is_none();
    // the query's detections are corrected as the prior's were
    let config = match &prior {
        Some(map) => config.calibrated_for(map),
        None => config,
    };
    let mut localizer = Localizer::new(prior, config.clone())?;
    let mut outputs = Vec::with_capacity(drive.frames.len());
    for frame in &drive.frames {
        let out = localizer
            .push_frame(frame)
            .with_context(|| format!("{}", frames_path.display()))?;
        outputs.push(out);
    }
    let first_fix = localizer.first_fix_frame();
    let session = localizer.finish()?;
    let mut summary = summary(&drive.frames, &outputs, &session, first_fix, &config);
    if let Some(images) = &drive.images {
        summary["image_stream"] = images.clone();
    }
    let Some(first_fix) = first_fix else {
        report(args, &summary, "no fix: nothing written")?;
        return Ok(1);
    };
    let times: Vec<f64> = drive.frames.iter().map(|f| f.t).collect();
    let poses = trajectory(&times, &outputs, &session, args, first_fix);
    write_tum(output, &poses)?;
    if let Some(path) = &args.map_out {
        segloc_maps::write_map(&session.map, path)?;
    }
    let what = if mapping {
        "mapping session"
    } else {
        "localized"
    };
    report(args, &summary, what)?;
    Ok(0)
}

/// A drive's frames, where they came from and, for images, the image stream's summary.
struct Drive {
    frames: Vec<FrameInput>,
    source: PathBuf,
    images: Option<serde_json::Value>,
}

/// The frames of `--frames`, or of `--lac` / `--images` through the image stream (written to
/// `--frames-out` when asked).
fn read_drive(args: &LocalizeArgs) -> Result<Drive> {
    if let Some(path) = &args.frames {
        let file = read_frames(path)?;
        for warning in &file.warnings {
            eprintln!("warning: {warning}");
        }
        return Ok(Drive {
            frames: file.frames,
            source: path.clone(),
            images: None,
        });
    }
    let config = super::load_toml(
        args.stream_config.as_deref(),
        "image stream config",
        ImageStreamConfig::validate,
    )?;
    let (sequence, source) = match (&args.lac, &args.images) {
        (Some(lac), _) => (StereoSequence::read_lac(lac)?, lac.clone()),
        (_, Some(dir)) => (StereoSequence::read_rendered(dir)?, dir.clone()),
        _ => bail!("give the drive: --frames FILE, --lac FILE or --images DIR"),
    };
    let segmenter = make_segmenter(args.segmenter, args.model.as_deref(), &config.front_end)?;
    let outputs = stream_sequence(&sequence, config.clone(), segmenter)
        .with_context(|| format!("{}", source.display()))?;
    let frames: Vec<FrameInput> = outputs.iter().map(|o| o.frame.clone()).collect();
    if let Some(path) = &args.frames_out {
        write_frames(path, &frames)?;
    }
    Ok(Drive {
        images: Some(image_summary(&outputs, &config)),
        frames,
        source,
    })
}

/// The image stream's part of the `--json` summary.
fn image_summary(outputs: &[StreamOutput], config: &ImageStreamConfig) -> serde_json::Value {
    let vo_ms: Vec<f64> = outputs.iter().map(|o| o.vo.time_ms).collect();
    let front_end_ms: Vec<f64> = outputs.iter().filter_map(|o| o.front_end_ms).collect();
    json!({
        "pairs": outputs.len(),
        "vo_lost_frames": outputs.iter().filter(|o| o.vo.lost).count(),
        "detection_frames": front_end_ms.len(),
        "detections": outputs.iter().map(|o| o.frame.detections.len()).sum::<usize>(),
        "vo_ms": stats(&vo_ms),
        "front_end_ms": stats(&front_end_ms),
        "config": config,
    })
}

/// The poses to write: from the first fix on (every frame with `--all-frames`), the final
/// solve's or, with `--online`, those given while driving.
fn trajectory(
    times: &[f64],
    outputs: &[FrameOutput],
    session: &SessionResult,
    args: &LocalizeArgs,
    first_fix: usize,
) -> Vec<(f64, nalgebra::Isometry3<f64>)> {
    let from = if args.all_frames { 0 } else { first_fix };
    (from..times.len())
        .filter_map(|k| {
            // with --online, what the localizer gave while driving, where it gave a pose
            let online = outputs.get(k).and_then(|o| o.prior_from_rover);
            let pose = match online.filter(|_| args.online) {
                Some(pose) => pose,
                None => *session.poses.get(k)?,
            };
            Some((times[k], pose))
        })
        .collect()
}

/// Print the summary: JSON, or a few lines for people (on stderr when there is no fix).
fn report(args: &LocalizeArgs, summary: &serde_json::Value, what: &str) -> Result<()> {
    if args.json {
        super::print_json(summary)?;
        return Ok(());
    }
    let fixes = &summary["fixes"];
    let line = format!(
        "{what}: {} frames, {} fixes accepted, {} refused {}, first fix at {} s; per frame {} ms median, {} ms p99",
        summary["frames"],
        fixes["accepted"],
        fixes["refused"],
        fixes["reasons"],
        summary["first_fix_t"],
        summary["per_frame_ms"]["median"],
        summary["per_frame_ms"]["p99"],
    );
    if summary["first_fix_t"].is_null() {
        eprintln!("{line}");
    } else {
        println!("{line}");
    }
    Ok(())
}

/// The `--json` summary.
fn summary(
    frames: &[segloc::localizer::FrameInput],
    outputs: &[FrameOutput],
    session: &SessionResult,
    first_fix: Option<usize>,
    config: &LocalizerConfig,
) -> serde_json::Value {
    let mut reasons: BTreeMap<String, usize> = BTreeMap::new();
    for a in session.attempts.iter().filter(|a| !a.accepted()) {
        *reasons.entry(a.status.code().to_string()).or_default() += 1;
    }
    let accepted = session.attempts.iter().filter(|a| a.accepted()).count();
    let prior_from_odom = match (frames.last(), session.poses.last(), first_fix) {
        (Some(f), Some(p), Some(_)) => {
            let m = (p * f.odom_from_rover.inverse()).to_homogeneous();
            json!((0..4)
                .map(|r| (0..4).map(|c| m[(r, c)]).collect::<Vec<_>>())
                .collect::<Vec<_>>())
        }
        _ => serde_json::Value::Null,
    };
    let plain: Vec<f64> = outputs
        .iter()
        .filter(|o| !o.attempted())
        .map(|o| o.time_ms)
        .collect();
    let attempts: Vec<f64> = outputs
        .iter()
        .filter(|o| o.attempted())
        .map(|o| o.time_ms)
        .collect();
    json!({
        "frames": frames.len(),
        "fixes": {
            "accepted": accepted,
            "refused": session.attempts.len() - accepted,
            "reasons": reasons,
        },
        "first_fix_t": first_fix.and_then(|k| frames.get(k)).map(|f| f.t),
        "prior_from_odom": prior_from_odom,
        "per_frame_ms": stats(&plain),
        "attempt_ms": stats(&attempts),
        "online_solves": session.online_solves,
        "landmarks_in_map": session.map.len(),
        "odometry_bias": session.odometry_bias,
        "config": config,
    })
}

/// Median, 99th percentile and maximum of `values` (nulls when empty).
fn stats(values: &[f64]) -> serde_json::Value {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let at = |q: f64| {
        v.get(((v.len() as f64 - 1.0) * q).round() as usize)
            .copied()
    };
    json!({"median": at(0.5), "p99": at(0.99), "max": v.last(), "count": v.len()})
}
