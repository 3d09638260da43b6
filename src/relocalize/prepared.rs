//! A map prepared for relocalization: positions, weights and ids in flat arrays.

use super::RelocalizeError;
use nalgebra::Point3;
use segloc_maps::ObjectMap;

/// The fewest landmarks a map needs to be relocalized against.
pub const MIN_LANDMARKS: usize = 3;

/// Flat arrays of one map's landmarks, built once per map.
#[derive(Clone, Debug)]
pub struct PreparedMap {
    /// Landmark positions in the map's frame.
    pub points: Vec<Point3<f64>>,
    /// Landmark weights: inverse of the mean position variance (1/m²).
    pub weights: Vec<f64>,
    /// Position variance (m²) along one horizontal direction: the mean of the covariance's
    /// x and y variances.
    pub var_xy: Vec<f64>,
    /// Height variance (m²).
    pub var_z: Vec<f64>,
    /// Position variance (m²) along any direction: a third of the covariance's trace.
    pub var_3d: Vec<f64>,
    /// Landmark ids, in the same order.
    pub ids: Vec<u32>,
    /// Landmark sizes (m), when known.
    pub sizes: Vec<Option<f64>>,
    /// Detections fused into each landmark.
    pub observations: Vec<u32>,
    /// Whether the map is gravity-aligned.
    pub gravity_aligned: bool,
}

impl PreparedMap {
    /// Check and flatten `map`; `role` ("prior" or "query") names it in errors.
    pub fn new(map: &ObjectMap, role: &'static str) -> Result<Self, RelocalizeError> {
        map.validate()
            .map_err(|source| RelocalizeError::InvalidMap { role, source })?;
        if map.len() < MIN_LANDMARKS {
            return Err(RelocalizeError::TooFewLandmarks {
                role,
                count: map.len(),
                required: MIN_LANDMARKS,
            });
        }
        let weights = map
            .landmarks
            .iter()
            .map(|l| {
                let variance = (l.covariance.trace() / 3.0).max(1e-8);
                1.0 / variance
            })
            .collect();
        let cov = |f: fn(&nalgebra::Matrix3<f64>) -> f64| -> Vec<f64> {
            map.landmarks.iter().map(|l| f(&l.covariance)).collect()
        };
        Ok(Self {
            points: map.positions(),
            weights,
            var_xy: cov(|c| 0.5 * (c[(0, 0)] + c[(1, 1)])),
            var_z: cov(|c| c[(2, 2)]),
            var_3d: cov(|c| c.trace() / 3.0),
            ids: map.landmarks.iter().map(|l| l.id).collect(),
            sizes: map.landmarks.iter().map(|l| l.size_m).collect(),
            observations: map.landmarks.iter().map(|l| l.observations).collect(),
            gravity_aligned: map.gravity_aligned,
        })
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Indices of the `limit` most observed landmarks (all of them when there are fewer),
    /// in index order.
    pub fn best_observed(&self, limit: usize) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.len()).collect();
        if self.len() > limit {
            order.sort_by_key(|&i| (std::cmp::Reverse(self.observations[i]), i));
            order.truncate(limit);
            order.sort_unstable();
        }
        order
    }

    /// Whether every landmark has 0 observations: a survey map (a rock grid), whose
    /// landmarks no detection count ranks.
    pub fn is_survey(&self) -> bool {
        self.observations.iter().all(|&o| o == 0)
    }

    /// Whether the map has no landmarks (never true once prepared).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}
