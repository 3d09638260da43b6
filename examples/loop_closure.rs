//! A SLAM loop closure calling segloc: one `Relocalizer` per prior map, many queries.
//!
//! The prior session's map is prepared once; every few seconds the running session's
//! recent detections are fused into a submap and relocalized against it. Accepted answers
//! come with a 6 × 6 information matrix, ready to become a factor in the pose graph.
//!
//! Run with `cargo run --release --example loop_closure`.
#![warn(clippy::too_many_lines)]

use segloc::eval::transform_error;
use segloc::landmarks::{fuse_detections, FusionConfig};
use segloc::relocalize::{RelocalizeConfig, Relocalizer};
use segloc::sim::boulder_field::{two_session_detections, FieldConfig};
use segloc_maps::DetectionSet;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (prior_detections, query_detections, truth) =
        two_session_detections(&FieldConfig::default(), 11);
    let prior_map = fuse_detections(&prior_detections, &FusionConfig::default());
    let relocalizer = Relocalizer::new(prior_map, RelocalizeConfig::default())?;

    // The query session arrives frame by frame; relocalize on a sliding window of frames.
    let last_frame = query_detections
        .detections
        .iter()
        .map(|d| d.frame)
        .max()
        .unwrap_or(0);
    let window = 40;
    for end in (window..=last_frame).step_by(20) {
        let mut submap_detections = DetectionSet::new("query", "query", true);
        submap_detections.detections = query_detections
            .detections
            .iter()
            .filter(|d| d.frame + window > end && d.frame <= end)
            .cloned()
            .collect();
        let submap = fuse_detections(&submap_detections, &FusionConfig::default());
        // a submap too small to fix a transform comes back refused (`too_few_landmarks`)
        let answer = relocalizer.relocalize(&submap)?;
        match &answer.outcome {
            Ok(accepted) => {
                let (t, r) = transform_error(&accepted.prior_from_query, &truth);
                println!(
                    "frames ..{end}: {} landmarks -> accepted, {} inliers, error {:.2} cm / {:.3}°, information trace {:.3e}",
                    submap.len(),
                    accepted.inliers.len(),
                    t * 100.0,
                    r,
                    accepted.information.trace()
                );
            }
            Err(refusal) => println!(
                "frames ..{end}: {} landmarks -> refused ({}): {refusal}",
                submap.len(),
                refusal.code()
            ),
        }
    }
    Ok(())
}
