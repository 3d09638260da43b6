//! Which ground the cameras have seen: a set of small square cells marked when they fall in a
//! camera's view cone. The arc planner treats unseen ground as possibly blocked, because the
//! IPEX's cameras look only forward and backward and a rock beside the rover is invisible.
//!
//! A cell can be required to have been seen in several camera frames
//! ([`SeenGrid::with_min_views`]): a visible rock is missed in one frame now and then, so one
//! frame that saw its ground is weaker evidence that the ground is clear than two.

use crate::planning::Pose2;
use rustc_hash::FxHashMap as HashMap;

/// Cells on either side of the origin kept in the dense bitmap (±64 m at 0.25 m cells);
/// the rare cells beyond go to a set.
const DENSE_HALF_CELLS: i64 = 256;

/// Seen cells of the horizontal plane (session frame).
#[derive(Clone, Debug)]
pub struct SeenGrid {
    cell_m: f64,
    /// Cells within ±`DENSE_HALF_CELLS` of the origin, row-major (the arc planner looks up
    /// thousands of cells per control cycle: with a hash set the lookups were 14 % of a
    /// mission's time): the number of frames that saw each cell (saturating; `KNOWN` for
    /// ground the rover stood on).
    dense: Vec<u8>,
    /// The last frame that counted for each dense cell.
    dense_frame: Vec<u32>,
    /// Seen cells outside the dense window: frames and last frame.
    outside: HashMap<(i64, i64), (u8, u32)>,
    /// Frames a cell must have been seen in to count as seen.
    min_views: u8,
    /// The current frame ([`SeenGrid::start_frame`]).
    frame: u32,
}

/// View count of ground the rover stood on: known whatever `min_views` asks.
const KNOWN: u8 = u8::MAX;

impl SeenGrid {
    /// Empty, with square cells of `cell_m` metres.
    pub fn new(cell_m: f64) -> Self {
        Self::with_min_views(cell_m, 1)
    }

    /// Empty, with square cells of `cell_m` metres that count as seen once seen in
    /// `min_views` frames (at least 1).
    pub fn with_min_views(cell_m: f64, min_views: u8) -> Self {
        let cells = (2 * DENSE_HALF_CELLS * 2 * DENSE_HALF_CELLS) as usize;
        Self {
            cell_m: if cell_m.is_finite() && cell_m > 0.01 {
                cell_m
            } else {
                0.25
            },
            dense: vec![0; cells],
            dense_frame: vec![0; cells],
            outside: HashMap::default(),
            min_views: min_views.max(1),
            frame: 1,
        }
    }

    /// Start a new camera frame: each cell counts at most once per frame.
    pub fn start_frame(&mut self) {
        self.frame = self.frame.wrapping_add(1).max(1);
    }

    fn dense_index(&self, (i, j): (i64, i64)) -> Option<usize> {
        let (a, b) = (i + DENSE_HALF_CELLS, j + DENSE_HALF_CELLS);
        let side = 2 * DENSE_HALF_CELLS;
        ((0..side).contains(&a) && (0..side).contains(&b)).then(|| (a * side + b) as usize)
    }

    fn views(&self, key: (i64, i64)) -> u8 {
        match self.dense_index(key) {
            Some(k) => self.dense[k],
            None => self.outside.get(&key).map_or(0, |&(n, _)| n),
        }
    }

    fn contains(&self, key: (i64, i64)) -> bool {
        self.views(key) >= self.min_views
    }

    /// Count one view of a cell in this frame (`known`: the rover stood on it).
    fn insert(&mut self, key: (i64, i64), known: bool) {
        let frame = self.frame;
        let count = |n: &mut u8, last: &mut u32| {
            if known {
                *n = KNOWN;
            } else if *last != frame {
                *n = n.saturating_add(1);
            }
            *last = frame;
        };
        match self.dense_index(key) {
            Some(k) => count(&mut self.dense[k], &mut self.dense_frame[k]),
            None => {
                let (n, last) = self.outside.entry(key).or_insert((0, 0));
                count(n, last);
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
        let seen = |n: u8| n >= self.min_views;
        self.dense.iter().filter(|&&n| seen(n)).count()
            + self.outside.values().filter(|&&(n, _)| seen(n)).count()
    }

    /// Whether nothing has been seen.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
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
                    self.insert((i, j), false);
                }
            }
        }
    }

    /// Mark every cell within `radius_m` of (x, y) as known, whatever `min_views` asks (the
    /// ground under the rover).
    pub fn mark_disc(&mut self, x: f64, y: f64, radius_m: f64) {
        self.mark_cells(x, y, radius_m, None, true);
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
        self.mark_cells(x, y, radius_m, from, false);
    }

    fn mark_cells(
        &mut self,
        x: f64,
        y: f64,
        radius_m: f64,
        from: Option<(f64, f64, f64)>,
        known: bool,
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
                    self.insert((i, j), known);
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
    fn with_two_views_a_cell_needs_two_frames() {
        let mut g = SeenGrid::with_min_views(0.25, 2);
        g.start_frame();
        g.mark_disc_seen_from(3.0, 0.0, 0.3, None);
        // a second point of the same frame does not count again
        g.mark_disc_seen_from(3.05, 0.0, 0.3, None);
        assert!(!g.is_seen(3.0, 0.0));
        g.start_frame();
        g.mark_disc_seen_from(3.0, 0.0, 0.3, None);
        assert!(g.is_seen(3.0, 0.0));
        // far cells alike; the ground under the rover is known at once
        g.mark_disc_seen_from(100.0, 0.0, 0.2, None);
        assert!(!g.is_seen(100.0, 0.0));
        g.start_frame();
        g.mark_disc_seen_from(100.0, 0.0, 0.2, None);
        assert!(g.is_seen(100.0, 0.0));
        g.mark_disc(-2.0, 0.0, 0.3);
        assert!(g.is_seen(-2.0, 0.0));
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
