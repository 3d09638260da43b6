//! The detection frames of a LunarLoc traverse: where the rover stood, which way its
//! camera looked, and what it detected.
//!
//! The LunarLoc traverses give rover positions but no orientation: the heading of a frame
//! is the direction of travel over ± `heading_window_frames`, replaced by the circular
//! mean bearing of the frame's detections when the rover barely moved or a detection lies
//! outside the field of view around it (turning on the spot, reversing). Detection frames
//! come at a fixed cadence per traverse (every 4, 6 or 20 simulator frames); the cadence
//! is the median gap between frames with detections, and frames at that cadence without
//! detections count as views too.

use super::rock_evidence::RockEvidenceConfig;
use nalgebra::{Point2, Point3};
use segloc_maps::Traverse;

/// The detection frames of a traverse as (rover position, heading, detections).
pub fn traverse_views(
    traverse: &Traverse,
    config: &RockEvidenceConfig,
) -> Vec<(Point3<f64>, f64, Vec<Point3<f64>>)> {
    let frames = &traverse.frames;
    let with: Vec<u64> = frames
        .iter()
        .filter(|f| !f.boulders.is_empty())
        .map(|f| f.frame)
        .collect();
    let Some(&first) = with.first() else {
        return Vec::new();
    };
    let mut gaps: Vec<u64> = with.windows(2).map(|w| w[1].saturating_sub(w[0])).collect();
    gaps.retain(|&g| g > 0);
    gaps.sort_unstable();
    let cadence = gaps.get(gaps.len() / 2).copied().unwrap_or(1).max(1);
    let phase = first % cadence;
    let half_fov = config.half_fov_deg.to_radians();
    let w = config.heading_window_frames;
    let mut views = Vec::new();
    let mut last_heading: Option<f64> = None;
    for (n, f) in frames.iter().enumerate() {
        if f.frame % cadence != phase {
            continue;
        }
        let a = &frames[n.saturating_sub(w)].rover_position;
        let b = &frames[(n + w).min(frames.len() - 1)].rover_position;
        let motion = Point2::new(b.x - a.x, b.y - a.y);
        let mut heading =
            (motion.coords.norm() >= config.min_heading_motion_m).then(|| motion.y.atan2(motion.x));
        let bearings: Vec<f64> = f
            .boulders
            .iter()
            .map(|d| (d.y - f.rover_position.y).atan2(d.x - f.rover_position.x))
            .collect();
        if !bearings.is_empty() {
            let outside = |h: f64| {
                bearings
                    .iter()
                    .any(|&be| wrap(be - h).abs() > half_fov + 5f64.to_radians())
            };
            if heading.is_none_or(outside) {
                let (s, c) = bearings
                    .iter()
                    .fold((0.0, 0.0), |(s, c), b| (s + b.sin(), c + b.cos()));
                heading = Some(f64::atan2(s, c));
            }
        }
        let Some(h) = heading.or(last_heading) else {
            continue;
        };
        last_heading = Some(h);
        views.push((f.rover_position, h, f.boulders.clone()));
    }
    views
}

/// An angle wrapped to (-π, π].
fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    let r = a.rem_euclid(t);
    if r > std::f64::consts::PI {
        r - t
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use segloc_maps::TraverseFrame;

    #[test]
    fn traverse_views_follow_the_cadence_and_the_motion() {
        // driving along +x at 0.2 m/s (20 Hz), detections every 20 frames
        let frames: Vec<TraverseFrame> = (0..200u64)
            .map(|f| TraverseFrame {
                frame: f,
                rover_position: Point3::new(0.01 * f as f64, 0.0, 0.0),
                boulders: if f % 20 == 0 && f < 100 {
                    vec![Point3::new(0.01 * f as f64 + 3.0, 0.5, 0.0)]
                } else {
                    vec![]
                },
            })
            .collect();
        let t = Traverse {
            name: "t".into(),
            frames,
        };
        let views = traverse_views(&t, &RockEvidenceConfig::default());
        assert_eq!(views.len(), 10); // frames 0, 20, ..., 180
        for (_, h, _) in &views {
            assert!(h.abs() < 1e-9);
        }
        assert_eq!(views[0].2.len(), 1);
        assert!(views[9].2.is_empty());
        let empty = Traverse {
            name: "e".into(),
            frames: vec![],
        };
        assert!(traverse_views(&empty, &RockEvidenceConfig::default()).is_empty());
    }

    #[test]
    fn wrap_angles() {
        assert!((wrap(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap(-0.5) + 0.5).abs() < 1e-12);
    }
}
