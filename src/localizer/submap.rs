//! The frame a fix on a submap is anchored at: a frame that saw the landmarks a
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
    let Some(centroid) = centroid(points) else {
        return start;
    };
    frames
        .filter(|&k| k < poses.len())
        .min_by(|&a, &b| {
            let da = (poses[a].translation.vector - centroid).xy().norm();
            let db = (poses[b].translation.vector - centroid).xy().norm();
            da.total_cmp(&db)
        })
        .unwrap_or(start)
}

/// How much farther from the matched landmarks than the nearest frame that saw them a
/// frame may be and still anchor a measurement on them (m): [`frame_observing`]'s
/// `near_slack_m` in [`anchor_frame`].
pub const ANCHOR_SLACK_M: f64 = 0.1;

/// The frame of `frames` a fix or loop closure on the matched landmarks `points` is
/// anchored at: [`frame_observing`] among `detections` (the submap's or map's, placed with
/// `poses`) within [`ANCHOR_SLACK_M`], else, when no detection lies within `radius_m` of a
/// matched landmark, [`frame_nearest`].
pub fn anchor_frame(
    poses: &[Isometry3<f64>],
    detections: &segloc_maps::DetectionSet,
    frames: std::ops::Range<usize>,
    points: &[Point3<f64>],
    radius_m: f64,
) -> usize {
    frame_observing(poses, detections, points, radius_m, ANCHOR_SLACK_M)
        .unwrap_or_else(|| frame_nearest(poses, frames, points))
}

/// The frame a measurement on matched landmarks (`points`) is anchored at: of the frames
/// whose detections in `detections` lie within `radius_m` of a matched landmark (the frames
/// whose poses the landmarks' fused positions carry), those horizontally nearest the
/// landmarks' centroid (within `near_slack_m` of the nearest, so the measurement's yaw
/// error has the shortest lever arm), and of those the middle one in time (a rover turning
/// on the spot sees the landmarks from one place with a drifting yaw). `None` when no
/// detection is that near a landmark.
pub fn frame_observing(
    poses: &[Isometry3<f64>],
    detections: &segloc_maps::DetectionSet,
    points: &[Point3<f64>],
    radius_m: f64,
    near_slack_m: f64,
) -> Option<usize> {
    let radius_sq = radius_m * radius_m;
    let centroid = centroid(points)?;
    let distance = |k: usize| {
        poses
            .get(k)
            .map(|p| (p.translation.vector - centroid).xy().norm())
    };
    let mut frames: Vec<(usize, f64)> = detections
        .detections
        .iter()
        .filter(|d| {
            points
                .iter()
                .any(|p| (d.p_world - p).norm_squared() <= radius_sq)
        })
        .filter_map(|d| usize::try_from(d.frame).ok())
        .filter_map(|k| distance(k).map(|r| (k, r)))
        .collect();
    let nearest = frames.iter().map(|f| f.1).min_by(f64::total_cmp)?;
    frames.retain(|f| f.1 <= nearest + near_slack_m);
    frames.sort_unstable_by_key(|f| f.0);
    frames.dedup_by_key(|f| f.0);
    frames.get(frames.len() / 2).map(|f| f.0)
}

fn centroid(points: &[Point3<f64>]) -> Option<nalgebra::Vector3<f64>> {
    if points.is_empty() {
        return None;
    }
    Some(
        points
            .iter()
            .map(|p| p.coords)
            .sum::<nalgebra::Vector3<f64>>()
            / points.len() as f64,
    )
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

    fn detection(frame: u64, x: f64, y: f64) -> segloc_maps::Detection {
        segloc_maps::Detection {
            frame,
            p_world: Point3::new(x, y, 0.0),
            rover_position: None,
            size_m: None,
            score: None,
        }
    }

    #[test]
    fn the_anchor_saw_the_landmarks_from_nearby_and_is_the_middle_one_in_time() {
        // frames 0-5 turn on the spot at the origin, frames 6-9 drive away along x
        let poses: Vec<_> = (0..10)
            .map(|k| Isometry3::translation((k as f64 - 5.0).max(0.0), 0.0, 0.0))
            .collect();
        let landmarks = [Point3::new(0.0, 2.0, 0.0), Point3::new(0.5, 2.5, 0.0)];
        let mut set = segloc_maps::DetectionSet::new("s", "odom", true);
        // frames 1 and 2 saw the first landmark, frame 3 the second, frame 8 the first from
        // afar; frame 0 saw only another boulder
        for (frame, x, y) in [(1, 0.02, 2.0), (2, 0.0, 1.98), (3, 0.5, 2.52)] {
            set.detections.push(detection(frame, x, y));
        }
        set.detections.push(detection(8, 0.01, 2.0));
        set.detections.push(detection(0, 3.0, -1.0));
        assert_eq!(frame_observing(&poses, &set, &landmarks, 0.1, 0.1), Some(2));
        // frame 8 is 1.3 m farther from the landmarks: within a 4 m slack it counts too
        assert_eq!(frame_observing(&poses, &set, &landmarks, 0.1, 4.0), Some(3));
        // nearest of all, without the frames that saw them, is frame 0 (the first)
        assert_eq!(frame_nearest(&poses, 0..10, &landmarks), 0);
        // no detection near a landmark, or no landmark
        assert_eq!(
            frame_observing(&poses, &set, &[Point3::new(9.0, 9.0, 0.0)], 0.1, 0.1),
            None
        );
        assert_eq!(frame_observing(&poses, &set, &[], 0.1, 0.1), None);
    }
}
