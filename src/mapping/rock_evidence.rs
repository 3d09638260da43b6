//! The rock layer from raw boulder detections: an evidence grid normalised by exposure.
//!
//! A rock cell keeps producing detections whenever it is in view; a spurious detection
//! (a shadow, a crater rim, the lander's legs) does not, and a boulder near the camera is
//! seen every second while one at 5 m is seen now and then. So each cell keeps two sums:
//!
//! - **hits**: detections whose centroid falls in the cell (each detection votes for its
//!   own cell: the centroids of one boulder spread over the cells the boulder covers, and
//!   a fused landmark's single centroid would mark only one of them);
//! - **exposure**: for every detection frame, whether the cell was in the camera's view
//!   (range in `[min_range_m, max_range_m]`, bearing within `half_fov_deg` of the
//!   heading), weighted by `(reference_range_m / range)^range_exponent` — the rate at which
//!   false detections land in a cell falls off about as range⁻³ on the real traverses
//!   (a wider wedge spreads them over more cells, and far detections are rarer).
//!
//! A cell is a rock when it has at least `min_hits` hits and `hits / exposure` is at least
//! `min_rate`: the hits are far more than the view alone explains.
//!
//! A detection's centroid lies on the face the camera sees, in front of the boulder's
//! centre ([`crate::landmarks::view_bias`]). Each detection is pushed back along its
//! horizontal line of sight by the viewpoint bias before it votes; the bias is estimated
//! from the traverses themselves (boulders seen from several sides), not from any ground
//! truth. On the 17 LunarLoc traverses the estimate is 0.82 cm; it moves 6 % of the votes
//! to the next cell back, and the false positives drop from 124 to 114 while the true
//! positives rise from 449 to 455 (F1 0.632 → 0.642 against the LAC ground truth).
//!
//! Detections on the lander's own body and antenna do not vote
//! ([`lander_structure`](super::lander_structure)): 8 fewer false positives, F1 0.646.
//!
//! Only *repeated* hits count: the detections within `repeat_radius_m` (1 cm) of the
//! cell's median vote. A boulder's visible face comes back to the same place view after
//! view, to the stereo noise at these ranges; shadows, crater rims and parts of other
//! objects scatter over the cell. With repeated hits the rate threshold can drop from
//! 0.11 to 0.055 without letting clutter in: on the 17 LunarLoc traverses 21 more true
//! positives for 30 more false positives, F1 0.646 → 0.653 (4-sector cross-validated
//! 0.644 → 0.648; BENCHMARKS.md).
//!
//! The heading and cadence of a LunarLoc traverse's detection frames come from
//! [`traverse_views`](mod@super::traverse_views).

use super::check_numbers;
use super::lander_structure::{lander_ground_from, LanderStructureConfig};
use super::traverse_views::traverse_views;
use crate::field_error::FieldError;
use crate::landmarks::{view_bias, FusionConfig};
use nalgebra::{Point2, Point3};
use rayon::prelude::*;
use segloc_maps::{DetectionSet, LacGrid, Traverse};
use serde::{Deserialize, Serialize};

/// Parameters of the detection evidence grid (defaults tuned on the real LunarLoc
/// traverses by spatial cross-validation; see BENCHMARKS.md).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RockEvidenceConfig {
    /// Detections and views nearer than this (m, horizontal) are ignored.
    pub min_range_m: f64,
    /// Detections and views farther than this (m, horizontal) are ignored.
    pub max_range_m: f64,
    /// Half the camera's horizontal field of view used for views (degrees).
    pub half_fov_deg: f64,
    /// Exponent of the range weighting of a view.
    pub range_exponent: f64,
    /// Range (m) at which a view weighs 1.
    pub reference_range_m: f64,
    /// A rock cell needs at least this many detections.
    pub min_hits: u32,
    /// A rock cell needs at least this many detections per unit of exposure.
    pub min_rate: f64,
    /// Only the *repeated* detections of a cell count towards `min_hits` and `min_rate`:
    /// those within this distance (m, horizontal) of the cell's median vote. A boulder's
    /// face comes back to the same place view after view; shadows and terrain scatter over
    /// the cell. 0: every detection in the cell counts.
    pub repeat_radius_m: f64,
    /// Heading from the motion between this many frames before and after (traverses).
    pub heading_window_frames: usize,
    /// Motion (m) below which the heading comes from the detections instead.
    pub min_heading_motion_m: f64,
    /// Viewpoint bias (m): each detection is pushed this far away from its rover along the
    /// horizontal line of sight before it votes (0 = no correction). Unset (omitted from
    /// the TOML), [`RockEvidence::from_traverses`] estimates it from the traverses
    /// ([`view_bias::estimate_view_bias`], the median over boulders seen from several
    /// sides) and a bare [`RockEvidence::new`] uses 0.
    pub view_bias_m: Option<f64>,
    /// Detections on the lander's own structure, which do not vote
    /// ([`lander_structure`](super::lander_structure)).
    pub lander: LanderStructureConfig,
}

impl Default for RockEvidenceConfig {
    fn default() -> Self {
        Self {
            min_range_m: 1.4,
            max_range_m: 6.0,
            half_fov_deg: 30.0,
            range_exponent: 3.0,
            reference_range_m: 2.0,
            min_hits: 2,
            min_rate: 0.055,
            repeat_radius_m: 0.01,
            heading_window_frames: 20,
            min_heading_motion_m: 0.1,
            view_bias_m: None,
            lander: LanderStructureConfig::default(),
        }
    }
}

impl RockEvidenceConfig {
    /// Check every field: a message naming the first bad one.
    pub fn validate(&self) -> Result<(), FieldError> {
        check_numbers(
            &[
                ("max_range_m", self.max_range_m),
                ("half_fov_deg", self.half_fov_deg),
                ("reference_range_m", self.reference_range_m),
            ],
            true,
        )?;
        check_numbers(
            &[
                ("min_range_m", self.min_range_m),
                ("range_exponent", self.range_exponent),
                ("min_rate", self.min_rate),
                ("repeat_radius_m", self.repeat_radius_m),
                ("min_heading_motion_m", self.min_heading_motion_m),
            ],
            false,
        )?;
        if self.min_range_m >= self.max_range_m {
            return Err(FieldError::new(
                "min_range_m",
                format!(
                    "({}) must be below max_range_m ({})",
                    self.min_range_m, self.max_range_m
                ),
            ));
        }
        if let Some(b) = self.view_bias_m {
            if !(b.is_finite() && b.abs() <= 0.5) {
                return Err(FieldError::new(
                    "view_bias_m",
                    format!("must be a number within ±0.5 m, got {b}"),
                ));
            }
        }
        self.lander.validate()
    }

    /// This configuration with the viewpoint bias set: the configured one, or else the
    /// estimate from `traverses` (0 when no boulder is seen by two of them).
    pub fn with_view_bias_from(&self, traverses: &[Traverse]) -> Self {
        let bias = self.view_bias_m.unwrap_or_else(|| {
            let sets: Vec<DetectionSet> = traverses.iter().map(Traverse::detections).collect();
            view_bias::estimate_view_bias(&sets, &FusionConfig::default()).map_or(0.0, |b| b.bias_m)
        });
        Self {
            view_bias_m: Some(bias),
            ..self.clone()
        }
    }

    /// This configuration with the lander's ground height set: the configured one, or
    /// else the estimate from the rover heights of `traverses` near the lander (left unset,
    /// and the lander test off, when none came near).
    pub fn with_lander_ground_from(&self, traverses: &[Traverse]) -> Self {
        let mut out = self.clone();
        if out.lander.ground_z_m.is_none() && out.lander.half_extent_m > 0.0 {
            out.lander.ground_z_m = lander_ground_from(traverses, &out.lander).map(|(z, _)| z);
        }
        out
    }
}

/// Hits and exposure per cell of a grid.
#[derive(Clone, Debug, PartialEq)]
pub struct RockEvidence {
    /// The grid geometry (heights unfilled, rocks unset).
    pub geometry: LacGrid,
    /// Detections per cell, at [`LacGrid::index`].
    pub hits: Vec<f64>,
    /// Where each cell's detections voted (world x, y after the viewpoint-bias
    /// correction), at [`LacGrid::index`].
    votes: Vec<Vec<Point2<f64>>>,
    /// Range-weighted views per cell, at [`LacGrid::index`].
    pub exposure: Vec<f64>,
    /// Views (detection frames) accumulated.
    pub views: usize,
    /// Detections dropped as the lander's own structure.
    pub lander_structure: usize,
    config: RockEvidenceConfig,
}

impl RockEvidence {
    /// Empty evidence on the geometry of `grid`.
    pub fn new(grid: &LacGrid, config: &RockEvidenceConfig) -> Self {
        let n = grid.num_cells();
        RockEvidence {
            geometry: LacGrid::new(grid.cells_per_side, grid.cell_size_m),
            hits: vec![0.0; n],
            votes: vec![Vec::new(); n],
            exposure: vec![0.0; n],
            views: 0,
            lander_structure: 0,
            config: config.clone(),
        }
    }

    /// The configuration in use.
    pub fn config(&self) -> &RockEvidenceConfig {
        &self.config
    }

    /// Add one detection frame: the rover at `rover_world` looking along `heading_rad`
    /// (world frame, from +x towards +y), and the boulder centroids it detected.
    pub fn add_view(
        &mut self,
        rover_world: &Point3<f64>,
        heading_rad: f64,
        detections_world: &[Point3<f64>],
    ) {
        let c = &self.config;
        if !(rover_world.x.is_finite() && rover_world.y.is_finite() && heading_rad.is_finite()) {
            return;
        }
        self.views += 1;
        let (r_min, r_max) = (c.min_range_m, c.max_range_m);
        let bias = c.view_bias_m.unwrap_or(0.0);
        for d in detections_world {
            let sight = d.xy() - rover_world.xy();
            let range = sight.norm();
            if range < r_min || range > r_max {
                continue;
            }
            if c.lander.is_structure(d) {
                self.lander_structure += 1;
                continue;
            }
            let centre = d.xy() + sight * (bias / range);
            if let Some((i, j)) = self.geometry.cell_of(centre.x, centre.y) {
                let k = self.geometry.index(i, j);
                self.hits[k] += 1.0;
                self.votes[k].push(centre);
            }
        }
        let g = &self.geometry;
        let n = g.cells_per_side;
        let half = g.half_extent_m();
        let size = g.cell_size_m;
        let cos_fov = c.half_fov_deg.to_radians().cos();
        let (ux, uy) = (heading_rad.cos(), heading_rad.sin());
        let span = |v: f64| -> (usize, usize) {
            let lo = ((v - r_max + half) / size).floor().max(0.0);
            let hi = ((v + r_max + half) / size).floor().min(n as f64 - 1.0);
            if hi < 0.0 || lo > n as f64 - 1.0 || lo > hi {
                (1, 0)
            } else {
                (lo as usize, hi as usize)
            }
        };
        let (i0, i1) = span(rover_world.x);
        let (j0, j1) = span(rover_world.y);
        let (r_min2, r_max2) = (r_min * r_min, r_max * r_max);
        let half_exp = c.range_exponent / 2.0;
        let ref2 = c.reference_range_m * c.reference_range_m;
        for i in i0..=i1 {
            let dx = g.cell_center(i, 0).0 - rover_world.x;
            for j in j0..=j1 {
                let dy = g.cell_center(0, j).1 - rover_world.y;
                let r2 = dx * dx + dy * dy;
                if r2 < r_min2 || r2 > r_max2 {
                    continue;
                }
                let along = dx * ux + dy * uy;
                if along < cos_fov * r2.sqrt() {
                    continue;
                }
                self.exposure[i * n + j] += (ref2 / r2).powf(half_exp);
            }
        }
    }

    /// Add every detection frame of a LunarLoc traverse (see the module docs for the
    /// heading and the cadence).
    pub fn add_traverse(&mut self, traverse: &Traverse) {
        for (rover, heading, detections) in traverse_views(traverse, &self.config) {
            self.add_view(&rover, heading, &detections);
        }
    }

    /// Evidence from many traverses, one thread per traverse, with the viewpoint bias and
    /// the lander's ground height estimated from them unless `config` sets them
    /// ([`RockEvidenceConfig::with_view_bias_from`],
    /// [`RockEvidenceConfig::with_lander_ground_from`]; [`RockEvidence::config`] then
    /// holds the values used).
    pub fn from_traverses(
        grid: &LacGrid,
        traverses: &[Traverse],
        config: &RockEvidenceConfig,
    ) -> Self {
        let config = &config
            .with_view_bias_from(traverses)
            .with_lander_ground_from(traverses);
        traverses
            .par_iter()
            .map(|t| {
                let mut e = RockEvidence::new(grid, config);
                e.add_traverse(t);
                e
            })
            .reduce(
                || RockEvidence::new(grid, config),
                |mut a, b| {
                    a.merge(&b);
                    a
                },
            )
    }

    /// Add another evidence grid of the same geometry (cells are matched by index).
    pub fn merge(&mut self, other: &RockEvidence) {
        for (a, b) in self.hits.iter_mut().zip(&other.hits) {
            *a += b;
        }
        for (a, b) in self.votes.iter_mut().zip(&other.votes) {
            a.extend_from_slice(b);
        }
        for (a, b) in self.exposure.iter_mut().zip(&other.exposure) {
            *a += b;
        }
        self.views += other.views;
        self.lander_structure += other.lander_structure;
    }

    /// Where the detections of cell `k` voted (world x, y).
    pub fn votes(&self, k: usize) -> &[Point2<f64>] {
        &self.votes[k]
    }

    /// The repeated detections of cell `k`: those within `repeat_radius_m` of the cell's
    /// median vote (each coordinate's median), or all of them when the radius is 0.
    pub fn repeated_hits(&self, k: usize) -> f64 {
        let votes = &self.votes[k];
        let radius = self.config.repeat_radius_m;
        if radius <= 0.0 || votes.len() < 2 {
            return self.hits[k];
        }
        let centre = Point2::new(
            median(votes.iter().map(|p| p.x)),
            median(votes.iter().map(|p| p.y)),
        );
        votes
            .iter()
            .filter(|p| (*p - centre).norm() <= radius)
            .count() as f64
    }

    /// Repeated detections per unit of exposure of cell `k` (infinite with hits but no
    /// exposure).
    pub fn rate(&self, k: usize) -> f64 {
        self.rate_of(self.repeated_hits(k), k)
    }

    /// The repeated detections of every cell ([`RockEvidence::repeated_hits`]), at
    /// [`LacGrid::index`]: computed once for testing many thresholds.
    pub fn repeated_counts(&self) -> Vec<f64> {
        (0..self.hits.len())
            .map(|k| self.repeated_hits(k))
            .collect()
    }

    /// Whether cell `k` is a rock under `min_hits` and `min_rate` (both of its repeated
    /// detections).
    pub fn is_rock(&self, k: usize, min_hits: u32, min_rate: f64) -> bool {
        // repeated hits are at most the hits: skip the median when the hits fall short
        self.hits[k] >= min_hits as f64
            && self.is_rock_with(k, self.repeated_hits(k), min_hits, min_rate)
    }

    /// [`RockEvidence::is_rock`] with cell `k`'s repeated detections given (from
    /// [`RockEvidence::repeated_counts`]).
    pub fn is_rock_with(&self, k: usize, repeated: f64, min_hits: u32, min_rate: f64) -> bool {
        repeated >= min_hits as f64 && self.rate_of(repeated, k) >= min_rate
    }

    fn rate_of(&self, hits: f64, k: usize) -> f64 {
        let e = self.exposure[k];
        if hits == 0.0 {
            0.0
        } else if e > 0.0 {
            hits / e
        } else {
            f64::INFINITY
        }
    }

    /// The rock grid under the configured thresholds (heights unfilled).
    pub fn rock_grid(&self) -> LacGrid {
        self.rock_grid_with(self.config.min_hits, self.config.min_rate)
    }

    /// The rock grid under other thresholds (for tuning).
    pub fn rock_grid_with(&self, min_hits: u32, min_rate: f64) -> LacGrid {
        let mut grid = self.geometry.clone();
        for (k, repeated) in self.repeated_counts().into_iter().enumerate() {
            grid.rock[k] = self.is_rock_with(k, repeated, min_hits, min_rate);
        }
        grid
    }
}

/// The median of `values` (the mean of the middle two for an even count; 0 when empty).
fn median(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

#[cfg(test)]
mod tests {
    //! Tests of [`super`]: the evidence grid, repeated hits, the viewpoint bias, validation.
    use super::*;
    use segloc_maps::TraverseFrame;

    #[test]
    fn exposure_covers_the_view_wedge_only() {
        let grid = LacGrid::new(100, 0.15);
        let mut e = RockEvidence::new(&grid, &RockEvidenceConfig::default());
        e.add_view(&Point3::new(-5.0, 0.0, 0.0), 0.0, &[]);
        let at = |x: f64, y: f64| {
            let (i, j) = grid.cell_of(x, y).unwrap();
            e.exposure[grid.index(i, j)]
        };
        assert!((at(-3.0, 0.0) - 1.0).abs() < 0.2); // 2 m ahead: weight about 1
        assert!(at(-1.0, 0.0) > 0.0 && at(-1.0, 0.0) < 0.2); // 4 m: (2/4)^3
        assert_eq!(at(-7.0, 0.0), 0.0); // behind
        assert_eq!(at(-4.5, 0.0), 0.0); // too close
        assert_eq!(at(-3.0, 2.0), 0.0); // 45° off the heading
        assert_eq!(at(2.0, 0.0), 0.0); // too far
        assert_eq!(e.views, 1);
    }

    #[test]
    fn repeated_detections_make_a_rock_and_a_single_one_does_not() {
        let grid = LacGrid::new(100, 0.15);
        let mut e = RockEvidence::new(&grid, &RockEvidenceConfig::default());
        let rock = Point3::new(-3.0, 0.02, 0.1);
        let stray = Point3::new(-3.0, 0.5, 0.1);
        for k in 0..10 {
            let dets = if k == 3 {
                vec![rock, stray]
            } else {
                vec![rock]
            };
            e.add_view(&Point3::new(-5.0, 0.0, 0.0), 0.0, &dets);
        }
        let g = e.rock_grid();
        assert_eq!(g.rock_count(), 1);
        let (i, j) = grid.cell_of(rock.x, rock.y).unwrap();
        assert!(g.rock[grid.index(i, j)]);
        assert_eq!(g.filled_count(), 0);
    }

    #[test]
    fn only_repeated_hits_count() {
        let grid = LacGrid::new(100, 0.15);
        let config = RockEvidenceConfig {
            view_bias_m: Some(0.0),
            ..RockEvidenceConfig::default()
        };
        let mut e = RockEvidence::new(&grid, &config);
        let (x, y) = grid.cell_center(60, 50);
        let rover = Point3::new(x - 3.0, y, 0.0);
        // three detections of one face within a few millimetres, two scattered over the cell
        let dets = [
            (0.002, 0.0),
            (-0.001, 0.003),
            (0.0, -0.002),
            (0.05, 0.05),
            (-0.06, 0.04),
        ];
        for (dx, dy) in dets {
            e.add_view(&rover, 0.0, &[Point3::new(x + dx, y + dy, 0.1)]);
        }
        let k = grid.index(60, 50);
        assert_eq!(e.hits[k], 5.0);
        assert_eq!(e.votes(k).len(), 5);
        assert_eq!(e.repeated_hits(k), 3.0);
        assert!((e.rate(k) - 3.0 / e.exposure[k]).abs() < 1e-12);
        // without the repeat test every hit counts
        let all = RockEvidence {
            config: RockEvidenceConfig {
                repeat_radius_m: 0.0,
                ..config.clone()
            },
            ..e.clone()
        };
        assert_eq!(all.repeated_hits(k), 5.0);
        // a cell whose votes all scatter has no repeated pair beyond its median one
        let mut scattered = RockEvidence::new(&grid, &config);
        for (dx, dy) in [(0.05, 0.05), (-0.05, 0.0), (0.0, -0.06)] {
            scattered.add_view(&rover, 0.0, &[Point3::new(x + dx, y + dy, 0.1)]);
        }
        assert_eq!(scattered.repeated_hits(k), 0.0);
        assert!(!scattered.is_rock(k, 2, 0.0));
        assert!(e.is_rock(k, 2, 0.0) && !e.is_rock(k, 4, 0.0));
    }

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median([3.0, 1.0, 2.0].into_iter()), 2.0);
        assert_eq!(median([4.0, 1.0, 2.0, 3.0].into_iter()), 2.5);
        assert_eq!(median(std::iter::empty()), 0.0);
    }

    #[test]
    fn the_viewpoint_bias_moves_a_vote_back_along_the_line_of_sight() {
        let grid = LacGrid::new(100, 0.15);
        // a detection 1 cm in front of a cell edge, seen from 3 m along +x
        let (edge_x, _) = grid.cell_center(60, 50);
        let edge_x = edge_x + 0.075;
        let detection = Point3::new(edge_x - 0.01, 0.0, 0.1);
        let rover = Point3::new(edge_x - 3.0, 0.0, 0.0);
        let vote = |bias: Option<f64>| {
            let config = RockEvidenceConfig {
                view_bias_m: bias,
                ..RockEvidenceConfig::default()
            };
            let mut e = RockEvidence::new(&grid, &config);
            e.add_view(&rover, 0.0, &[detection]);
            let k = e.hits.iter().position(|&h| h > 0.0).unwrap();
            (k / grid.cells_per_side, k % grid.cells_per_side)
        };
        assert_eq!(vote(None), (60, 50));
        assert_eq!(vote(Some(0.0)), (60, 50));
        assert_eq!(vote(Some(0.02)), (61, 50)); // pushed 2 cm away from the rover
        assert_eq!(vote(Some(-0.1)), (60, 50));
    }

    #[test]
    fn the_viewpoint_bias_is_estimated_from_boulders_seen_from_both_sides() {
        // two traverses pass a row of boulders, one on each side; every detection lies
        // 1.5 cm in front of its boulder
        let boulders: Vec<Point3<f64>> = (0..20)
            .map(|k| Point3::new(0.5 * k as f64, 0.0, 0.1))
            .collect();
        let pass = |name: &str, side: f64| {
            let frames = (0..100u64)
                .map(|f| {
                    let rover = Point3::new(0.1 * f as f64, 3.0 * side, 0.0);
                    let seen = boulders
                        .iter()
                        .filter(|b| (b.xy() - rover.xy()).norm() < 5.0)
                        .map(|b| {
                            let u = (rover.xy() - b.xy()).normalize();
                            Point3::new(b.x + 0.015 * u.x, b.y + 0.015 * u.y, b.z)
                        })
                        .collect();
                    TraverseFrame {
                        frame: f,
                        rover_position: rover,
                        boulders: seen,
                    }
                })
                .collect();
            Traverse {
                name: name.into(),
                frames,
            }
        };
        let traverses = [pass("north", 1.0), pass("south", -1.0)];
        let config = RockEvidenceConfig::default().with_view_bias_from(&traverses);
        let bias = config.view_bias_m.unwrap();
        assert!((bias - 0.015).abs() < 0.002, "bias {bias}");
        let fixed = RockEvidenceConfig {
            view_bias_m: Some(0.0),
            ..RockEvidenceConfig::default()
        };
        assert_eq!(fixed.with_view_bias_from(&traverses).view_bias_m, Some(0.0));
        // one traverse: no boulder is seen by two, nothing to estimate from
        let one = RockEvidenceConfig::default().with_view_bias_from(&traverses[..1]);
        assert_eq!(one.view_bias_m, Some(0.0));
    }

    #[test]
    fn validate_names_the_bad_field() {
        assert!(RockEvidenceConfig::default().validate().is_ok());
        let bad = |c: RockEvidenceConfig| c.validate().unwrap_err().to_string();
        let d = RockEvidenceConfig::default;
        assert!(bad(RockEvidenceConfig {
            min_rate: -1.0,
            ..d()
        })
        .contains("min_rate"));
        assert!(bad(RockEvidenceConfig {
            max_range_m: f64::NAN,
            ..d()
        })
        .contains("max_range_m"));
        assert!(bad(RockEvidenceConfig {
            min_range_m: 7.0,
            ..d()
        })
        .contains("min_range_m"));
        let far = RockEvidenceConfig {
            view_bias_m: Some(2.0),
            ..d()
        };
        assert!(bad(far).contains("view_bias_m"));
    }
}
