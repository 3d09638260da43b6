//! Every reader of segloc-maps under mutation (issue 25 §3): map JSON, detections CSV,
//! LunarLoc traverse CSV, LAC grid CSV, frames JSON Lines, TUM trajectories, point lists.
//! Mutations of small valid files and random bytes, fixed seed, 2,000 cases per reader
//! (`SEGLOC_FUZZ_CASES` for more; `scripts/fuzz.sh`). The property (no panic, no hang, no
//! allocation beyond what the input justifies) is in `fuzz_support`.

mod fuzz_support;

use fuzz_support::{fuzz, text, text_bound, Tracking};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use segloc_maps::*;
use std::path::Path;

#[global_allocator]
static ALLOC: Tracking = Tracking;

fn map_seed() -> ObjectMap {
    let mut m = ObjectMap::new("world", "traverse_3", true);
    for (k, p) in [(1.0, -2.5, 0.25), (3.0, 4.0, -0.5), (-7.5, 0.125, 1.0)]
        .into_iter()
        .enumerate()
    {
        let mut l = Landmark::new(
            k as u32 + 1,
            Point3::new(p.0, p.1, p.2),
            Matrix3::from_diagonal(&Vector3::new(0.01, 0.02, 0.03)),
        );
        l.size_m = (k != 1).then_some(0.4 + k as f64);
        l.observations = 3 + k as u32;
        l.sessions = vec!["traverse_3".into()];
        m.landmarks.push(l);
    }
    m.notes.insert("source".into(), "fuzz seed".into());
    m
}

#[test]
fn fuzz_map_json() {
    let seeds = vec![
        map_to_string(&map_seed()).into_bytes(),
        map_to_string(&ObjectMap::new("world", "s", false)).into_bytes(),
    ];
    fuzz("map json", seeds, text_bound, |b| {
        map_from_str(&text(b), Path::new("fuzz.json"))
            .map(drop)
            .map_err(|e| e.to_string())
    });
}

#[test]
fn fuzz_detections_csv() {
    let mut set = DetectionSet::new("traverse_5", "odom", true);
    for k in 0..4u64 {
        set.detections.push(Detection {
            frame: 10 * k,
            p_world: Point3::new(k as f64 * 1.5, -2.0, 0.3),
            rover_position: (k % 2 == 0).then(|| Point3::new(0.5, k as f64, 0.0)),
            size_m: (k != 2).then_some(0.3),
            score: (k != 3).then_some(0.9),
        });
    }
    let seeds = vec![
        detections_to_string(&set).into_bytes(),
        detections_to_string(&DetectionSet::new("s", "world", false)).into_bytes(),
    ];
    fuzz("detections csv", seeds, text_bound, |b| {
        parse_detections(&text(b), Path::new("fuzz.csv"))
            .map(drop)
            .map_err(|e| e.to_string())
    });
}

#[test]
fn fuzz_lunarloc_traverse_csv() {
    let seeds = vec![format!(
        "{TRAVERSE_HEADER}\n\
         1,-3.5,-6.9,1.48,0,[]\n\
         120,-3.5185,-6.8368,1.5035,2,\"[(-3.0341, -4.9741, 1.3523), (-3.5111, -4.1534, 1.3662)]\"\n\
         121,-3.52,-6.83,1.50,1,\"[(-3.0, -4.9, 1.35)]\"\n"
    )
    .into_bytes()];
    fuzz("traverse csv", seeds, text_bound, |b| {
        parse_lunarloc_traverse(&text(b), Path::new("traverse_1.csv"))
            .map(drop)
            .map_err(|e| e.to_string())
    });
}

#[test]
fn fuzz_grid_csv() {
    let mut grid = LacGrid::new(4, 0.15);
    for (k, h) in grid.height.iter_mut().enumerate() {
        *h = if k % 5 == 3 {
            f64::NAN
        } else {
            0.01 * k as f64
        };
    }
    grid.rock[6] = true;
    let seeds = vec![grid_to_string(&grid).into_bytes()];
    fuzz("grid csv", seeds, text_bound, |b| {
        parse_grid_csv(&text(b), Path::new("grid.csv"))
            .map(drop)
            .map_err(|e| e.to_string())
    });
}

#[test]
fn fuzz_frames_jsonl() {
    let mut text_file =
        format!("{{\"format\": \"{FRAMES_FORMAT_NAME}\", \"version\": {FRAMES_FORMAT_VERSION}}}\n");
    for k in 0..3 {
        let mut f = StreamFrame::new(
            0.5 * k as f64,
            Isometry3::new(
                Vector3::new(k as f64, 0.5, 0.0),
                Vector3::new(0.0, 0.0, 0.1),
            ),
        );
        f.gravity_rover = (k != 1).then(|| Vector3::new(0.0, 0.0, -1.62));
        f.detections.push(FrameDetection {
            p_rover: Point3::new(2.0, -0.5, 0.1),
            size_m: Some(0.3),
            cov_rover: (k == 2).then(|| Matrix3::from_diagonal_element(0.01)),
        });
        if k == 1 {
            f.lander_points_rover.push(Point3::new(3.0, 0.0, 0.5));
            f.path = Some(FramePath {
                distance_m: 0.5,
                turned_rad: 0.1,
                turned_abs_rad: 0.1,
            });
        }
        text_file.push_str(&frame_to_json_line(&f));
        text_file.push('\n');
    }
    let seeds = vec![text_file.into_bytes()];
    fuzz("frames jsonl", seeds, text_bound, |b| {
        parse_frames(&text(b), "frames.jsonl")
            .map(drop)
            .map_err(|e| e.to_string())
    });
}

#[test]
fn fuzz_tum() {
    let poses = vec![
        (0.0, Isometry3::identity()),
        (
            0.1,
            Isometry3::new(Vector3::new(1.0, -2.5, 1e-3), Vector3::new(0.1, 0.2, -0.3)),
        ),
        (
            1_700_000_000.25,
            Isometry3::new(Vector3::new(-3.0, 4.9, 0.3), Vector3::new(0.0, 0.0, 3.0)),
        ),
    ];
    let seeds = vec![tum_to_string(&poses).into_bytes()];
    fuzz("tum", seeds, text_bound, |b| {
        parse_tum(&text(b), "traj.tum")
            .map(drop)
            .map_err(|e| e.to_string())
    });
}

#[test]
fn fuzz_point_list() {
    let seeds = vec![b"[(-3.0341, -4.9741, 1.3523), (-3.5111, -4.1534, 1.3662)]".to_vec()];
    fuzz("point list", seeds, text_bound, |b| {
        let mut out = Vec::new();
        parse_point_list(&text(b), &mut out).map_err(String::from)
    });
}

/// The path readers refuse bytes that are not UTF-8 with a typed error naming the file.
#[test]
fn non_utf8_files_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.txt");
    std::fs::write(&p, b"frame,x\n\xff\xfe1,2\n").unwrap();
    let errors = [
        read_map(&p).map(drop).unwrap_err(),
        read_detections(&p).map(drop).unwrap_err(),
        read_any_detections(&p).map(drop).unwrap_err(),
        read_lunarloc_traverse(&p).map(drop).unwrap_err(),
        read_grid_csv(&p).map(drop).unwrap_err(),
        read_frames(&p).map(drop).unwrap_err(),
        read_tum(&p).map(drop).unwrap_err(),
    ];
    for e in errors {
        assert!(e.to_string().contains("bad.txt"), "{e}");
    }
}
