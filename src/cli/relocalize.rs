//! `segloc relocalize --prior A --query B [--dof 4|6|auto] [--json]`.

use super::print_json;
use anyhow::{Context, Result};
use clap::Args;
use segloc::align::Dof;
use segloc::io::load_map;
use segloc::relocalize::result::{matrix6_rows, matrix_rows};
use segloc::relocalize::{Relocalization, RelocalizeConfig, Relocalizer};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `segloc relocalize`.
#[derive(Args, Debug)]
pub struct RelocalizeArgs {
    /// The prior session: a map file, a detections CSV or a LunarLoc traverse CSV.
    #[arg(long)]
    pub prior: PathBuf,
    /// The query session, same kinds of file.
    #[arg(long)]
    pub query: PathBuf,
    /// Motion model: 4 (yaw + translation, gravity-aligned maps), 6 (full rigid motion) or
    /// auto (gravity-aligned maps whose tilt may be off by a few tenths of a degree: 4-DOF
    /// association, then an alignment that also estimates the residual roll and pitch when
    /// the inliers determine them). Default: auto when both maps are gravity-aligned, else 6.
    #[arg(long, value_parser = ["4", "6", "auto"])]
    pub dof: Option<String>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Also write the all-to-all association problem of the two maps to this file (the
    /// exchange format of `segloc bench associate`), for benchmarking on real data.
    #[arg(long, value_name = "FILE")]
    pub dump_problem: Option<PathBuf>,
}

/// Parse a `--dof` value.
pub fn parse_dof(dof: Option<&str>) -> Option<Dof> {
    match dof {
        Some("4") => Some(Dof::Four),
        Some("6") => Some(Dof::Six),
        Some("auto") => Some(Dof::Auto),
        _ => None,
    }
}

/// Run it: 0 accepted, 1 refused, 2 bad input.
pub fn run(args: &RelocalizeArgs, config: &RelocalizeConfig) -> Result<i32> {
    let started = Instant::now();
    let mut config = config.clone();
    if let Some(dof) = parse_dof(args.dof.as_deref()) {
        config.dof = Some(dof);
    }
    let (prior, _) = load_map(&args.prior, &config.landmarks)?;
    let (query, _) = load_map(&args.query, &config.landmarks)?;
    if let Some(path) = &args.dump_problem {
        let dof = answer_dof(&config, &prior, &query);
        let text = segloc::io::association_problem::problem_to_string(
            &prior.positions(),
            &query.positions(),
            &segloc::relocalize::consistency::invariant(dof, &config.consistency),
        );
        segloc_maps::write_atomic(path, text.as_bytes())?;
    }
    let answer = Relocalizer::new(prior, config.clone())
        .and_then(|r| r.relocalize(&query))
        .with_context(|| {
            format!(
                "relocalizing {} against {}",
                args.query.display(),
                args.prior.display()
            )
        })?;
    let time_ms = started.elapsed().as_secs_f64() * 1e3;
    if args.json {
        print_json(&report(&answer, &config, time_ms))?;
    } else {
        print_summary(&answer, time_ms);
    }
    Ok(if answer.is_accepted() { 0 } else { 1 })
}

fn answer_dof(
    config: &RelocalizeConfig,
    prior: &segloc_maps::ObjectMap,
    query: &segloc_maps::ObjectMap,
) -> Dof {
    config
        .dof
        .unwrap_or(if prior.gravity_aligned && query.gravity_aligned {
            config.gravity_aligned_dof
        } else {
            Dof::Six
        })
}

/// The JSON report of one relocalization.
pub fn report(
    answer: &Relocalization,
    config: &RelocalizeConfig,
    time_ms: f64,
) -> serde_json::Value {
    let d = &answer.diagnostics;
    let mut out = json!({
        "status": if answer.is_accepted() { "ok" } else { "no_match" },
        "inliers": answer.accepted().map_or(0, |a| a.inliers.len()),
        "rmse_m": finite_or_null(answer.rmse_m),
        "landmarks": {"prior": d.prior_landmarks, "query": d.query_landmarks},
        "associations": d.associations,
        "graph_edges": d.graph_edges,
        "dof": d.dof,
        "tilt_aware": d.tilt_aware,
        "tolerances": d.tolerances,
        "max_rmse_m": d.hypotheses.first().map(|h| h.max_rmse_m),
        "time_ms": time_ms,
        "timings_ms": d.timings,
        "hypotheses": d.hypotheses,
        "config": config,
    });
    if let Some(accepted) = answer.accepted() {
        out["prior_from_query"] = json!(matrix_rows(&accepted.prior_from_query));
        out["information"] = json!(matrix6_rows(&accepted.information));
        out["inlier_pairs"] = json!(accepted.inliers);
        if let Some(tilt) = d.hypotheses.first().and_then(|h| h.tilt) {
            out["tilt"] = json!(tilt);
        }
    }
    if let Some(reason) = answer.refusal() {
        out["reason"] = json!(reason.to_string());
        out["reason_code"] = json!(reason.code());
        out["refusal"] = json!(reason);
    }
    out
}

fn finite_or_null(v: f64) -> serde_json::Value {
    if v.is_finite() {
        json!(v)
    } else {
        serde_json::Value::Null
    }
}

fn print_summary(answer: &Relocalization, time_ms: f64) {
    let d = &answer.diagnostics;
    println!(
        "landmarks: prior {}, query {}; {} associations, {} consistent pairs, {}-DOF{}",
        d.prior_landmarks,
        d.query_landmarks,
        d.associations,
        d.graph_edges,
        d.dof,
        if d.tilt_aware { ", tilt-aware" } else { "" }
    );
    match &answer.outcome {
        Ok(accepted) => {
            let t = &accepted.prior_from_query;
            let yaw = segloc::align::yaw_only::yaw_of(t).to_degrees();
            println!(
                "ok: {} inliers, rmse {:.2} cm, yaw {:.3}°, translation ({:.3}, {:.3}, {:.3}) m",
                accepted.inliers.len(),
                answer.rmse_m * 100.0,
                yaw,
                t.translation.x,
                t.translation.y,
                t.translation.z
            );
            if let Some(tilt) = d.hypotheses.first().and_then(|h| h.tilt) {
                println!(
                    "tilt: ({:.3}°, {:.3}°) about x, y, σ {:.3}°: {}",
                    tilt.tilt_deg[0],
                    tilt.tilt_deg[1],
                    tilt.sigma_deg,
                    match (tilt.determined, tilt.applied) {
                        (true, true) => "estimated and applied",
                        (true, false) => "estimated, indistinguishable from level",
                        _ => "not determined by the inliers, kept level",
                    }
                );
            }
            for row in matrix_rows(t) {
                println!(
                    "  [{:>10.6} {:>10.6} {:>10.6} {:>10.4}]",
                    row[0], row[1], row[2], row[3]
                );
            }
        }
        Err(reason) => println!("no match: {reason}"),
    }
    println!("time: {time_ms:.1} ms");
}
