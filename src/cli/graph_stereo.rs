//! `segloc graph stereo-ba`: stereo bundle adjustment of GTSAM's stereo VO example files,
//! reported in GTSAM's cost convention (`½ Σ ‖r / σ‖²`) for the side-by-side benchmark
//! (`scripts/bench_stereo_ba.sh`). Solved by [`segloc::graph::PoseGraph::optimize_bundle`].

use super::graph::{StereoBaArgs, UsageError};
use segloc::graph::stereo_file::StereoProblem;
use segloc::graph::{RobustKernel, SolverConfig};
use serde::Serialize;
use std::time::Instant;

#[derive(Serialize)]
struct StereoBaOutput {
    poses: usize,
    landmarks: usize,
    factors: usize,
    initial_cost: f64,
    final_cost: f64,
    iterations: usize,
    factorizations: usize,
    time_ms: f64,
    time_median_ms: f64,
    repeat: usize,
    read_ms: f64,
    converged: bool,
    termination: segloc::graph::Termination,
}

/// Runs `segloc graph stereo-ba`.
pub fn stereo_ba(a: &StereoBaArgs) -> anyhow::Result<()> {
    if a.repeat == 0 {
        return Err(UsageError("--repeat must be at least 1".into()).into());
    }
    let t = Instant::now();
    let problem = StereoProblem::read(&a.calibration, &a.poses, &a.factors)?;
    let read_ms = t.elapsed().as_secs_f64() * 1e3;
    let config = SolverConfig {
        log_iterations: false,
        ..SolverConfig::default()
    };
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..a.repeat {
        let (mut graph, size) = problem.build_graph(a.sigma_px, RobustKernel::None)?;
        let report = graph.optimize_bundle(&config)?;
        times.push(report.time_ms);
        last = Some((report, size));
    }
    let Some((report, size)) = last else {
        return Err(UsageError("--repeat must be at least 1".into()).into());
    };
    times.sort_by(f64::total_cmp);
    let out = StereoBaOutput {
        poses: size.poses,
        landmarks: size.landmarks,
        factors: size.factors,
        initial_cost: report.initial_cost,
        final_cost: report.final_cost,
        iterations: report.iterations,
        factorizations: report.factorizations,
        time_ms: times[0],
        time_median_ms: times[times.len() / 2],
        repeat: times.len(),
        read_ms,
        converged: report.converged,
        termination: report.termination,
    };
    if a.json {
        super::print_json(&out)?;
    } else {
        println!(
            "{} poses, {} landmarks, {} stereo factors: cost {:.6} -> {:.6} in {} iterations, {:.2} ms (median {:.2} ms of {})",
            out.poses, out.landmarks, out.factors, out.initial_cost, out.final_cost,
            out.iterations, out.time_ms, out.time_median_ms, out.repeat
        );
    }
    Ok(())
}
