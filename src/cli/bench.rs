//! `segloc bench associate <problem> [--repeat R] [--threads N] [--json]`, and
//! `segloc bench detect` (the perception front end, see `bench_detect.rs`).

use super::print_json;
use anyhow::{Context, Result};
use clap::Subcommand;
use segloc::io::{read_ground_truth, read_problem};
use segloc::relocalize::RelocalizeConfig;
use segloc_clipper::{densest_clique, ConsistencyGraph, DensestCliqueConfig};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Benchmark commands.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Solve an association problem file (format: `../shared/docs/association.md`):
    /// consistency graph + densest clique, timed.
    Associate {
        /// The problem file (its `.gt` beside it, if present, gives precision and recall).
        problem: PathBuf,
        /// Repeats; times are medians.
        #[arg(long, default_value_t = 5)]
        repeat: usize,
        /// Worker threads for the graph build (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// The perception front end in steady state: one process, one front end reused for
    /// every frame; median / p90 / min per pair and per stage.
    Detect(super::bench_detect::BenchDetectArgs),
    /// The renderer in steady state: stereo pairs along mapping drives of held-out seeds;
    /// median / p90 wall and CPU time a pair.
    Render(super::bench_render::BenchRenderArgs),
}

/// Run a benchmark.
pub fn run(cmd: &BenchCommand, config: &RelocalizeConfig) -> Result<i32> {
    let (problem, repeat, threads, json) = match cmd {
        BenchCommand::Associate {
            problem,
            repeat,
            threads,
            json,
        } => (problem, repeat, threads, json),
        BenchCommand::Detect(args) => return super::bench_detect::run(args),
        BenchCommand::Render(args) => return super::bench_render::run(args),
    };
    let p = read_problem(problem)?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        builder = builder.num_threads(*n);
    }
    let pool = builder.build().context("cannot start the thread pool")?;
    let solver = DensestCliqueConfig {
        seed: config.clique.seed,
        ..DensestCliqueConfig::default()
    };
    let (mut graph_ms, mut solve_ms, mut total_ms) = (Vec::new(), Vec::new(), Vec::new());
    let mut selected = Vec::new();
    let mut edges = 0;
    for _ in 0..(*repeat).max(1) {
        let (g, s, sel, e) = pool.install(|| -> Result<_> {
            let t0 = Instant::now();
            let graph = ConsistencyGraph::build(&p.prior, &p.query, &p.associations, &p.invariant)?;
            let t1 = Instant::now();
            let solution = densest_clique(&graph, &solver);
            let t2 = Instant::now();
            Ok((
                (t1 - t0).as_secs_f64() * 1e3,
                (t2 - t1).as_secs_f64() * 1e3,
                solution.vertices,
                graph.num_edges(),
            ))
        })?;
        graph_ms.push(g);
        solve_ms.push(s);
        total_ms.push(g + s);
        selected = sel;
        edges = e;
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2]
    };
    let mut out = json!({
        "selected": selected,
        "time_ms": median(&mut total_ms),
        "graph_ms": median(&mut graph_ms),
        "solve_ms": median(&mut solve_ms),
        "associations": p.associations.len(),
        "graph_edges": edges,
    });
    let gt_path = PathBuf::from(format!("{}.gt", problem.display()));
    if gt_path.exists() {
        let truth = read_ground_truth(&gt_path)?;
        let truth: std::collections::HashSet<usize> = truth.inliers.into_iter().collect();
        let hits = selected
            .iter()
            .filter(|&&v| truth.contains(&(v as usize)))
            .count();
        out["precision"] = json!(if selected.is_empty() {
            0.0
        } else {
            hits as f64 / selected.len() as f64
        });
        out["recall"] = json!(if truth.is_empty() {
            0.0
        } else {
            hits as f64 / truth.len() as f64
        });
    }
    if *json {
        print_json(&out)?;
    } else {
        println!(
            "{} associations, {} edges: selected {} in {:.2} ms (graph {:.2} ms, solve {:.2} ms)",
            p.associations.len(),
            edges,
            selected.len(),
            out["time_ms"],
            out["graph_ms"],
            out["solve_ms"]
        );
        if let (Some(pr), Some(rc)) = (out.get("precision"), out.get("recall")) {
            println!("precision {pr:.4}, recall {rc:.4}");
        }
    }
    Ok(0)
}
