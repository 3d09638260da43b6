//! `segloc detect`: boulders from stereo images (one pair, or a whole `.lac` recording).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use nalgebra::Point3;
use segloc::perception::lac::LacRecording;
use segloc::perception::onnx::{shipped_model, LearnedSegmenter, OnnxSegmenter};
use segloc::perception::{
    overlay::write_overlay, read_gray_png, write_gray_png, DisparityMap, FrontEnd, FrontEndConfig,
    GeometricSegmenter, GrayImage, Segmenter,
};
use segloc_maps::{write_detections, Detection, DetectionSet};
use serde_json::json;

/// Which segmenter to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SegmenterKind {
    /// Training-free: what stands out of the ground in the stereo depth.
    Geometric,
    /// A FastSAM / YOLOv8-seg ONNX model (`--model`).
    Onnx,
    /// segloc's U-Net trained on rendered frames (`models/boulders.onnx`, found beside
    /// the binary or through `SEGLOC_MODELS`; `--model` overrides it).
    Learned,
}

/// Arguments of `segloc detect`.
#[derive(Args, Debug)]
pub struct DetectArgs {
    /// Left (reference) image: 8-bit grayscale PNG, rectified.
    #[arg(long, value_name = "PNG", requires = "right", conflicts_with = "lac")]
    pub left: Option<PathBuf>,
    /// Right image of the same instant.
    #[arg(long, value_name = "PNG", requires = "left")]
    pub right: Option<PathBuf>,
    /// A `.lac` recording: run every stereo frame and write detections (`-o`).
    #[arg(long, value_name = "ARCHIVE", requires = "output")]
    pub lac: Option<PathBuf>,
    /// Detections CSV to write for `--lac` (readable by `segloc map build`).
    #[arg(short, long, value_name = "CSV")]
    pub output: Option<PathBuf>,
    /// The segmenter.
    #[arg(long, value_enum, default_value = "geometric")]
    pub segmenter: SegmenterKind,
    /// ONNX model file for `--segmenter onnx` (or another model for `--segmenter learned`).
    #[arg(long, value_name = "ONNX")]
    pub model: Option<PathBuf>,
    /// Write an overlay picture (RGB PNG) of what was found.
    #[arg(long, value_name = "PNG")]
    pub overlay: Option<PathBuf>,
    /// Write the disparity map as a grayscale PNG (brighter = nearer, black = no match).
    #[arg(long, value_name = "PNG")]
    pub disparity: Option<PathBuf>,
    /// Front-end settings (TOML, as printed by `--print-config`).
    #[arg(long, value_name = "TOML")]
    pub frontend_config: Option<PathBuf>,
    /// Print the front-end settings as TOML and exit.
    #[arg(long)]
    pub print_config: bool,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Run `segloc detect`.
pub fn run(args: &DetectArgs) -> Result<i32> {
    let config = load_frontend_config(args.frontend_config.as_deref())?;
    if args.print_config {
        print!("{}", toml::to_string_pretty(&config)?);
        return Ok(0);
    }
    let segmenter = make_segmenter(args.segmenter, args.model.as_deref(), &config)?;
    let mut front_end = FrontEnd::new(config, segmenter)?;
    match (&args.left, &args.right, &args.lac) {
        (Some(left), Some(right), None) => detect_pair(args, &mut front_end, left, right),
        (None, None, Some(lac)) => detect_lac(args, &mut front_end, lac),
        _ => bail!("give either --left and --right, or --lac with -o"),
    }
}

/// The front-end settings from a TOML file, or the defaults.
pub(super) fn load_frontend_config(path: Option<&Path>) -> Result<FrontEndConfig> {
    let Some(path) = path else {
        return Ok(FrontEndConfig::default());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read front-end config {}", path.display()))?;
    toml::from_str(&text).with_context(|| format!("front-end config {}", path.display()))
}

/// The segmenter of this kind (`model`: the ONNX file for `onnx`, or another model than
/// the shipped one for `learned`).
pub(super) fn make_segmenter(
    kind: SegmenterKind,
    model: Option<&Path>,
    config: &FrontEndConfig,
) -> Result<Box<dyn Segmenter>> {
    match kind {
        SegmenterKind::Geometric => {
            if model.is_some() {
                bail!("--model is only used with --segmenter onnx or learned");
            }
            Ok(Box::new(GeometricSegmenter::new(config.geometric.clone())))
        }
        SegmenterKind::Onnx => {
            let Some(model) = model else {
                bail!("--segmenter onnx needs --model <file.onnx>");
            };
            let segmenter = OnnxSegmenter::load(model, config.onnx.clone())?;
            Ok(Box::new(segmenter))
        }
        SegmenterKind::Learned => {
            let path = match model {
                Some(p) => p.to_path_buf(),
                None => shipped_model()?,
            };
            Ok(Box::new(LearnedSegmenter::load(
                &path,
                config.learned.clone(),
            )?))
        }
    }
}

/// Reads a stereo pair of grayscale PNGs; an error names both files when their sizes differ.
pub(super) fn read_stereo_pair(left: &Path, right: &Path) -> Result<(GrayImage, GrayImage)> {
    let left_image = read_gray_png(left)?;
    let right_image = read_gray_png(right)?;
    if (left_image.width, left_image.height) != (right_image.width, right_image.height) {
        bail!(
            "{} is {} × {} but {} is {} × {}: not a stereo pair",
            left.display(),
            left_image.width,
            left_image.height,
            right.display(),
            right_image.width,
            right_image.height
        );
    }
    Ok((left_image, right_image))
}

fn detect_pair(
    args: &DetectArgs,
    front_end: &mut FrontEnd,
    left: &Path,
    right: &Path,
) -> Result<i32> {
    let (left_image, right_image) = read_stereo_pair(left, right)?;
    front_end
        .config()
        .camera
        .for_size(left_image.width, left_image.height)
        .with_context(|| format!("{}", left.display()))?;
    let result = front_end.process(&left_image, &right_image)?;
    if let Some(path) = &args.overlay {
        write_overlay(&left_image, &result, path)?;
    }
    if let Some(path) = &args.disparity {
        write_disparity_png(&result.disparity, path)?;
    }
    if args.json {
        let boulders: Vec<_> = result
            .boulders
            .iter()
            .map(|b| {
                json!({
                    "pixel_centroid": b.pixel_centroid,
                    "pixel_box": b.pixel_box,
                    "position_camera": b.position_camera,
                    "position_rover": b.position_rover,
                    "depth_m": b.depth_m,
                    "size_m": b.size_m,
                    "score": b.score,
                })
            })
            .collect();
        super::print_json(&json!({
            "boulders": boulders,
            "valid_disparity_fraction": valid_disparity_fraction(&result.disparity, &left_image),
            "gray_histogram": gray_histogram(&left_image),
            "time_ms": result.timing.total_ms,
            "timing": result.timing,
            "segmenter": front_end.segmenter_name(),
            "masks": result.masks.len(),
        }))?;
    } else {
        println!(
            "{} boulders ({} masks, {} segmenter) in {:.1} ms (stereo {:.1}, segment {:.1}, boulders {:.1})",
            result.boulders.len(),
            result.masks.len(),
            front_end.segmenter_name(),
            result.timing.total_ms,
            result.timing.stereo_ms,
            result.timing.segment_ms,
            result.timing.boulders_ms
        );
        println!("   u      v    depth_m   x_cam   y_cam   z_cam  size_m  score");
        for b in &result.boulders {
            println!(
                "{:6.1} {:6.1} {:8.2} {:7.2} {:7.2} {:7.2} {:7.2} {:6.2}",
                b.pixel_centroid[0],
                b.pixel_centroid[1],
                b.depth_m,
                b.position_camera[0],
                b.position_camera[1],
                b.position_camera[2],
                b.size_m,
                b.score
            );
        }
    }
    Ok(0)
}

fn detect_lac(args: &DetectArgs, front_end: &mut FrontEnd, lac: &Path) -> Result<i32> {
    let Some(output) = &args.output else {
        bail!("--lac needs -o <detections.csv>");
    };
    let recording = LacRecording::open(lac)?;
    let frames = recording.front_stereo_frames()?;
    let session = lac
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "lac".into());
    let with_pose = frames
        .iter()
        .all(|&f| recording.frame(f).and_then(|r| r.pose).is_some());
    let mut set = DetectionSet::new(
        session,
        if with_pose { "world" } else { "rover" },
        with_pose,
    );
    let mut total_ms = 0.0;
    let mut boulders = 0;
    for &frame in &frames {
        let (left, right) = recording.front_pair(frame)?;
        let result = front_end
            .process(&left, &right)
            .with_context(|| format!("{} frame {frame}", lac.display()))?;
        total_ms += result.timing.total_ms;
        boulders += result.boulders.len();
        let pose = recording
            .frame(frame)
            .and_then(|r| r.pose)
            .filter(|_| with_pose);
        for b in &result.boulders {
            let [x, y, z] = b.position_rover;
            let p_rover = Point3::new(x, y, z);
            let (p_world, rover_position) = match &pose {
                Some(world_from_rover) => (
                    world_from_rover * p_rover,
                    Some(Point3::from(world_from_rover.translation.vector)),
                ),
                None => (p_rover, None),
            };
            set.detections.push(Detection {
                frame,
                p_world,
                rover_position,
                size_m: Some(b.size_m),
                score: Some(b.score),
            });
        }
    }
    write_detections(&set, output)?;
    if args.json {
        super::print_json(&json!({
            "frames": frames.len(),
            "detections": boulders,
            "output": output,
            "frame": set.frame,
            "mean_time_ms": total_ms / frames.len() as f64,
        }))?;
    } else {
        println!(
            "{} detections from {} stereo frames ({:.1} ms per frame) -> {}",
            boulders,
            frames.len(),
            total_ms / frames.len() as f64,
            output.display()
        );
    }
    Ok(0)
}

/// Fraction of the lit pixels (grey level above 10, so not the black sky) whose disparity
/// is valid.
fn valid_disparity_fraction(map: &DisparityMap, left: &GrayImage) -> f64 {
    let (mut lit, mut valid) = (0usize, 0usize);
    for y in 0..map.height {
        for x in 0..map.width {
            let (u, v) = (x * map.scale, y * map.scale);
            if u < left.width && v < left.height && left.get(u, v) > 10 {
                lit += 1;
                valid += usize::from(map.data[y * map.width + x].is_finite());
            }
        }
    }
    valid as f64 / lit.max(1) as f64
}

/// Histogram of the grey levels in 32 bins of 8 levels, as fractions of the pixels.
fn gray_histogram(image: &GrayImage) -> Vec<f64> {
    let mut bins = vec![0.0; 32];
    for &g in &image.data {
        bins[g as usize / 8] += 1.0;
    }
    let n = image.data.len().max(1) as f64;
    bins.iter().map(|b| b / n).collect()
}

fn write_disparity_png(map: &DisparityMap, path: &Path) -> Result<()> {
    let max = map
        .data
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(1.0f32, f32::max);
    let data = map
        .data
        .iter()
        .map(|&d| {
            if d.is_finite() {
                (30.0 + 225.0 * d / max) as u8
            } else {
                0
            }
        })
        .collect();
    let image = GrayImage::new(map.width, map.height, data).context("disparity image")?;
    write_gray_png(&image, path)?;
    Ok(())
}
