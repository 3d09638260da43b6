//! Segmenters against the hand labels of the real LAC pairs
//! (`tests/fixtures/real_rock_labels.csv`, see tests/fixtures/README.md), and the shipped
//! learned model (`models/boulders.onnx`) on a real pair. The learned tests need the
//! onnxruntime library (`scripts/fetch-onnxruntime.sh`): without it they skip, saying so,
//! except under `CI=true`, where `.ci/run` fetches it first and a missing library fails.

mod common;

use std::path::PathBuf;

use common::{assert_refused, segloc};
use segloc::perception::onnx::{runtime_available, shipped_model, LearnedSegmenter};
use segloc::perception::{read_gray_png, FrontEnd, FrontEndConfig};

fn labels() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/real_rock_labels.csv"
    ))
}

fn runtime() -> bool {
    if runtime_available() {
        return true;
    }
    let ci = std::env::var("CI").is_ok_and(|v| v == "true");
    assert!(!ci, "under CI=true the learned-segmenter tests must not skip: onnxruntime missing (scripts/fetch-onnxruntime.sh)");
    eprintln!("SKIPPED: onnxruntime not loadable (scripts/fetch-onnxruntime.sh)");
    false
}

/// Recall and precision of `segloc eval segmenter` on the fixture.
fn eval(segmenter: &str) -> (f64, f64) {
    let data = common::data_dir().expect("real data");
    let out = segloc()
        .args([
            "eval",
            "segmenter",
            "--json",
            "--segmenter",
            segmenter,
            "--labels",
        ])
        .arg(labels())
        .arg("--data")
        .arg(&data)
        .output()
        .unwrap();
    common::assert_success(&out);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    (
        report["recall"].as_f64().unwrap(),
        report["precision"].as_f64().unwrap(),
    )
}

#[test]
fn geometric_segmenter_against_the_hand_labels() {
    if common::data_dir().is_none() {
        return;
    }
    let (recall, precision) = eval("geometric");
    println!("geometric: recall {recall:.2}, precision {precision:.2}");
    // measured 2026-11-29: recall 0.91, precision 0.84 (models/README.md)
    assert!(recall >= 0.8, "recall {recall}");
    assert!(precision >= 0.7, "precision {precision}");
}

#[test]
fn learned_segmenter_against_the_hand_labels() {
    if common::data_dir().is_none() || !runtime() {
        return;
    }
    let (recall, precision) = eval("learned");
    println!("learned: recall {recall:.2}, precision {precision:.2}");
    // measured 2026-11-29 with the shipped model (retrained on the angular rocks) and the
    // front end's stereo check of its boulders (docs/design/relief-gate.md): recall 0.96,
    // precision 0.56 (without the check: 0.96 / 0.14); still less precise than the
    // geometric segmenter (models/README.md); the precision floor fails if the check is lost
    assert!(recall >= 0.8, "recall {recall}");
    assert!(precision >= 0.4, "precision {precision}");
}

#[test]
fn shipped_model_finds_the_big_rocks_of_a_real_pair() {
    let Some(data) = common::data_dir() else {
        return;
    };
    if !runtime() {
        return;
    }
    let config = FrontEndConfig::default();
    let model = shipped_model().unwrap();
    let seg = LearnedSegmenter::load(&model, config.learned.clone()).unwrap();
    assert_eq!(seg.input_size(), (640, 360));
    let mut fe = FrontEnd::new(config, Box::new(seg)).unwrap();
    let dir = data.join("lac-images");
    let left = read_gray_png(&dir.join("2_1357_0.png")).unwrap();
    let right = read_gray_png(&dir.join("2_1357_1.png")).unwrap();
    let result = fe.process(&left, &right).unwrap();
    // the dark rock with a lit cap at (508, 575), 4.1 m
    let found = result.boulders.iter().any(|b| {
        (b.pixel_centroid[0] - 508.0).abs() < 15.0 && (b.pixel_centroid[1] - 575.0).abs() < 15.0
    });
    assert!(
        found,
        "boulders: {:?}",
        result
            .boulders
            .iter()
            .map(|b| b.pixel_centroid)
            .collect::<Vec<_>>()
    );
}

#[test]
fn learned_segmenter_bad_models_exit_2_naming_the_problem() {
    if !runtime() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("segloc-learned-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let not_onnx = dir.join("not.onnx");
    std::fs::write(&not_onnx, b"this is not a model").unwrap();
    let tiny_yolo = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/target/test-models/tiny_yoloseg.onnx"
    ));
    let left = dir.join("l.png");
    let image = segloc::perception::GrayImage::zeros(64, 36);
    segloc::perception::write_gray_png(&image, &left).unwrap();
    let mut cases = vec![
        (dir.join("missing.onnx"), "not found"),
        (not_onnx, "cannot load the model"),
    ];
    if tiny_yolo.is_file() {
        cases.push((tiny_yolo, "expected one input [1, 1, H, W]"));
    }
    for (model, expected) in cases {
        let out = segloc()
            .args(["detect", "--segmenter", "learned", "--left"])
            .arg(&left)
            .arg("--right")
            .arg(&left)
            .arg("--model")
            .arg(&model)
            .output()
            .unwrap();
        assert_refused(&out, expected);
    }
    let out = segloc()
        .args(["detect", "--segmenter", "learned", "--left"])
        .arg(&left)
        .arg("--right")
        .arg(&left)
        .env("SEGLOC_MODELS", &dir)
        .output()
        .unwrap();
    assert_refused(&out, "SEGLOC_MODELS");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn shipped_model_mask_counts_on_two_rendered_frames() {
    if !runtime() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("segloc-learned-render-{}", std::process::id()));
    let out = segloc()
        .args([
            "sim",
            "render",
            "--seed",
            "901",
            "--seconds",
            "3",
            "--every",
            "20",
            "--half",
            "-o",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    common::assert_success(&out);
    let config = FrontEndConfig::default();
    let mut seg = LearnedSegmenter::load(&shipped_model().unwrap(), config.learned).unwrap();
    // stored 2026-11-29 (held-out seed 901, default sun; the model retrained on the angular
    // rocks under McEwen's photometry): 35 and 16 masks (38 and 21 with the sphere-trained
    // model, 25 and 21 when the rocks were spheres)
    for (frame, stored) in [("000000", 35usize), ("000040", 16)] {
        let left = read_gray_png(&dir.join(format!("{frame}_0.png"))).unwrap();
        let n = seg.segment_image(&left).unwrap().len();
        println!("frame {frame}: {n} masks (stored {stored})");
        let tolerance = 4.max(stored * 2 / 5);
        assert!(
            n.abs_diff(stored) <= tolerance,
            "frame {frame}: {n} masks, stored {stored}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
