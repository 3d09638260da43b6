//! A route out of a pocket: the shortest collision-free path (A* over a local occupancy
//! grid) from the rover to its waypoint, for when the arc fan has nothing to offer.
//!
//! The arc planner only looks 8 s ahead along constant-curvature arcs. Between the lander's
//! clearance and a handful of small rocks it can find every arc toward the waypoint blocked
//! while the only way out is a narrow gap behind it, and the rover then turns, scans and
//! backs up in the same square metre for minutes (seeds 4, 10 and 13 of the mission). The
//! route sees the whole neighbourhood at once: it is planned in the same configuration space
//! as the arcs (an obstacle of radius r blocks the centres within
//! [`ArcPlannerConfig::required_m`], the lander box its clearance, the site bounds), on
//! cells of `cell_m`, with ground the cameras have not seen passable at a higher cost, and
//! the navigator steers for a point along it instead of the waypoint itself. No route means
//! the waypoint cannot be reached from here at all, and it is skipped at once.

use crate::planning::arc_planner::{ArcPlannerConfig, Scene};
use nalgebra::Point2;
use serde::{Deserialize, Serialize};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Parameters of the route planner.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RouteConfig {
    /// Plan routes at all (when the arc fan is stuck).
    pub enabled: bool,
    /// Cell size of the occupancy grid, metres.
    pub cell_m: f64,
    /// The grid spans the rover and the goal plus this margin on every side, metres; when
    /// no route is found the margin is doubled (up to `max_cells_per_side`) and the search
    /// repeated.
    pub margin_m: f64,
    /// At most this many cells per side (a farther goal is approached as far as the grid
    /// reaches); at most [`MAX_CELLS_PER_SIDE`] whatever is asked.
    pub max_cells_per_side: usize,
    /// Cost of a metre over ground the cameras have not seen, in metres of seen ground.
    pub unseen_cost: f64,
    /// Around the rover this much counts as free, metres (it may stand inside an
    /// obstacle's clearance after the map moved).
    pub start_free_m: f64,
    /// The navigator steers for the route point this far ahead along it, metres.
    pub lookahead_m: f64,
    /// A route is followed for at most this long before it is planned again, seconds.
    pub replan_after_s: f64,
}

impl Default for RouteConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            cell_m: 0.1,
            margin_m: 3.0,
            max_cells_per_side: 300,
            unseen_cost: 3.0,
            start_free_m: 0.3,
            lookahead_m: 1.2,
            replan_after_s: 20.0,
        }
    }
}

/// The largest grid side, cells, whatever the configuration asks (4 million cells).
pub const MAX_CELLS_PER_SIDE: usize = 2000;

/// A planned route, session frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Route {
    /// Cell centres from the rover's cell to the goal's, session frame.
    pub points: Vec<Point2<f64>>,
    /// Length, metres.
    pub length_m: f64,
}

impl Route {
    /// Index of the route point nearest `here`.
    fn nearest(&self, here: Point2<f64>) -> usize {
        let d = |p: &Point2<f64>| (p - here).norm_squared();
        (0..self.points.len())
            .min_by(|&a, &b| d(&self.points[a]).total_cmp(&d(&self.points[b])))
            .unwrap_or(0)
    }

    /// The point `lookahead_m` along the route past the point nearest `here` (the goal
    /// when less is left).
    pub fn carrot(&self, here: Point2<f64>, lookahead_m: f64) -> Option<Point2<f64>> {
        let start = self.nearest(here);
        let mut walked = 0.0;
        for w in self.points[start..].windows(2) {
            walked += (w[1] - w[0]).norm();
            if walked >= lookahead_m {
                return Some(w[1]);
            }
        }
        self.points.last().copied()
    }

    /// Length of the route left from the point nearest `here`, metres.
    pub fn remaining_m(&self, here: Point2<f64>) -> f64 {
        let start = self.nearest(here);
        let along: f64 = self.points[start..]
            .windows(2)
            .map(|w| (w[1] - w[0]).norm())
            .sum();
        along + self.points.get(start).map_or(0.0, |p| (p - here).norm())
    }
}

/// The occupancy grid: cells of `cell_m` from `origin` (the lower corner's centre).
struct Grid {
    origin: Point2<f64>,
    cell_m: f64,
    nx: usize,
    ny: usize,
}

impl Grid {
    fn centre(&self, i: usize, j: usize) -> Point2<f64> {
        self.origin + nalgebra::Vector2::new(i as f64, j as f64) * self.cell_m
    }

    fn cell(&self, p: Point2<f64>) -> (usize, usize) {
        let f = |v: f64, n: usize| ((v / self.cell_m).round().max(0.0) as usize).min(n - 1);
        (
            f(p.x - self.origin.x, self.nx),
            f(p.y - self.origin.y, self.ny),
        )
    }

    /// Index of cell (i, j) in the row-major cell vectors.
    fn index(&self, i: usize, j: usize) -> usize {
        i * self.ny + j
    }

    /// Index of the cell holding `p` (clamped to the grid).
    fn index_of(&self, p: Point2<f64>) -> usize {
        let (i, j) = self.cell(p);
        self.index(i, j)
    }

    /// Cell (i, j) of index `k`.
    fn ij(&self, k: usize) -> (usize, usize) {
        (k / self.ny, k % self.ny)
    }

    /// Centre of the cell with index `k`.
    fn centre_of(&self, k: usize) -> Point2<f64> {
        let (i, j) = self.ij(k);
        self.centre(i, j)
    }

    /// The cells of the square of half-side `r` around `c` (clamped to the grid): index and
    /// distance of the centre from `c`.
    fn cells_near(&self, c: Point2<f64>, r: f64) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (i0, j0) = self.cell(c - nalgebra::Vector2::repeat(r));
        let (i1, j1) = self.cell(c + nalgebra::Vector2::repeat(r));
        (i0..=i1).flat_map(move |i| {
            (j0..=j1).map(move |j| (self.index(i, j), (self.centre(i, j) - c).norm()))
        })
    }
}

/// The shortest route from `from` to `to` (session frame) in the configuration space of
/// `arcs` in `scene`, or `None` when `to` cannot be reached inside the largest grid (or the
/// grid would be degenerate).
pub fn plan_route(
    from: Point2<f64>,
    to: Point2<f64>,
    arcs: &ArcPlannerConfig,
    scene: &Scene,
    config: &RouteConfig,
) -> Option<Route> {
    let finite = from
        .coords
        .iter()
        .chain(to.coords.iter())
        .all(|v| v.is_finite());
    if config.cell_m.is_nan() || config.cell_m <= 0.0 || !finite {
        return None;
    }
    let max_side_m = config.cell_m * config.max_cells_per_side.clamp(2, MAX_CELLS_PER_SIDE) as f64;
    let mut margin_m = config.margin_m.max(config.cell_m);
    loop {
        let route = plan_in_grid(from, to, [margin_m, max_side_m], arcs, scene, config);
        let span_m = (to - from).abs().max() + 2.0 * margin_m;
        if route.is_some() || span_m >= max_side_m {
            return route;
        }
        margin_m *= 2.0;
    }
}

/// [`plan_route`] over the grid spanning both ends plus `margin_m`, at most `max_side_m`
/// wide.
fn plan_in_grid(
    from: Point2<f64>,
    to: Point2<f64>,
    [margin_m, max_side_m]: [f64; 2],
    arcs: &ArcPlannerConfig,
    scene: &Scene,
    config: &RouteConfig,
) -> Option<Route> {
    // the grid: both ends plus the margin, cropped around the rover to the largest size
    let lo = from.coords.inf(&to.coords).add_scalar(-margin_m);
    let hi = from.coords.sup(&to.coords).add_scalar(margin_m);
    let crop = |lo: f64, hi: f64, at: f64| {
        let half = max_side_m / 2.0;
        (lo.max(at - half), hi.min(at + half))
    };
    let (x0, x1) = crop(lo.x, hi.x, from.x);
    let (y0, y1) = crop(lo.y, hi.y, from.y);
    let grid = Grid {
        origin: Point2::new(x0, y0),
        cell_m: config.cell_m,
        nx: (((x1 - x0) / config.cell_m).ceil() as usize + 1).max(2),
        ny: (((y1 - y0) / config.cell_m).ceil() as usize + 1).max(2),
    };
    let blocked = occupancy(&grid, from, arcs, scene, config);
    let cost_of = |k: usize| {
        let p = grid.centre_of(k);
        match scene.seen {
            Some(seen) if !seen.is_seen(p.x, p.y) => config.unseen_cost.max(1.0),
            _ => 1.0,
        }
    };
    let (start, goal) = (grid.index_of(from), grid.index_of(to));
    if blocked[goal] {
        return None;
    }
    let goal_p = grid.centre_of(goal);
    // A*, costs in micrometres so that the heap orders integers
    let to_um = |m: f64| (m * 1e6).round() as u64;
    let heuristic_um = |k: usize| to_um((grid.centre_of(k) - goal_p).norm());
    let n = grid.nx * grid.ny;
    let mut best = vec![u64::MAX; n];
    let mut parent = vec![usize::MAX; n];
    let mut heap = BinaryHeap::new();
    best[start] = 0;
    heap.push(Reverse((heuristic_um(start), start)));
    while let Some(Reverse((f, k))) = heap.pop() {
        if k == goal {
            break;
        }
        if f > best[k].saturating_add(heuristic_um(k)) {
            continue; // a stale entry: the cell was reached more cheaply since
        }
        let (i, j) = grid.ij(k);
        for (di, dj) in NEIGHBOURS {
            let (Some(a), Some(b)) = (i.checked_add_signed(di), j.checked_add_signed(dj)) else {
                continue;
            };
            if a >= grid.nx || b >= grid.ny {
                continue;
            }
            let m = grid.index(a, b);
            if blocked[m] {
                continue;
            }
            let step_m = config.cell_m * ((di * di + dj * dj) as f64).sqrt();
            let g = best[k].saturating_add(to_um(step_m * 0.5 * (cost_of(k) + cost_of(m))));
            if g < best[m] {
                best[m] = g;
                parent[m] = k;
                heap.push(Reverse((g.saturating_add(heuristic_um(m)), m)));
            }
        }
    }
    if best[goal] == u64::MAX {
        return None;
    }
    let mut cells = vec![goal];
    while let Some(&k) = cells.last() {
        if k == start || parent[k] == usize::MAX {
            break;
        }
        cells.push(parent[k]);
    }
    cells.reverse();
    let points: Vec<Point2<f64>> = cells.iter().map(|&k| grid.centre_of(k)).collect();
    let length_m = points.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    Some(Route { points, length_m })
}

const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, -1),
    (0, 1),
    (1, -1),
    (1, 0),
    (1, 1),
];

/// Blocked cells: within the clearance of an obstacle or of the lander, or outside the site
/// (nav frame); the cells around the rover are free.
fn occupancy(
    grid: &Grid,
    from: Point2<f64>,
    arcs: &ArcPlannerConfig,
    scene: &Scene,
    config: &RouteConfig,
) -> Vec<bool> {
    let bound = arcs.site_half_extent_m;
    let mut blocked: Vec<bool> = (0..grid.nx * grid.ny)
        .map(|k| {
            let p = grid.centre_of(k);
            let q = scene.nav_from_session * p;
            q.x.abs() > bound
                || q.y.abs() > bound
                || scene
                    .lander
                    .is_some_and(|lander| lander.distance_m(p) < arcs.clearance_m)
        })
        .collect();
    // each obstacle blocks the disc of its required distance
    let centre = grid.centre(grid.nx / 2, grid.ny / 2);
    let half_diag = grid.cell_m * (grid.nx.max(grid.ny) as f64) * std::f64::consts::FRAC_1_SQRT_2;
    let reach = arcs.required_m(scene.obstacles.max_radius_m());
    scene
        .obstacles
        .for_each_near(centre, half_diag + reach, |o| {
            let r = arcs.required_m(o.radius_m);
            for (k, d) in grid.cells_near(o.p, r) {
                if d < r {
                    blocked[k] = true;
                }
            }
        });
    for (k, d) in grid.cells_near(from, config.start_free_m) {
        if d <= config.start_free_m + 1e-9 {
            blocked[k] = false;
        }
    }
    blocked[grid.index_of(from)] = false;
    blocked
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::arc_planner::LanderBox;
    use crate::planning::obstacles::{ObstacleConfig, ObstacleMemory};
    use nalgebra::Isometry2;

    fn rock(m: &mut ObstacleMemory, x: f64, y: f64, r: f64) {
        // two detections confirm a rock
        m.add_rock(Point2::new(x, y), r);
        m.add_rock(Point2::new(x, y), r);
    }

    fn scene(obstacles: &ObstacleMemory) -> Scene<'_> {
        Scene {
            obstacles,
            lander: Some(LanderBox {
                session_from_lander: Isometry2::identity(),
                half_extent_m: 1.5,
            }),
            nav_from_session: Isometry2::identity(),
            seen: None,
        }
    }

    #[test]
    fn open_ground_is_a_straight_line() {
        let m = ObstacleMemory::new(&ObstacleConfig::default());
        let arcs = ArcPlannerConfig::default();
        let r = plan_route(
            Point2::new(4.0, -4.0),
            Point2::new(8.0, -4.0),
            &arcs,
            &scene(&m),
            &RouteConfig::default(),
        )
        .expect("a route");
        assert!((r.length_m - 4.0).abs() < 0.11, "{}", r.length_m);
        assert!(r.points.iter().all(|p| (p.y + 4.0).abs() < 0.06));
    }

    #[test]
    fn the_way_out_of_a_pocket_goes_around_and_keeps_clear() {
        // a wall of rocks across the way east, open to the north
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        for k in 0..8 {
            rock(&mut m, 6.0, -8.0 + 0.5 * k as f64, 0.1);
        }
        let arcs = ArcPlannerConfig::default();
        let s = scene(&m);
        let from = Point2::new(4.5, -6.0);
        let to = Point2::new(8.0, -6.0);
        let r = plan_route(from, to, &arcs, &s, &RouteConfig::default()).expect("a route");
        assert!(r.length_m > 4.0, "{}", r.length_m);
        for p in &r.points {
            for o in m.obstacles() {
                assert!((p - o.p).norm() >= arcs.required_m(o.radius_m) - 1e-9);
            }
        }
        // the carrot leads north first, around the wall's end
        let c = r.carrot(from, 1.2).expect("a carrot");
        assert!(c.y > from.y, "{c:?}");
        assert!(r.remaining_m(from) > 4.0);
    }

    #[test]
    fn an_enclosed_goal_has_no_route() {
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        for k in 0..24 {
            let a = k as f64 * std::f64::consts::TAU / 24.0;
            rock(&mut m, 8.0 + 1.6 * a.cos(), -6.0 + 1.6 * a.sin(), 0.1);
        }
        let (arcs, s) = (ArcPlannerConfig::default(), scene(&m));
        let from = Point2::new(4.0, -6.0);
        let plan = |to| plan_route(from, to, &arcs, &s, &RouteConfig::default());
        assert!(plan(Point2::new(8.0, -6.0)).is_none());
        // a goal inside the lander's clearance neither
        assert!(plan(Point2::new(0.0, -2.0)).is_none());
    }
}
