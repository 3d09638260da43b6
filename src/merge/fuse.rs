//! Fusing landmarks that are the same boulder across maps.
//!
//! Maps are taken in input order (the reference first); each map's landmarks, moved into
//! the reference frame, are matched one-to-one with the merged landmarks (mutual nearest
//! neighbours within the gate). A matched pair is fused by information weighting
//! (`Σ = (Σ₁⁻¹ + Σ₂⁻¹)⁻¹`, `p = Σ (Σ₁⁻¹ p₁ + Σ₂⁻¹ p₂)`), observation counts summed and the
//! sessions that saw it united; unmatched landmarks are added as they are.

use super::MergeConfig;
use crate::align::refine::mutual_nearest;
use crate::spatial::GridIndex;
use nalgebra::{Isometry3, Matrix3};
use segloc_maps::{Landmark, ObjectMap};

/// The merged map and how many of its landmarks were fused from several maps.
pub struct Fused {
    /// The merged map, in the reference frame.
    pub map: ObjectMap,
    /// Landmarks seen by two or more maps.
    pub fused: usize,
}

/// Fuse the placed maps (those with a frame) into the reference frame.
pub fn fuse_maps(
    maps: &[ObjectMap],
    reference_from_map: &[Option<Isometry3<f64>>],
    reference: usize,
    config: &MergeConfig,
) -> Fused {
    let base = &maps[reference];
    let mut merged = ObjectMap::new(
        base.frame.clone(),
        base.session.clone(),
        base.gravity_aligned,
    );
    merged
        .notes
        .insert("source".into(), "segloc map merge".into());
    let mut order: Vec<usize> = vec![reference];
    order.extend((0..maps.len()).filter(|&k| k != reference));
    for k in order {
        let Some(transform) = reference_from_map[k] else {
            continue;
        };
        let moved = maps[k].transformed(&transform, &merged.frame);
        let merged_points = merged.positions();
        let index = GridIndex::from_points(&merged_points, config.fuse_gate_m);
        let moved_points = moved.positions();
        let matches = mutual_nearest(
            &merged_points,
            &index,
            &moved_points,
            &Isometry3::identity(),
            config.fuse_gate_m,
        );
        let mut matched = vec![false; moved.len()];
        for (i, j) in matches {
            fuse_into(
                &mut merged.landmarks[i as usize],
                &moved.landmarks[j as usize],
                &moved.session,
            );
            matched[j as usize] = true;
        }
        for (j, landmark) in moved.landmarks.iter().enumerate() {
            if !matched[j] {
                let mut l = landmark.clone();
                l.id = merged.landmarks.len() as u32;
                if l.sessions.is_empty() {
                    l.sessions = vec![moved.session.clone()];
                }
                merged.landmarks.push(l);
            }
        }
    }
    let fused = merged
        .landmarks
        .iter()
        .filter(|l| l.sessions.len() > 1)
        .count();
    Fused { map: merged, fused }
}

fn fuse_into(target: &mut Landmark, other: &Landmark, other_session: &str) {
    let regularise = |c: &Matrix3<f64>| c + Matrix3::identity() * 1e-10;
    let (Some(info_a), Some(info_b)) = (
        regularise(&target.covariance).try_inverse(),
        regularise(&other.covariance).try_inverse(),
    ) else {
        return;
    };
    let Some(covariance) = (info_a + info_b).try_inverse() else {
        return;
    };
    target.position =
        (covariance * (info_a * target.position.coords + info_b * other.position.coords)).into();
    target.covariance = (covariance + covariance.transpose()) * 0.5;
    target.observations += other.observations;
    target.size_m = match (target.size_m, other.size_m) {
        (Some(a), Some(b)) => Some(0.5 * (a + b)),
        (a, b) => a.or(b),
    };
    let sessions: Vec<String> = if other.sessions.is_empty() {
        vec![other_session.to_string()]
    } else {
        other.sessions.clone()
    };
    for s in sessions {
        if !target.sessions.contains(&s) {
            target.sessions.push(s);
        }
    }
}
