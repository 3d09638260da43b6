//! Clustering detections of the same boulder.
//!
//! Two passes over the detections in time order. The first grows clusters greedily: a
//! detection joins the nearest cluster whose running centroid is within the radius, or
//! starts a new one. The first pass depends on the order of arrival (an early stray
//! detection can seed a cluster between two boulders), so a second pass re-assigns every
//! detection to the nearest final centroid and drops the centroids that win no detection
//! — one step of k-means with the number of clusters found by the first pass.

use crate::spatial::GridIndex;
use nalgebra::{Point3, Vector3};

/// Group `points` into clusters of radius `radius_m`; returns the member indices of each
/// cluster (clusters in order of first detection, members in input order).
pub fn cluster_points(points: &[Point3<f64>], radius_m: f64) -> Vec<Vec<u32>> {
    let mut sums: Vec<Vector3<f64>> = Vec::new();
    let mut counts: Vec<u32> = Vec::new();
    let mut centroids: Vec<Point3<f64>> = Vec::new();
    let mut index = GridIndex::new(radius_m);
    for p in points {
        match index.nearest(&centroids, p, radius_m) {
            Some((c, _)) => {
                let c = c as usize;
                sums[c] += p.coords;
                counts[c] += 1;
                let moved = Point3::from(sums[c] / counts[c] as f64);
                index.relocate(c as u32, &centroids[c], &moved);
                centroids[c] = moved;
            }
            None => {
                index.insert(centroids.len() as u32, p);
                centroids.push(*p);
                sums.push(p.coords);
                counts.push(1);
            }
        }
    }
    // Second pass: nearest final centroid.
    let final_index = GridIndex::from_points(&centroids, radius_m);
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); centroids.len()];
    for (k, p) in points.iter().enumerate() {
        if let Some((c, _)) = final_index.nearest(&centroids, p, radius_m) {
            members[c as usize].push(k as u32);
        }
    }
    members.retain(|m| !m.is_empty());
    members
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separates_nearby_boulders_and_keeps_order_independence() {
        let mut points = Vec::new();
        for k in 0..10 {
            let e = 0.004 * (k as f64 - 4.5);
            points.push(Point3::new(0.0 + e, 0.0, 0.0));
            points.push(Point3::new(0.5 - e, 0.1, 0.0));
        }
        // A stray detection between the two arriving first.
        points.insert(0, Point3::new(0.25, 0.05, 0.0));
        let clusters = cluster_points(&points, 0.2);
        let mut sizes: Vec<_> = clusters.iter().map(|c| c.len()).collect();
        sizes.sort();
        assert_eq!(sizes.iter().sum::<usize>(), 21);
        assert!(sizes.iter().filter(|&&s| s >= 10).count() == 2, "{sizes:?}");
    }

    #[test]
    fn empty_input_gives_no_clusters() {
        assert!(cluster_points(&[], 0.2).is_empty());
    }
}
