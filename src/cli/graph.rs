//! `segloc graph …`: optimise pose-graph files, benchmark incremental updates, inject
//! outliers and measure trajectory error.
//!
//! Exit codes: 0 success, 2 bad input or usage (malformed files, bad options, an output
//! path that cannot be written), 1 other failures.

use clap::{Args, Subcommand, ValueEnum};
use segloc::graph::file::{
    write_atomic, BuildOptions, FileFormat, GraphFile, InitialEstimate, ReadOptions,
};
use segloc::graph::metrics::trajectory_error;
use segloc::graph::synthetic::{self, SyntheticConfig};
use segloc::graph::{
    Algorithm, GraphError, IncrementalConfig, IncrementalGraph, Initialization, OptimizationReport,
    PoseGraph, RobustKernel, SolverConfig, UpdateMethod,
};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `segloc graph`.
#[derive(Args, Debug)]
pub struct GraphArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: GraphCommand,
}

/// Subcommands of `segloc graph`.
#[derive(Subcommand, Debug)]
pub enum GraphCommand {
    /// Optimise a g2o or TORO 3D file.
    Optimize(OptimizeArgs),
    /// Time appending poses and factors to a synthetic graph and re-optimising.
    BenchIncremental(BenchIncrementalArgs),
    /// Replace a fraction of a file's loop closures with random relative poses.
    Corrupt(CorruptArgs),
    /// Trajectory error of an estimate against ground truth.
    Ate(AteArgs),
    /// Stereo bundle adjustment of GTSAM's stereo VO example format (calibration, camera
    /// poses, stereo factors `pose landmark uL uR v X Y Z`).
    StereoBa(StereoBaArgs),
}

/// Arguments of `segloc graph stereo-ba`.
#[derive(Args, Debug)]
pub struct StereoBaArgs {
    /// Calibration file: `fx fy skew cx cy baseline_m`.
    #[arg(long)]
    pub calibration: PathBuf,
    /// Camera poses: `id` and the 4 × 4 matrix `world_from_camera` row by row per line.
    #[arg(long)]
    pub poses: PathBuf,
    /// Stereo factors: `pose landmark u_left u_right v X Y Z` per line.
    #[arg(long)]
    pub factors: PathBuf,
    /// Pixel noise (isotropic standard deviation, pixels).
    #[arg(long, default_value_t = 1.0)]
    pub sigma_px: f64,
    /// Solve this many times from the same start and report the fastest run (`time_ms`)
    /// and the median (`time_median_ms`).
    #[arg(long, default_value_t = 1)]
    pub repeat: usize,
    /// Print one JSON object with the results.
    #[arg(long)]
    pub json: bool,
}

/// Robust kernel choice on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RobustChoice {
    /// Plain least squares.
    None,
    /// Huber.
    Huber,
    /// Cauchy.
    Cauchy,
    /// Geman–McClure by graduated non-convexity.
    Gnc,
}

/// Initialisation choice on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum InitChoice {
    /// Chordal without a robust kernel; with one, the file's vertices (chained odometry
    /// when it has none).
    Auto,
    /// Chordal relaxation (rotations, then translations) before iterating.
    Chordal,
    /// The file's vertices (an error when it has none).
    File,
    /// Chained odometry from the edges, whatever the vertices say.
    Odometry,
    /// The file's vertices, or chained odometry when it has none (the older name).
    #[value(hide = true)]
    Chained,
}

/// The start a run actually used, as `--json` reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum InitUsed {
    Chordal,
    File,
    Odometry,
}

impl InitUsed {
    fn name(self) -> &'static str {
        match self {
            InitUsed::Chordal => "chordal",
            InitUsed::File => "file",
            InitUsed::Odometry => "odometry",
        }
    }
}

/// Arguments of `segloc graph optimize`.
#[derive(Args, Debug)]
pub struct OptimizeArgs {
    /// Input file (g2o `VERTEX_SE3:QUAT`/`EDGE_SE3:QUAT` or TORO `VERTEX3`/`EDGE3`).
    pub input: PathBuf,
    /// Write the optimised graph here (g2o if the name ends in .g2o, else the input's format).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Robust kernel on the loop closures (edges other than (i, i+1)).
    #[arg(long, value_enum, default_value_t = RobustChoice::None)]
    pub robust: RobustChoice,
    /// Kernel scale on the Mahalanobis distance (default: 3 for Huber and Cauchy, 4 for GNC).
    #[arg(long)]
    pub robust_scale: Option<f64>,
    /// Apply the robust kernel to odometry edges too.
    #[arg(long)]
    pub robust_odometry: bool,
    /// Use Gauss–Newton instead of Levenberg–Marquardt.
    #[arg(long)]
    pub gauss_newton: bool,
    /// Initial estimate: the chordal relaxation, the file's vertices, chained odometry, or
    /// auto (chordal without a robust kernel, since the relaxation is not robust to wrong
    /// loop closures; otherwise the file's vertices, or chained odometry without them).
    #[arg(long, value_enum, default_value_t = InitChoice::Auto)]
    pub init: InitChoice,
    /// Refuse information matrices that are not positive definite instead of replacing
    /// them by the nearest positive-definite ones (with a warning).
    #[arg(long)]
    pub strict: bool,
    /// Chord steps after each factorisation (overrides the configuration).
    #[arg(long)]
    pub chord_steps: Option<usize>,
    /// Solver configuration file (TOML, fields of `SolverConfig`, as printed by
    /// `--print-config`). Named apart from the global `--config` (the relocalizer's).
    #[arg(long, value_name = "FILE")]
    pub solver_config: Option<PathBuf>,
    /// Print the effective solver configuration as TOML and exit.
    #[arg(long)]
    pub print_config: bool,
    /// Print one JSON object with the results.
    #[arg(long)]
    pub json: bool,
    /// Solve this many times from the same start and report the fastest run (`time_ms`)
    /// and the median (`time_median_ms`), for timing on a busy machine.
    #[arg(long, default_value_t = 1)]
    pub repeat: usize,
}

/// Arguments of `segloc graph bench-incremental`.
#[derive(Args, Debug)]
pub struct BenchIncrementalArgs {
    /// Poses in the base graph.
    #[arg(long, default_value_t = 5000)]
    pub poses: usize,
    /// Loop closures in the base graph.
    #[arg(long, default_value_t = 200)]
    pub loop_closures: usize,
    /// Number of timed appends of each kind (odometry only, then with a loop closure); 200
    /// let the window of exactly solved recent poses fill up, so that the model rebuilds it
    /// costs are part of the figures.
    #[arg(long, default_value_t = 200)]
    pub appends: usize,
    /// Random seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Print one JSON object with the results.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `segloc graph corrupt`.
#[derive(Args, Debug)]
pub struct CorruptArgs {
    /// Input file.
    pub input: PathBuf,
    /// Output file (same format as the input unless it ends in .g2o).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Fraction of loop closures to replace.
    #[arg(long, default_value_t = 0.1)]
    pub fraction: f64,
    /// Half-width of the box the random translations are drawn from.
    #[arg(long, default_value_t = 10.0)]
    pub half_width_m: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Arguments of `segloc graph ate`.
#[derive(Args, Debug)]
pub struct AteArgs {
    /// Estimated graph (its vertices; chained odometry if it has none).
    pub estimate: PathBuf,
    /// Ground-truth graph (same rule).
    pub truth: PathBuf,
    /// Align the estimate to the truth with a rigid transform first.
    #[arg(long)]
    pub align: bool,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `segloc graph …`; returns the process exit code.
pub fn run(args: &GraphArgs) -> anyhow::Result<i32> {
    let result = match &args.command {
        GraphCommand::Optimize(a) => optimize(a),
        GraphCommand::BenchIncremental(a) => bench_incremental(a),
        GraphCommand::Corrupt(a) => corrupt(a),
        GraphCommand::Ate(a) => ate(a),
        GraphCommand::StereoBa(a) => super::graph_stereo::stereo_ba(a),
    };
    match result {
        Ok(()) => Ok(0),
        Err(e) => {
            // Bad input (files, options, output paths) is exit code 2; a failure of the
            // linear algebra or anything unforeseen propagates (exit code 1).
            let bad_input = match e.downcast_ref::<GraphError>() {
                Some(GraphError::LinearAlgebra(_)) => false,
                Some(_) => true,
                None => e.downcast_ref::<UsageError>().is_some(),
            };
            if bad_input {
                eprintln!("error: {e:#}");
                Ok(2)
            } else {
                Err(e)
            }
        }
    }
}

/// An invalid command-line value.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct UsageError(pub(crate) String);

fn read_file(path: &Path, options: &ReadOptions) -> anyhow::Result<GraphFile> {
    let file = GraphFile::read_with(path, options)?;
    for w in &file.warnings {
        eprintln!("warning: {w}");
    }
    Ok(file)
}

fn output_format(path: &Path, input: FileFormat) -> FileFormat {
    match path.extension().and_then(|e| e.to_str()) {
        Some("g2o") => FileFormat::G2o,
        _ => input,
    }
}

fn kernel_of(choice: RobustChoice, scale: Option<f64>) -> anyhow::Result<RobustKernel> {
    if let Some(s) = scale {
        if !(s.is_finite() && s > 0.0) {
            return Err(UsageError(format!("--robust-scale must be positive, got {s}")).into());
        }
    }
    Ok(match choice {
        RobustChoice::None => RobustKernel::None,
        RobustChoice::Huber => RobustKernel::Huber {
            k: scale.unwrap_or(3.0),
        },
        RobustChoice::Cauchy => RobustKernel::Cauchy {
            c: scale.unwrap_or(3.0),
        },
        RobustChoice::Gnc => RobustKernel::Gnc {
            c: scale.unwrap_or(4.0),
        },
    })
}

/// How many information matrices were repaired on reading, and the first lines.
#[derive(Serialize)]
struct RepairedOutput {
    count: usize,
    first_lines: Vec<usize>,
}

/// Lines of repaired edges listed in `--json`.
const REPAIRED_LINES_LISTED: usize = 5;

#[derive(Serialize)]
struct OptimizeOutput<'a> {
    poses: usize,
    factors: usize,
    initial_cost: f64,
    final_cost: f64,
    iterations: usize,
    factorizations: usize,
    single_precision_factorizations: usize,
    factor_nnz: usize,
    time_ms: f64,
    time_median_ms: f64,
    repeat: usize,
    read_ms: f64,
    init: &'a str,
    repaired_information: RepairedOutput,
    profile: &'a segloc::graph::Profile,
    converged: bool,
    termination: segloc::graph::Termination,
    components: usize,
    robust: &'a str,
    output: Option<&'a Path>,
    warnings: &'a [String],
}

/// The start a run uses: `--init file` needs vertices; the older `chained` and a robust
/// `auto` take the vertices when there are some, chained odometry otherwise.
fn init_used(
    choice: InitChoice,
    chordal: bool,
    file: &GraphFile,
    input: &Path,
) -> anyhow::Result<InitUsed> {
    let has_vertices = !file.vertices.is_empty();
    Ok(match choice {
        _ if chordal => InitUsed::Chordal,
        InitChoice::File if !has_vertices => {
            return Err(UsageError(format!(
            "{}: --init file needs vertices and the file has none (use --init odometry or chordal)",
            input.display()
        ))
            .into())
        }
        InitChoice::Odometry => InitUsed::Odometry,
        _ if has_vertices => InitUsed::File,
        _ => InitUsed::Odometry,
    })
}

/// The solver configuration of `optimize` (file, then options) and whether it starts with
/// the chordal relaxation.
fn optimize_config(a: &OptimizeArgs) -> anyhow::Result<(SolverConfig, bool)> {
    let mut config = match &a.solver_config {
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(|source| GraphError::Io {
                path: p.clone(),
                source,
            })?;
            toml::from_str::<SolverConfig>(&text)
                .map_err(|e| UsageError(format!("{}: {e}", p.display())))?
        }
        None => SolverConfig::default(),
    };
    if a.gauss_newton {
        config.algorithm = Algorithm::GaussNewton;
    }
    let chordal = match a.init {
        InitChoice::Auto => a.robust == RobustChoice::None,
        InitChoice::Chordal => true,
        InitChoice::File | InitChoice::Odometry | InitChoice::Chained => false,
    };
    if chordal {
        config.initialization = Initialization::Chordal;
    }
    if let Some(c) = a.chord_steps {
        config.chord_steps = c;
    }
    Ok((config, chordal))
}

fn optimize(a: &OptimizeArgs) -> anyhow::Result<()> {
    let (config, chordal) = optimize_config(a)?;
    if a.print_config {
        print!("{}", toml::to_string(&config)?);
        return Ok(());
    }
    let kernel = kernel_of(a.robust, a.robust_scale)?;
    let t_read = Instant::now();
    let read_options = ReadOptions {
        strict: a.strict,
        ..ReadOptions::default()
    };
    let file = read_file(&a.input, &read_options)?;
    let init = init_used(a.init, chordal, &file, &a.input)?;
    let options = BuildOptions {
        loop_closure_kernel: kernel,
        odometry_kernel: if a.robust_odometry {
            kernel
        } else {
            RobustKernel::None
        },
        fix_first: true,
        initial: if init == InitUsed::Odometry {
            InitialEstimate::Odometry
        } else {
            InitialEstimate::File
        },
    };
    let graph = file.to_pose_graph(&options)?;
    let read_ms = t_read.elapsed().as_secs_f64() * 1e3;
    let (graph, report, times) = solve_timed(graph, &file, &options, &config, a.repeat)?;
    let time_median_ms = times[times.len() / 2];
    if let Some(out) = &a.output {
        let fmt = output_format(out, file.format);
        let mut written = GraphFile::from_pose_graph(&graph, fmt)?;
        if fmt == FileFormat::Toro {
            written.fixed.clear();
        }
        written.write(out, fmt)?;
    }
    let robust = format!("{:?}", a.robust).to_lowercase();
    if a.json {
        let out = OptimizeOutput {
            poses: report.poses,
            factors: report.factors,
            initial_cost: report.initial_cost,
            final_cost: report.final_cost,
            iterations: report.iterations,
            factorizations: report.factorizations,
            single_precision_factorizations: report.single_precision_factorizations,
            factor_nnz: report.factor_nnz,
            time_ms: report.time_ms,
            time_median_ms,
            repeat: times.len(),
            read_ms,
            init: init.name(),
            repaired_information: RepairedOutput {
                count: file.repaired.len(),
                first_lines: file
                    .repaired
                    .iter()
                    .take(REPAIRED_LINES_LISTED)
                    .copied()
                    .collect(),
            },
            profile: &report.profile,
            converged: report.converged,
            termination: report.termination,
            components: report.components.len(),
            robust: &robust,
            output: a.output.as_deref(),
            warnings: &file.warnings,
        };
        println!("{}", serde_json::to_string(&out)?);
    } else {
        print_report(&a.input, &report);
    }
    Ok(())
}

/// Solves `graph` (built from `file` with `options`), then `repeat − 1` fresh copies for
/// timing; returns the last run's graph (every run gives the same one), the fastest run's
/// report, and every run's time, sorted. Each copy is built after the previous one is
/// dropped, so that a run reuses the memory the previous run freed, as a solver called in
/// a loop does.
fn solve_timed(
    mut graph: PoseGraph,
    file: &GraphFile,
    options: &BuildOptions,
    config: &SolverConfig,
    repeat: usize,
) -> anyhow::Result<(PoseGraph, OptimizationReport, Vec<f64>)> {
    let mut report = graph.optimize(config)?;
    let mut times = vec![report.time_ms];
    for _ in 1..repeat.max(1) {
        drop(graph);
        graph = file.to_pose_graph(options)?;
        let r = graph.optimize(config)?;
        times.push(r.time_ms);
        if r.time_ms < report.time_ms {
            report = r;
        }
    }
    times.sort_by(f64::total_cmp);
    Ok((graph, report, times))
}

/// The human-readable report of `optimize`: the iterations, where the time went, the costs.
fn print_report(input: &Path, report: &OptimizationReport) {
    println!(
        "{}: {} poses, {} factors, {} component(s)",
        input.display(),
        report.poses,
        report.factors,
        report.components.len()
    );
    for it in &report.log {
        println!(
            "  iter {:3}  cost {:.9e} -> {:.9e}  lambda {:.1e}  |step| {:.2e}  rejected {}{}{}",
            it.iteration,
            it.cost_before,
            it.cost_after,
            it.lambda,
            it.step_max,
            it.rejected_steps,
            if report.gnc_stages > 0 {
                format!("  mu {:.3}", it.mu)
            } else {
                String::new()
            },
            if it.chord { "  (chord)" } else { "" }
        );
    }
    let p = &report.profile;
    println!(
        "time: analysis {:.1} ms, initialize {:.1} ms, linearize {:.1} ms, factorize {:.1} ms ({} times, {} in single precision), solve {:.1} ms, cost {:.1} ms; factor nnz {}",
        p.analysis_ms, p.initialize_ms, p.linearize_ms, p.factorize_ms, report.factorizations, report.single_precision_factorizations, p.solve_ms, p.cost_ms, report.factor_nnz
    );
    println!(
        "initial cost {:.6}, final cost {:.6}, {} iterations, {:.1} ms, {:?}",
        report.initial_cost,
        report.final_cost,
        report.iterations,
        report.time_ms,
        report.termination
    );
}

#[derive(Serialize)]
struct BenchOutput {
    poses: usize,
    factors: usize,
    batch_ms: f64,
    batch_iterations: usize,
    /// One pose + its odometry factor; the update detects that the optimum is unchanged.
    odometry_append_ms: Summary,
    /// Fraction of odometry appends that needed no solve.
    odometry_append_skipped: f64,
    /// One pose + its odometry factor, with a forced full warm-started re-optimisation.
    odometry_append_full_ms: Summary,
    /// One pose + odometry + a loop closure to a pose 40–90 steps back, consecutively.
    loop_closure_append_ms: Summary,
    /// Loop-closure appends done incrementally: the window solved exactly, the settled
    /// variables moved on the last model's linearisation.
    loop_closure_incremental: usize,
    /// Times of the incremental loop-closure appends alone.
    loop_closure_incremental_ms: Summary,
    /// Loop-closure appends that built the model again at the incremental estimate.
    loop_closure_relinearized: usize,
    /// Their times.
    loop_closure_relinearized_ms: Summary,
    /// Times of the loop-closure appends that re-optimised by a batch.
    loop_closure_batch_ms: Summary,
    /// Loop-closure appends done by a batch re-optimisation.
    loop_closure_batch: usize,
    /// Relative cost gap to the full batch optimum of the same graph after each append.
    loop_closure_cost_gap: Summary,
    /// Largest position difference to that batch optimum after each append.
    loop_closure_max_position_diff_m: Summary,
}

#[derive(Serialize)]
struct Summary {
    median: f64,
    p90: f64,
    max: f64,
}

fn summarise(mut v: Vec<f64>) -> Summary {
    if v.is_empty() {
        return Summary {
            median: f64::NAN,
            p90: f64::NAN,
            max: f64::NAN,
        };
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    Summary {
        median: at(0.5),
        p90: at(0.9),
        max: v[v.len() - 1],
    }
}

fn bench_incremental(a: &BenchIncrementalArgs) -> anyhow::Result<()> {
    if a.poses < 100 || a.appends == 0 {
        return Err(UsageError("need --poses >= 100 and --appends >= 1".into()).into());
    }
    let forced = a.appends.div_ceil(5);
    let total = a.poses + 2 * a.appends + forced + 1;
    let synth = synthetic::generate(&SyntheticConfig {
        poses: total,
        loop_closures: a.loop_closures,
        seed: a.seed,
        ..SyntheticConfig::default()
    });
    // Base graph: the first `poses` poses and the factors among them.
    let mut base = synth.file.clone();
    let n = a.poses as u64;
    base.vertices.retain(|v| v.id < n);
    base.edges.retain(|e| e.from < n && e.to < n);
    let graph = base.to_pose_graph(&BuildOptions::default())?;
    let mut inc = IncrementalGraph::new(graph, IncrementalConfig::default());
    let batch = inc.update()?;
    let (batch_ms, batch_iterations, factors) = match &batch.report {
        Some(r) => (r.time_ms, r.iterations, r.factors),
        None => (batch.time_ms, 0, inc.graph().num_factors()),
    };
    let mut appender = Appender {
        inc,
        synth: &synth,
        odometry: synth.odometry(),
        next: n,
    };
    // 1. Odometry only: one pose and its odometry factor per update.
    let (odo_ms, skipped) = appender.odometry_only(a.appends)?;
    // 2. One pose, its odometry and a loop closure back to a pose 40–90 steps earlier per
    //    update, consecutively (batches included whenever the updater decides on one).
    let mut closures = appender.loop_closures(a.appends)?;
    // 3. Reference: one pose + odometry with a forced full warm-started re-optimisation.
    let odo_full_ms = appender.forced_full(forced)?;
    let mut by_method =
        |m: UpdateMethod| summarise(std::mem::take(&mut closures.by_method[m as usize]));
    let out = BenchOutput {
        poses: a.poses,
        factors,
        batch_ms,
        batch_iterations,
        odometry_append_ms: summarise(odo_ms),
        odometry_append_skipped: skipped as f64 / a.appends as f64,
        odometry_append_full_ms: summarise(odo_full_ms),
        loop_closure_append_ms: summarise(std::mem::take(&mut closures.ms)),
        loop_closure_incremental: closures.methods[UpdateMethod::Incremental as usize],
        loop_closure_incremental_ms: by_method(UpdateMethod::Incremental),
        loop_closure_relinearized: closures.methods[UpdateMethod::Relinearized as usize],
        loop_closure_relinearized_ms: by_method(UpdateMethod::Relinearized),
        loop_closure_batch_ms: by_method(UpdateMethod::Batch),
        loop_closure_batch: closures.methods[UpdateMethod::Batch as usize],
        loop_closure_cost_gap: summarise(std::mem::take(&mut closures.gaps)),
        loop_closure_max_position_diff_m: summarise(std::mem::take(&mut closures.pose_diffs)),
    };
    if a.json {
        println!("{}", serde_json::to_string(&out)?);
    } else {
        println!("{}", serde_json::to_string_pretty(&out)?);
    }
    Ok(())
}

/// Appends the synthetic graph's poses one by one to the incremental graph.
struct Appender<'a> {
    inc: IncrementalGraph,
    synth: &'a synthetic::SyntheticGraph,
    /// The odometry edges, entry `i` from pose `i` to `i + 1`.
    odometry: Vec<&'a segloc::graph::file::FileEdge>,
    /// The next pose to append.
    next: u64,
}

/// What the loop-closure appends measured.
struct LoopClosureRun {
    /// Time of each append (its update included), milliseconds.
    ms: Vec<f64>,
    /// Appends by update method.
    methods: [usize; 4],
    /// Their times, by update method.
    by_method: [Vec<f64>; 4],
    /// Relative cost gap to the full batch optimum after each append.
    gaps: Vec<f64>,
    /// Largest position difference to that optimum after each append, metres.
    pose_diffs: Vec<f64>,
}

impl Appender<'_> {
    /// `appends` poses with their odometry, one update each: the times (milliseconds) and
    /// how many updates were skipped.
    fn odometry_only(&mut self, appends: usize) -> anyhow::Result<(Vec<f64>, usize)> {
        let mut odo_ms = Vec::new();
        let mut skipped = 0usize;
        for _ in 0..appends {
            let e = self.odometry[(self.next - 1) as usize];
            let t = Instant::now();
            self.inc
                .add_odometry(e.from, e.to, e.measured, e.information)?;
            let r = self.inc.update()?;
            odo_ms.push(t.elapsed().as_secs_f64() * 1e3);
            skipped += usize::from(r.method == UpdateMethod::Skipped);
            self.next += 1;
        }
        Ok((odo_ms, skipped))
    }

    /// `appends` poses with their odometry and a loop closure 40–90 poses back, one update
    /// each, every one compared (untimed) with the full batch optimum.
    fn loop_closures(&mut self, appends: usize) -> anyhow::Result<LoopClosureRun> {
        let mut run = LoopClosureRun {
            ms: Vec::new(),
            methods: [0usize; 4],
            by_method: Default::default(),
            gaps: Vec::new(),
            pose_diffs: Vec::new(),
        };
        for k in 0..appends {
            let next = self.next;
            let e = self.odometry[(next - 1) as usize];
            let back = next.saturating_sub(40 + (7 * k as u64) % 50);
            let z = self.synth.truth[back as usize].inv_mul(&self.synth.truth[next as usize]);
            let t = Instant::now();
            self.inc
                .add_odometry(e.from, e.to, e.measured, e.information)?;
            self.inc
                .graph_mut()
                .add_between(back, next, z, e.information, RobustKernel::None)?;
            let r = self.inc.update()?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            run.ms.push(ms);
            run.methods[r.method as usize] += 1;
            run.by_method[r.method as usize].push(ms);
            self.next += 1;
            let (gap, diff) = self.gap_to_batch()?;
            run.gaps.push(gap);
            run.pose_diffs.push(diff);
        }
        Ok(run)
    }

    /// Accuracy (untimed): the relative cost gap to the full batch optimum of the same
    /// graph, and the largest position difference to it.
    fn gap_to_batch(&self) -> anyhow::Result<(f64, f64)> {
        let mut full = self.inc.graph().clone();
        let report = full.optimize(&SolverConfig {
            relative_tolerance: 1e-10,
            absolute_tolerance: 0.0,
            log_iterations: false,
            ..SolverConfig::default()
        })?;
        let cost = self.inc.graph().cost();
        let diff = (0..=self.next)
            .filter_map(|id| Some((self.inc.graph().pose(id)?, full.pose(id)?)))
            .map(|(p, q)| (p.translation.vector - q.translation.vector).norm())
            .fold(0.0f64, f64::max);
        Ok(((cost - report.final_cost) / report.final_cost, diff))
    }

    /// `count` poses with their odometry, each followed by a forced full warm-started
    /// re-optimisation: the times, milliseconds.
    fn forced_full(&mut self, count: usize) -> anyhow::Result<Vec<f64>> {
        let mut odo_full_ms = Vec::new();
        for _ in 0..count {
            let e = self.odometry[(self.next - 1) as usize];
            let t = Instant::now();
            self.inc
                .add_odometry(e.from, e.to, e.measured, e.information)?;
            self.inc.invalidate();
            self.inc.update()?;
            odo_full_ms.push(t.elapsed().as_secs_f64() * 1e3);
            self.next += 1;
        }
        Ok(odo_full_ms)
    }
}

fn corrupt(a: &CorruptArgs) -> anyhow::Result<()> {
    let valid =
        (0.0..=1.0).contains(&a.fraction) && a.half_width_m.is_finite() && a.half_width_m > 0.0;
    if !valid {
        return Err(UsageError("need 0 <= --fraction <= 1 and --half-width-m > 0".into()).into());
    }
    let mut file = read_file(&a.input, &ReadOptions::default())?;
    let replaced =
        synthetic::corrupt_loop_closures(&mut file.edges, a.fraction, a.half_width_m, a.seed);
    let fmt = output_format(&a.output, file.format);
    write_atomic(&a.output, file.to_text(fmt).as_bytes())?;
    eprintln!(
        "replaced {} of {} edges with random relative poses",
        replaced.len(),
        file.edges.len()
    );
    Ok(())
}

fn ate(a: &AteArgs) -> anyhow::Result<()> {
    let est = read_file(&a.estimate, &ReadOptions::default())?.initial_estimates();
    let truth = read_file(&a.truth, &ReadOptions::default())?.initial_estimates();
    let err = trajectory_error(&est, &truth, a.align);
    if a.json {
        println!("{}", serde_json::to_string(&err)?);
    } else {
        println!(
            "{} poses: position RMSE {:.6} m (max {:.6} m), rotation RMSE {:.6} rad",
            err.matched, err.position_rmse_m, err.position_max_m, err.rotation_rmse_rad
        );
    }
    Ok(())
}
