//! Where a session anchored by the site's rock grid ([`super::grid_start`]) lies in the
//! world, fitted at its end onto the grid: the mapping localizer's frame was set by the one
//! grid fix that anchored it (a few centimetres off: the first fixes come from boulders not
//! yet corrected for the viewpoint bias), and the grid now offers better:
//!
//! 1. the 4-DOF fit of the session's poses onto the grid localizer's poses of the same
//!    frames (every grid fix of the session, not the first alone);
//! 2. the horizontal fit (x, y, yaw) of the session's map onto the grid's rocks: the map's
//!    boulders, corrected for the viewpoint bias and adjusted, lie where the rocks are, and
//!    some two hundred pairs average the cells' quantisation out;
//! 3. the height from the grid's height layer: the median difference between the cells'
//!    heights and the session's near ground points (a grid rock sits at its cells' terrain
//!    height, a detected boulder at its centroid, so the rocks do not give the height).

use super::grid_start::LostStart1Config;
use crate::align::refine::{refine, Refined};
use crate::align::{align_yaw, Dof, WeightedPair};
use crate::sim::session::SessionLog;
use nalgebra::{Isometry3, Point3};
use segloc_maps::{LacGrid, ObjectMap};

/// The end's fit of an anchored session onto the grid.
#[derive(Clone, Debug, PartialEq)]
pub struct GridFit {
    /// The correction of the session's (anchored) frame into the world.
    pub world_from_anchor: Isometry3<f64>,
    /// Rocks paired by the horizontal map fit (`None`: no fit; applied only with at least
    /// `map_fit_min_pairs`).
    pub map_fit_pairs: Option<usize>,
    /// Ground points the height fit used (`None`: not applied).
    pub height_points: Option<usize>,
}

/// Fit the session anchored at log frame `first` onto the grid: `tail` is the log from
/// that frame on, `anchored` its poses (one per frame of `tail`) and `map` its map in the
/// anchored frame, `grid_poses` the grid localizer's poses of every frame of the log.
pub fn world_from_anchor(
    (site, prior): (&LacGrid, &ObjectMap),
    tail: &SessionLog,
    (grid_poses, anchored): (&[Isometry3<f64>], &[Isometry3<f64>]),
    first: usize,
    map: &ObjectMap,
    config: &LostStart1Config,
) -> GridFit {
    let by_poses = pose_fit(grid_poses.get(first..).unwrap_or_default(), anchored);
    let map_fit = horizontal_fit(prior, &map.transformed(&by_poses, "world"), config);
    let map_fit_pairs = map_fit.as_ref().map(|f| f.inliers.len());
    let mut world_from_anchor = match map_fit {
        Some(fit) if fit.inliers.len() >= config.map_fit_min_pairs => {
            fit.prior_from_query * by_poses
        }
        _ => by_poses,
    };
    let height = height_fit(site, tail, anchored, &world_from_anchor, config);
    if let Some((dz, _)) = height {
        world_from_anchor.translation.vector.z += dz;
    }
    GridFit {
        world_from_anchor,
        map_fit_pairs,
        height_points: height.map(|(_, n)| n),
    }
}

/// The 4-DOF correction carrying `anchored` onto `grid` (the same frames' poses), identity
/// when degenerate.
fn pose_fit(grid: &[Isometry3<f64>], anchored: &[Isometry3<f64>]) -> Isometry3<f64> {
    let pairs: Vec<WeightedPair> = grid
        .iter()
        .zip(anchored)
        .map(|(g, a)| WeightedPair {
            p_prior: Point3::from(g.translation.vector),
            p_query: Point3::from(a.translation.vector),
            weight: 1.0,
        })
        .collect();
    align_yaw(&pairs).unwrap_or_else(Isometry3::identity)
}

/// The horizontal correction carrying `map` (world frame, a few centimetres off) onto the
/// rocks of the grid prior `grid`, heights left out. `None` without landmarks.
fn horizontal_fit(grid: &ObjectMap, map: &ObjectMap, config: &LostStart1Config) -> Option<Refined> {
    let flat = |m: &ObjectMap| -> Vec<Point3<f64>> {
        m.landmarks
            .iter()
            .map(|l| Point3::new(l.position.x, l.position.y, 0.0))
            .collect()
    };
    let (prior, query) = (flat(grid), flat(map));
    if prior.is_empty() || query.is_empty() {
        return None;
    }
    Some(refine(
        &prior,
        &vec![1.0; prior.len()],
        &query,
        &vec![1.0; query.len()],
        &Isometry3::identity(),
        Dof::Four,
        &config.map_fit,
    ))
}

/// The height correction (m) and the number of ground points behind it: the median of the
/// grid cells' heights minus the heights of the ground points (of the frames of `tail`) within
/// `height_fit_max_range_m` of the rover, placed with `world_from_anchor * anchored`.
/// `None` with fewer than `height_fit_min_points` (or the fit off: range 0).
pub fn height_fit(
    site: &LacGrid,
    tail: &SessionLog,
    anchored: &[Isometry3<f64>],
    world_from_anchor: &Isometry3<f64>,
    config: &LostStart1Config,
) -> Option<(f64, usize)> {
    let max_range_m = config.height_fit_max_range_m;
    let mut dz: Vec<f64> = Vec::new();
    for (frame, pose) in tail.frames.iter().zip(anchored) {
        let world_from_rover = world_from_anchor * pose;
        for g in frame
            .ground
            .iter()
            .filter(|g| g.p_rover.coords.norm() <= max_range_m)
        {
            let p = world_from_rover * g.p_rover;
            let Some((i, j)) = site.cell_of(p.x, p.y) else {
                continue;
            };
            let h = site.height[site.index(i, j)];
            if h.is_finite() {
                dz.push(h - p.z);
            }
        }
    }
    if dz.len() < config.height_fit_min_points.max(1) {
        return None;
    }
    dz.sort_by(f64::total_cmp);
    Some((dz[dz.len() / 2], dz.len()))
}
