//! Multi-agent map merging through the library: three rovers mapped overlapping parts of
//! the LAC site, each in its own frame; one call places every map in the first one's frame
//! and fuses the boulders they share.
//!
//! The agents are three real LunarLoc traverses (from `SEGLOC_DATA`, default
//! `../shared/data`), each moved by a known rigid transform so the result can be checked.
//!
//! Run with `cargo run --release --example three_agent_merge`.
#![warn(clippy::too_many_lines)]

use nalgebra::{Isometry3, Vector3};
use segloc::eval::{transform_error, traverse_path};
use segloc::landmarks::view_bias::{LUNARLOC_VIEW_BIAS_M, LUNARLOC_VIEW_BIAS_SIGMA_M};
use segloc::landmarks::{fuse_detections, FusionConfig};
use segloc::merge::{merge_maps, MergeConfig};
use segloc::relocalize::RelocalizeConfig;
use segloc_maps::read_lunarloc_traverse;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let data = std::env::var_os("SEGLOC_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    // LunarLoc detections: centroids on the boulders' visible faces; fusion moves them
    // back by the measured viewpoint bias and weighs one-sided boulders less.
    let fusion = FusionConfig {
        view_bias_m: LUNARLOC_VIEW_BIAS_M,
        view_bias_sigma_m: LUNARLOC_VIEW_BIAS_SIGMA_M,
        ..FusionConfig::default()
    };
    // Each agent's own frame: world_from_agent, unknown to the merge.
    let agents = [
        (13, Isometry3::identity()),
        (
            9,
            Isometry3::new(Vector3::new(12.0, -7.0, 0.3), Vector3::z() * 2.1),
        ),
        (
            15,
            Isometry3::new(Vector3::new(-5.0, 18.0, -0.2), Vector3::z() * -0.7),
        ),
    ];
    let mut maps = Vec::new();
    for (traverse, world_from_agent) in &agents {
        let path = traverse_path(&data, *traverse);
        let detections = read_lunarloc_traverse(&path)
            .map_err(|e| format!("{} (set SEGLOC_DATA to the data folder)", e))?
            .detections()
            .transformed(&world_from_agent.inverse(), "agent");
        let map = fuse_detections(&detections, &fusion);
        println!(
            "agent {}: traverse {traverse}, {} landmarks",
            maps.len(),
            map.len()
        );
        maps.push(map);
    }

    let report = merge_maps(
        &maps,
        0,
        &RelocalizeConfig::default(),
        &MergeConfig::default(),
    )?;
    for (placement, (_, world_from_agent)) in report.maps.iter().zip(&agents) {
        match placement.reference_from_map {
            Some(reference_from_map) => {
                let (t, r) = transform_error(&(agents[0].1 * reference_from_map), world_from_agent);
                println!(
                    "map {}: {:?}, error against the truth {:.2} cm, {:.3}°",
                    placement.index,
                    placement.status,
                    100.0 * t,
                    r
                );
            }
            None => println!("map {}: {:?}", placement.index, placement.status),
        }
    }
    println!(
        "merged map: {} landmarks ({} fused from two or more maps) in {:.0} ms",
        report.landmarks, report.fused, report.time_ms
    );
    Ok(())
}
