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
                b.depth_m > 0.5 && b.depth_m < 10.0,
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
    common::assert_refused(&out, "small.png");
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
    common::assert_refused(&out, "junk.png");
    // a missing file
    let out = common::segloc()
        .args(["detect", "--left", "/nonexistent/l.png", "--right"])
        .arg(&left)
        .output()
        .unwrap();
    common::assert_refused(&out, "/nonexistent/l.png");
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

/// `segloc bench detect` times every real pair in one process and reports each stage; a
/// folder without pairs is bad input (exit code 2).
#[test]
fn bench_detect_times_every_pair_and_stage() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let out = common::segloc()
        .args([
            "bench", "detect", "--repeat", "2", "--warmup", "0", "--json", "--images",
        ])
        .arg(data.join("lac-images"))
        .output()
        .unwrap();
    common::assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let pairs = v["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), PAIRS.len());
    for (p, name) in pairs.iter().zip(PAIRS) {
        assert_eq!(p["pair"], name);
        assert_eq!(p["runs"], 2);
        for stage in ["total", "stereo", "segment", "boulders", "cpu"] {
            let ms = &p["ms"][stage];
            let (min, median, p90) = (
                ms["min"].as_f64(),
                ms["median"].as_f64(),
                ms["p90"].as_f64(),
            );
            let (min, median, p90) = (min.unwrap(), median.unwrap(), p90.unwrap());
            assert!(
                0.0 <= min && min <= median && median <= p90,
                "{name} {stage}: {ms}"
            );
        }
    }
    assert_eq!(v["all"]["runs"], 2 * PAIRS.len());
    assert!(v["first_frame_ms"]["total_ms"].as_f64().unwrap() > 0.0);
    let tmp = tempfile::tempdir().unwrap();
    let out = common::segloc()
        .args(["bench", "detect", "--images"])
        .arg(tmp.path())
        .output()
        .unwrap();
    common::assert_refused(&out, "no NAME_0.png");
}

/// Rocks the geometric segmenter finds on the real pairs (read off the overlays): each
/// must come out as a boulder whose centroid lies within 20 px of the listed pixel, at a
/// depth within 15 % of the listed one.
#[test]
fn geometric_segmenter_finds_the_known_real_rocks() {
    let Some(data) = common::data_dir() else {
        return;
    };
    // (pair, [(u, v, depth_m)])
    type Rock = (f64, f64, f64);
    let rocks: [(&str, &[Rock]); 8] = [
        ("1_155", &[(455.0, 379.0, 3.3), (693.0, 294.0, 5.6)]),
        ("1_179", &[(507.0, 470.0, 2.9), (779.0, 384.0, 5.1)]),
        ("1_185", &[(496.0, 493.0, 2.8), (776.0, 411.0, 5.0)]),
        ("1_191", &[(496.0, 487.0, 2.7), (778.0, 384.0, 5.0)]),
        (
            "1_247",
            &[
                (346.0, 445.0, 1.8),
                (762.0, 310.0, 4.1),
                (355.0, 321.0, 4.9),
            ],
        ),
        ("1_283", &[(784.0, 264.0, 3.4), (159.0, 414.0, 1.2)]),
        ("2_1357", &[(1074.0, 676.0, 1.3), (508.0, 574.0, 4.2)]),
        ("2_915", &[(915.0, 473.0, 1.9)]),
    ];
    let dir = data.join("lac-images");
    let config = FrontEndConfig::default();
    let segmenter = GeometricSegmenter::new(config.geometric.clone());
    let mut fe = FrontEnd::new(config, Box::new(segmenter)).unwrap();
    let mut missing = Vec::new();
    for (name, expected) in rocks {
        let left = read_gray_png(&dir.join(format!("{name}_0.png"))).unwrap();
        let right = read_gray_png(&dir.join(format!("{name}_1.png"))).unwrap();
        let result = fe.process(&left, &right).unwrap();
        for &(u, v, depth) in expected {
            let found = result.boulders.iter().any(|b| {
                (b.pixel_centroid[0] - u).abs() <= 20.0
                    && (b.pixel_centroid[1] - v).abs() <= 20.0
                    && (b.depth_m - depth).abs() <= 0.15 * depth
            });
            if !found {
                missing.push(format!("{name} ({u}, {v}) at {depth} m"));
            }
        }
    }
    assert!(missing.is_empty(), "rocks not found: {missing:?}");
}

/// The box under the lander's deck at the left edge of 2_915 (pixel (54, 335), 5.6 m) is no
/// boulder: the lander stands straight above it at its depth.
#[test]
fn geometric_segmenter_invents_no_boulder_at_the_lander_foot() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let dir = data.join("lac-images");
    let config = FrontEndConfig::default();
    let segmenter = GeometricSegmenter::new(config.geometric.clone());
    let mut fe = FrontEnd::new(config, Box::new(segmenter)).unwrap();
    let left = read_gray_png(&dir.join("2_915_0.png")).unwrap();
    let right = read_gray_png(&dir.join("2_915_1.png")).unwrap();
    let result = fe.process(&left, &right).unwrap();
    let invented: Vec<_> = result
        .boulders
        .iter()
        .filter(|b| {
            (b.pixel_centroid[0] - 54.0).abs() <= 60.0
                && (b.pixel_centroid[1] - 335.0).abs() <= 60.0
        })
        .map(|b| (b.pixel_centroid, b.depth_m))
        .collect();
    assert!(
        invented.is_empty(),
        "boulders at the lander's foot: {invented:?}"
    );
    // the rock on the right is still found
    assert!(result
        .boulders
        .iter()
        .any(|b| (b.pixel_centroid[0] - 915.0).abs() <= 20.0
            && (b.pixel_centroid[1] - 473.0).abs() <= 20.0));
}
