//! `segloc sim render`: a drive of the mission's planner rendered as stereo images with
//! ground truth, in the layout of `docs/render-format.md`:
//!
//! `DIR/NNNNNN_0.png` (left), `NNNNNN_1.png` (right), `NNNNNN_ids.png` (rock instances,
//! 16-bit), `NNNNNN_depth.png` (left depth, 16-bit mm), `calibration.json`, `truth.tum`
//! (left camera poses), `rover_truth.tum`, `imu.csv` (gravity and the gyro's mean rate since
//! the previous frame, rover frame, [`segloc::sim::gyro`]) and
//! `rocks.json`; with `--lac`, the same frames as a `.lac` recording.
//!
//! Everything is written into a temporary directory beside `DIR`, renamed onto `DIR` at the
//! end: a failed run leaves nothing half-written.

use anyhow::{bail, Context, Result};
use clap::Args;
use nalgebra::{Isometry3, Vector3};
use segloc::mission::mapping_session::map_session;
use segloc::mission::{drive_sessions, MissionConfig, Silent};
use segloc::perception::lac::{ImageKind, Imu, LacFrame, LacWriter, FRONT_LEFT, FRONT_RIGHT};
use segloc::perception::write_gray_png;
use segloc::sim::gyro::{gyro_rates, GyroConfig};
use segloc::sim::ipex::TICK_S;
use segloc::sim::moon::Moon;
use segloc::sim::render::{rover_from_front_left_optical, RenderConfig, Renderer, StereoFrame};
use segloc::sim::session::{SessionLog, TickRecord};
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `segloc sim render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Seed of the mission (moon and drive).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The session to render: 1 (mapping, known start) or 2 (lost, after session 1).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=2))]
    session: u8,
    /// Simulated seconds of the rendered session.
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Render every K-th simulator tick (20 Hz): 20 gives the mission's 1 Hz camera frames,
    /// 2 gives 10 Hz.
    #[arg(long, default_value_t = 20)]
    every: usize,
    /// Output directory (refused if it exists and is not empty, unless `--overwrite`).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Replace a non-empty output directory.
    #[arg(long)]
    overwrite: bool,
    /// Also write the frames as a `.lac` recording (for `segloc detect --lac`).
    #[arg(long, value_name = "FILE")]
    lac: Option<PathBuf>,
    /// Renderer settings (TOML, the fields of `RenderConfig`; defaults otherwise).
    #[arg(long, value_name = "TOML")]
    render_config: Option<PathBuf>,
    /// Half resolution (640 × 360), overriding the settings' scale.
    #[arg(long)]
    half: bool,
    /// Sun elevation, degrees (overrides the settings).
    #[arg(long, allow_negative_numbers = true)]
    sun_elevation: Option<f64>,
    /// Sun azimuth, degrees counter-clockwise from +x (overrides the settings).
    #[arg(long, allow_negative_numbers = true)]
    sun_azimuth: Option<f64>,
}

/// The renderer's settings from a TOML file, or the defaults.
pub(super) fn load_render_config(path: Option<&Path>) -> Result<RenderConfig> {
    let Some(path) = path else {
        return Ok(RenderConfig::default());
    };
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    toml::from_str(&text).with_context(|| format!("{}", path.display()))
}

/// The renderer's settings from the arguments.
fn render_config(args: &RenderArgs) -> Result<RenderConfig> {
    let mut config = load_render_config(args.render_config.as_deref())?;
    if args.half {
        config.resolution_scale = 0.5;
    }
    if let Some(e) = args.sun_elevation {
        config.sun_elevation_deg = e;
    }
    if let Some(a) = args.sun_azimuth {
        config.sun_azimuth_deg = a;
    }
    let origin = args
        .render_config
        .as_ref()
        .map_or("command line".into(), |p| p.display().to_string());
    config.validate().with_context(|| origin)?;
    Ok(config)
}

/// Run `segloc sim render`.
pub fn run(args: &RenderArgs) -> Result<i32> {
    if !(args.seconds.is_finite() && args.seconds > 0.0 && args.seconds <= 1e5) {
        bail!("--seconds must be within (0, 1e5] (got {})", args.seconds);
    }
    if args.every == 0 {
        bail!("--every must be at least 1");
    }
    let config = render_config(args)?;
    check_output_dir(&args.output, args.overwrite)?;
    let (moon, log) = drive(args)?;
    let renderer = Renderer::new(&moon, &config, args.seed)?;
    let tmp = temp_dir_beside(&args.output)?;
    let written = write_frames(args, &renderer, &moon, &log, &tmp);
    if let Err(e) = written {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    if args.output.exists() {
        std::fs::remove_dir_all(&args.output)
            .with_context(|| format!("cannot replace {}", args.output.display()))?;
    }
    std::fs::rename(&tmp, &args.output)
        .with_context(|| format!("cannot move the frames to {}", args.output.display()))?;
    Ok(0)
}

/// Refuse an existing non-empty directory (or a file) unless `overwrite`.
fn check_output_dir(dir: &Path, overwrite: bool) -> Result<()> {
    if dir.is_file() {
        bail!("{}: exists and is a file, not a directory", dir.display());
    }
    if dir.is_dir() {
        let mut entries =
            std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))?;
        if entries.next().is_some() && !overwrite {
            bail!(
                "{}: exists and is not empty (pass --overwrite to replace it)",
                dir.display()
            );
        }
    }
    Ok(())
}

fn temp_dir_beside(dir: &Path) -> Result<PathBuf> {
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
    Ok(tmp)
}

/// The moon and the log of the session to render.
fn drive(args: &RenderArgs) -> Result<(Moon, SessionLog)> {
    let mut config = MissionConfig::default();
    if args.session == 1 {
        config.seconds_per_session = args.seconds;
        config.validate()?;
        let moon = Moon::generate(&config.moon, args.seed)?;
        let min_rock = config.session.collision_min_rock_radius_m;
        let s = config.start_1;
        let (x, y) = moon.nearest_clear_position(s[0], s[1], 1.0, min_rock);
        let one = map_session(
            &moon,
            &config,
            [x, y, s[2]],
            args.seed.wrapping_mul(2),
            &Silent,
        )?;
        Ok((moon, one.log))
    } else {
        config.seconds_session_2 = Some(args.seconds);
        let sessions = drive_sessions(args.seed, &config, &Silent)?;
        Ok((sessions.moon, sessions.two.log))
    }
}

/// The gyro's own seed for a rendered session.
fn gyro_seed(args: &RenderArgs) -> u64 {
    args.seed
        .wrapping_mul(4)
        .wrapping_add(u64::from(args.session))
}

/// Render every `--every`-th tick of `log` into `dir`.
fn write_frames(
    args: &RenderArgs,
    renderer: &Renderer,
    moon: &Moon,
    log: &SessionLog,
    dir: &Path,
) -> Result<()> {
    let rendered: Vec<(usize, &TickRecord)> =
        log.ticks.iter().enumerate().step_by(args.every).collect();
    let poses: Vec<_> = rendered
        .iter()
        .map(|(_, r)| (r.time_s, r.world_from_rover))
        .collect();
    let gyro = gyro_rates(&poses, &GyroConfig::default(), gyro_seed(args));
    let mut out = FrameOutputs::new(args);
    for ((tick, record), w) in rendered.into_iter().zip(gyro) {
        let frame = renderer.render_stereo(&record.world_from_rover, tick as u64);
        out.render_ms.push(frame.render_ms);
        write_frame_images(dir, tick, &frame)?;
        out.add(tick, record, w, frame);
    }
    out.write_truth(dir, moon)?;
    write_text(
        &dir.join("calibration.json"),
        &serde_json::to_string_pretty(&calibration(args, renderer, log.ticks.len()))?,
    )?;
    if let (Some(path), Some(writer)) = (&args.lac, &out.lac) {
        let bytes = writer.to_bytes()?;
        segloc_maps::write_atomic(path, &bytes)?;
    }
    report_render_times(args, renderer, out.render_ms);
    Ok(())
}

/// What the rendered frames leave besides their images, gathered frame by frame.
struct FrameOutputs {
    /// Time and `world_from_left` of each frame.
    truth: Vec<(f64, Isometry3<f64>)>,
    /// Time and `world_from_rover` of each frame.
    rover_truth: Vec<(f64, Isometry3<f64>)>,
    /// The text of `imu.csv`.
    imu: String,
    /// Each frame's entry of `rocks.json`.
    frames_json: Vec<serde_json::Value>,
    /// The `.lac` recording (with `--lac`).
    lac: Option<LacWriter>,
    /// Each pair's rendering time, milliseconds.
    render_ms: Vec<f64>,
}

impl FrameOutputs {
    /// Nothing rendered yet; a `.lac` recording when `args` asks for one.
    fn new(args: &RenderArgs) -> Self {
        FrameOutputs {
            truth: Vec::new(),
            rover_truth: Vec::new(),
            imu: String::from("frame,time_s,gravity_x,gravity_y,gravity_z,gyro_x,gyro_y,gyro_z\n"),
            frames_json: Vec::new(),
            lac: args.lac.as_ref().map(|_| {
                let mut meta = toml::Table::new();
                meta.insert("source".into(), "segloc sim render".into());
                meta.insert("seed".into(), (args.seed as i64).into());
                LacWriter::new(meta, toml::Table::new())
            }),
            render_ms: Vec::new(),
        }
    }

    /// Add the frame rendered at `tick` (`record` its tick, `w` the gyro's reading).
    fn add(&mut self, tick: usize, record: &TickRecord, w: Vector3<f64>, frame: StereoFrame) {
        self.truth.push((record.time_s, frame.world_from_left));
        self.rover_truth
            .push((record.time_s, record.world_from_rover));
        let g = record.gravity_rover;
        self.imu.push_str(&format!(
            "{tick},{:.3},{},{},{},{},{},{}\n",
            record.time_s, g.x, g.y, g.z, w.x, w.y, w.z
        ));
        self.frames_json
            .push(json!({"frame": tick, "time_s": record.time_s, "visible": frame.rocks}));
        if let Some(writer) = self.lac.as_mut() {
            writer.add_frame(LacFrame {
                frame: tick as u64,
                time_s: Some(record.time_s),
                pose: Some(record.world_from_rover),
                imu: Some(Imu {
                    accel: [-g.x, -g.y, -g.z],
                    gyro: [w.x, w.y, w.z],
                }),
            });
            writer.add_image(FRONT_LEFT, ImageKind::Grayscale, tick as u64, frame.left);
            writer.add_image(FRONT_RIGHT, ImageKind::Grayscale, tick as u64, frame.right);
        }
    }

    /// Write `truth.tum`, `rover_truth.tum`, `imu.csv` and `rocks.json` (`moon`'s rocks and
    /// the frames') into `dir`.
    fn write_truth(&self, dir: &Path, moon: &Moon) -> Result<()> {
        segloc_maps::write_tum(&dir.join("truth.tum"), &self.truth)?;
        segloc_maps::write_tum(&dir.join("rover_truth.tum"), &self.rover_truth)?;
        write_text(&dir.join("imu.csv"), &self.imu)?;
        let rocks: Vec<_> = moon
            .rocks()
            .iter()
            .enumerate()
            .map(|(id, r)| {
                json!({"id": id, "center_world": [r.center.x, r.center.y, r.center.z],
                    "radius_m": moon.rock_size_radius_m(id), "bounding_radius_m": r.radius_m,
                    "shape": r.shape})
            })
            .collect();
        let rocks_json = json!({"rocks": rocks, "frames": self.frames_json});
        write_text(
            &dir.join("rocks.json"),
            &serde_json::to_string(&rocks_json)?,
        )
    }
}

/// Tell how many pairs were rendered (`render_ms` their times) and their median time.
fn report_render_times(args: &RenderArgs, renderer: &Renderer, mut render_ms: Vec<f64>) {
    render_ms.sort_by(f64::total_cmp);
    let median = render_ms.get(render_ms.len() / 2).copied().unwrap_or(0.0);
    eprintln!(
        "{} stereo frames of session {} (seed {}) rendered at {} × {}, median {:.0} ms a pair -> {}",
        render_ms.len(),
        args.session,
        args.seed,
        renderer.camera().width,
        renderer.camera().height,
        median,
        args.output.display()
    );
}

fn calibration(args: &RenderArgs, renderer: &Renderer, ticks: usize) -> serde_json::Value {
    let c = renderer.camera();
    let m = rover_from_front_left_optical();
    let q = m.rotation.coords;
    json!({
        "format": "segloc sim render 1",
        "width": c.width, "height": c.height,
        "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
        "baseline_m": c.baseline_m,
        "camera_frame": "optical: x right, y down, z forward; the right camera is the left one moved by +baseline_m along x",
        "rover_frame": "x forward, y left, z up, origin at the IMU",
        "rover_from_left_camera": {
            "translation_m": [m.translation.x, m.translation.y, m.translation.z],
            "quaternion_xyzw": [q.x, q.y, q.z, q.w],
        },
        "seed": args.seed, "session": args.session,
        "every_ticks": args.every, "tick_s": TICK_S, "ticks": ticks,
        "render": renderer.config(),
    })
}

fn write_frame_images(dir: &Path, tick: usize, frame: &StereoFrame) -> Result<()> {
    write_gray_png(&frame.left, &dir.join(format!("{tick:06}_0.png")))?;
    write_gray_png(&frame.right, &dir.join(format!("{tick:06}_1.png")))?;
    let (w, h) = (frame.left.width as u32, frame.left.height as u32);
    let ids: Vec<u16> = frame
        .instance
        .iter()
        .map(|&i| i.min(u16::MAX as u32) as u16)
        .collect();
    write_png16(&dir.join(format!("{tick:06}_ids.png")), w, h, ids)?;
    let depth: Vec<u16> = frame
        .depth_m
        .iter()
        .map(|&d| {
            let mm = (d as f64 * 1000.0).round();
            if mm > 0.0 && mm < 65535.0 {
                mm as u16
            } else {
                0
            }
        })
        .collect();
    write_png16(&dir.join(format!("{tick:06}_depth.png")), w, h, depth)
}

fn write_png16(path: &Path, width: u32, height: u32, data: Vec<u16>) -> Result<()> {
    let image = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(width, height, data)
        .context("16-bit image of the wrong size")?;
    image
        .save_with_format(path, image::ImageFormat::Png)
        .with_context(|| format!("cannot write {}", path.display()))
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    let mut f =
        std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?;
    f.write_all(text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
}
