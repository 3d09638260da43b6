//! `segloc eval grid`: global localization of LunarLoc traverses against the rock grid.

use super::print_json;
use anyhow::{bail, Result};
use segloc::eval::grid::{evaluate_grid, GridEvalOptions, GridReport, KindSummary};
use segloc::eval::lunarloc::TRAVERSES;
use segloc::landmarks::GridRocksConfig;
use segloc::relocalize::RelocalizeConfig;
use std::path::PathBuf;

/// Arguments of `segloc eval grid`.
#[derive(clap::Args, Debug)]
pub struct GridArgs {
    /// The data folder holding `lunarloc/` and `lac-groundtruth/`.
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Cell size (m) of the prior grid: 0.15 (the ground truth), or 0.3 / 0.45 (cells
    /// OR-ed together).
    #[arg(long, default_value_t = 0.15)]
    pub cell_size: f64,
    /// Random transforms per whole traverse.
    #[arg(long, default_value_t = 20)]
    pub trials: usize,
    /// Traverse numbers, comma-separated (default: all 17).
    #[arg(long, value_delimiter = ',')]
    pub traverses: Vec<usize>,
    /// Also query every 60 s submap of each traverse (one random transform each).
    #[arg(long)]
    pub submaps: bool,
    /// Submap length (s).
    #[arg(long, default_value_t = 60.0)]
    pub submap_s: f64,
    /// Also query every traverse mirrored in x (`--trials` transforms each): every
    /// acceptance is wrong.
    #[arg(long)]
    pub negatives: bool,
    /// Seed of the transforms (and of the extra rocks).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Add this many synthetic single-cell rocks to the prior (timing a larger site).
    #[arg(long, default_value_t = 0)]
    pub extra_rocks: usize,
    /// Cells at least this large (m) are each one rock landmark (default: the
    /// `grid_rocks.split_from_cell_m` default, 0.3), instead of one per cluster of touching cells.
    #[arg(long)]
    pub split_from_cell: Option<f64>,
    /// Print one JSON object (every query included).
    #[arg(long)]
    pub json: bool,
}

/// Run `segloc eval grid`.
pub fn run(args: &GridArgs, config: &RelocalizeConfig) -> Result<i32> {
    if args.trials == 0 {
        bail!("--trials must be at least 1");
    }
    if !(args.submap_s.is_finite() && args.submap_s > 0.0) {
        bail!("--submap-s must be positive, got {}", args.submap_s);
    }
    let traverses = if args.traverses.is_empty() {
        (1..=TRAVERSES).collect()
    } else {
        args.traverses.clone()
    };
    if let Some(n) = traverses.iter().find(|&&n| !(1..=TRAVERSES).contains(&n)) {
        bail!("--traverses: {n} is not a traverse number (1..={TRAVERSES})");
    }
    let options = GridEvalOptions {
        traverses,
        cell_size_m: args.cell_size,
        trials: args.trials,
        submaps: args.submaps,
        submap_s: args.submap_s,
        negatives: args.negatives,
        seed: args.seed,
        extra_rocks: args.extra_rocks,
        grid_rocks: GridRocksConfig {
            split_from_cell_m: args
                .split_from_cell
                .unwrap_or(GridRocksConfig::default().split_from_cell_m),
            ..GridRocksConfig::default()
        },
    };
    options.grid_rocks.validate()?;
    let report = evaluate_grid(&args.data, &options, config, |_, _| {})?;
    if args.json {
        print_json(&report)?;
    } else {
        print_report(&report);
    }
    Ok(0)
}

fn print_report(report: &GridReport) {
    println!(
        "prior: {} rocks from the {} m grid; {} transforms per traverse",
        report.prior_landmarks, report.cell_size_m, report.trials
    );
    let line = |name: &str, s: &KindSummary| {
        if s.queries == 0 {
            return;
        }
        println!(
            "{name:>10}: {} queries, {} accepted, {} within 5 cm/0.3°, {} within 15 cm, {} wrong, \
             {} refused; traverses all within 5 cm {} / 15 cm {}; max error {:.1} cm {:.2}°; \
             time median {:.0} ms (CPU {:.0} ms), max {:.0} ms",
            s.queries,
            s.accepted,
            s.within_5cm,
            s.within_15cm,
            s.wrong,
            s.refused,
            s.traverses_all_within_5cm,
            s.traverses_all_within_15cm,
            s.max_error_m * 100.0,
            s.max_error_deg,
            s.time_ms_median,
            s.cpu_ms_median,
            s.time_ms_max
        );
    };
    line("traverses", &report.traverses);
    line("submaps", &report.submaps);
    line("negatives", &report.negatives);
}
