//! `segloc bench associate <problem> [--repeat R] [--threads N] [--json]`, and
//! `segloc bench detect` (the perception front end, see `bench_detect.rs`).

use super::print_json;
use anyhow::{Context, Result};
use clap::Subcommand;
use segloc::io::{read_ground_truth, read_problem, AssociationProblem};
use segloc::relocalize::RelocalizeConfig;
use segloc_clipper::{densest_clique, ConsistencyGraph, DensestCliqueConfig};
use serde_json::json;
use std::path::{Path, PathBuf};
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
    let pool = thread_pool(*threads)?;
    let solver = DensestCliqueConfig {
        seed: config.clique.seed,
        ..DensestCliqueConfig::default()
    };
    let mut runs = time_solves(&pool, &p, &solver, *repeat)?;
    let mut out = json!({
        "selected": runs.selected,
        "time_ms": median(&mut runs.total_ms),
        "graph_ms": median(&mut runs.graph_ms),
        "solve_ms": median(&mut runs.solve_ms),
        "associations": p.associations.len(),
        "graph_edges": runs.edges,
    });
    add_precision_recall(&mut out, problem, &runs.selected)?;
    if *json {
        print_json(&out)?;
    } else {
        print_summary(&out, p.associations.len(), runs.edges, runs.selected.len());
    }
    Ok(0)
}

/// The times of repeated solves of a problem, milliseconds, and the last solve's result.
struct Solves {
    /// Consistency graph builds.
    graph_ms: Vec<f64>,
    /// Densest clique solves.
    solve_ms: Vec<f64>,
    /// Both.
    total_ms: Vec<f64>,
    /// The associations selected.
    selected: Vec<u32>,
    /// Edges of the consistency graph.
    edges: usize,
}

/// A thread pool of `threads` workers (all cores when None).
fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        builder = builder.num_threads(n);
    }
    builder.build().context("cannot start the thread pool")
}

/// Solve `p` `repeat` times (at least once) in `pool`, timed.
fn time_solves(
    pool: &rayon::ThreadPool,
    p: &AssociationProblem,
    solver: &DensestCliqueConfig,
    repeat: usize,
) -> Result<Solves> {
    let mut solves = Solves {
        graph_ms: Vec::new(),
        solve_ms: Vec::new(),
        total_ms: Vec::new(),
        selected: Vec::new(),
        edges: 0,
    };
    for _ in 0..repeat.max(1) {
        let (g, s, sel, e) = pool.install(|| solve_once(p, solver))?;
        solves.graph_ms.push(g);
        solves.solve_ms.push(s);
        solves.total_ms.push(g + s);
        solves.selected = sel;
        solves.edges = e;
    }
    Ok(solves)
}

/// Build the consistency graph of `p` and find its densest clique: the build's and the
/// solve's times (milliseconds), the associations selected and the graph's edges.
fn solve_once(
    p: &AssociationProblem,
    solver: &DensestCliqueConfig,
) -> Result<(f64, f64, Vec<u32>, usize)> {
    let t0 = Instant::now();
    let graph = ConsistencyGraph::build(&p.prior, &p.query, &p.associations, &p.invariant)?;
    let t1 = Instant::now();
    let solution = densest_clique(&graph, solver);
    let t2 = Instant::now();
    Ok((
        (t1 - t0).as_secs_f64() * 1e3,
        (t2 - t1).as_secs_f64() * 1e3,
        solution.vertices,
        graph.num_edges(),
    ))
}

/// The median of `v` (not empty), sorting it.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Add the precision and recall of `selected` to `out` when `problem` has a `.gt` beside it.
fn add_precision_recall(
    out: &mut serde_json::Value,
    problem: &Path,
    selected: &[u32],
) -> Result<()> {
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
    Ok(())
}

/// Print the result `out` of solving a problem of `associations` associations (a graph of
/// `edges` edges, `selected` of them selected) for a reader.
fn print_summary(out: &serde_json::Value, associations: usize, edges: usize, selected: usize) {
    println!(
        "{} associations, {} edges: selected {} in {:.2} ms (graph {:.2} ms, solve {:.2} ms)",
        associations, edges, selected, out["time_ms"], out["graph_ms"], out["solve_ms"]
    );
    if let (Some(pr), Some(rc)) = (out.get("precision"), out.get("recall")) {
        println!("precision {pr:.4}, recall {rc:.4}");
    }
}
