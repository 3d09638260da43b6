//! The perception front end on rendered stereo pairs of known geometry: depth accuracy of a
//! boulder at 5 m, detection of resting spheres, nothing invented on bare ground.

mod common;

use common::{assert_refused, assert_success, segloc};

use segloc::perception::render::{render_stereo, SyntheticScene};
use segloc::perception::{
    FrontEnd, FrontEndConfig, GeometricSegmenter, Mask, PerceptionError, Rejection, SegmentInput,
    Segmenter, StereoCamera,
};

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

/// An image-only segmenter that returns fixed masks (as the learned one would).
struct FixedMasks(Vec<Mask>);

impl Segmenter for FixedMasks {
    fn name(&self) -> &'static str {
        "fixed"
    }

    fn segment(&mut self, _: &SegmentInput<'_>) -> Result<Vec<Mask>, PerceptionError> {
        Ok(self.0.clone())
    }
}

/// The pixels of the left image that see object `id` (2 + k: sphere k; 1: ground) within
/// `radius` pixels of `(u, v)`.
fn pixels_of(
    pair: &segloc::perception::render::RenderedPair,
    width: usize,
    id: u16,
    (u, v): (f64, f64),
    radius: f64,
) -> Vec<(usize, usize)> {
    (0..pair.object.len())
        .map(|i| (i % width, i / width))
        .filter(|&(x, y)| {
            pair.object[y * width + x] == id && (x as f64 - u).hypot(y as f64 - v) <= radius
        })
        .collect()
}

/// An image-only segmenter's mask on a rock is kept, its mask on bare ground is rejected as
/// flat by the front end's stereo check, and without the check both become boulders.
#[test]
fn stereo_check_keeps_the_rock_and_rejects_the_ground_patch() {
    let camera = StereoCamera::ipex();
    let mut scene = SyntheticScene::default();
    let rock = scene.resting_sphere(4.0, -0.5, 0.12);
    scene.spheres.push(rock);
    let pair = render_stereo(&scene, &camera);
    let (u, v) = camera.project(&rock.center).unwrap();
    let on_rock = Mask::from_pixels(&pixels_of(&pair, camera.width, 2, (u, v), 60.0), 0.9);
    // a patch of the ground as wide as the rock, at the same range, a metre to the right
    let ground = scene.resting_sphere(4.0, 0.5, 0.12).center;
    let (gu, gv) = camera.project(&ground).unwrap();
    let r_px = 0.12 * camera.fx / 4.0;
    let on_ground = Mask::from_pixels(
        &pixels_of(&pair, camera.width, 1, (gu, gv + r_px), r_px),
        0.9,
    );
    let masks = vec![on_rock.unwrap(), on_ground.unwrap()];
    let run = |config: FrontEndConfig| {
        let mut fe = FrontEnd::new(config, Box::new(FixedMasks(masks.clone()))).unwrap();
        fe.process(&pair.left, &pair.right).unwrap().verdicts
    };
    let checked = run(FrontEndConfig::default());
    assert!(checked[0].is_ok(), "the rock: {:?}", checked[0]);
    assert_eq!(checked[1], Err(Rejection::Flat), "the ground patch");
    let mut config = FrontEndConfig::default();
    config.relief.enabled = false;
    let unchecked = run(config);
    assert!(unchecked.iter().all(|v| v.is_ok()), "{unchecked:?}");
}

/// A two-frame `.lac` of a rendered scene, played back by `segloc detect --lac`, gives
/// detections in the world frame that `segloc map build` accepts; a truncated copy exits 2.
#[test]
fn lac_playback_writes_detections_that_map_build_reads() {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use segloc::perception::lac::{ImageKind, LacFrame, LacWriter};

    let camera = StereoCamera::ipex();
    let mut scene = SyntheticScene::default();
    let s = scene.resting_sphere(4.0, 0.3, 0.25);
    scene.spheres.push(s);
    let pair = render_stereo(&scene, &camera);
    let mut writer = LacWriter::new(toml::Table::new(), toml::Table::new());
    for (k, frame) in [100u64, 120].into_iter().enumerate() {
        writer.add_frame(LacFrame {
            frame,
            time_s: Some(frame as f64 * 0.05),
            pose: Some(Isometry3::from_parts(
                Translation3::new(k as f64, 2.0, 0.5),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
            )),
            imu: None,
        });
        writer.add_image("FrontLeft", ImageKind::Grayscale, frame, pair.left.clone());
        writer.add_image(
            "FrontRight",
            ImageKind::Grayscale,
            frame,
            pair.right.clone(),
        );
    }
    let tmp = tempfile::tempdir().unwrap();
    let lac = tmp.path().join("rendered.lac");
    writer.write(&lac).unwrap();
    let detections = tmp.path().join("det.csv");
    let out = segloc()
        .args(["detect", "--lac"])
        .arg(&lac)
        .arg("-o")
        .arg(&detections)
        .output()
        .unwrap();
    assert_success(&out);
    let set = segloc::maps::read_detections(&detections).unwrap();
    assert_eq!(set.frame, "world");
    assert_eq!(set.len(), 2, "{set:?}");
    // the sphere's visible surface: rover frame ~ (0.28 + 3.8, 0.081 - 0.3, ...) rotated by yaw 0.5
    let d = &set.detections[0];
    let rover = d.rover_position.unwrap();
    assert!((rover - nalgebra::Point3::new(0.0, 2.0, 0.5)).norm() < 1e-9);
    let range = (d.p_world - rover).norm();
    assert!((range - 4.05).abs() < 0.3, "range {range}");
    let map = tmp.path().join("map.json");
    let out = segloc()
        .args(["map", "build"])
        .arg(&detections)
        .arg("-o")
        .arg(&map)
        .output()
        .unwrap();
    assert_success(&out);

    // truncated archive: exit code 2 and the file named
    let bytes = std::fs::read(&lac).unwrap();
    let cut = tmp.path().join("cut.lac");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = segloc()
        .args(["detect", "--lac"])
        .arg(&cut)
        .arg("-o")
        .arg(tmp.path().join("x.csv"))
        .output()
        .unwrap();
    assert_refused(&out, "cut.lac");
}
