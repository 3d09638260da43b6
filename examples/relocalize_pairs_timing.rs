//! The paper pairs relocalized through the library, timed: the Rust side of the Python
//! bindings' overhead figure (`python/examples/relocalize_pairs.py` makes the same calls;
//! `scripts/bench_python.sh` runs both).
//!
//! Each pair's query traverse is fused as `segloc map build` does, moved by one fixed
//! rigid transform (yaw from the 3-4-5 triangle, exact in binary), and relocalized against
//! the prior traverse `repeat` times after two warm-up calls; one JSON line per pair with
//! the median wall time of `Relocalizer::relocalize`.
//!
//! ```sh
//! cargo run --release --example relocalize_pairs_timing -- [REPEAT]
//! ```
#![warn(clippy::too_many_lines)]

use nalgebra::Matrix4;
use segloc::eval::lunarloc::PAPER_PAIRS;
use segloc::eval::traverse_path;
use segloc::landmarks::{fuse_detections, FusionConfig};
use segloc::relocalize::{RelocalizeConfig, Relocalizer};
use segloc_maps::{isometry_from_matrix, read_lunarloc_traverse, ObjectMap};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `query_from_world` of every trial: the same matrix as the Python example's.
#[rustfmt::skip]
const QUERY_FROM_WORLD: [f64; 16] = [
    0.6, -0.8, 0.0, 3.0,
    0.8, 0.6, 0.0, -2.0,
    0.0, 0.0, 1.0, 0.5,
    0.0, 0.0, 0.0, 1.0,
];

fn fused(data: &Path, n: usize) -> Result<ObjectMap, Box<dyn std::error::Error>> {
    let traverse = read_lunarloc_traverse(&traverse_path(data, n))?;
    Ok(fuse_detections(
        &traverse.detections(),
        &FusionConfig::default(),
    ))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let repeat: usize = std::env::args().nth(1).map_or(Ok(20), |s| s.parse())?;
    let data = std::env::var_os("SEGLOC_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    let query_from_world = isometry_from_matrix(&Matrix4::from_row_slice(&QUERY_FROM_WORLD))?;
    for (a, b) in PAPER_PAIRS {
        let relocalizer = Relocalizer::new(fused(&data, a)?, RelocalizeConfig::default())?;
        let query = fused(&data, b)?.transformed(&query_from_world, "query");
        let mut times_ms = Vec::with_capacity(repeat);
        let mut inliers = 0;
        for k in 0..repeat + 2 {
            let t = Instant::now();
            let answer = relocalizer.relocalize(&query)?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            inliers = answer.accepted().map_or(0, |a| a.inliers.len());
            if k >= 2 {
                times_ms.push(ms);
            }
        }
        times_ms.sort_by(f64::total_cmp);
        println!(
            "{{\"pair\": [{a}, {b}], \"inliers\": {inliers}, \"median_ms\": {}}}",
            times_ms[times_ms.len() / 2]
        );
    }
    Ok(())
}
