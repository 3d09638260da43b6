//! `segloc sim field [--seed S] [--out DIR] [--json]`: a generated boulder field seen by two
//! rover sessions (the second in its own frame), fused into maps and relocalized end to end —
//! a quick fixture of detection files and maps for `segloc relocalize` and `segloc map`.

use super::print_json;
use anyhow::{Context, Result};
use clap::Args;
use segloc::eval::transform_error;
use segloc::landmarks::fuse_detections;
use segloc::relocalize::{RelocalizeConfig, Relocalizer};
use segloc::sim::boulder_field::{two_session_detections, FieldConfig};
use segloc_maps::{write_detections, write_map};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `segloc sim field`.
#[derive(Args, Debug)]
pub struct FieldArgs {
    /// Seed of the generated field and sessions.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Folder to write the sessions' detections, maps and the report into.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Run it: 0 when the relocalization is accepted and correct, 1 otherwise.
pub fn run(args: &FieldArgs, config: &RelocalizeConfig) -> Result<i32> {
    let started = Instant::now();
    let field = FieldConfig::default();
    let (prior_dets, query_dets, truth) = two_session_detections(&field, args.seed);
    let prior = fuse_detections(&prior_dets, &config.landmarks);
    let query = fuse_detections(&query_dets, &config.landmarks);
    let answer = Relocalizer::new(prior.clone(), config.clone())?.relocalize(&query)?;
    let errors = answer
        .prior_from_query()
        .map(|t| transform_error(&t, &truth));
    let correct = errors.is_some_and(|(t, r)| t < 0.05 && r < 0.5);
    let time_ms = started.elapsed().as_secs_f64() * 1e3;
    let mut report = super::relocalize::report(&answer, config, time_ms);
    report["field"] = serde_json::json!({
        "seed": args.seed,
        "prior_detections": prior_dets.len(),
        "query_detections": query_dets.len(),
        "true_prior_from_query": segloc::relocalize::result::matrix_rows(&truth),
        "translation_error_m": errors.map(|e| e.0),
        "rotation_error_deg": errors.map(|e| e.1),
        "correct": correct,
    });
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        write_detections(&prior_dets, &dir.join("prior_detections.csv"))?;
        write_detections(&query_dets, &dir.join("query_detections.csv"))?;
        write_map(&prior, &dir.join("prior_map.json"))?;
        write_map(&query, &dir.join("query_map.json"))?;
        segloc_maps::write_atomic(
            &dir.join("report.json"),
            serde_json::to_string_pretty(&report)?.as_bytes(),
        )?;
    }
    if args.json {
        print_json(&report)?;
    } else {
        println!(
            "segloc sim field (seed {}): a generated boulder field, two rover sessions",
            args.seed
        );
        println!(
            "  prior session: {} detections -> {} landmarks; query session: {} detections -> {} landmarks",
            prior_dets.len(), prior.len(), query_dets.len(), query.len()
        );
        println!("  the query session starts in its own frame: unknown yaw and position");
        match &answer.outcome {
            Ok(accepted) => {
                let (t, r) = errors.unwrap_or_default();
                println!(
                    "  relocalized: {} inliers, rmse {:.2} cm; error against the truth {:.2} cm, {:.3}°",
                    accepted.inliers.len(), answer.rmse_m * 100.0, t * 100.0, r
                );
            }
            Err(reason) => println!("  refused: {reason}"),
        }
        println!("  {:.1} ms in all", time_ms);
        if let Some(dir) = &args.out {
            println!(
                "  wrote detections, maps and report.json to {}",
                dir.display()
            );
        }
    }
    Ok(if correct { 0 } else { 1 })
}
