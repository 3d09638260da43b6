//! `segloc bench detect`: the perception front end timed in steady state, one process, one
//! [`FrontEnd`] reused for every frame (as `.lac` playback or a rover's camera loop would).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use segloc::perception::{FrontEnd, FrontEndTiming, GrayImage};
use serde_json::{json, Value};

use super::detect::read_stereo_pair;
use super::print_json;

/// Arguments of `segloc bench detect`.
#[derive(Args, Debug)]
pub struct BenchDetectArgs {
    /// Left image of one pair (8-bit grayscale PNG, rectified).
    #[arg(
        long,
        value_name = "PNG",
        requires = "right",
        conflicts_with = "images"
    )]
    pub left: Option<PathBuf>,
    /// Right image of that pair.
    #[arg(long, value_name = "PNG", requires = "left")]
    pub right: Option<PathBuf>,
    /// A folder of pairs named `NAME_0.png` (left) and `NAME_1.png` (right), e.g.
    /// `../shared/data/lac-images`; every pair is run in each round.
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
    /// Timed rounds (each round runs every pair once).
    #[arg(long, default_value_t = 20)]
    pub repeat: usize,
    /// Untimed rounds first (the very first frame of the process is reported apart).
    #[arg(long, default_value_t = 1)]
    pub warmup: usize,
    /// The segmenter.
    #[arg(long, value_enum, default_value = "geometric")]
    pub segmenter: super::detect::SegmenterKind,
    /// ONNX model (`--segmenter onnx`, or another model for `learned`).
    #[arg(long, value_name = "ONNX")]
    pub model: Option<PathBuf>,
    /// Front-end settings (TOML, as printed by `segloc detect --print-config`).
    #[arg(long, value_name = "TOML")]
    pub frontend_config: Option<PathBuf>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// One stereo pair, decoded once before timing.
struct Pair {
    name: String,
    left: GrayImage,
    right: GrayImage,
}

/// Run `segloc bench detect`.
pub fn run(args: &BenchDetectArgs) -> Result<i32> {
    let pairs = load_pairs(args)?;
    let runs = time_rounds(args, &pairs)?;
    let out = summary(args, &pairs, &runs);
    if args.json {
        print_json(&out)?;
        return Ok(0);
    }
    println!(
        "{} pair(s) × {} rounds after {} warm-up, {} threads; first frame of the process {:.1} ms",
        pairs.len(),
        args.repeat.max(1),
        args.warmup,
        rayon::current_num_threads(),
        runs.first.map_or(f64::NAN, |t| t.total_ms)
    );
    print_table(&out);
    Ok(0)
}

/// What the timed rounds measured, per pair.
struct Runs {
    /// Stage timings of each timed run.
    timings: Vec<Vec<FrontEndTiming>>,
    /// Boulders found (last run).
    boulders: Vec<usize>,
    /// Process CPU time of each timed run, milliseconds.
    cpu_ms: Vec<Vec<f64>>,
    /// The very first frame of the process.
    first: Option<FrontEndTiming>,
}

/// Runs the warm-up and timed rounds, one front end for every frame.
fn time_rounds(args: &BenchDetectArgs, pairs: &[Pair]) -> Result<Runs> {
    let config = super::detect::load_frontend_config(args.frontend_config.as_deref())?;
    let segmenter = super::detect::make_segmenter(args.segmenter, args.model.as_deref(), &config)?;
    let mut front_end = FrontEnd::new(config, segmenter)?;
    let mut runs = Runs {
        timings: vec![Vec::new(); pairs.len()],
        boulders: vec![0usize; pairs.len()],
        cpu_ms: vec![Vec::new(); pairs.len()],
        first: None,
    };
    for round in 0..args.warmup + args.repeat.max(1) {
        for (k, pair) in pairs.iter().enumerate() {
            let cpu_before = process_cpu_ms();
            let result = front_end
                .process(&pair.left, &pair.right)
                .with_context(|| format!("pair {}", pair.name))?;
            let cpu = process_cpu_ms() - cpu_before;
            runs.first.get_or_insert(result.timing);
            runs.boulders[k] = result.boulders.len();
            if round >= args.warmup {
                runs.timings[k].push(result.timing);
                runs.cpu_ms[k].push(cpu);
            }
        }
    }
    Ok(runs)
}

/// The JSON summary: statistics per pair and over all of them.
fn summary(args: &BenchDetectArgs, pairs: &[Pair], runs: &Runs) -> Value {
    let all: Vec<FrontEndTiming> = runs.timings.iter().flatten().copied().collect();
    let per_pair: Vec<Value> = pairs
        .iter()
        .zip(&runs.timings)
        .zip(&runs.boulders)
        .zip(&runs.cpu_ms)
        .map(|(((pair, t), &n), cpu)| {
            let mut ms = stage_stats(t);
            ms["cpu"] = stats(cpu.clone());
            json!({"pair": pair.name, "runs": t.len(), "boulders": n, "ms": ms})
        })
        .collect();
    let mut all_ms = stage_stats(&all);
    all_ms["cpu"] = stats(runs.cpu_ms.concat());
    json!({
        "pairs": per_pair,
        "all": {"runs": all.len(), "ms": all_ms},
        "first_frame_ms": runs.first,
        "threads": rayon::current_num_threads(),
        "warmup_rounds": args.warmup,
    })
}

/// The table of [`summary`]: one line per pair, then all.
fn print_table(out: &Value) {
    println!(
        "{:<10} {:>4}  {:>23}  {:>23}  {:>17}  {:>17}  {:>7}",
        "pair",
        "rocks",
        "total med/p90/min",
        "stereo med/p90/min",
        "segment med/p90",
        "boulders med/p90",
        "cpu med"
    );
    let per_pair = out["pairs"].as_array().map_or(&[][..], Vec::as_slice);
    let rows = per_pair
        .iter()
        .map(|p| {
            (
                p["pair"].as_str().unwrap_or("").to_string(),
                p["boulders"].clone(),
                &p["ms"],
            )
        })
        .chain(std::iter::once((
            "all".to_string(),
            Value::Null,
            &out["all"]["ms"],
        )));
    for (name, n, ms) in rows {
        let f = |stage: &str, stat: &str| ms[stage][stat].as_f64().unwrap_or(f64::NAN);
        println!(
            "{:<10} {:>4}  {:>7.1} {:>7.1} {:>7.1}  {:>7.1} {:>7.1} {:>7.1}  {:>8.1} {:>8.1}  {:>8.1} {:>8.1}  {:>7.1}",
            name,
            n.as_u64().map_or(String::new(), |n| n.to_string()),
            f("total", "median"),
            f("total", "p90"),
            f("total", "min"),
            f("stereo", "median"),
            f("stereo", "p90"),
            f("stereo", "min"),
            f("segment", "median"),
            f("segment", "p90"),
            f("boulders", "median"),
            f("boulders", "p90"),
            f("cpu", "median"),
        );
    }
}

fn load_pairs(args: &BenchDetectArgs) -> Result<Vec<Pair>> {
    let names: Vec<(String, PathBuf, PathBuf)> = match (&args.left, &args.right, &args.images) {
        (Some(l), Some(r), None) => vec![(file_stem(l), l.clone(), r.clone())],
        (None, None, Some(dir)) => pairs_in(dir)?,
        _ => bail!("give either --left and --right, or --images DIR"),
    };
    names
        .into_iter()
        .map(|(name, l, r)| {
            let (left, right) = read_stereo_pair(&l, &r)?;
            Ok(Pair { name, left, right })
        })
        .collect()
}

/// `NAME_0.png` / `NAME_1.png` pairs in `dir`, sorted by name.
fn pairs_in(dir: &Path) -> Result<Vec<(String, PathBuf, PathBuf)>> {
    let mut out = Vec::new();
    let entries =
        std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))?;
    for entry in entries {
        let path = entry?.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        if let Some(stem) = name.strip_suffix("_0.png") {
            let right = dir.join(format!("{stem}_1.png"));
            if right.is_file() {
                out.push((stem.to_string(), path.clone(), right));
            }
        }
    }
    if out.is_empty() {
        bail!("{}: no NAME_0.png / NAME_1.png pairs", dir.display());
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

fn file_stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "pair".into())
}

/// User + system CPU time of the whole process so far (all threads), milliseconds: with
/// other work on the machine this says what a frame costs, whatever the wall clock says.
pub(super) fn process_cpu_ms() -> f64 {
    let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: getrusage fills the struct it is given; on failure we read the zeroed struct.
    let usage = unsafe {
        libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr());
        usage.assume_init()
    };
    let ms = |t: libc::timeval| t.tv_sec as f64 * 1e3 + t.tv_usec as f64 * 1e-3;
    ms(usage.ru_utime) + ms(usage.ru_stime)
}

/// Median, 90th percentile (nearest rank) and minimum.
fn stats(mut v: Vec<f64>) -> Value {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return json!(null);
    }
    let n = v.len();
    let p90 = v[((0.9 * n as f64).ceil() as usize).clamp(1, n) - 1];
    let median = 0.5 * (v[(n - 1) / 2] + v[n / 2]);
    json!({"median": median, "p90": p90, "min": v[0]})
}

/// [`stats`] of each stage, milliseconds.
fn stage_stats(timings: &[FrontEndTiming]) -> Value {
    let of = |f: fn(&FrontEndTiming) -> f64| stats(timings.iter().map(f).collect());
    json!({
        "total": of(|t| t.total_ms),
        "stereo": of(|t| t.stereo_ms),
        "segment": of(|t| t.segment_ms),
        "boulders": of(|t| t.boulders_ms),
    })
}
