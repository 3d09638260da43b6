//! Reads an association problem file (format: shared/docs/association.md), builds the
//! consistency graph, solves it, and prints timings and precision / recall against
//! `PROBLEM.gt` when present.
//!
//! cargo run --release -p segloc-clipper --example solve_problem -- PROBLEM [--repeat N]
//!     [--strategy auto|join|scan] [--exact] [--no-prune]
#![warn(clippy::too_many_lines)]

use std::time::Instant;

use nalgebra::Point3;
use segloc_clipper::{
    choose_strategy, densest_clique, max_clique, Association, BuildStrategy, CliqueSolution,
    ConsistencyGraph, DensestCliqueConfig, Invariant, MaxCliqueLimits,
};

/// What went wrong, for the message `main` prints.
type Error = Box<dyn std::error::Error>;

struct Problem {
    prior: Vec<Point3<f64>>,
    query: Vec<Point3<f64>>,
    associations: Vec<Association>,
    invariant: Invariant,
}

fn parse(text: &str) -> Result<Problem, Error> {
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<&str> = lines
        .next()
        .ok_or("empty file")?
        .split_whitespace()
        .collect();
    if header.len() < 5 {
        return Err("header needs n_prior n_query n_assoc epsilon sigma [dof]".into());
    }
    let num = |s: &str| s.parse::<f64>().map_err(|e| format!("{s}: {e}"));
    let (np, nq, na) = (
        num(header[0])? as usize,
        num(header[1])? as usize,
        num(header[2])? as usize,
    );
    let (epsilon, sigma) = (num(header[3])?, num(header[4])?);
    let dof = if header.len() > 5 {
        num(header[5])? as u32
    } else {
        6
    };
    let mut point = || -> Result<Point3<f64>, Error> {
        let l = lines.next().ok_or("missing point line")?;
        let v: Vec<f64> = l.split_whitespace().map(num).collect::<Result<_, _>>()?;
        if v.len() != 3 {
            return Err(format!("bad point line: {l}").into());
        }
        Ok(Point3::new(v[0], v[1], v[2]))
    };
    let prior = (0..np).map(|_| point()).collect::<Result<Vec<_>, _>>()?;
    let query = (0..nq).map(|_| point()).collect::<Result<Vec<_>, _>>()?;
    let associations = (0..na)
        .map(|_| {
            let l = lines.next().ok_or("missing association line")?;
            let v: Vec<u32> = l
                .split_whitespace()
                .map(|s| s.parse::<u32>().map_err(|e| format!("{s}: {e}")))
                .collect::<Result<_, _>>()?;
            if v.len() != 2 {
                return Err(format!("bad association line: {l}").into());
            }
            Ok(Association::new(v[0], v[1]))
        })
        .collect::<Result<Vec<_>, Error>>()?;
    let invariant = if dof == 4 {
        Invariant::GravityAligned {
            epsilon,
            sigma,
            epsilon_z: epsilon,
            sigma_z: sigma,
        }
    } else {
        Invariant::Distance { epsilon, sigma }
    };
    Ok(Problem {
        prior,
        query,
        associations,
        invariant,
    })
}

/// Process CPU time in milliseconds (all threads).
fn cpu_ms() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 * 1e3 + ts.tv_nsec as f64 * 1e-6
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The command line.
struct Options {
    path: String,
    repeat: usize,
    strategy: BuildStrategy,
    exact: bool,
    prune: bool,
}

fn parse_args(args: &[String]) -> Result<Options, Error> {
    let path = args
        .first()
        .ok_or("usage: solve_problem PROBLEM [--repeat N]")?;
    let mut options = Options {
        path: path.clone(),
        repeat: 5,
        strategy: BuildStrategy::Auto,
        exact: false,
        prune: true,
    };
    let mut k = 1;
    while k < args.len() {
        match args[k].as_str() {
            "--repeat" => {
                k += 1;
                options.repeat = args
                    .get(k)
                    .and_then(|s| s.parse().ok())
                    .ok_or("--repeat N")?;
            }
            "--strategy" => {
                k += 1;
                options.strategy = match args.get(k).map(String::as_str) {
                    Some("join") => BuildStrategy::Join,
                    Some("scan") => BuildStrategy::PairwiseScan,
                    _ => BuildStrategy::Auto,
                };
            }
            "--exact" => options.exact = true,
            "--no-prune" => options.prune = false,
            other => return Err(format!("unknown argument {other}").into()),
        }
        k += 1;
    }
    Ok(options)
}

/// Wall and CPU times (milliseconds) of each run's graph build and solve, and the last
/// run's graph and solution.
struct Runs {
    t_graph: Vec<f64>,
    t_solve: Vec<f64>,
    c_graph: Vec<f64>,
    c_solve: Vec<f64>,
    graph: ConsistencyGraph,
    solution: CliqueSolution,
}

fn time_runs(p: &Problem, options: &Options) -> Result<Runs, Error> {
    let config = DensestCliqueConfig {
        prune_by_core: options.prune,
        ..Default::default()
    };
    let (mut t_graph, mut t_solve) = (Vec::new(), Vec::new());
    let (mut c_graph, mut c_solve) = (Vec::new(), Vec::new());
    let mut last = None;
    for _ in 0..options.repeat.max(1) {
        let c0 = cpu_ms();
        let t0 = Instant::now();
        let g = ConsistencyGraph::build_with(
            &p.prior,
            &p.query,
            &p.associations,
            &p.invariant,
            options.strategy,
        )?;
        let t1 = Instant::now();
        let c1 = cpu_ms();
        let s = if options.exact {
            max_clique(&g, &MaxCliqueLimits::default())?
        } else {
            densest_clique(&g, &config)
        };
        let t2 = Instant::now();
        let c2 = cpu_ms();
        c_graph.push(c1 - c0);
        c_solve.push(c2 - c1);
        t_graph.push((t1 - t0).as_secs_f64() * 1e3);
        t_solve.push((t2 - t1).as_secs_f64() * 1e3);
        last = Some((g, s));
    }
    let (graph, solution) = last.ok_or("no run")?;
    Ok(Runs {
        t_graph,
        t_solve,
        c_graph,
        c_solve,
        graph,
        solution,
    })
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = parse_args(&args)?;
    let path = &options.path;
    let repeat = options.repeat;
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let p = parse(&text)?;
    let truth: Option<Vec<u32>> =
        std::fs::read_to_string(format!("{path}.gt"))
            .ok()
            .and_then(|t| {
                t.lines().next().map(|l| {
                    l.split_whitespace()
                        .filter_map(|s| s.parse().ok())
                        .collect()
                })
            });
    let chosen = match options.strategy {
        BuildStrategy::Auto => choose_strategy(&p.prior, &p.query, &p.associations, &p.invariant)?,
        s => s,
    };
    let runs = time_runs(&p, &options)?;
    let (g, s) = (&runs.graph, &runs.solution);
    let (tg, ts) = (median(runs.t_graph), median(runs.t_solve));
    println!(
        "associations {} vertices {} edges {} strategy {:?} threads {}",
        p.associations.len(),
        g.num_vertices(),
        g.num_edges(),
        chosen,
        rayon::current_num_threads()
    );
    let (cg, cs) = (median(runs.c_graph), median(runs.c_solve));
    println!(
        "wall: graph_ms {tg:.2} solve_ms {ts:.2} total_ms {:.2} (median of {repeat})",
        tg + ts
    );
    println!(
        "cpu:  graph_ms {cg:.2} solve_ms {cs:.2} total_ms {:.2} (median of {repeat})",
        cg + cs
    );
    println!(
        "clique {} objective {:.3} certified {} upper_bound {} pruned {} outer {} inner {} nodes {}",
        s.vertices.len(),
        s.objective,
        s.certified_maximum,
        s.upper_bound,
        s.pruned_vertices,
        s.outer_iterations,
        s.inner_iterations,
        s.search_nodes
    );
    if let Some(truth) = truth {
        print_precision_recall(s, &truth);
    }
    Ok(())
}

/// Precision and recall of the clique against the true associations (sorted).
fn print_precision_recall(s: &CliqueSolution, truth: &[u32]) {
    let tp = s
        .vertices
        .iter()
        .filter(|v| truth.binary_search(v).is_ok())
        .count() as f64;
    let precision = if s.vertices.is_empty() {
        0.0
    } else {
        tp / s.vertices.len() as f64
    };
    let recall = if truth.is_empty() {
        1.0
    } else {
        tp / truth.len() as f64
    };
    println!(
        "precision {precision:.4} recall {recall:.4} (truth {})",
        truth.len()
    );
}
