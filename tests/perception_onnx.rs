//! The ONNX segmenter with the tiny models of known output that
//! `scripts/make-test-models.sh` builds, run by the onnxruntime library that
//! `scripts/fetch-onnxruntime.sh` fetches. Without them the tests skip (saying so), except
//! under `CI=true`, where `.ci/run` runs both scripts first and a missing piece fails.

mod common;

use common::{assert_refused, segloc};

use std::path::PathBuf;

use segloc::perception::onnx::{runtime_available, OnnxSegmenter, YoloSegConfig};
use segloc::perception::GrayImage;

fn models() -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/target/test-models"));
    let ci = std::env::var("CI").is_ok_and(|v| v == "true");
    let have_models = dir.join("tiny_yoloseg.onnx").is_file();
    let have_runtime = runtime_available();
    if have_models && have_runtime {
        return Some(dir);
    }
    let why = format!(
        "test models present: {have_models} (scripts/make-test-models.sh), onnxruntime loadable: {have_runtime} (scripts/fetch-onnxruntime.sh)"
    );
    assert!(!ci, "under CI=true the ONNX tests must not skip: {why}");
    eprintln!("SKIPPED: {why}");
    None
}

#[test]
fn tiny_model_masks_are_decoded_where_they_were_built() {
    let Some(dir) = models() else { return };
    let mut seg =
        OnnxSegmenter::load(&dir.join("tiny_yoloseg.onnx"), YoloSegConfig::default()).unwrap();
    assert_eq!(seg.input_size(), 160);
    let image = GrayImage::zeros(1280, 720);
    let mut masks = seg.segment_image(&image).unwrap();
    assert_eq!(
        masks.len(),
        2,
        "NMS and the score threshold leave two masks"
    );
    masks.sort_by_key(|m| m.x0);
    // disk: centre (480, 360), radius 120 image px (prototype resolution blurs the edge)
    let disk = &masks[0];
    let (cx, cy) = centroid(disk);
    assert!(
        (cx - 480.0).abs() < 6.0 && (cy - 360.0).abs() < 6.0,
        "disk at {cx}, {cy}"
    );
    let area = disk.area() as f64;
    let expected = std::f64::consts::PI * 120.0 * 120.0;
    assert!(
        (area / expected - 1.0).abs() < 0.12,
        "disk area {area} vs {expected}"
    );
    assert!((disk.score - 0.9).abs() < 1e-6);
    // square: x 800..1024, y 200..424
    let square = &masks[1];
    let [x0, y0, x1, y1] = square.bbox();
    for (got, want) in [(x0, 800), (y0, 200), (x1, 1024), (y1, 424)] {
        assert!(
            (got as i64 - want).abs() <= 12,
            "square bbox {:?}",
            square.bbox()
        );
    }
    // the point-prompt grid keeps only masks hit by a grid point: a 5 × 5 grid hits both
    // (points (384, 360) and (896, 216)), a 3 × 3 grid neither (its points at u = 213, 640,
    // 1066, v = 120, 360, 600 miss the disk and the square)
    for (grid, expected) in [(5usize, 2usize), (3, 0)] {
        let mut seg = OnnxSegmenter::load(
            &dir.join("tiny_yoloseg.onnx"),
            YoloSegConfig {
                point_grid: grid,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(
            seg.segment_image(&image).unwrap().len(),
            expected,
            "grid {grid}"
        );
    }
}

fn centroid(m: &segloc::perception::Mask) -> (f64, f64) {
    let n = m.area() as f64;
    let (sx, sy) = m
        .pixels()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x as f64, b + y as f64));
    (sx / n, sy / n)
}

#[test]
fn bad_models_are_refused_with_the_file_named() {
    let Some(dir) = models() else { return };
    let bad = dir.join("tiny_bad_outputs.onnx");
    let err = OnnxSegmenter::load(&bad, YoloSegConfig::default())
        .err()
        .unwrap();
    let text = err.to_string();
    assert!(
        text.contains("tiny_bad_outputs.onnx") && text.contains("outputs"),
        "{text}"
    );
    let tmp = tempfile::tempdir().unwrap();
    let corrupt = tmp.path().join("corrupt.onnx");
    std::fs::write(&corrupt, b"not a model").unwrap();
    let err = OnnxSegmenter::load(&corrupt, YoloSegConfig::default())
        .err()
        .unwrap();
    assert!(err.to_string().contains("corrupt.onnx"), "{err}");
    let err = OnnxSegmenter::load(&tmp.path().join("missing.onnx"), YoloSegConfig::default())
        .err()
        .unwrap();
    assert!(err.to_string().contains("missing.onnx"), "{err}");
    // the CLI: exit code 2
    let data = std::env::var_os("SEGLOC_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data")));
    let left = data.join("lac-images/1_155_0.png");
    if left.is_file() {
        let out = segloc()
            .args(["detect", "--segmenter", "onnx", "--model"])
            .arg(&corrupt)
            .arg("--left")
            .arg(&left)
            .arg("--right")
            .arg(data.join("lac-images/1_155_1.png"))
            .output()
            .unwrap();
        assert_refused(&out, "corrupt.onnx");
    }
}
