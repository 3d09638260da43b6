//! The perception front end on rendered stereo pairs of known geometry: depth accuracy of a
//! boulder at 5 m, detection of resting spheres, nothing invented on bare ground.

use segloc::perception::render::{render_stereo, SyntheticScene};
use segloc::perception::{FrontEnd, FrontEndConfig, GeometricSegmenter, StereoCamera};

fn front_end(config: FrontEndConfig) -> FrontEnd {
    let segmenter = GeometricSegmenter::new(config.geometric.clone());
    FrontEnd::new(config, Box::new(segmenter)).unwrap()
}

/// Median of the true depth over the pixels that see sphere `k`.
fn true_median_depth(pair: &segloc::perception::render::RenderedPair, k: usize) -> f64 {
    let mut d: Vec<f64> = pair
        .object
        .iter()
        .zip(&pair.depth_m)
        .filter(|(&o, _)| o as usize == k + 2)
        .map(|(_, &z)| z)
        .collect();
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

#[test]
fn boulder_at_5_m_has_its_depth_within_5_cm() {
    let camera = StereoCamera::ipex();
    let mut scene = SyntheticScene::default();
    let spheres = [
        (5.0, -0.6, 0.2),
        (5.0, 0.9, 0.3),
        (3.0, 0.2, 0.15),
        (7.5, -1.8, 0.35),
    ];
    for (z, x, r) in spheres {
        let s = scene.resting_sphere(z, x, r);
        scene.spheres.push(s);
    }
    let pair = render_stereo(&scene, &camera);
    for levels in [1u32, 0] {
        let mut config = FrontEndConfig::default();
        config.stereo.levels = levels;
        config.stereo.max_disparity = if levels == 0 { 192 } else { 96 };
        let mut fe = front_end(config);
        let result = fe.process(&pair.left, &pair.right).unwrap();
        for (k, s) in scene.spheres.iter().enumerate() {
            let (u, v) = camera.project(&s.center).unwrap();
            let found = result.boulders.iter().find(|b| {
                let [x0, y0, x1, y1] = b.pixel_box;
                (x0 as f64) <= u && u <= x1 as f64 && (y0 as f64) <= v && v <= y1 as f64
            });
            let truth = true_median_depth(&pair, k);
            let b = found.unwrap_or_else(|| panic!("levels {levels}: sphere {k} not found"));
            let err = b.depth_m - truth;
            let size_err = b.size_m - 2.0 * s.radius_m;
            println!(
                "levels {levels} sphere {k} at {:.1} m: depth {:.4} true {:.4} err {:+.4} m, size {:.3} (true {:.2}), time {:.1} ms",
                s.center.z, b.depth_m, truth, err, b.size_m, 2.0 * s.radius_m, result.timing.total_ms
            );
            if (s.center.z - 5.0).abs() < 1e-9 {
                assert!(
                    err.abs() < 0.05,
                    "levels {levels} sphere {k}: depth error {err}"
                );
            }
            assert!(
                size_err.abs() < 0.35 * 2.0 * s.radius_m,
                "size error {size_err}"
            );
        }
        assert_eq!(
            result.boulders.len(),
            scene.spheres.len(),
            "levels {levels}: invented boulders"
        );
    }
}

#[test]
fn bare_ground_gives_no_boulders() {
    let camera = StereoCamera::ipex().for_size(640, 360).unwrap();
    let scene = SyntheticScene::default();
    let pair = render_stereo(&scene, &camera);
    let mut config = FrontEndConfig::default();
    config.stereo.levels = 0;
    let mut fe = front_end(config);
    let result = fe.process(&pair.left, &pair.right).unwrap();
    assert!(result.boulders.is_empty(), "{:?}", result.boulders);
}
