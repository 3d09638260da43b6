//! The planner's obstacle memory: detected rocks (merged when detected again) and points
//! measured on the lander, in the session frame.

use crate::spatial::GridIndex;
use nalgebra::{Point2, Point3};
use serde::{Deserialize, Serialize};

/// Which detections become obstacles and how they merge.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObstacleConfig {
    /// Rocks of this radius and above must be avoided, metres.
    pub min_rock_radius_m: f64,
    /// A detection counts as such a rock when its measured radius reaches this fraction of
    /// `min_rock_radius_m` (the measured radius is noisy).
    pub radius_tolerance: f64,
    /// Detections closer than this to a remembered obstacle update it, metres.
    pub merge_radius_m: f64,
    /// Smallest weight of a new detection in an obstacle's position (the rest on the
    /// previous estimate).
    pub recent_weight: f64,
    /// A rock counts once detected this many times (spurious detections rarely repeat);
    /// lander points count at once.
    pub min_hits: u32,
}

impl Default for ObstacleConfig {
    fn default() -> Self {
        Self {
            min_rock_radius_m: 0.08,
            radius_tolerance: 0.85,
            merge_radius_m: 0.3,
            min_hits: 2,
            recent_weight: 0.4,
        }
    }
}

/// One remembered obstacle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Obstacle {
    /// Position, session frame (running mean of its detections), metres.
    pub p: Point2<f64>,
    /// Radius to keep clear of, metres (largest measured).
    pub radius_m: f64,
    /// Number of detections merged in.
    pub hits: u32,
}

/// The remembered obstacles.
#[derive(Clone, Debug)]
pub struct ObstacleMemory {
    config: ObstacleConfig,
    obstacles: Vec<Obstacle>,
    index: GridIndex,
    max_radius_m: f64,
}

fn p3(p: &Point2<f64>) -> Point3<f64> {
    Point3::new(p.x, p.y, 0.0)
}

impl ObstacleMemory {
    /// An empty memory.
    pub fn new(config: &ObstacleConfig) -> Self {
        Self {
            config: config.clone(),
            obstacles: Vec::new(),
            index: GridIndex::new(1.0),
            max_radius_m: 0.0,
        }
    }

    /// The obstacles.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Largest remembered radius, metres.
    pub fn max_radius_m(&self) -> f64 {
        self.max_radius_m
    }

    /// Remember a rock detected at `p` (session frame) with measured `radius_m`; rocks too
    /// small to matter and non-finite input are ignored. Returns whether it was kept.
    pub fn add_rock(&mut self, p: Point2<f64>, radius_m: f64) -> bool {
        if radius_m.is_nan()
            || radius_m < self.config.min_rock_radius_m * self.config.radius_tolerance
        {
            return false;
        }
        self.add(p, radius_m, 1)
    }

    /// Remember a point measured on the lander (radius 0: the point itself is the obstacle).
    pub fn add_point(&mut self, p: Point2<f64>) -> bool {
        self.add(p, 0.0, self.config.min_hits.max(1))
    }

    fn add(&mut self, p: Point2<f64>, radius_m: f64, hits: u32) -> bool {
        if !p.x.is_finite() || !p.y.is_finite() || !radius_m.is_finite() {
            return false;
        }
        let merge = self.config.merge_radius_m;
        let mut nearest: Option<(u32, f64)> = None;
        self.index.for_each_near(&p3(&p), merge, |id| {
            let d = (self.obstacles[id as usize].p - p).norm();
            if d <= merge && nearest.is_none_or(|(_, bd)| d < bd) {
                nearest = Some((id, d));
            }
        });
        match nearest {
            Some((id, _)) => {
                let o = &mut self.obstacles[id as usize];
                let old = o.p;
                // running mean, but never weighting the newest detection below
                // `recent_weight`: odometry drifts, and the latest detection was made in the
                // frame the rover is driving in now
                let n = f64::from(o.hits);
                let w = (1.0 / (n + 1.0)).max(self.config.recent_weight);
                o.p = Point2::from(old.coords + (p.coords - old.coords) * w);
                o.hits += hits;
                o.radius_m = o.radius_m.max(radius_m);
                let (old3, new3) = (p3(&old), p3(&o.p));
                self.index.relocate(id, &old3, &new3);
            }
            None => {
                self.index.insert(self.obstacles.len() as u32, &p3(&p));
                self.obstacles.push(Obstacle { p, radius_m, hits });
            }
        }
        self.max_radius_m = self.max_radius_m.max(radius_m);
        true
    }

    /// Calls `visit` for every confirmed obstacle (at least `min_hits` detections) within
    /// `radius_m` of `p` (centre distance).
    pub fn for_each_near(&self, p: Point2<f64>, radius_m: f64, mut visit: impl FnMut(&Obstacle)) {
        let min_hits = self.config.min_hits;
        self.index.for_each_near(&p3(&p), radius_m, |id| {
            let o = &self.obstacles[id as usize];
            if o.hits >= min_hits && (o.p - p).norm() <= radius_m {
                visit(o);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merges_and_filters() {
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        assert!(!m.add_rock(Point2::new(1.0, 1.0), 0.03));
        assert!(m.add_rock(Point2::new(1.0, 1.0), 0.1));
        assert!(m.add_rock(Point2::new(1.1, 1.0), 0.12));
        assert!(!m.add_rock(Point2::new(f64::NAN, 1.0), 0.2));
        assert_eq!(m.obstacles().len(), 1);
        let o = m.obstacles()[0];
        assert_eq!(o.hits, 2);
        assert!((o.p.x - 1.05).abs() < 1e-12 && (o.radius_m - 0.12).abs() < 1e-12);
        // later detections weigh at least `recent_weight`
        m.add_rock(Point2::new(1.05, 1.0), 0.1);
        m.add_rock(Point2::new(1.3, 1.0), 0.1);
        assert!((m.obstacles()[0].p.x - 1.15).abs() < 1e-12);
        assert!(m.add_point(Point2::new(3.0, 0.0)));
        assert!(m.add_rock(Point2::new(2.0, 1.0), 0.2));
        let mut seen = 0;
        m.for_each_near(Point2::new(2.0, 0.5), 1.5, |_| seen += 1);
        assert_eq!(seen, 2);
    }
}
