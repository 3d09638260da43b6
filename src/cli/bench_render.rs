//! `segloc bench render`: the renderer timed in steady state, one renderer per seed (as a
//! drive or a mission uses it), stereo pairs along the seed's mapping drive; wall time and
//! process CPU time a pair, median and 90th percentile, and the load average.

use super::bench_detect::process_cpu_ms;
use super::print_json;
use anyhow::{bail, Result};
use clap::Args;
use segloc::eval::render_front_end::drive;
use segloc::sim::render::scoring::quantile;
use segloc::sim::render::{RenderConfig, Renderer};
use serde_json::json;
use std::time::Instant;

/// Arguments of `segloc bench render`.
#[derive(Args, Debug)]
pub struct BenchRenderArgs {
    /// Seeds (one renderer each); held-out seeds by default.
    #[arg(long, value_delimiter = ',', default_value = "11,12,13,14")]
    seeds: Vec<u64>,
    /// Timed stereo pairs per seed, spread along the seed's 60 s mapping drive.
    #[arg(long, default_value_t = 6)]
    pairs: usize,
    /// Half resolution (640 × 360).
    #[arg(long)]
    half: bool,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// Run `segloc bench render`.
pub fn run(args: &BenchRenderArgs) -> Result<i32> {
    if args.pairs == 0 || args.seeds.is_empty() {
        bail!("--pairs must be at least 1 and --seeds not empty");
    }
    let config = RenderConfig {
        resolution_scale: if args.half { 0.5 } else { 1.0 },
        ..RenderConfig::default()
    };
    let (mut wall_ms, mut cpu_ms, mut setup_ms) = (Vec::new(), Vec::new(), Vec::new());
    for &seed in &args.seeds {
        let (moon, poses) = drive(seed, 60.0)?;
        let start = Instant::now();
        let renderer = Renderer::new(&moon, &config, seed)?;
        setup_ms.push(start.elapsed().as_secs_f64() * 1e3);
        let step = (poses.len() / args.pairs).max(1);
        // one untimed pair first (page-in)
        renderer.render_stereo(&poses[0], 0);
        for (tick, pose) in poses.iter().enumerate().step_by(step).take(args.pairs) {
            let cpu = process_cpu_ms();
            let start = Instant::now();
            let frame = renderer.render_stereo(pose, tick as u64);
            wall_ms.push(start.elapsed().as_secs_f64() * 1e3);
            cpu_ms.push(process_cpu_ms() - cpu);
            std::hint::black_box(frame);
        }
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let load: Vec<&str> = load.split_whitespace().take(3).collect();
    let out = json!({
        "width": config.width(), "height": config.height(),
        "seeds": args.seeds, "pairs": wall_ms.len(),
        "threads": rayon::current_num_threads(),
        "pair_ms": {"median": quantile(&wall_ms, 0.5), "p90": quantile(&wall_ms, 0.9)},
        "pair_cpu_ms": {"median": quantile(&cpu_ms, 0.5), "p90": quantile(&cpu_ms, 0.9)},
        "renderer_setup_ms": {"median": quantile(&setup_ms, 0.5)},
        "load_average": load,
    });
    if args.json {
        print_json(&out)?;
    } else {
        println!(
            "{} pairs at {} × {} ({} threads): {:.0} ms median, {:.0} ms p90 a pair (CPU {:.0} ms median); renderer setup {:.0} ms; load average {}",
            wall_ms.len(),
            config.width(),
            config.height(),
            rayon::current_num_threads(),
            quantile(&wall_ms, 0.5),
            quantile(&wall_ms, 0.9),
            quantile(&cpu_ms, 0.5),
            quantile(&setup_ms, 0.5),
            load.join(" ")
        );
    }
    Ok(0)
}
