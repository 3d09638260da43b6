//! `segloc eval render`: the perception front end on rendered frames of the synthetic moon,
//! scored against the renderer's truth (recall, precision, centroid error; overall, by range
//! band and by sun elevation). See `segloc::eval::render_front_end`.

use super::detect::{load_frontend_config, make_segmenter, SegmenterKind};
use super::print_json;
use anyhow::{bail, Context, Result};
use clap::Args;
use segloc::eval::render_breakdown::diagnose_frame;
use segloc::eval::render_front_end::{
    evaluate_render, summarize, FrameScore, MatchConfig, RenderEvalOptions, Summary,
};
use segloc::perception::FrontEnd;
use segloc::sim::render::scoring::quantile;
use segloc::sim::render::RenderConfig;
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `segloc eval render`.
#[derive(Args, Debug)]
pub struct EvalRenderArgs {
    /// Seeds of the moons and drives: a list and ranges, e.g. `1-10` or `1,3,5-7`.
    #[arg(long, default_value = "1-10")]
    seeds: String,
    /// Sun elevations, degrees.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "5,15,30",
        allow_negative_numbers = true
    )]
    sun_deg: Vec<f64>,
    /// Seconds of each seed's mapping session.
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Render every K-th simulator tick (20 Hz).
    #[arg(long, default_value_t = 200)]
    every: usize,
    /// Half resolution (640 × 360).
    #[arg(long)]
    half: bool,
    /// Renderer settings (TOML, the fields of `RenderConfig`).
    #[arg(long, value_name = "TOML")]
    render_config: Option<PathBuf>,
    /// Front-end settings (TOML, as `segloc detect --frontend-config`).
    #[arg(long, value_name = "TOML")]
    frontend_config: Option<PathBuf>,
    /// The segmenter, as `segloc detect --segmenter`.
    #[arg(long, value_enum, default_value = "geometric")]
    segmenter: SegmenterKind,
    /// ONNX model (`--segmenter onnx`, or another model for `learned`).
    #[arg(long, value_name = "ONNX")]
    model: Option<PathBuf>,
    /// Write every frame's rocks and detections as JSON lines here.
    #[arg(long, value_name = "FILE")]
    frames: Option<PathBuf>,
    /// Write a diagnosis of every counted rock (stages, cause of a miss) as JSON lines here:
    /// the geometric segmenter's stages, and the front end's own mask on the rock and the
    /// boulder stage's verdict on it (`mask_*`, whatever the segmenter).
    #[arg(long, value_name = "FILE")]
    breakdown: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// Parse `1-10`, `1,3,5-7`.
fn parse_seeds(text: &str) -> Result<Vec<u64>> {
    let mut seeds = Vec::new();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let bad = || format!("--seeds: '{part}' is not a seed or a range a-b");
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b): (u64, u64) = (
                    a.trim().parse().with_context(bad)?,
                    b.trim().parse().with_context(bad)?,
                );
                if b < a || b - a > 10_000 {
                    bail!("--seeds: range '{part}' is empty or too long");
                }
                seeds.extend(a..=b);
            }
            None => seeds.push(part.parse().with_context(bad)?),
        }
    }
    if seeds.is_empty() {
        bail!("--seeds: no seed given");
    }
    Ok(seeds)
}

/// Run `segloc eval render`.
pub fn run(args: &EvalRenderArgs) -> Result<i32> {
    let seeds = parse_seeds(&args.seeds)?;
    let mut render = super::sim_render::load_render_config(args.render_config.as_deref())?;
    if args.half {
        render.resolution_scale = 0.5;
    }
    for &sun in &args.sun_deg {
        RenderConfig {
            sun_elevation_deg: sun,
            ..render.clone()
        }
        .validate()
        .context("--sun-deg")?;
    }
    let config = load_frontend_config(args.frontend_config.as_deref())?;
    let segmenter = make_segmenter(args.segmenter, args.model.as_deref(), &config)?;
    let mut front_end = FrontEnd::new(config, segmenter)?;
    let options = RenderEvalOptions {
        seeds: seeds.clone(),
        sun_elevations_deg: args.sun_deg.clone(),
        seconds: args.seconds,
        every_ticks: args.every,
        render,
        matching: MatchConfig::default(),
    };
    let geometric = front_end.config().geometric.clone();
    let (mut lines, mut diagnoses) = (String::new(), String::new());
    let scores = evaluate_render(&options, &mut front_end, |f| {
        push_json_line(&mut lines, f.score);
        if args.breakdown.is_some() {
            for d in diagnose_frame(f.moon, f.frame, f.result, f.score, &geometric) {
                push_json_line(&mut diagnoses, &d);
            }
        }
    })?;
    if let Some(path) = &args.frames {
        segloc_maps::write_atomic(path, lines.as_bytes())?;
    }
    if let Some(path) = &args.breakdown {
        segloc_maps::write_atomic(path, diagnoses.as_bytes())?;
    }
    report(
        args,
        &seeds,
        &scores,
        &options.matching,
        front_end.segmenter_name(),
    )
}

fn push_json_line(out: &mut String, value: &impl serde::Serialize) {
    if let Ok(line) = serde_json::to_string(value) {
        out.push_str(&line);
        out.push('\n');
    }
}

fn report(
    args: &EvalRenderArgs,
    seeds: &[u64],
    scores: &[FrameScore],
    matching: &MatchConfig,
    segmenter: &str,
) -> Result<i32> {
    let all: Vec<&FrameScore> = scores.iter().collect();
    let everything = (0.0, f64::INFINITY);
    let overall = summarize(&all, everything, matching);
    let bands = [(0.0, 2.0), (2.0, 4.0), (4.0, 6.0)];
    let by_band: Vec<(String, Summary)> = bands
        .iter()
        .map(|&b| (format!("{}-{} m", b.0, b.1), summarize(&all, b, matching)))
        .collect();
    let by_sun: Vec<(f64, Summary)> = args
        .sun_deg
        .iter()
        .map(|&sun| {
            let f: Vec<&FrameScore> = all
                .iter()
                .copied()
                .filter(|s| s.sun_elevation_deg == sun)
                .collect();
            (sun, summarize(&f, everything, matching))
        })
        .collect();
    let render: Vec<f64> = scores.iter().map(|s| s.render_ms).collect();
    let render_ms = quantile(&render, 0.5);
    let front_end: Vec<f64> = scores.iter().map(|s| s.front_end_ms).collect();
    let fe = |q| quantile(&front_end, q);
    if args.json {
        print_json(&json!({
            "seeds": seeds, "sun_deg": args.sun_deg, "matching": matching, "segmenter": segmenter,
            "overall": overall,
            "by_range": by_band.iter().map(|(k, s)| json!({"band": k, "summary": s})).collect::<Vec<_>>(),
            "by_sun": by_sun.iter().map(|(k, s)| json!({"sun_deg": k, "summary": s})).collect::<Vec<_>>(),
            "render_ms": {"median": render_ms},
            "front_end_ms": {"median": fe(0.5), "p90": fe(0.9)},
        }))?;
        return Ok(0);
    }
    println!("segmenter {segmenter}");
    println!("| set | frames | rocks | detections | recall | precision | centroid error median / p90 (cm) |");
    println!("|---|---|---|---|---|---|---|");
    let row = |name: &str, s: &Summary| {
        println!(
            "| {name} | {} | {} | {} | {:.3} | {:.3} | {:.1} / {:.1} |",
            s.frames,
            s.rocks,
            s.detections,
            s.recall,
            s.precision,
            100.0 * s.centroid_error_median_m,
            100.0 * s.centroid_error_p90_m
        )
    };
    row("all", &overall);
    for (k, s) in &by_band {
        row(k, s);
    }
    for (k, s) in &by_sun {
        row(&format!("sun {k}°"), s);
    }
    println!(
        "render {render_ms:.0} ms a pair (median); front end {:.0} / {:.0} ms (median / p90)",
        fe(0.5),
        fe(0.9)
    );
    Ok(0)
}

#[cfg(test)]
mod tests {
    use super::parse_seeds;

    #[test]
    fn seeds_parse_lists_and_ranges() {
        assert_eq!(parse_seeds("1-3,7").unwrap(), vec![1, 2, 3, 7]);
        assert!(parse_seeds("3-1").is_err());
        assert!(parse_seeds("x").is_err());
    }
}
