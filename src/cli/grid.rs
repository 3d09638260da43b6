//! `segloc grid rocks|score|tune`: LAC grids from real detections, and their score.

use super::print_json;
use anyhow::{Context, Result};
use clap::Subcommand;
use segloc::mapping::{
    cross_validate, pictures, score, sensitivity, RockEvidence, RockEvidenceConfig, ThresholdResult,
};
use segloc_maps::{read_grid_csv, read_lunarloc_traverse, write_grid_csv, LacGrid, Traverse};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Grid commands.
#[derive(Subcommand, Debug)]
pub enum GridCommand {
    /// Build the LAC rock map (180 × 180 cells of 0.15 m, heights unfilled) from LunarLoc
    /// traverse CSVs: cells detected far more often than their exposure explains.
    Rocks {
        /// LunarLoc traverse CSVs (`traverse_N.csv`).
        #[arg(long, num_args = 1.., required = true)]
        traverses: Vec<PathBuf>,
        /// The grid CSV to write (atomically), in the ground-truth format.
        #[arg(short, long)]
        output: PathBuf,
        /// Rock-evidence parameters (TOML of `RockEvidenceConfig`); defaults otherwise.
        #[arg(long, value_name = "FILE")]
        evidence_config: Option<PathBuf>,
        /// Override the minimum (repeated) detections per rock cell.
        #[arg(long)]
        min_hits: Option<u32>,
        /// Override the minimum (repeated) detections per unit of exposure.
        #[arg(long)]
        min_rate: Option<f64>,
        /// Print a JSON summary.
        #[arg(long)]
        json: bool,
    },
    /// Score a grid CSV against a ground-truth grid CSV by the LAC rules.
    Score {
        /// The grid to score.
        grid: PathBuf,
        /// The ground truth (e.g. lac-groundtruth/moon_map_01_preset_1.csv).
        #[arg(long)]
        groundtruth: PathBuf,
        /// Mission duration (s) for the productivity points.
        #[arg(long)]
        mission_seconds: Option<f64>,
        /// Also draw the rock map (true / false positives and negatives) to this PNG.
        #[arg(long, value_name = "PNG")]
        rock_picture: Option<PathBuf>,
        /// Also draw the height error to this PNG.
        #[arg(long, value_name = "PNG")]
        height_picture: Option<PathBuf>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Tune the rock-evidence thresholds: sector cross-validation and sensitivity.
    Tune {
        /// LunarLoc traverse CSVs.
        #[arg(long, num_args = 1.., required = true)]
        traverses: Vec<PathBuf>,
        /// The ground truth grid CSV.
        #[arg(long)]
        groundtruth: PathBuf,
        /// Rock-evidence parameters (TOML of `RockEvidenceConfig`); defaults otherwise.
        /// Everything but the two thresholds is taken from it.
        #[arg(long, value_name = "FILE")]
        evidence_config: Option<PathBuf>,
        /// Number of angular sectors.
        #[arg(long, default_value_t = 4)]
        folds: usize,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
}

/// Run a grid command.
pub fn run(cmd: &GridCommand) -> Result<i32> {
    match cmd {
        GridCommand::Rocks {
            traverses,
            output,
            evidence_config,
            min_hits,
            min_rate,
            json,
        } => {
            let mut config = load_evidence_config(evidence_config.as_deref())?;
            if let Some(h) = min_hits {
                config.min_hits = *h;
            }
            if let Some(r) = min_rate {
                anyhow::ensure!(
                    r.is_finite() && *r >= 0.0,
                    "--min-rate must be a non-negative number, got {r}"
                );
                config.min_rate = *r;
            }
            rocks(traverses, output, &config, *json)
        }
        GridCommand::Score {
            grid,
            groundtruth,
            mission_seconds,
            rock_picture,
            height_picture,
            json,
        } => {
            let wanted = Pictures {
                rock: rock_picture.as_deref(),
                height: height_picture.as_deref(),
            };
            score_grid(grid, groundtruth, *mission_seconds, &wanted, *json)
        }
        GridCommand::Tune {
            traverses,
            groundtruth,
            evidence_config,
            folds,
            json,
        } => tune(
            traverses,
            groundtruth,
            evidence_config.as_deref(),
            *folds,
            *json,
        ),
    }
}

/// `grid rocks`: the rock grid from the traverses' detections, written to `output`.
fn rocks(
    traverses: &[PathBuf],
    output: &Path,
    config: &RockEvidenceConfig,
    json: bool,
) -> Result<i32> {
    let loaded = read_traverses(traverses)?;
    let evidence = RockEvidence::from_traverses(&LacGrid::new_lac(), &loaded, config);
    let grid = evidence.rock_grid();
    write_grid_csv(&grid, output).context("writing the rock grid")?;
    let detections: usize = loaded.iter().map(Traverse::num_detections).sum();
    let used = evidence.config();
    let bias_m = used.view_bias_m.unwrap_or(0.0);
    let bias_source = if config.view_bias_m.is_some() {
        "configured"
    } else {
        "estimated from the traverses"
    };
    if json {
        print_json(&json!({
            "output": output, "traverses": loaded.len(), "detections": detections,
            "views": evidence.views, "rock_cells": grid.rock_count(),
            "view_bias_m": bias_m, "view_bias_source": bias_source,
            "lander_ground_z_m": used.lander.ground_z_m,
            "lander_structure_detections": evidence.lander_structure, "config": used,
        }))?;
    } else {
        println!(
            "{} rock cells from {} detections in {} traverses ({} views; viewpoint bias {:.2} cm, {}; {}) -> {}",
            grid.rock_count(),
            detections,
            loaded.len(),
            evidence.views,
            100.0 * bias_m,
            bias_source,
            lander_note(used, evidence.lander_structure),
            output.display()
        );
    }
    Ok(0)
}

/// The optional pictures of `grid score`.
struct Pictures<'a> {
    /// The rock map (true / false positives and negatives).
    rock: Option<&'a Path>,
    /// The height error.
    height: Option<&'a Path>,
}

/// `grid score`: the LAC score of `grid` against `groundtruth`, and its pictures.
fn score_grid(
    grid: &Path,
    groundtruth: &Path,
    mission_seconds: Option<f64>,
    wanted: &Pictures<'_>,
    json: bool,
) -> Result<i32> {
    let estimate = read_grid_csv(grid)?;
    let truth = read_grid_csv(groundtruth)?;
    let s = score(&estimate, &truth, mission_seconds)
        .with_context(|| format!("scoring {}", grid.display()))?;
    if let Some(p) = wanted.rock {
        let title = format!("ROCK MAP F1 {:.3}", s.rock_f1);
        pictures::rock_map_png(&estimate, &truth, &title, p)?;
    }
    if let Some(p) = wanted.height {
        let title = format!("HEIGHT MAP {:.1}/300", s.geometric);
        pictures::height_error_png(&estimate, &truth, &title, p)?;
    }
    if json {
        print_json(&s)?;
        return Ok(0);
    }
    println!(
        "geometric    {:7.2} / 300  ({:.2}% of cells within 5 cm)",
        s.geometric,
        100.0 * s.height_within_5cm_fraction
    );
    println!(
        "rocks        {:7.2} / 300  (F1 {:.4}: precision {:.4}, recall {:.4}; TP {}, FP {}, FN {})",
        s.rocks,
        s.rock_f1,
        s.rock_precision,
        s.rock_recall,
        s.true_positives,
        s.false_positives,
        s.false_negatives
    );
    match mission_seconds {
        Some(_) => println!("productivity {:7.2} / 250", s.productivity),
        None => println!("productivity    0.00 / 250  (no --mission-seconds)"),
    }
    println!("fiducials    {:7.2} / 150", s.fiducials);
    println!("total        {:7.2} / 1000", s.total);
    Ok(0)
}

/// `grid tune`: sector cross-validation of the rock-evidence thresholds, and their
/// sensitivity.
fn tune(
    traverses: &[PathBuf],
    groundtruth: &Path,
    evidence_config: Option<&Path>,
    folds: usize,
    json: bool,
) -> Result<i32> {
    anyhow::ensure!(folds >= 2, "--folds must be at least 2");
    let truth = read_grid_csv(groundtruth)?;
    let loaded = read_traverses(traverses)?;
    let config = load_evidence_config(evidence_config)?;
    let evidence = RockEvidence::from_traverses(&truth, &loaded, &config);
    let hits = [1, 2, 3, 4, 5];
    let rates: Vec<f64> = (1..=80).map(|k| 0.005 * k as f64).collect();
    let cv = cross_validate(&evidence, &truth, &hits, &rates, folds);
    let table = sensitivity(&evidence, &truth, &hits, &rates);
    let at_default = sensitivity(&evidence, &truth, &[config.min_hits], &[config.min_rate]);
    let best = table.iter().max_by(|a, b| a.f1.total_cmp(&b.f1)).cloned();
    if json {
        print_json(&json!({
            "cross_validation": cv, "default": at_default.first(), "best_in_sample": best,
            "sensitivity": table, "config": evidence.config(),
        }))?;
        return Ok(0);
    }
    let h = &cv.held_out;
    println!(
        "{}-sector cross-validation: held-out F1 {:.4} (precision {:.4}, recall {:.4}; TP {}, FP {}, FN {}); chosen {:?}",
        cv.folds, h.f1, h.precision, h.recall, h.tp, h.fp, h.fn_, cv.chosen
    );
    if let Some(d) = at_default.first() {
        println!(
            "defaults (min_hits {}, min_rate {}): F1 {:.4} (precision {:.4}, recall {:.4})",
            d.min_hits, d.min_rate, d.f1, d.precision, d.recall
        );
    }
    print_sensitivity(&table, &hits, &rates);
    Ok(0)
}

/// The F1 table of `grid tune`: one row per `min_hits`, one column per fourth `min_rate`.
fn print_sensitivity(table: &[ThresholdResult], hits: &[u32], rates: &[f64]) {
    println!("sensitivity (F1 by min_hits, rows; min_rate, columns):");
    print!("      ");
    for r in rates.iter().skip(3).step_by(4) {
        print!(" {r:5.2}");
    }
    println!();
    for &hh in hits {
        print!("  {hh:2}  ");
        for r in rates.iter().skip(3).step_by(4) {
            let f = table
                .iter()
                .find(|t| t.min_hits == hh && t.min_rate == *r)
                .map_or(f64::NAN, |t| t.f1);
            print!(" {f:5.3}");
        }
        println!();
    }
}

fn read_traverses(paths: &[PathBuf]) -> Result<Vec<Traverse>> {
    paths
        .iter()
        .map(|p| read_lunarloc_traverse(p).map_err(anyhow::Error::from))
        .collect()
}

fn load_evidence_config(path: Option<&Path>) -> Result<RockEvidenceConfig> {
    let Some(path) = path else {
        return Ok(RockEvidenceConfig::default());
    };
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let config: RockEvidenceConfig =
        toml::from_str(&text).with_context(|| format!("evidence config {}", path.display()))?;
    config
        .validate()
        .map_err(|e| anyhow::anyhow!("evidence config {}: {e}", path.display()))?;
    Ok(config)
}

/// What the lander-structure test did, for the one-line summary.
fn lander_note(used: &RockEvidenceConfig, dropped: usize) -> String {
    let lander = &used.lander;
    match lander.ground_z_m {
        Some(z) if lander.is_active() => {
            format!("{dropped} detections on the lander's structure dropped (ground z {z:.2} m)")
        }
        _ if lander.half_extent_m > 0.0 => {
            "lander test off: no rover frame near the lander".to_string()
        }
        _ => "lander test off".to_string(),
    }
}
