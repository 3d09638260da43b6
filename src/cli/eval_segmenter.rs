//! `segloc eval segmenter`: a segmenter's recall and precision on the real LAC pairs
//! against hand labels (`tests/fixtures/real_rock_labels.csv`).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context, Result};
use segloc::eval::segmenter_labels::{
    read_labels, score_pair, LabelMatchConfig, LabelScore, RockLabel, ScoredDetection,
};
use segloc::perception::FrontEnd;
use serde_json::json;

use super::detect::{load_frontend_config, make_segmenter, read_stereo_pair, SegmenterKind};

/// Arguments of `segloc eval segmenter`.
#[derive(clap::Args, Debug)]
pub struct EvalSegmenterArgs {
    /// Label CSV (`pair,u,v,class,...`; class `rock` or `may`).
    #[arg(long, value_name = "CSV")]
    pub labels: PathBuf,
    /// The data folder holding `lac-images/PAIR_0.png` and `PAIR_1.png`.
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// The segmenter.
    #[arg(long, value_enum, default_value = "geometric")]
    pub segmenter: SegmenterKind,
    /// ONNX model (`--segmenter onnx`, or another model for `learned`).
    #[arg(long, value_name = "ONNX")]
    pub model: Option<PathBuf>,
    /// Front-end settings (TOML).
    #[arg(long, value_name = "TOML")]
    pub frontend_config: Option<PathBuf>,
    /// A detection's centroid this close to a label finds it, pixels.
    #[arg(long, default_value_t = 8.0)]
    pub radius_px: f64,
    /// Detections beyond this depth are outside the labelled range and not counted, m.
    #[arg(long, default_value_t = 9.0)]
    pub max_depth_m: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Run `segloc eval segmenter`.
pub fn run(args: &EvalSegmenterArgs) -> Result<i32> {
    let labels = read_labels(&args.labels)?;
    let mut by_pair: BTreeMap<&str, Vec<&RockLabel>> = BTreeMap::new();
    for l in &labels {
        by_pair.entry(l.pair.as_str()).or_default().push(l);
    }
    let config = load_frontend_config(args.frontend_config.as_deref())?;
    let segmenter = make_segmenter(args.segmenter, args.model.as_deref(), &config)?;
    let mut front_end = FrontEnd::new(config, segmenter)?;
    let match_config = LabelMatchConfig {
        radius_px: args.radius_px,
        max_depth_m: args.max_depth_m,
    };
    let mut total = LabelScore::default();
    let mut rows = Vec::new();
    let mut time_ms = Vec::new();
    for (pair, pair_labels) in &by_pair {
        let dir = args.data.join("lac-images");
        let (left, right) = (
            dir.join(format!("{pair}_0.png")),
            dir.join(format!("{pair}_1.png")),
        );
        let (l, r) = read_stereo_pair(&left, &right)
            .with_context(|| format!("pair {pair:?} of {}", args.labels.display()))?;
        let result = front_end.process(&l, &r)?;
        time_ms.push(result.timing.segment_ms);
        let detections: Vec<ScoredDetection<'_>> = result
            .verdicts
            .iter()
            .zip(&result.masks)
            .filter_map(|(v, mask)| {
                let b = &result.boulders[*v.as_ref().ok()?];
                Some(ScoredDetection {
                    mask,
                    pixel_centroid: b.pixel_centroid,
                    depth_m: b.depth_m,
                })
            })
            .collect();
        let score = score_pair(pair_labels, &detections, &match_config);
        total.add(&score);
        rows.push((pair.to_string(), score));
    }
    print_report(args, &rows, &total, &time_ms, front_end.segmenter_name())?;
    Ok(0)
}

fn print_report(
    args: &EvalSegmenterArgs,
    rows: &[(String, LabelScore)],
    total: &LabelScore,
    segment_ms: &[f64],
    segmenter: &str,
) -> Result<()> {
    let mean_ms = segment_ms.iter().sum::<f64>() / segment_ms.len().max(1) as f64;
    if args.json {
        let pairs: Vec<_> = rows
            .iter()
            .map(|(p, s)| json!({"pair": p, "recall": s.recall(), "precision": s.precision(), "score": s}))
            .collect();
        super::print_json(&json!({
            "segmenter": segmenter,
            "labels": args.labels,
            "recall": total.recall(),
            "precision": total.precision(),
            "total": total,
            "pairs": pairs,
            "mean_segment_ms": mean_ms,
            "radius_px": args.radius_px,
            "max_depth_m": args.max_depth_m,
        }))?;
        return Ok(());
    }
    println!("segmenter {segmenter}: labels {}", args.labels.display());
    println!("pair      rocks found  recall   TP  FP  ignored  precision");
    for (p, s) in rows
        .iter()
        .chain(std::iter::once(&("all".to_string(), total.clone())))
    {
        println!(
            "{p:8} {:6} {:6} {:7.2} {:4} {:3} {:8} {:10.2}",
            s.rocks,
            s.found,
            s.recall(),
            s.true_positives,
            s.false_positives,
            s.ignored,
            s.precision()
        );
    }
    println!("mean segmentation time {mean_ms:.1} ms per pair");
    Ok(())
}
