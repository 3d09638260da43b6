//! The LAC maps of the mission: ground points of both sessions re-projected with the
//! optimised poses into the height map, the boulder detections of both sessions into the
//! rock map ([`rock_grid_from_detections`]: centroids moved from the visible face to the
//! boulder's centre, fused, footprints painted), both scored against the moon's ground
//! truth.

use super::MissionConfig;
use crate::mapping::rock_footprint::rock_grid_from_detections;
use crate::mapping::{score, HeightMapBuilder, LacScore, ScoreError};
use crate::sim::session::SessionLog;
use nalgebra::Isometry3;
use segloc_maps::{DetectionSet, LacGrid};

use super::stream::detections_with_poses;

/// The mission's map and its score.
pub struct MissionMaps {
    /// Heights and rock flags.
    pub grid: LacGrid,
    /// The LAC score.
    pub score: LacScore,
    /// Boulders in the fused world map.
    pub landmarks: usize,
}

/// Build and score the maps of `sessions` (each with its optimised world poses, one per
/// frame) against `truth`.
pub fn build_maps(
    sessions: &[(&SessionLog, &[Isometry3<f64>])],
    truth: &LacGrid,
    mission_seconds: f64,
    config: &MissionConfig,
) -> Result<MissionMaps, ScoreError> {
    let mut heights = HeightMapBuilder::new(truth.clone());
    let mut all = DetectionSet::new("mission", "world", true);
    for (log, poses) in sessions {
        for (f, pose) in log.frames.iter().zip(poses.iter()) {
            for g in &f.ground {
                heights.add_point(&(pose * g.p_rover));
            }
        }
        let set = detections_with_poses(log, poses, 0..log.frames.len(), "mission", "world");
        all.detections.extend(set.detections);
    }
    let height_grid = heights.build();
    let (grid, landmarks) = rock_grid_from_detections(
        &all,
        &height_grid,
        &config.localizer.fusion,
        &config.rock_grid,
    );
    let score = score(&grid, truth, Some(mission_seconds))?;
    Ok(MissionMaps {
        grid,
        score,
        landmarks,
    })
}
