//! The planner's obstacle memory: detected rocks (merged when detected again) and points
//! measured on the lander, in the session frame.
//!
//! A rock counts as *confirmed* once detected `min_hits` times. A rock detected fewer times
//! still counts, *tentatively*, until a camera has looked at its place `refute_after_views`
//! times (frames in which it lay well inside the field of view and near enough for a reliable
//! detection) without detecting it again. Spurious detections land on ground in view and are
//! refuted within a frame or two; a small half-buried rock glimpsed once and then beside the
//! rover (where neither camera looks) stays an obstacle instead of being forgotten.
//!
//! Size decides too: a rock counts only while a robust upper quantile of its measured radii
//! reaches the threshold, and detections measured a little smaller are sightings of it
//! (not misses). One generous measurement of a small rock no longer makes an obstacle of
//! it for good, and a rock at the threshold is not refuted by its own small measurements.

use crate::planning::Pose2;
use crate::spatial::GridIndex;
use nalgebra::{Isometry3, Point2, Point3};
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
    /// Detections made within `near_range_m` of the rover merge only within this distance,
    /// metres (0: `merge_radius_m` everywhere). Near stereo is precise to a centimetre or
    /// two, and two rocks 0.3 m apart are two obstacles: merged, the obstacle's running
    /// mean follows whichever of them was detected last, and the other one is lost (seed
    /// 128 of the mission drove onto a 0.093 m rock whose obstacle had wandered 0.24 m to
    /// a smaller neighbour while the rock itself sat below the image). Default 0.12
    /// (BENCHMARKS.md, "Misses only in the image").
    pub near_merge_radius_m: f64,
    /// See `near_merge_radius_m`, metres.
    pub near_range_m: f64,
    /// A detection merges into a rock only when its measured radius is within this factor
    /// of the rock's (either way); otherwise it is another rock (0: any size merges). The
    /// measured radius is noisy (15 %), but not by a factor of two: a 0.19 m rock whose
    /// detections landed, after 1.4 m of odometry drift, on the remembered place of a
    /// 0.05 m one merged into it, and the pair's radius stayed below the threshold (seed 77
    /// of the mission drove onto it). Default 2.
    pub merge_size_ratio: f64,
    /// Smallest weight of a new detection in an obstacle's position (the rest on the
    /// previous estimate).
    pub recent_weight: f64,
    /// A rock is confirmed once detected this many times (spurious detections rarely
    /// repeat); lander points count at once.
    pub min_hits: u32,
    /// An unconfirmed rock counts until it has been in view this many times without being
    /// detected; 0: unconfirmed rocks never count.
    pub refute_after_views: u32,
    /// A view counts against an unconfirmed rock only within this distance of the camera,
    /// metres (farther out the line of sight to a small half-buried rock grazes the terrain
    /// and misses it).
    pub refute_max_range_m: f64,
    /// … and only when the rock lies at least this far inside the field of view, radians.
    pub refute_fov_margin_rad: f64,
    /// … vertically too ([`ObstacleMemory::record_camera_view`]): a rock whose remembered
    /// centre lies below the image's lower edge (near the rover, in a dip, or with the rover
    /// pitched up on a slope) cannot be detected and is not missed. Without it, a rock
    /// detected once at 1.6–2 m counted a miss in the next frame, with its centre already
    /// below the image, was refuted, and the rover drove onto it (seeds 79, 104 and 119 of
    /// the mission; BENCHMARKS.md, "Misses only in the image").
    pub refute_within_image: bool,
    /// … at least this far inside the image's upper and lower edges, radians (the
    /// remembered height is precise to a centimetre or two near the rover; 0.1 measured
    /// alike, BENCHMARKS.md).
    pub refute_vertical_margin_rad: f64,
    /// A confirmed rock is dropped after this many views in a row (the same views as for
    /// `refute_after_views`) without being detected; 0 (the default): confirmed rocks are
    /// kept for good. The memory lives in the drifting odometry frame (unless the mission's
    /// `online_loop_closures` re-anchors it, [`ObstacleMemory::reanchor`]): a rock passed again
    /// minutes later can land more than `merge_radius_m` from its first copy, and the stale
    /// copies, never seen again where they are, fence the rover in (seed 14 of the mission
    /// drives 112 m in 600 s, 166 m with 3). On the mission's 20 seeds it raised the
    /// coverage but let the rover touch rocks on 3 of them (BENCHMARKS.md), so it is off.
    pub refute_confirmed_after_views: u32,
    /// … counting only the views at least this many frames after its last detection.
    pub stale_after_frames: u64,
    /// Detections measured smaller than the avoid threshold (`min_rock_radius_m` ×
    /// `radius_tolerance`) but at least this fraction of `min_rock_radius_m` count as
    /// *sightings* of a remembered rock they land within `merge_radius_m` of: a sighting
    /// is a detection (it confirms the rock and is no miss), and its radius joins the
    /// rock's measured radii (`size_quantile`). The measured radius is noisy (15 % in the
    /// simulation): a 0.085 m rock measured once at 0.104 m and then at 0.055–0.067 m was
    /// otherwise refuted by its own small sightings. 0: off (smaller detections are
    /// ignored). Default 0.5 (BENCHMARKS.md, "Obstacle sizes from their sightings").
    pub sighting_radius_fraction: f64,
    /// A rock's radius is this quantile of its measured radii (since it was last refuted),
    /// and it counts only while that reaches the threshold: 1 takes the largest (one
    /// generous measurement keeps a 0.06 m rock an obstacle for good), 0.5 the median (a
    /// small neighbour merged into the same obstacle drags a large rock's median below
    /// the threshold), in between a robust upper value. Default 0.75.
    pub size_quantile: f64,
    /// A refuted rock detected again within this many frames of its previous detection
    /// gets its earlier detections back (a rock in plain view missed once by chance, which
    /// a second detection then confirms); farther apart, the earlier ones stay forgotten,
    /// so spurious detections near one another over a long stay do not add up. 0: off.
    pub redetect_window_frames: u64,
    /// Unconfirmed rocks count only within this distance of the rover
    /// ([`ObstacleMemory::set_rover_position`]), metres: farther ones will be seen again (and
    /// confirmed or refuted) if the rover heads for them.
    pub unconfirmed_range_m: f64,
}

impl Default for ObstacleConfig {
    fn default() -> Self {
        Self {
            min_rock_radius_m: 0.08,
            radius_tolerance: 0.85,
            merge_radius_m: 0.3,
            near_merge_radius_m: 0.12,
            near_range_m: 2.5,
            merge_size_ratio: 2.0,
            min_hits: 2,
            recent_weight: 0.4,
            refute_after_views: 1,
            refute_max_range_m: 2.5,
            refute_fov_margin_rad: 0.1,
            refute_within_image: true,
            refute_vertical_margin_rad: 0.04,
            unconfirmed_range_m: 2.5,
            refute_confirmed_after_views: 0,
            stale_after_frames: 60,
            sighting_radius_fraction: 0.5,
            size_quantile: 0.75,
            redetect_window_frames: 0,
        }
    }
}

impl ObstacleConfig {
    /// Check the fields whose range is not already their type's: a message naming the
    /// first bad one.
    pub fn validate(&self) -> Result<(), String> {
        if !(0.0..=1.0).contains(&self.size_quantile) {
            return Err("obstacles.size_quantile must be within 0..1".into());
        }
        if !(0.0..=1.0).contains(&self.sighting_radius_fraction) {
            return Err("obstacles.sighting_radius_fraction must be within 0..1".into());
        }
        let non_negative = [
            (
                "refute_vertical_margin_rad",
                self.refute_vertical_margin_rad,
            ),
            ("near_merge_radius_m", self.near_merge_radius_m),
            ("near_range_m", self.near_range_m),
            ("merge_size_ratio", self.merge_size_ratio),
        ];
        for (name, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return Err(format!("obstacles.{name} must be finite and not negative"));
            }
        }
        Ok(())
    }
}

/// One remembered obstacle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Obstacle {
    /// Position, session frame (running mean of its detections), metres.
    pub p: Point2<f64>,
    /// Height of its centre, session frame (running mean of the detections that had one;
    /// NaN: none had), metres.
    pub z_m: f64,
    /// Radius to keep clear of, metres (the `size_quantile` of its measured radii).
    pub radius_m: f64,
    /// Number of detections merged in (since it was last refuted; 0: refuted).
    pub hits: u32,
    /// Views since the last detection in which it should have been detected and was not
    /// (unconfirmed rocks only; reset when it is refuted, with `hits`).
    pub misses: u32,
    /// The frame ([`ObstacleMemory::start_frame`]) of the latest detection.
    pub last_hit_frame: u64,
    /// Number of measured radii since it was last refuted (0: a lander point).
    pub sightings: u32,
    /// Detections it had when it was last refuted (restored by a prompt re-detection,
    /// `redetect_window_frames`).
    pub refuted_hits: u32,
}

/// The remembered obstacles.
#[derive(Clone, Debug)]
pub struct ObstacleMemory {
    config: ObstacleConfig,
    obstacles: Vec<Obstacle>,
    /// Each obstacle's measured radii since it was last refuted, metres.
    radii: Vec<Vec<f64>>,
    index: GridIndex,
    max_radius_m: f64,
    frame: u64,
    rover: Option<Point2<f64>>,
    /// Rocks known beforehand (a prior session's map placed in this memory's frame): they
    /// always count and are never refuted ([`ObstacleMemory::set_known_rocks`]).
    known: Vec<Obstacle>,
    known_index: GridIndex,
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
            radii: Vec::new(),
            index: GridIndex::new(1.0),
            max_radius_m: 0.0,
            frame: 0,
            rover: None,
            known: Vec::new(),
            known_index: GridIndex::new(1.0),
        }
    }

    /// Replace the rocks known beforehand: `(p, radius_m)` in this memory's (session)
    /// frame, e.g. a prior session's boulder map placed with the current relocalization.
    /// They count as obstacles whatever the cameras see (a rock below the image or behind
    /// a crest is still there) and are never refuted; rocks smaller than the avoid
    /// threshold and non-finite ones are left out. Returns how many were kept.
    pub fn set_known_rocks(&mut self, rocks: &[(Point2<f64>, f64)]) -> usize {
        let threshold = self.avoid_radius_m();
        self.known = rocks
            .iter()
            .filter(|(p, r)| p.x.is_finite() && p.y.is_finite() && r.is_finite())
            .filter(|(_, r)| *r >= threshold)
            .map(|&(p, radius_m)| Obstacle {
                p,
                z_m: f64::NAN,
                radius_m,
                hits: self.config.min_hits.max(1),
                misses: 0,
                last_hit_frame: 0,
                sightings: 1,
                refuted_hits: 0,
            })
            .collect();
        let mut index = GridIndex::new(1.0);
        for (id, o) in self.known.iter().enumerate() {
            index.insert(id as u32, &p3(&o.p));
            self.max_radius_m = self.max_radius_m.max(o.radius_m);
        }
        self.known_index = index;
        self.known.len()
    }

    /// The rocks known beforehand ([`ObstacleMemory::set_known_rocks`]).
    pub fn known_rocks(&self) -> &[Obstacle] {
        &self.known
    }

    /// Where the rover is now (session frame): unconfirmed rocks count only within
    /// `unconfirmed_range_m` of it. Until set, they count anywhere.
    pub fn set_rover_position(&mut self, p: Point2<f64>) {
        if p.x.is_finite() && p.y.is_finite() {
            self.rover = Some(p);
        }
    }

    /// Start a new camera frame: detections added from now on belong to it, and
    /// [`ObstacleMemory::record_view`] leaves them alone.
    pub fn start_frame(&mut self) {
        self.frame += 1;
    }

    /// Whether an obstacle counts: confirmed, or unconfirmed, not refuted (no hits left)
    /// and near the rover.
    fn counts(&self, o: &Obstacle) -> bool {
        if o.sightings > 0 && o.radius_m < self.avoid_radius_m() {
            return false;
        }
        o.hits >= self.config.min_hits
            || (self.config.refute_after_views > 0
                && o.hits > 0
                && self
                    .rover
                    .is_none_or(|r| (o.p - r).norm() <= self.config.unconfirmed_range_m))
    }

    /// A camera at `camera` (session frame, looking along its yaw) with half field of view
    /// `half_fov_rad` and nearest detection depth `min_depth_m` has looked: every
    /// unconfirmed rock well inside its view and within `refute_max_range_m` that was not
    /// detected in this frame counts one miss (and so does a confirmed rock not detected for
    /// `stale_after_frames`, when `refute_confirmed_after_views` is set). At
    /// `refute_after_views` (`refute_confirmed_after_views`) misses its
    /// detections are dropped (it is refuted): confirming it takes `min_hits` new ones, so
    /// spurious detections that happen to fall near each other over a long stay do not add
    /// up to an obstacle.
    pub fn record_view(&mut self, camera: Pose2, half_fov_rad: f64, min_depth_m: f64) {
        self.record_misses(camera, half_fov_rad, min_depth_m, |_| true);
    }

    /// [`ObstacleMemory::record_view`] for a camera with its full pose
    /// (`session_from_camera`: x along the optical axis, y left, z up) and a vertical half
    /// field of view: with `refute_within_image`, a rock with a remembered height counts a
    /// miss only when its centre lies inside the image vertically as well
    /// (`refute_vertical_margin_rad` from the edge) — a rock below the image's lower edge
    /// cannot be detected.
    pub fn record_camera_view(
        &mut self,
        session_from_camera: &Isometry3<f64>,
        half_fov_rad: f64,
        half_vertical_fov_rad: f64,
        min_depth_m: f64,
    ) {
        let camera = Pose2::from_isometry3(session_from_camera);
        let camera_from_session = session_from_camera.inverse();
        let max_tan = (half_vertical_fov_rad - self.config.refute_vertical_margin_rad).tan();
        let check = self.config.refute_within_image;
        self.record_misses(camera, half_fov_rad, min_depth_m, |o| {
            if !check || !o.z_m.is_finite() {
                return true;
            }
            let p_cam = camera_from_session * Point3::new(o.p.x, o.p.y, o.z_m);
            p_cam.x > 0.0 && p_cam.z.abs() <= max_tan * p_cam.x
        });
    }

    /// Count a miss for every rock in view (as `record_view` says) that `visible` also
    /// accepts.
    fn record_misses(
        &mut self,
        camera: Pose2,
        half_fov_rad: f64,
        min_depth_m: f64,
        visible: impl Fn(&Obstacle) -> bool,
    ) {
        let range = self.config.refute_max_range_m;
        if self.config.refute_after_views == 0
            || !camera.x.is_finite()
            || !camera.y.is_finite()
            || range.is_nan()
            || range <= 0.0
        {
            // no refutation: unconfirmed rocks keep their detections (and never count)
            return;
        }
        let c = Point2::new(camera.x, camera.y);
        let axis = nalgebra::Vector2::new(camera.yaw.cos(), camera.yaw.sin());
        let max_angle = half_fov_rad - self.config.refute_fov_margin_rad;
        let (frame, min_hits) = (self.frame, self.config.min_hits);
        let stale_after = self.config.refute_confirmed_after_views;
        let stale_age = self.config.stale_after_frames;
        let mut missed = Vec::new();
        self.index.for_each_near(&p3(&c), range, |id| {
            let o = &self.obstacles[id as usize];
            let confirmed = o.hits >= min_hits;
            // lander points (radius 0) are re-measured, not detected: left alone
            if (confirmed && (stale_after == 0 || o.radius_m <= 0.0))
                || o.hits == 0
                || o.last_hit_frame == frame
            {
                return;
            }
            // a confirmed rock counts a miss only when its last detection is old: a rock
            // detected on the way in is not dropped for a few frames without it
            if confirmed && frame.saturating_sub(o.last_hit_frame) < stale_age {
                return;
            }
            let to = o.p - c;
            let (dist, depth) = (to.norm(), to.dot(&axis));
            if dist <= range
                && depth >= min_depth_m
                && depth >= dist * max_angle.cos()
                && visible(o)
            {
                missed.push(id);
            }
        });
        for id in missed {
            let o = &mut self.obstacles[id as usize];
            o.misses += 1;
            let refute = if o.hits >= min_hits {
                stale_after
            } else {
                self.config.refute_after_views
            };
            if o.misses >= refute {
                o.refuted_hits = o.hits;
                o.hits = 0;
                o.misses = 0;
            }
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
        self.add_rock_at(Point3::new(p.x, p.y, f64::NAN), radius_m)
    }

    /// [`ObstacleMemory::add_rock`] with the detection's height (session frame; NaN:
    /// unknown), which [`ObstacleMemory::record_camera_view`] uses.
    pub fn add_rock_at(&mut self, p: Point3<f64>, radius_m: f64) -> bool {
        if radius_m.is_nan() {
            return false;
        }
        if radius_m >= self.avoid_radius_m() {
            return self.add(p, radius_m, 1, true);
        }
        // a smaller detection: only a sighting of a rock already remembered
        let floor = self.config.sighting_radius_fraction * self.config.min_rock_radius_m;
        floor > 0.0 && radius_m >= floor && self.add(p, radius_m, 1, false)
    }

    /// The measured radius from which a detection is a rock to avoid, metres.
    fn avoid_radius_m(&self) -> f64 {
        self.config.min_rock_radius_m * self.config.radius_tolerance
    }

    /// Remember a point measured on the lander (radius 0: the point itself is the obstacle).
    pub fn add_point(&mut self, p: Point2<f64>) -> bool {
        self.add(
            Point3::new(p.x, p.y, f64::NAN),
            0.0,
            self.config.min_hits.max(1),
            true,
        )
    }

    /// Merge a detection into the nearest remembered obstacle within `merge_radius_m`, or
    /// (when `may_start`) remember a new one.
    fn add(&mut self, p3d: Point3<f64>, radius_m: f64, hits: u32, may_start: bool) -> bool {
        let (p, z_m) = (p3d.xy(), p3d.z);
        if !p.x.is_finite() || !p.y.is_finite() || !radius_m.is_finite() {
            return false;
        }
        let near = self.config.near_merge_radius_m > 0.0
            && self
                .rover
                .is_some_and(|r| (p - r).norm() <= self.config.near_range_m);
        let merge = if near {
            self.config
                .near_merge_radius_m
                .min(self.config.merge_radius_m)
        } else {
            self.config.merge_radius_m
        };
        let ratio = self.config.merge_size_ratio;
        // a rock of very different size is another rock (lander points merge by place only)
        let same_size = |o: &Obstacle| {
            ratio <= 0.0
                || radius_m <= 0.0
                || o.radius_m <= 0.0
                || (radius_m <= ratio * o.radius_m && o.radius_m <= ratio * radius_m)
        };
        let mut nearest: Option<(u32, f64)> = None;
        self.index.for_each_near(&p3(&p), merge, |id| {
            let o = &self.obstacles[id as usize];
            let d = (o.p - p).norm();
            if d <= merge && same_size(o) && nearest.is_none_or(|(_, bd)| d < bd) {
                nearest = Some((id, d));
            }
        });
        let (frame, window) = (self.frame, self.config.redetect_window_frames);
        let quantile = self.config.size_quantile;
        // a sighting merges into a rock only (lander points have no sightings)
        let nearest =
            nearest.filter(|&(id, _)| may_start || self.obstacles[id as usize].sightings > 0);
        match nearest {
            Some((id, _)) => {
                let o = &mut self.obstacles[id as usize];
                let radii = &mut self.radii[id as usize];
                if o.hits == 0 && o.sightings > 0 {
                    // refuted: detected again promptly, it gets its detections back;
                    // otherwise it starts afresh
                    if window > 0 && frame.saturating_sub(o.last_hit_frame) <= window {
                        o.hits = o.refuted_hits;
                    } else {
                        radii.clear();
                        o.sightings = 0;
                        o.radius_m = 0.0;
                    }
                }
                let old = o.p;
                // running mean, but never weighting the newest detection below
                // `recent_weight`: odometry drifts, and the latest detection was made in the
                // frame the rover is driving in now
                let n = f64::from(o.hits);
                let w = (1.0 / (n + 1.0)).max(self.config.recent_weight);
                o.p = Point2::from(old.coords + (p.coords - old.coords) * w);
                if z_m.is_finite() {
                    o.z_m = if o.z_m.is_finite() {
                        o.z_m + (z_m - o.z_m) * w
                    } else {
                        z_m
                    };
                }
                o.hits += hits;
                o.misses = 0;
                o.last_hit_frame = frame;
                if radius_m > 0.0 {
                    radii.push(radius_m);
                    o.sightings += 1;
                    o.radius_m = quantile_of(radii, quantile);
                }
                let (old3, new3) = (p3(&old), p3(&o.p));
                self.index.relocate(id, &old3, &new3);
            }
            None if !may_start => return false,
            None => {
                self.index.insert(self.obstacles.len() as u32, &p3(&p));
                self.radii.push(if radius_m > 0.0 {
                    vec![radius_m]
                } else {
                    Vec::new()
                });
                self.obstacles.push(Obstacle {
                    p,
                    z_m,
                    radius_m,
                    hits,
                    misses: 0,
                    last_hit_frame: frame,
                    sightings: u32::from(radius_m > 0.0),
                    refuted_hits: 0,
                });
            }
        }
        self.max_radius_m = self.max_radius_m.max(radius_m);
        true
    }

    /// Move every obstacle to `moved(last_hit_frame, p)`: the planner's frame was corrected
    /// (a loop closure), and each obstacle moves as the pose of the frame that last
    /// detected it. Non-finite results leave an obstacle where it was.
    pub fn reanchor(&mut self, mut moved: impl FnMut(u64, Point2<f64>) -> Point2<f64>) {
        let mut index = GridIndex::new(1.0);
        for (id, o) in self.obstacles.iter_mut().enumerate() {
            let p = moved(o.last_hit_frame, o.p);
            if p.x.is_finite() && p.y.is_finite() {
                o.p = p;
            }
            index.insert(id as u32, &p3(&o.p));
        }
        self.index = index;
    }

    /// Calls `visit` for every obstacle that counts (confirmed, or unconfirmed and not
    /// refuted, and the rocks known beforehand) within `radius_m` of `p` (centre distance).
    pub fn for_each_near(&self, p: Point2<f64>, radius_m: f64, mut visit: impl FnMut(&Obstacle)) {
        self.index.for_each_near(&p3(&p), radius_m, |id| {
            let o = &self.obstacles[id as usize];
            if self.counts(o) && (o.p - p).norm() <= radius_m {
                visit(o);
            }
        });
        self.known_index.for_each_near(&p3(&p), radius_m, |id| {
            let o = &self.known[id as usize];
            if (o.p - p).norm() <= radius_m {
                visit(o);
            }
        });
    }
}

/// The `q` quantile (0–1, nearest rank) of `values`; 0 when empty.
fn quantile_of(values: &[f64], q: f64) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let Some(last) = sorted.len().checked_sub(1) else {
        return 0.0;
    };
    let k = (q.clamp(0.0, 1.0) * last as f64).round() as usize;
    sorted[k.min(last)]
}

#[cfg(test)]
#[path = "obstacles_tests.rs"]
mod tests;
