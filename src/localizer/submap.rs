//! The frame a fix on a submap is anchored at: the frame nearest the landmarks a
//! relocalization matched (where the odometry has drifted least relative to them).

use nalgebra::{Isometry3, Point3};

/// The frame in `frames` whose pose (`poses`, one per frame) lies horizontally nearest the
/// centroid of `points` (the first of `frames` when there are no points).
pub fn frame_nearest(
    poses: &[Isometry3<f64>],
    frames: std::ops::Range<usize>,
    points: &[Point3<f64>],
) -> usize {
    let start = frames.start;
    if points.is_empty() {
        return start;
    }
    let centroid = points
        .iter()
        .map(|p| p.coords)
        .sum::<nalgebra::Vector3<f64>>()
        / points.len() as f64;
    frames
        .filter(|&k| k < poses.len())
        .min_by(|&a, &b| {
            let da = (poses[a].translation.vector - centroid).xy().norm();
            let db = (poses[b].translation.vector - centroid).xy().norm();
            da.total_cmp(&db)
        })
        .unwrap_or(start)
}

/// Positions of the landmarks of `map` with these ids.
pub fn landmark_positions(
    map: &segloc_maps::ObjectMap,
    ids: impl Iterator<Item = u32>,
) -> Vec<Point3<f64>> {
    ids.filter_map(|id| map.landmarks.iter().find(|l| l.id == id))
        .map(|l| l.position)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_frame_to_the_points() {
        let poses: Vec<_> = (0..5)
            .map(|k| Isometry3::translation(k as f64, 0.0, 0.0))
            .collect();
        let points = [Point3::new(2.8, 1.0, 0.0), Point3::new(3.2, -1.0, 0.0)];
        assert_eq!(frame_nearest(&poses, 0..5, &points), 3);
        assert_eq!(frame_nearest(&poses, 0..2, &points), 1);
        assert_eq!(frame_nearest(&poses, 2..5, &[]), 2);
    }
}
