//! `segloc eval lunarloc|merge|landmarks|stream|segmenter|render`.

use super::print_json;
use super::relocalize::parse_dof;
use anyhow::{bail, Result};
use clap::Subcommand;
use segloc::align::Dof;
use segloc::eval::landmark_quality::{match_map, match_rocks};
use segloc::eval::lunarloc::{
    all_pairs, evaluate, self_pairs, EvalOptions, EvalReport, PAPER_PAIRS, TRAVERSES,
};
use segloc::eval::merge::{evaluate_merge, merged_rock_map, MergeEvalOptions};
use segloc::eval::stream::{
    carry_calibration, evaluate_stream, CalibrationDrives, DriftConfig, PairChoice, StreamReport,
};
use segloc::eval::traverse_path;
use segloc::landmarks::fuse_detections;
use segloc::localizer::LocalizerConfig;
use segloc::relocalize::RelocalizeConfig;
use segloc_maps::{read_grid_csv, read_lunarloc_traverse};
use serde_json::json;
use std::path::PathBuf;

/// Evaluation commands.
#[derive(Subcommand, Debug)]
pub enum EvalCommand {
    /// Stereo visual odometry on a KITTI-layout sequence with ground truth: end-point
    /// translation error as a percentage of the distance, rotation error, time per frame.
    Vo(super::vo::EvalVoArgs),
    /// Relocalize pairs of LunarLoc traverses under random rigid transforms.
    Lunarloc(LunarlocArgs),
    /// Merge random subsets of LunarLoc traverses, each moved by its own random transform,
    /// and compare every placement with the truth.
    Merge(MergeArgs),
    /// Replay LunarLoc traverses frame by frame through the online localizer, each against
    /// another traverse's map, with drifting odometry; score every pose against the truth.
    Stream(StreamArgs),
    /// Global localization: every LunarLoc traverse (and 60 s submap) against the
    /// ground-truth rock grid, under random rigid transforms, with no prior session.
    Grid(super::eval_grid::GridArgs),
    /// A segmenter's recall and precision on the real LAC pairs against hand labels.
    Segmenter(super::eval_segmenter::EvalSegmenterArgs),
    /// The perception front end on rendered frames of the synthetic moon against their
    /// truth: recall, precision and centroid error, by range band and sun elevation.
    Render(super::eval_render::EvalRenderArgs),
    /// How fused landmarks fall on the ground-truth rock cells, per traverse.
    Landmarks(LandmarksArgs),
}

/// Arguments of `segloc eval lunarloc`.
#[derive(clap::Args, Debug)]
pub struct LunarlocArgs {
    /// The data folder holding `lunarloc/traverse_N.csv`.
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Which pairs: the five of the LunarLoc paper, or all 136.
    #[arg(long, default_value = "paper", value_parser = ["paper", "all"])]
    pub pairs: String,
    /// Negatives: mirror every query traverse in x, so that no answer is right and
    /// every acceptance counts as a false accept; the pairs gain each traverse against
    /// its own mirror image.
    #[arg(long)]
    pub negatives: bool,
    /// Random transforms per pair.
    #[arg(long, default_value_t = 20)]
    pub trials: usize,
    /// Seed of the transforms.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Motion model (see `segloc relocalize --dof`).
    #[arg(long, default_value = "auto", value_parser = ["4", "6", "auto"])]
    pub dof: String,
    /// Tilt every query by a random roll and pitch, each within ± this many degrees,
    /// which the query map does not declare (it still claims to be gravity-aligned), as
    /// an IMU's error would: gravity-aligned models only.
    #[arg(long, default_value_t = 0.0)]
    pub tilt_deg: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `segloc eval merge`.
#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// The data folder holding `lunarloc/traverse_N.csv`.
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Agents (traverses) per trial.
    #[arg(long, default_value_t = 5)]
    pub agents: usize,
    /// Decoy agents per trial: traverses mirrored in x, which share no boulder with any
    /// other map and must be reported disconnected.
    #[arg(long, default_value_t = 1)]
    pub decoys: usize,
    /// Trials.
    #[arg(long, default_value_t = 10)]
    pub trials: usize,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Instead: merge all 17 traverses and compare the merged map's rock grid with
    /// every single traverse's, against the LAC ground truth.
    #[arg(long)]
    pub rock_map: bool,
    /// Viewpoint-bias correction (m) of the detections when each agent's map is fused
    /// (the value measured on the LunarLoc traverses by default; 0 = none).
    #[arg(long, default_value_t = segloc::landmarks::view_bias::LUNARLOC_VIEW_BIAS_M)]
    pub view_bias_m: f64,
    /// Boulder-to-boulder spread (m) of the viewpoint bias, modelled in the landmark
    /// covariances along each landmark's mean line of sight (0 = not modelled).
    #[arg(long, default_value_t = segloc::landmarks::view_bias::LUNARLOC_VIEW_BIAS_SIGMA_M)]
    pub view_bias_sigma_m: f64,
}

/// Arguments of `segloc eval landmarks`.
#[derive(clap::Args, Debug)]
pub struct LandmarksArgs {
    /// The data folder holding `lunarloc/` and `lac-groundtruth/`.
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `segloc eval stream`.
#[derive(clap::Args, Debug)]
pub struct StreamArgs {
    /// The data folder holding `lunarloc/traverse_N.csv`.
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Which ordered pairs (prior, query): `paper` (the five of the LunarLoc paper, both
    /// ways), `all` (every ordered pair whose maps share a boulder) or a list `3:5,5:3`.
    #[arg(long, default_value = "paper")]
    pub pairs: String,
    /// Seed of the odometry's random start and yaw random walk.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The odometry's yaw drift, degrees per 10 m driven.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub yaw_drift_deg_per_10m: f64,
    /// The odometry's scale error (0.01: distances 1 % too long).
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    pub scale_error: f64,
    /// The odometry's yaw random walk, 1 σ, radians per √m driven.
    #[arg(long, default_value_t = 0.0005)]
    pub yaw_walk_rad_per_sqrt_m: f64,
    /// The localizer's configuration (TOML, a `LocalizerConfig`); defaults otherwise. (The
    /// global `--config` is the relocalizer's: its `[landmarks]` fuse the prior maps, as in
    /// `segloc map build`.)
    #[arg(long, value_name = "FILE")]
    pub localizer_config: Option<PathBuf>,
    /// Carry an odometry calibration into the pairs from earlier drives of the same rover:
    /// `others` (every ordered pair sharing a boulder among the traverses the pairs do not
    /// use) or a list `1:2,2:1`. The drives run first, in order, each starting from the
    /// median of the earlier drives' estimates (random walks seeded with the seed + 1000);
    /// every pair then starts from the median of all, as `[calibration.known]`, with its
    /// standard error as the priors' σ.
    #[arg(long, value_name = "DRIVES")]
    pub carry_calibration: Option<String>,
    /// Print one JSON object (per-pair rows, the aggregate, the configuration).
    #[arg(long)]
    pub json: bool,
}

/// Run an evaluation.
pub fn run(cmd: &EvalCommand, config: &RelocalizeConfig) -> Result<i32> {
    match cmd {
        EvalCommand::Vo(args) => super::vo::eval(args),
        EvalCommand::Lunarloc(args) => run_lunarloc(args, config),
        EvalCommand::Merge(args) if args.rock_map => run_merged_rock_map(args, config),
        EvalCommand::Merge(args) => run_merge(args, config),
        EvalCommand::Stream(args) => run_stream(args, config),
        EvalCommand::Grid(args) => super::eval_grid::run(args, config),
        EvalCommand::Segmenter(args) => super::eval_segmenter::run(args),
        EvalCommand::Render(args) => super::eval_render::run(args),
        EvalCommand::Landmarks(args) => run_landmarks(args, config),
    }
}

/// `segloc eval lunarloc`.
fn run_lunarloc(args: &LunarlocArgs, config: &RelocalizeConfig) -> Result<i32> {
    let LunarlocArgs {
        data,
        pairs,
        negatives,
        trials,
        seed,
        dof,
        tilt_deg,
        json,
    } = args;
    if *trials == 0 {
        bail!("--trials must be at least 1");
    }
    let dof = parse_dof(Some(dof)).unwrap_or(Dof::Auto);
    if !(tilt_deg.is_finite() && (0.0..=10.0).contains(tilt_deg)) {
        bail!("--tilt-deg must be within 0..=10, got {tilt_deg}");
    }
    if *tilt_deg > 0.0 && !dof.needs_gravity() {
        bail!("--tilt-deg is for the gravity-aligned models (--dof 4 or auto)");
    }
    let mut config = config.clone();
    config.dof = Some(dof);
    let mut chosen = if pairs == "all" {
        all_pairs()
    } else {
        PAPER_PAIRS.to_vec()
    };
    if *negatives {
        chosen.extend(self_pairs());
    }
    let options = EvalOptions {
        pairs: chosen,
        trials: *trials,
        seed: *seed,
        dof,
        negatives: *negatives,
        tilt_deg: *tilt_deg,
    };
    let bar = indicatif::ProgressBar::new(options.pairs.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} pairs {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let report = evaluate(data, &options, &config, |done, _| {
        bar.set_position(done as u64)
    })?;
    bar.finish_and_clear();
    if *json {
        print_json(&report)?;
    } else {
        print_table(&report);
    }
    Ok(0)
}

/// `segloc eval merge --rock-map`.
fn run_merged_rock_map(args: &MergeArgs, config: &RelocalizeConfig) -> Result<i32> {
    let mut fusion = config.landmarks.clone();
    fusion.view_bias_m = args.view_bias_m;
    fusion.view_bias_sigma_m = args.view_bias_sigma_m;
    let r = merged_rock_map(&args.data, args.seed, &fusion, config)?;
    if args.json {
        print_json(&r)?;
    } else {
        println!(
            "merged map of all 17 traverses: rock F1 {:.3} (precision {:.3}, recall {:.3})",
            r.merged_f1, r.merged_precision, r.merged_recall
        );
        println!(
            "best single traverse: {} with F1 {:.3}",
            r.best_single.0, r.best_single.1
        );
    }
    Ok(0)
}

/// `segloc eval merge`.
fn run_merge(args: &MergeArgs, config: &RelocalizeConfig) -> Result<i32> {
    if args.agents < 2 || args.trials == 0 {
        bail!("--agents must be at least 2 and --trials at least 1");
    }
    let options = MergeEvalOptions {
        agents: args.agents,
        decoys: args.decoys,
        trials: args.trials,
        seed: args.seed,
        view_bias_m: args.view_bias_m,
        view_bias_sigma_m: args.view_bias_sigma_m,
    };
    let report = evaluate_merge(&args.data, &options, config, |_, _| {})?;
    if args.json {
        let mut value = serde_json::to_value(&report)?;
        value["config"] = json!(config);
        value["view_bias_m"] = json!(args.view_bias_m);
        value["view_bias_sigma_m"] = json!(args.view_bias_sigma_m);
        return print_json(&value).map(|()| 0);
    }
    for (k, t) in report.trials.iter().enumerate() {
        let line: Vec<String> = t
            .agents
            .iter()
            .map(|a| match (a.decoy, a.merged, a.translation_error_m) {
                (true, false, _) => format!("decoy {}: disconnected", a.traverse),
                (true, true, _) => format!("decoy {}: PLACED", a.traverse),
                (false, true, Some(e)) => format!("{}: {:.2} cm", a.traverse, e * 100.0),
                _ => format!("{}: disconnected", a.traverse),
            })
            .collect();
        println!("trial {k:>2} ({:.0} ms): {}", t.time_ms, line.join(", "));
    }
    println!(
        "placed {}/{} real agents ({} outside 1 cm / 0.1°); decoys placed {}/{}; translation error mean {:.2} cm, max {:.2} cm; rotation max {:.3}°; merge time median {:.0} ms",
        report.placed, report.agents, report.placed_outside_1cm_0p1deg, report.decoys_placed, report.decoys,
        report.translation_error_m.mean * 100.0, report.translation_error_m.max * 100.0,
        report.rotation_error_deg.max, report.time_ms.median
    );
    Ok(0)
}

/// `segloc eval landmarks`.
fn run_landmarks(args: &LandmarksArgs, config: &RelocalizeConfig) -> Result<i32> {
    let data = &args.data;
    let grid = read_grid_csv(&data.join("lac-groundtruth/moon_map_01_preset_1.csv"))?;
    let mut rows = Vec::new();
    for n in 1..=TRAVERSES {
        let traverse = read_lunarloc_traverse(&traverse_path(data, n))?;
        let set = traverse.detections();
        let map = fuse_detections(&set, &config.landmarks);
        let raw = match_rocks(&set.positions(), &grid);
        let fused = match_map(&map, &grid);
        rows.push(json!({"traverse": n, "detections": raw, "landmarks": fused, "landmark_count": map.len()}));
        if !args.json {
            println!(
                "traverse {n:>2}: {:>5} detections ({:>4.1}% on rock, {:>4.1}% on/beside) -> {:>4} landmarks ({:>4.1}% on rock, {:>4.1}% on/beside)",
                raw.points, 100.0 * raw.on_rock, 100.0 * raw.near_rock,
                fused.points, 100.0 * fused.on_rock, 100.0 * fused.near_rock
            );
        }
    }
    if args.json {
        print_json(&json!({"traverses": rows, "config": config.landmarks}))?;
    }
    Ok(0)
}

fn print_table(report: &EvalReport) {
    println!(
        "{:>5} {:>5} {:>6} {:>6} {:>6} {:>8} {:>8} {:>6} {:>10} {:>10} {:>9}",
        "prior",
        "query",
        "lm_p",
        "lm_q",
        "common",
        "success",
        "false+",
        "inl",
        "t_err_cm",
        "r_err_deg",
        "time_ms"
    );
    for p in &report.pairs {
        let t_err: Vec<f64> = p
            .trials
            .iter()
            .filter(|t| t.correct)
            .filter_map(|t| t.translation_error_m)
            .collect();
        let r_err: Vec<f64> = p
            .trials
            .iter()
            .filter(|t| t.correct)
            .filter_map(|t| t.rotation_error_deg)
            .collect();
        let mean = |v: &[f64]| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let inl =
            p.trials.iter().map(|t| t.inliers).sum::<usize>() as f64 / p.trials.len().max(1) as f64;
        let time = p.trials.iter().map(|t| t.time_ms).sum::<f64>() / p.trials.len().max(1) as f64;
        println!(
            "{:>5} {:>5} {:>6} {:>6} {:>6} {:>5}/{:<2} {:>8} {:>6.1} {:>10.3} {:>10.4} {:>9.1}",
            p.prior,
            p.query,
            p.prior_landmarks,
            p.query_landmarks,
            p.true_common,
            p.successes,
            p.trials.len(),
            p.false_accepts,
            inl,
            100.0 * mean(&t_err),
            mean(&r_err),
            time
        );
    }
    let t = &report.totals;
    if report.negatives {
        println!(
            "negatives (queries mirrored in x, no answer is right): accepted {} of {} (every one a false accept); time ms: mean {:.1} max {:.1}",
            t.false_accepts, t.trials, t.time_ms.mean, t.time_ms.max
        );
        return;
    }
    println!(
        "success {}/{} ({:.1}%), false accepts {}, pairs with >= 8 common: {}/{}",
        t.successes,
        t.trials,
        100.0 * t.success_rate,
        t.false_accepts,
        t.successes_with_8_common,
        t.trials_with_8_common
    );
    println!(
        "motion model {}, query tilt within ±{}°: accepted within 2 cm {}/{} ({:.1}%), accepted over 10 cm {}",
        report.motion_model,
        report.tilt_deg,
        t.accepted_within_2cm,
        t.trials,
        100.0 * t.accepted_within_2cm as f64 / t.trials.max(1) as f64,
        t.accepted_over_10cm
    );
    println!(
        "translation error cm: mean {:.3} median {:.3} max {:.3}; rotation error deg: mean {:.4} max {:.4}; time ms: mean {:.1} max {:.1}",
        100.0 * t.translation_error_m.mean, 100.0 * t.translation_error_m.median, 100.0 * t.translation_error_m.max,
        t.rotation_error_deg.mean, t.rotation_error_deg.max, t.time_ms.mean, t.time_ms.max
    );
}

/// `segloc eval stream`.
fn run_stream(args: &StreamArgs, config: &RelocalizeConfig) -> Result<i32> {
    let choice = parse_pairs(&args.pairs)?;
    let mut localizer = super::load_toml(
        args.localizer_config.as_deref(),
        "localizer config",
        LocalizerConfig::validate,
    )?;
    let drift = DriftConfig {
        yaw_walk_rad_per_sqrt_m: args.yaw_walk_rad_per_sqrt_m,
        yaw_drift_deg_per_10m: args.yaw_drift_deg_per_10m,
        scale_error: args.scale_error,
    };
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} pairs {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let carried = match &args.carry_calibration {
        Some(drives) => {
            let drives = match (drives.as_str(), parse_pairs(drives)) {
                ("others", _) => CalibrationDrives::OtherTraverses,
                (_, Ok(PairChoice::List(list))) => CalibrationDrives::List(list),
                _ => bail!(
                    "--carry-calibration: expected `others` or pairs PRIOR:QUERY separated by \
                     commas (e.g. 1:2,2:1), got `{drives}`"
                ),
            };
            let carried = carry_calibration(
                &args.data,
                &drives,
                &choice,
                &drift,
                args.seed,
                &config.landmarks,
                &localizer,
            )?;
            localizer.calibration.carry(carried.known, carried.sigma);
            Some(carried)
        }
        None => None,
    };
    let mut report = evaluate_stream(
        &args.data,
        &choice,
        &drift,
        args.seed,
        &config.landmarks,
        &localizer,
        |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        },
    )?;
    report.carried_calibration = carried;
    bar.finish_and_clear();
    if args.json {
        print_json(&report)?;
    } else {
        print_stream_table(&report);
    }
    Ok(0)
}

/// `paper`, `all`, or a list of ordered pairs `3:5,5:3`.
fn parse_pairs(text: &str) -> Result<PairChoice> {
    match text {
        "paper" => return Ok(PairChoice::Paper),
        "all" => return Ok(PairChoice::All),
        _ => {}
    }
    let mut list = Vec::new();
    for item in text.split(',') {
        let parsed = item
            .split_once(':')
            .and_then(|(a, b)| Some((a.trim().parse().ok()?, b.trim().parse().ok()?)));
        match parsed {
            Some(pair) => list.push(pair),
            None => bail!(
                "--pairs: expected `paper`, `all` or pairs PRIOR:QUERY separated by commas \
                 (e.g. 3:5,5:3), got `{item}`"
            ),
        }
    }
    Ok(PairChoice::List(list))
}

/// Centimetres with two decimals, `-` when absent.
fn cm(value: Option<f64>) -> String {
    value.map_or_else(|| "-".into(), |v| format!("{:.2}", 100.0 * v))
}

fn print_stream_table(report: &StreamReport) {
    println!(
        "{:>5} {:>5} {:>6} {:>5} {:>6} {:>4} {:>4} {:>6} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>6} {:>7} {:>5} {:>6} {:>6} {:>7}  refused",
        "prior", "query", "common", "step", "frames", "att", "acc", "fix_s", "online", "smooth",
        "pre_ba", "odom", "oracle", "cal_orc", "seen", "online", "wrong", "ms_med", "ms_p99", "ms_att"
    );
    for p in &report.pairs {
        let refused: Vec<String> = p.refused.iter().map(|(k, n)| format!("{k} {n}")).collect();
        let (all, seen) = (&p.rmse, &p.rmse_seeing_prior);
        println!(
            "{:>5} {:>5} {:>6} {:>5} {:>6} {:>4} {:>4} {:>6} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>6} {:>7} {:>5} {:>6.2} {:>6.2} {:>7.1}  {}",
            p.prior,
            p.query,
            p.common_landmarks,
            p.frame_step,
            p.frames,
            p.attempts,
            p.accepted,
            p.time_to_first_fix_s
                .map_or_else(|| "-".into(), |t| format!("{t:.0}")),
            cm(all.online_m),
            cm(all.smoothed_m),
            cm(all.before_adjustment_m),
            cm(all.odometry_m),
            cm(all.oracle_m),
            cm(all.calibrated_oracle_m),
            seen.frames,
            cm(seen.online_m),
            p.wrong_fixes.len(),
            p.time.median_ms,
            p.time.p99_ms,
            p.time.attempt_median_ms,
            refused.join(", ")
        );
    }
    let a = &report.aggregate;
    println!(
        "(RMSE in cm over the frames from the first fix on: online, smoothed, smoothed before \
         the boulder adjustment, odometry alone aligned at the first frame, the fix oracle \
         (frames seeing the prior map placed exactly, odometry between), the same on perfectly \
         calibrated odometry (its random walk only); then the frames \
         among them that see the prior map and their online RMSE)"
    );
    println!(
        "{} pairs, {} with a fix; online RMSE median {:.2} cm, max {:.2} cm (seeing the prior \
         map: median {:.2}, max {:.2}); smoothed median {:.2} cm, max {:.2} cm; accepted {}, \
         wrong fixes {}; first fix after {:.0} s (median); frame {:.3} ms, with an attempt \
         {:.1} ms (medians)",
        a.pairs,
        a.pairs_with_fix,
        100.0 * a.median_rmse_online_m,
        100.0 * a.max_rmse_online_m,
        100.0 * a.median_rmse_online_seeing_prior_m,
        100.0 * a.max_rmse_online_seeing_prior_m,
        100.0 * a.median_rmse_smoothed_m,
        100.0 * a.max_rmse_smoothed_m,
        a.accepted,
        a.wrong_fixes,
        a.median_time_to_first_fix_s,
        a.median_frame_ms,
        a.median_attempt_ms
    );
    if let Some(c) = &report.carried_calibration {
        let (k, s) = (&c.known, &c.sigma);
        println!(
            "odometry calibration carried in from {} drives (seed {}): scale error {:.3} ± {:.3} %, \
             yaw drift {:.5} ± {:.5} rad/m, yaw-rate scale error {:.4} ± {:.4} %",
            c.drives.len(),
            c.seed,
            100.0 * k.scale_error,
            100.0 * s.scale_error,
            k.yaw_drift_rad_per_m,
            s.yaw_drift_rad_per_m,
            100.0 * k.yaw_scale_error,
            100.0 * s.yaw_scale_error
        );
    }
}
