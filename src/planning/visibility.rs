//! Which ground the cameras have seen: a set of small square cells marked when they fall in a
//! camera's view cone. The arc planner treats unseen ground as possibly blocked, because the
//! IPEX's cameras look only forward and backward and a rock beside the rover is invisible.

use crate::planning::Pose2;
use rustc_hash::FxHashSet as HashSet;

/// Cells on either side of the origin kept in the dense bitmap (±64 m at 0.25 m cells);
/// the rare cells beyond go to a set.
const DENSE_HALF_CELLS: i64 = 256;

/// Seen cells of the horizontal plane (session frame).
#[derive(Clone, Debug)]
pub struct SeenGrid {
    cell_m: f64,
    /// Cells within ±`DENSE_HALF_CELLS` of the origin, row-major (the arc planner looks up
    /// thousands of cells per control cycle: with a hash set the lookups were 14 % of a
    /// mission's time).
    dense: Vec<bool>,
    /// Seen cells outside the dense window.
    outside: HashSet<(i64, i64)>,
}

impl SeenGrid {
    /// Empty, with square cells of `cell_m` metres.
    pub fn new(cell_m: f64) -> Self {
        Self {
            cell_m: if cell_m.is_finite() && cell_m > 0.01 {
                cell_m
            } else {
                0.25
            },
            dense: vec![false; (2 * DENSE_HALF_CELLS * 2 * DENSE_HALF_CELLS) as usize],
            outside: HashSet::default(),
        }
    }

    fn dense_index(&self, (i, j): (i64, i64)) -> Option<usize> {
        let (a, b) = (i + DENSE_HALF_CELLS, j + DENSE_HALF_CELLS);
        let side = 2 * DENSE_HALF_CELLS;
        ((0..side).contains(&a) && (0..side).contains(&b)).then(|| (a * side + b) as usize)
    }

    fn contains(&self, key: (i64, i64)) -> bool {
        match self.dense_index(key) {
            Some(k) => self.dense[k],
            None => self.outside.contains(&key),
        }
    }

    fn insert(&mut self, key: (i64, i64)) {
        match self.dense_index(key) {
            Some(k) => self.dense[k] = true,
            None => {
                self.outside.insert(key);
            }
        }
    }

    fn key(&self, x: f64, y: f64) -> (i64, i64) {
        (
            (x / self.cell_m).floor() as i64,
            (y / self.cell_m).floor() as i64,
        )
    }

    /// Number of seen cells.
    pub fn len(&self) -> usize {
        self.dense.iter().filter(|&&seen| seen).count() + self.outside.len()
    }

    /// Whether nothing has been seen.
    pub fn is_empty(&self) -> bool {
        self.outside.is_empty() && !self.dense.contains(&true)
    }

    /// Whether the cell holding (x, y) has been seen.
    pub fn is_seen(&self, x: f64, y: f64) -> bool {
        x.is_finite() && y.is_finite() && self.contains(self.key(x, y))
    }

    /// Mark the cells whose centres lie in the view cone of a camera at `camera` (position
    /// and viewing direction), within `half_fov_rad` of its axis and `min_m`..`max_m` of it.
    pub fn mark_view(&mut self, camera: Pose2, half_fov_rad: f64, min_m: f64, max_m: f64) {
        if !camera.x.is_finite()
            || !camera.y.is_finite()
            || !(0.0..=100.0).contains(&max_m)
            || max_m == 0.0
        {
            return;
        }
        let (lo, hi) = (
            self.key(camera.x - max_m, camera.y - max_m),
            self.key(camera.x + max_m, camera.y + max_m),
        );
        let cos_half = half_fov_rad.cos();
        let (ax, ay) = (camera.yaw.cos(), camera.yaw.sin());
        for i in lo.0..=hi.0 {
            for j in lo.1..=hi.1 {
                let cx = (i as f64 + 0.5) * self.cell_m - camera.x;
                let cy = (j as f64 + 0.5) * self.cell_m - camera.y;
                let d = cx.hypot(cy);
                if d >= min_m && d <= max_m && (cx * ax + cy * ay) >= cos_half * d {
                    self.insert((i, j));
                }
            }
        }
    }

    /// Mark every cell within `radius_m` of (x, y) (the ground under the rover).
    pub fn mark_disc(&mut self, x: f64, y: f64, radius_m: f64) {
        self.mark_disc_seen_from(x, y, radius_m, None);
    }

    /// Mark the cells within `radius_m` of a ground point at (x, y) measured from
    /// `from = (camera x, camera y, toward_m)`: cells nearer the camera than the point by
    /// more than `toward_m` along the line of sight stay unmarked (ground just in front of a
    /// measured point may lie hidden in a dip or behind a crest: its own points would show
    /// it). `None`: the whole disc.
    pub fn mark_disc_seen_from(
        &mut self,
        x: f64,
        y: f64,
        radius_m: f64,
        from: Option<(f64, f64, f64)>,
    ) {
        if !x.is_finite() || !y.is_finite() || !(0.0..=100.0).contains(&radius_m) {
            return;
        }
        // unit line of sight (camera → point) and how far back along it the disc may reach
        let sight = from.and_then(|(cx, cy, toward_m)| {
            let (dx, dy) = (x - cx, y - cy);
            let d = dx.hypot(dy);
            (d > 1e-9 && toward_m.is_finite()).then(|| (dx / d, dy / d, toward_m))
        });
        let (lo, hi) = (
            self.key(x - radius_m, y - radius_m),
            self.key(x + radius_m, y + radius_m),
        );
        for i in lo.0..=hi.0 {
            for j in lo.1..=hi.1 {
                let cx = (i as f64 + 0.5) * self.cell_m - x;
                let cy = (j as f64 + 0.5) * self.cell_m - y;
                let behind = sight.is_some_and(|(ux, uy, toward_m)| cx * ux + cy * uy < -toward_m);
                if cx.hypot(cy) <= radius_m && !behind {
                    self.insert((i, j));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_marks_ahead_only() {
        let mut g = SeenGrid::new(0.25);
        g.mark_view(Pose2::new(0.0, 0.0, 0.0), 35f64.to_radians(), 0.3, 5.0);
        assert!(g.is_seen(3.0, 0.5));
        assert!(!g.is_seen(-3.0, 0.0));
        assert!(!g.is_seen(1.0, 1.5));
        assert!(!g.is_seen(6.0, 0.0));
        g.mark_disc(0.0, 0.0, 0.5);
        assert!(g.is_seen(0.0, 0.3));
    }

    #[test]
    fn a_point_seen_from_afar_leaves_the_ground_before_it_unmarked() {
        // a point 3 m ahead of a camera at the origin: the disc reaches 0.35 m beyond it and
        // to the sides, but only 0.05 m back towards the camera (a dip there stays unseen)
        let mut g = SeenGrid::new(0.1);
        g.mark_disc_seen_from(3.0, 0.0, 0.35, Some((0.0, 0.0, 0.05)));
        assert!(g.is_seen(3.3, 0.0) && g.is_seen(3.05, 0.3) && g.is_seen(3.0, -0.3));
        assert!(!g.is_seen(2.75, 0.0) && !g.is_seen(2.8, 0.1));
        let mut full = SeenGrid::new(0.1);
        full.mark_disc_seen_from(3.0, 0.0, 0.35, None);
        assert!(full.is_seen(2.75, 0.0));
        assert!(full.len() > g.len());
    }

    #[test]
    fn far_cells_and_the_count() {
        let mut g = SeenGrid::new(0.25);
        g.mark_disc(100.0, -100.0, 0.2);
        g.mark_disc(100.0, -100.0, 0.2);
        g.mark_disc(1.0, 1.0, 0.2);
        assert!(g.is_seen(100.0, -100.0) && g.is_seen(1.0, 1.0));
        assert!(!g.is_seen(-100.0, 100.0) && !g.is_seen(f64::NAN, 0.0));
        assert_eq!(g.len(), 2 * 4);
    }
}
