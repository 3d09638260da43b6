//! `segloc mission`: the two-session mission on the synthetic moon of a seed — session 1
//! maps, session 2 starts lost and relocalizes against it — with the LAC maps scored.

use super::detect::{make_segmenter, SegmenterKind};
use super::print_json;
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use segloc::mission::grid_start::Session1Start;
use segloc::mission::perception::{BoulderSensors, OdometrySource};
use segloc::mission::{
    run_mission_with, MissionConfig, MissionOutput, MissionProgress, MissionStage, Silent,
};
use segloc::perception::Segmenter;
use segloc::relocalize::RelocalizeConfig;
use std::cell::Cell;
use std::path::{Path, PathBuf};

/// Arguments of `segloc mission`.
#[derive(Args, Debug)]
pub struct MissionArgs {
    /// Seed of the moon and of both sessions.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated seconds per session (default: the mission configuration's).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write report.json, the pictures and each session's trajectories (TUM: truth, estimate,
    /// odometry alone; with `--sensors rendered`, every VO pair as `sessionN_vo.csv`) into
    /// this directory.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Mission configuration (TOML, fields of `MissionConfig`); defaults otherwise. Its
    /// `relocalize` table is replaced by the global `--config` when that is given.
    #[arg(long, value_name = "FILE")]
    pub mission_config: Option<PathBuf>,
    /// Show a progress bar on stderr.
    #[arg(long)]
    pub progress: bool,
    /// Start from the coverage mission (`MissionConfig::lac_coverage`: both sessions 600 s
    /// on the LAC coverage loops; by default only session 1 is) instead of the defaults,
    /// when no `--mission-config`.
    #[arg(long)]
    pub coverage: bool,
    /// Where the boulder detections come from: the sensor model, or the perception front
    /// end on rendered stereo pairs (default: the mission configuration's
    /// `perception.sensors`, "model").
    #[arg(long, value_enum)]
    pub sensors: Option<SensorsArg>,
    /// The segmenter of `--sensors rendered`.
    #[arg(long, value_enum, default_value = "geometric")]
    pub segmenter: SegmenterKind,
    /// ONNX model file for `--segmenter onnx` (or another model for `--segmenter learned`).
    #[arg(long, value_name = "ONNX")]
    pub model: Option<PathBuf>,
    /// Render at half resolution (640 × 360) with `--sensors rendered`.
    #[arg(long)]
    pub half: bool,
    /// With `--sensors rendered`: the odometry from the stereo VO on the rendered front
    /// pair (`images`), or from the drift model (`model`) (default: the mission
    /// configuration's `perception.odometry`, "images").
    #[arg(long, value_enum)]
    pub vo: Option<VoArg>,
    /// How session 1 starts: at its known pose, or lost with a seeded wrong guess,
    /// relocalizing against the site's ground-truth rock grid (default: the mission
    /// configuration's `session_1_start`, "known").
    #[arg(long, value_enum)]
    pub session1_start: Option<Session1StartArg>,
}

/// `--session1-start`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Session1StartArg {
    /// At `start_1`, known.
    Known,
    /// Lost, relocalized against the site's rock grid (`session_1_start = "lost_vs_grid"`).
    LostVsGrid,
}

/// `--vo`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum VoArg {
    /// The stereo visual odometry on rendered images.
    Images,
    /// The drift model (`sim::visual_odometry`).
    Model,
}

/// `--sensors`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SensorsArg {
    /// The sensor model (`sim::sensors`).
    Model,
    /// The front end on rendered images.
    Rendered,
}

/// Run the mission; exit code 0, or 2 on bad input.
pub fn run(
    args: &MissionArgs,
    relocalize: &RelocalizeConfig,
    global_config_given: bool,
) -> Result<i32> {
    let config = mission_config(args, relocalize, global_config_given)?;
    let segmenter = segmenter(args, &config)?;
    let output = if args.progress {
        let lost_1 = config.session_1_start == Session1Start::LostVsGrid;
        let bar = Bar::new(config.session_seconds(), lost_1);
        let output = run_mission_with(args.seed, &config, &bar, segmenter);
        bar.bar.finish_and_clear();
        output?
    } else {
        run_mission_with(args.seed, &config, &Silent, segmenter)?
    };
    if let Some(dir) = &args.out {
        output
            .write(dir)
            .with_context(|| format!("writing the mission's outputs to {}", dir.display()))?;
    }
    if args.json {
        print_json(&output.report)?;
    } else {
        print_summary(&output, args.out.as_deref());
    }
    Ok(0)
}

/// The mission configuration: `--mission-config` or the defaults, with `--seconds` and the
/// global relocalization `--config` applied.
fn mission_config(
    args: &MissionArgs,
    relocalize: &RelocalizeConfig,
    global_config_given: bool,
) -> Result<MissionConfig> {
    let base: MissionConfig = match &args.mission_config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            MissionConfig::from_toml(&text)
                .with_context(|| format!("mission config {}", path.display()))?
        }
        None if args.coverage => MissionConfig::lac_coverage(),
        None => MissionConfig::default(),
    };
    let seconds = args.seconds.unwrap_or(base.seconds_per_session);
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 1e5) {
        bail!("--seconds must be within (0, 1e5]");
    }
    let mut mission = MissionConfig {
        seconds_per_session: seconds,
        // `--seconds` sets both sessions
        seconds_session_2: if args.seconds.is_some() {
            None
        } else {
            base.seconds_session_2
        },
        ..base
    };
    if global_config_given {
        mission.localizer.relocalize = relocalize.clone();
    }
    match args.sensors {
        Some(SensorsArg::Model) => mission.perception.sensors = BoulderSensors::Model,
        Some(SensorsArg::Rendered) => mission.perception.sensors = BoulderSensors::Rendered,
        None => {}
    }
    if args.half {
        mission.perception.render.resolution_scale = 0.5;
    }
    match args.vo {
        Some(VoArg::Images) => mission.perception.odometry = OdometrySource::Images,
        Some(VoArg::Model) => mission.perception.odometry = OdometrySource::Model,
        None => {}
    }
    match args.session1_start {
        Some(Session1StartArg::Known) => mission.session_1_start = Session1Start::Known,
        Some(Session1StartArg::LostVsGrid) => mission.session_1_start = Session1Start::LostVsGrid,
        None => {}
    }
    Ok(mission)
}

/// The segmenter of the rendered sensing (`None`: the sensor model, or the default
/// geometric one); `--segmenter`, `--model` and `--half` are refused with the sensor model.
fn segmenter(args: &MissionArgs, config: &MissionConfig) -> Result<Option<Box<dyn Segmenter>>> {
    if config.perception.sensors == BoulderSensors::Model {
        if args.segmenter != SegmenterKind::Geometric
            || args.model.is_some()
            || args.half
            || args.vo.is_some()
        {
            bail!("--segmenter, --model, --half and --vo need --sensors rendered");
        }
        return Ok(None);
    }
    let front_end = &config.perception.front_end;
    Ok(Some(make_segmenter(
        args.segmenter,
        args.model.as_deref(),
        front_end,
    )?))
}

/// A progress bar over both sessions' simulated time; `session` is the one its message
/// names (0: none yet), so the message is set once per session, not every tick.
struct Bar {
    bar: ProgressBar,
    session: Cell<usize>,
    /// Simulated seconds of session 1 (where session 2 starts on the bar).
    first_s: f64,
    /// Session 1 starts lost against the site's rock grid.
    lost_1: bool,
}

impl Bar {
    const STEPS_PER_S: f64 = 10.0;

    fn new(session_seconds: [f64; 2], lost_1: bool) -> Self {
        let total_s: f64 = session_seconds.iter().sum();
        let bar = ProgressBar::new((total_s * Self::STEPS_PER_S) as u64);
        bar.set_style(
            ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Bar {
            bar,
            session: Cell::new(0),
            first_s: session_seconds[0],
            lost_1,
        }
    }
}

impl MissionProgress for Bar {
    fn update(&self, stage: MissionStage) {
        match stage {
            MissionStage::Driving {
                session, time_s, ..
            } => {
                let done_s = if session > 1 { self.first_s } else { 0.0 } + time_s;
                self.bar.set_position((done_s * Self::STEPS_PER_S) as u64);
                if self.session.replace(session) != session {
                    self.bar.set_message(match session {
                        1 if self.lost_1 => {
                            "session 1: lost, relocalizing against the site's grid".to_string()
                        }
                        1 => "session 1: mapping from a known start".to_string(),
                        _ => format!("session {session}: lost, relocalizing"),
                    });
                }
            }
            MissionStage::Mapping => {
                self.bar.set_position(self.bar.length().unwrap_or(0));
                self.bar.set_message("height and rock maps, LAC score");
            }
        }
    }
}

/// The human-readable summary.
pub fn print_summary(output: &MissionOutput, out: Option<&Path>) {
    let r = &output.report;
    for s in &r.sessions {
        println!(
            "session {}: {:.0} s, {:.1} m, RMSE {:.3} m (odometry only {:.3} m), {} collisions",
            s.session, s.duration_s, s.distance_m, s.rmse_m, s.rmse_without_global_m, s.collisions
        );
        if let Some(l) = &s.lost_start {
            let first = l
                .first_fix_s
                .map_or_else(|| "never".to_string(), |t| format!("at {t:.0} s"));
            let rmse = l
                .rmse_after_first_fix_m
                .map_or_else(|| "-".to_string(), |r| format!("{r:.3} m"));
            println!(
                "  lost start against the {} ({} landmarks): first fix {first}, {} accepted, \
                 {} refused, {} wrong accepted; RMSE from the first fix {rmse}",
                l.prior,
                l.prior_landmarks,
                l.fixes.accepted,
                l.fixes.refused,
                l.fixes.wrong_accepted
            );
        }
    }
    println!(
        "relocalizations: {} accepted, {} refused, {} wrong accepted",
        r.relocalizations.accepted, r.relocalizations.refused, r.relocalizations.wrong_accepted
    );
    println!(
        "LAC: geometric {:.1}, rocks {:.1}, productivity {:.1}, total {:.1}",
        r.lac.geometric, r.lac.rocks, r.lac.productivity, r.lac.total
    );
    if let Some(p) = &r.perception {
        println!(
            "perception ({} pairs at {} px, {}): recall {:.2}, precision {:.2}, centroid \
             error median {:.3} m; per pair: render {:.0} ms, front end {:.0} ms median, \
             {:.0} ms p99",
            p.pairs,
            p.width_px,
            p.segmenter,
            p.recall,
            p.precision,
            p.centroid_error_m.median,
            p.render_ms.median,
            p.front_end_ms.median,
            p.front_end_ms.p99
        );
    }
    println!(
        "{:.1} s wall, {:.0}× real time",
        r.wall_s, r.realtime_factor
    );
    if let Some(dir) = out {
        let recording = if cfg!(feature = "rerun") {
            ", mission.rrd (open with `rerun`)"
        } else {
            ""
        };
        println!(
            "wrote report.json, height_error.png, rock_map.png, trajectories.png, sessionN_{{truth,estimate,odometry}}.tum{recording} to {}",
            dir.display()
        );
    }
}

impl MissionArgs {
    /// The arguments `segloc demo` runs the mission with.
    pub fn for_demo(
        seed: u64,
        out: PathBuf,
        json: bool,
        mission_config: Option<PathBuf>,
        coverage: bool,
    ) -> Self {
        MissionArgs {
            seed,
            seconds: None,
            json,
            out: Some(out),
            mission_config,
            progress: true,
            coverage,
            sensors: None,
            segmenter: SegmenterKind::Geometric,
            model: None,
            half: false,
            vo: None,
            session1_start: None,
        }
    }
}
