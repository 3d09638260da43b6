//! The perception front end on the 8 real LAC stereo pairs (unlabelled): it must run on
//! every pair, find at least one boulder in most of them, and place each in front of the
//! camera at a plausible depth. Bad inputs must give clear errors (exit code 2).

mod common;

use segloc::perception::{read_gray_png, FrontEnd, FrontEndConfig, GeometricSegmenter};

const PAIRS: [&str; 8] = [
    "1_155", "1_179", "1_185", "1_191", "1_247", "1_283", "2_1357", "2_915",
];

#[test]
fn front_end_runs_on_all_real_pairs() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let dir = data.join("lac-images");
    let config = FrontEndConfig::default();
    let segmenter = GeometricSegmenter::new(config.geometric.clone());
    let mut fe = FrontEnd::new(config, Box::new(segmenter)).unwrap();
    let mut with_boulders = 0;
    let mut times = Vec::new();
    for name in PAIRS {
        let left = read_gray_png(&dir.join(format!("{name}_0.png"))).unwrap();
        let right = read_gray_png(&dir.join(format!("{name}_1.png"))).unwrap();
        let result = fe.process(&left, &right).unwrap();
        times.push(result.timing.total_ms);
        if !result.boulders.is_empty() {
            with_boulders += 1;
        }
        for b in &result.boulders {
            assert!(
                b.depth_m > 0.5 && b.depth_m < 15.0,
                "{name}: depth {}",
                b.depth_m
            );
            assert!(
                b.size_m > 0.05 && b.size_m < 2.5,
                "{name}: size {}",
                b.size_m
            );
        }
        println!(
            "{name}: {} boulders, {:.1} ms",
            result.boulders.len(),
            result.timing.total_ms
        );
    }
    assert!(
        with_boulders >= 5,
        "boulders found in only {with_boulders} of 8 pairs"
    );
}

#[test]
fn detect_cli_rejects_bad_input_with_exit_code_2() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let left = data.join("lac-images/1_155_0.png");
    let tmp = tempfile::tempdir().unwrap();
    // a right image of another size
    let small = tmp.path().join("small.png");
    let image = segloc::perception::GrayImage::zeros(640, 300);
    segloc::perception::write_gray_png(&image, &small).unwrap();
    let out = common::segloc()
        .args(["detect", "--left"])
        .arg(&left)
        .arg("--right")
        .arg(&small)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("small.png"), "{err}");
    // not a PNG
    let junk = tmp.path().join("junk.png");
    std::fs::write(&junk, b"junk").unwrap();
    let out = common::segloc()
        .args(["detect", "--left"])
        .arg(&left)
        .arg("--right")
        .arg(&junk)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("junk.png"));
    // a missing file
    let out = common::segloc()
        .args(["detect", "--left", "/nonexistent/l.png", "--right"])
        .arg(&left)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/l.png"));
    // JSON output of a good pair
    let right = data.join("lac-images/1_155_1.png");
    let out = common::segloc()
        .args(["detect", "--json", "--left"])
        .arg(&left)
        .arg("--right")
        .arg(&right)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["time_ms"].as_f64().unwrap() > 0.0);
    assert!(v["boulders"].is_array());
}
