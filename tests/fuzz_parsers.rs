//! The root crate's readers under mutation (issue 25 §3): g2o and TORO pose graphs, `.lac`
//! recordings, association problems and their ground truth, and the configuration TOMLs
//! (`RelocalizeConfig`, `LocalizerConfig`, `MissionConfig`, through `toml::from_str` and
//! `validate()`). Mutations of small valid files and random bytes, fixed seed, 2,000 cases
//! per reader (`SEGLOC_FUZZ_CASES` for more; `scripts/fuzz.sh`). The machinery and the
//! property (no panic, no hang, no allocation beyond what the input justifies) are shared
//! with `maps/tests/fuzz.rs`.

#[path = "../maps/tests/fuzz_support/mod.rs"]
mod fuzz_support;

use fuzz_support::{fuzz, text, text_bound, Tracking};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use segloc::graph::file::{BuildOptions, GraphFile};
use segloc::io::association_problem::{parse_problem, problem_to_string, read_ground_truth};
use segloc::localizer::LocalizerConfig;
use segloc::mission::MissionConfig;
use segloc::perception::lac::{ImageKind, Imu, LacFrame, LacRecording, LacWriter};
use segloc::perception::GrayImage;
use segloc::relocalize::RelocalizeConfig;
use std::io::{Read, Write};
use std::path::Path;

#[global_allocator]
static ALLOC: Tracking = Tracking;

const INFO: &str = "100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400";

fn graph(b: &[u8]) -> Result<(), String> {
    let file = GraphFile::parse(&text(b), Path::new("fuzz.g2o")).map_err(|e| e.to_string())?;
    // a file that reads must also build (initial estimates, gauge) without panicking
    file.to_pose_graph(&BuildOptions::default())
        .map(drop)
        .map_err(|e| e.to_string())
}

#[test]
fn fuzz_g2o() {
    let seeds = vec![
        format!(
            "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n\
             VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n\
             VERTEX_SE3:QUAT 2 2 0.5 0 0 0 0.0998 0.995\n\
             EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 {INFO}\n\
             EDGE_SE3:QUAT 1 2 1 0.5 0 0 0 0.0998 0.995 {INFO}\n\
             EDGE_SE3:QUAT 0 2 2 0.5 0 0 0 0.0998 0.995 {INFO}\n\
             FIX 0\n"
        )
        .into_bytes(),
        // edges only: the initial estimate is chained from odometry
        format!(
            "# no vertices\nEDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 {INFO}\n\
             EDGE_SE3:QUAT 1 2 1 0 0 0 0 0 1 {INFO}\nEDGE_SE3:QUAT 5 6 1 0 0 0 0 0 1 {INFO}\n"
        )
        .into_bytes(),
    ];
    fuzz("g2o", seeds, text_bound, graph);
}

#[test]
fn fuzz_toro() {
    let seeds = vec![format!(
        "VERTEX3 0 0 0 0 0 0 0\n\
         VERTEX3 1 1 0 0 0 0 0.1\n\
         VERTEX3 2 2 0.5 0 0.01 0 0.2\n\
         EDGE3 0 1 1 0 0 0 0 0.1 {INFO}\n\
         EDGE3 1 2 1 0.5 0 0.01 0 0.1 {INFO}\n\
         EDGE3 2 0 -2 -0.5 0 0 0 -0.2 {INFO}\n\
         UNKNOWN_TAG 1 2 3\n"
    )
    .into_bytes()];
    fuzz("toro", seeds, text_bound, graph);
}

fn lac_sample() -> Vec<u8> {
    let mut meta = toml::Table::new();
    meta.insert("description".into(), "fuzz".into());
    let mut initial = toml::Table::new();
    initial.insert("rover".into(), toml::Value::Table(toml::Table::new()));
    let mut w = LacWriter::new(meta, initial);
    for f in [10u64, 20] {
        w.add_frame(LacFrame {
            frame: f,
            time_s: Some(f as f64 * 0.05),
            pose: Some(Isometry3::from_parts(
                Translation3::new(1.0, 2.0, 0.5),
                UnitQuaternion::from_euler_angles(0.0, 0.1, 0.3),
            )),
            imu: Some(Imu {
                accel: [0.0, 0.0, 1.622],
                gyro: [0.0, 0.0, 0.1],
            }),
        });
        let img = GrayImage::new(4, 2, vec![f as u8; 8]).unwrap();
        w.add_image("FrontLeft", ImageKind::Grayscale, f, img.clone());
        w.add_image("FrontRight", ImageKind::Grayscale, f, img.clone());
        w.add_image("FrontLeft", ImageKind::Semantic, f, img);
    }
    w.to_bytes().unwrap()
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes)
        .read_to_end(&mut out)
        .unwrap();
    out
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

/// Read a recording and decode every image it lists.
fn lac(gz: &[u8]) -> Result<(), String> {
    let r = LacRecording::from_reader(gz, Path::new("fuzz.lac")).map_err(|e| e.to_string())?;
    for camera in r.cameras() {
        let frames = r.camera_frames.get(&camera).cloned().unwrap_or_default();
        for f in frames {
            for kind in [ImageKind::Grayscale, ImageKind::Semantic] {
                r.image(&camera, kind, f).map_err(|e| e.to_string())?;
            }
        }
    }
    Ok(())
}

/// The archive's compressed bytes under mutation (mostly gzip's own checks).
#[test]
fn fuzz_lac_gzip_bytes() {
    // deflate expands at most ~1032:1
    fuzz(
        "lac gzip",
        vec![lac_sample()],
        |n| (1 << 20) + 1100 * n,
        lac,
    );
}

/// The tarball inside under mutation, re-compressed, so the tar headers, TOML, CSV and PNG
/// members are reached.
#[test]
fn fuzz_lac_tarball() {
    fuzz(
        "lac tar",
        vec![gunzip(&lac_sample())],
        |n| (1 << 20) + 64 * n,
        |tar| lac(&gzip(tar)),
    );
}

#[test]
fn fuzz_association_problem() {
    let prior = [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.5),
        Point3::new(0.0, 2.0, -0.5),
    ];
    let query = [Point3::new(0.1, 0.0, 0.0), Point3::new(1.1, 0.2, 0.5)];
    let seeds = vec![
        problem_to_string(
            &prior,
            &query,
            &segloc::clipper::Invariant::Distance {
                epsilon: 0.3,
                sigma: 0.1,
            },
        )
        .into_bytes(),
        b"2 2 2 0.3 0.1 4\n0 0 0\n1 0 0\n0 0 0\n0 1 0\n0 0\n1 1\n".to_vec(),
    ];
    fuzz("association problem", seeds, text_bound, |b| {
        parse_problem(&text(b), Path::new("p.txt"))
            .map(drop)
            .map_err(|e| e.to_string())
    });
}

/// The ground-truth reader takes a path only: each case goes through a file.
#[test]
fn fuzz_association_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.gt");
    fuzz(
        "association ground truth",
        vec![b"0 3 4 17\n".to_vec()],
        text_bound,
        |b| {
            std::fs::write(&path, b).unwrap();
            read_ground_truth(&path)
                .map(drop)
                .map_err(|e| e.to_string())
        },
    );
}

#[test]
fn fuzz_relocalize_config_toml() {
    let seeds = vec![
        toml::to_string(&RelocalizeConfig::default())
            .unwrap()
            .into_bytes(),
        b"dof = \"4\"\n[clique]\n".to_vec(),
    ];
    fuzz("relocalize config", seeds, text_bound, |b| {
        toml::from_str::<RelocalizeConfig>(&text(b))
            .map(drop)
            .map_err(|e| e.to_string())
    });
}

#[test]
fn fuzz_localizer_config_toml() {
    let seeds = vec![toml::to_string(&LocalizerConfig::default())
        .unwrap()
        .into_bytes()];
    fuzz("localizer config", seeds, text_bound, |b| {
        let c: LocalizerConfig = toml::from_str(&text(b)).map_err(|e| e.to_string())?;
        c.validate().map_err(|e| e.to_string())
    });
}

#[test]
fn fuzz_mission_config_toml() {
    let seeds = vec![toml::to_string(&MissionConfig::default())
        .unwrap()
        .into_bytes()];
    fuzz("mission config", seeds, text_bound, |b| {
        MissionConfig::from_toml(&text(b))
            .map(|_| ())
            .map_err(|e| e.to_string())
    });
}
