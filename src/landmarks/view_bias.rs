//! Viewpoint bias of boulder detections: correction and estimation from the data.
//!
//! A boulder's centroid from stereo points lies on the surface the camera sees, so it
//! sits nearer the camera than the boulder's centre. A map made from one side of a
//! boulder field is therefore shifted (and, for a short or curved traverse, turned) by
//! about that offset relative to the true boulder positions; two maps of the same boulders
//! seen from different sides disagree by about twice it.
//!
//! Model: a detection `p = c + b · u + noise`, with `c` the boulder's centre, `u` the
//! horizontal unit line of sight from the rover to the detection and `b` the bias (m,
//! negative: toward the camera). [`corrected`] removes a known bias. [`estimate_view_bias`]
//! estimates it from detection sets that share a frame (for example the LunarLoc
//! traverses, all in the world frame): the detections of every boulder seen by two or more
//! sets are clustered together and `b` and the centres are solved by alternating least
//! squares — only boulders seen from several directions separate `b` from `c`.

use super::{cluster::cluster_points, FusionConfig};

/// The viewpoint bias (m) of the LunarLoc boulder detections, estimated with
/// [`estimate_view_bias`] from the 17 traverses (all in the world frame): the median over
/// the 150 boulders seen from diverse directions is 0.8 cm (pooled over detections 1.4 cm:
/// the boulders seen most often, the large ones, lie farther behind their faces).
pub const LUNARLOC_VIEW_BIAS_M: f64 = 0.008;

/// The spread (m) of that bias from boulder to boulder ([`ViewBias::sigma_m`]).
pub const LUNARLOC_VIEW_BIAS_SIGMA_M: f64 = 0.01;
use nalgebra::Vector3;
use segloc_maps::{Detection, DetectionSet};

/// `detection` pushed `bias_m` away from its rover along the horizontal line of sight (a
/// detection without a rover position, or right under it, is returned unchanged).
pub fn corrected(detection: &Detection, bias_m: f64) -> Detection {
    let mut out = detection.clone();
    if let Some(u) = line_of_sight(detection) {
        out.p_world += u * bias_m;
    }
    out
}

fn line_of_sight(detection: &Detection) -> Option<Vector3<f64>> {
    let rover = detection.rover_position?;
    let d = (detection.p_world - rover).xy();
    let n = d.norm();
    (n > 1e-6).then(|| Vector3::new(d.x / n, d.y / n, 0.0))
}

/// The mean horizontal line of sight of `detections` (those with rover positions): a
/// vector of length 1 when all look the same way, near 0 when they surround the boulder;
/// `None` when none has a rover position.
pub fn mean_line_of_sight(detections: &[&Detection]) -> Option<Vector3<f64>> {
    let rays: Vec<Vector3<f64>> = detections.iter().filter_map(|d| line_of_sight(d)).collect();
    (!rays.is_empty()).then(|| rays.iter().sum::<Vector3<f64>>() / rays.len() as f64)
}

/// The estimated viewpoint bias.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ViewBias {
    /// How far (m) the detections lie from the boulder centres toward the camera, the
    /// median over boulders: the value for [`FusionConfig::view_bias_m`] (every landmark
    /// counts once in an alignment, whatever its number of detections).
    pub bias_m: f64,
    /// The same, pooled over detections (boulders seen more often weigh more; larger
    /// boulders are seen more often and lie farther behind their visible faces).
    pub pooled_bias_m: f64,
    /// Robust spread (m) of the per-boulder bias (1.4826 × MAD): the value for
    /// [`FusionConfig::view_bias_sigma_m`].
    pub sigma_m: f64,
    /// Boulders seen by two or more sets from directions diverse enough to fit a bias of
    /// their own (mean line of sight shorter than 0.8).
    pub boulders: usize,
    /// Detections of boulders seen by two or more sets.
    pub detections: usize,
}

/// Estimate the viewpoint bias from `sets` that share one frame, with the range gates and
/// cluster radius of `config`; `None` when no boulder is seen by two sets.
pub fn estimate_view_bias(sets: &[DetectionSet], config: &FusionConfig) -> Option<ViewBias> {
    let mut points = Vec::new();
    let mut rays = Vec::new();
    let mut owner = Vec::new();
    for (k, set) in sets.iter().enumerate() {
        for d in &set.detections {
            let (Some(rover), Some(u)) = (d.rover_position, line_of_sight(d)) else {
                continue;
            };
            let range = (d.p_world - rover).xy().norm();
            if range < config.min_range_m || range > config.max_range_m {
                continue;
            }
            points.push(d.p_world);
            rays.push(u);
            owner.push(k);
        }
    }
    let clusters: Vec<Vec<u32>> = cluster_points(&points, config.cluster_radius_m)
        .into_iter()
        .filter(|members| {
            let first = owner[members[0] as usize];
            members.iter().any(|&i| owner[i as usize] != first)
        })
        .collect();
    let detections: usize = clusters.iter().map(Vec::len).sum();
    if detections == 0 {
        return None;
    }
    let mut bias = 0.0;
    for _ in 0..50 {
        let mut along = 0.0;
        for members in &clusters {
            let centre: Vector3<f64> = members
                .iter()
                .map(|&i| points[i as usize].coords - rays[i as usize] * bias)
                .sum::<Vector3<f64>>()
                / members.len() as f64;
            along += members
                .iter()
                .map(|&i| (points[i as usize].coords - centre).dot(&rays[i as usize]))
                .sum::<f64>();
        }
        let next = along / detections as f64;
        let done = (next - bias).abs() < 1e-7;
        bias = next;
        if done {
            break;
        }
    }
    // Per boulder: least squares for (centre x, centre y, bias) in the plane.
    let mut per_boulder: Vec<f64> = clusters
        .iter()
        .filter_map(|members| {
            let rays: Vec<Vector3<f64>> = members.iter().map(|&i| rays[i as usize]).collect();
            let mean = rays.iter().sum::<Vector3<f64>>() / rays.len() as f64;
            if mean.norm() > 0.8 {
                return None;
            }
            let mut normal = nalgebra::Matrix3::<f64>::zeros();
            let mut rhs = Vector3::zeros();
            for (&i, u) in members.iter().zip(&rays) {
                let p = points[i as usize];
                let rows = [Vector3::new(1.0, 0.0, u.x), Vector3::new(0.0, 1.0, u.y)];
                for (row, value) in rows.iter().zip([p.x, p.y]) {
                    normal += row * row.transpose();
                    rhs += row * value;
                }
            }
            normal.lu().solve(&rhs).map(|x| -x.z)
        })
        .collect();
    if per_boulder.is_empty() {
        return None;
    }
    let median_bias = super::estimate::median(&mut per_boulder);
    let mut deviations: Vec<f64> = per_boulder
        .iter()
        .map(|b| (b - median_bias).abs())
        .collect();
    let sigma_m = 1.4826 * super::estimate::median(&mut deviations);
    Some(ViewBias {
        bias_m: median_bias,
        pooled_bias_m: -bias,
        sigma_m,
        boulders: per_boulder.len(),
        detections,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    /// `p` moved `bias_m` along the horizontal line of sight from `rover`.
    fn shifted(p: &Point3<f64>, rover: &Point3<f64>, bias_m: f64) -> Point3<f64> {
        let d = (p - rover).xy().normalize();
        p + Vector3::new(d.x, d.y, 0.0) * bias_m
    }

    use crate::landmarks::detection_seen_from as detection;

    /// Boulders on a grid, each seen from four rovers around it; every detection drawn
    /// `bias` toward its rover.
    fn biased_sets(bias: f64) -> Vec<DetectionSet> {
        let rovers = [
            Vector3::new(3.0, 0.0, 0.3),
            Vector3::new(-3.0, 0.0, 0.3),
            Vector3::new(0.0, 2.5, 0.3),
            Vector3::new(0.5, -4.0, 0.3),
        ];
        rovers
            .iter()
            .enumerate()
            .map(|(k, offset)| {
                let mut set = DetectionSet::new(format!("s{k}"), "world", true);
                for i in 0..6 {
                    for j in 0..6 {
                        let c = Point3::new(i as f64 * 1.1, j as f64 * 0.9, 0.0);
                        let rover = c + offset;
                        for _ in 0..3 {
                            set.detections
                                .push(detection(shifted(&c, &rover, -bias), rover));
                        }
                    }
                }
                set
            })
            .collect()
    }

    #[test]
    fn recovers_the_bias_from_boulders_seen_from_several_sides() {
        let estimate = estimate_view_bias(&biased_sets(0.015), &FusionConfig::default()).unwrap();
        assert!((estimate.bias_m - 0.015).abs() < 1e-4, "{estimate:?}");
        assert!(
            (estimate.pooled_bias_m - 0.015).abs() < 1e-4,
            "{estimate:?}"
        );
        assert!(estimate.sigma_m < 1e-6, "{estimate:?}");
        assert_eq!(estimate.boulders, 36);
        let none = estimate_view_bias(&biased_sets(0.0), &FusionConfig::default()).unwrap();
        assert!(none.bias_m.abs() < 1e-6);
    }

    #[test]
    fn correction_undoes_the_bias() {
        let sets = biased_sets(0.015);
        for d in &sets[0].detections {
            let c = corrected(d, 0.015);
            let rover = d.rover_position.unwrap();
            // Back on the grid.
            let x = c.p_world.x / 1.1;
            assert!(
                (x - x.round()).abs() < 1e-9,
                "{:?} from {rover:?}",
                c.p_world
            );
        }
        let bare = Detection {
            rover_position: None,
            ..sets[0].detections[0].clone()
        };
        assert_eq!(corrected(&bare, 0.015).p_world, bare.p_world);
    }

    #[test]
    fn mean_line_of_sight_is_long_from_one_side_and_short_from_all() {
        let sets = biased_sets(0.0);
        let one_side: Vec<&Detection> = sets[0].detections.iter().take(3).collect();
        let m = mean_line_of_sight(&one_side).unwrap();
        assert!((m.norm() - 1.0).abs() < 1e-9);
        let opposite = [&sets[0].detections[0], &sets[1].detections[0]];
        assert!(mean_line_of_sight(&opposite).unwrap().norm() < 1e-9);
    }

    #[test]
    fn one_set_alone_gives_no_estimate() {
        assert!(estimate_view_bias(&biased_sets(0.01)[..1], &FusionConfig::default()).is_none());
    }
}
