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

use crate::field_error::FieldError;
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
    /// metres (0: `merge_radius_m` everywhere). Default 0.12; why: docs/design/obstacle-memory.md.
    pub near_merge_radius_m: f64,
    /// See `near_merge_radius_m`, metres.
    pub near_range_m: f64,
    /// A detection merges into a rock only when its measured radius is within this factor
    /// of the rock's (either way); otherwise it is another rock (0: any size merges).
    /// Default 2; why: docs/design/obstacle-memory.md.
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
    /// centre lies below the image's lower edge cannot be detected and is not missed
    /// (docs/design/obstacle-memory.md).
    pub refute_within_image: bool,
    /// … at least this far inside the image's upper and lower edges, radians.
    pub refute_vertical_margin_rad: f64,
    /// A confirmed rock is dropped after this many views in a row (the same views as for
    /// `refute_after_views`) without being detected; 0 (the default): confirmed rocks are
    /// kept for good (why: docs/design/obstacle-memory.md; see also
    /// [`ObstacleMemory::reanchor`]).
    pub refute_confirmed_after_views: u32,
    /// … counting only the views at least this many frames after its last detection.
    pub stale_after_frames: u64,
    /// Detections measured smaller than the avoid threshold (`min_rock_radius_m` ×
    /// `radius_tolerance`) but at least this fraction of `min_rock_radius_m` count as
    /// *sightings* of a remembered rock they land within `merge_radius_m` of: a sighting
    /// is a detection (it confirms the rock and is no miss), and its radius joins the
    /// rock's measured radii (`size_quantile`). 0: off (smaller detections are ignored).
    /// Default 0.5 (docs/design/obstacle-memory.md).
    pub sighting_radius_fraction: f64,
    /// A rock's radius is this quantile of its measured radii (since it was last refuted),
    /// and it counts only while that reaches the threshold: 1 the largest, 0.5 the median.
    /// Default 0.75 (docs/design/obstacle-memory.md).
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
    pub fn validate(&self) -> Result<(), FieldError> {
        if !(0.0..=1.0).contains(&self.size_quantile) {
            return Err(FieldError::new(
                "obstacles.size_quantile",
                "must be within 0..1",
            ));
        }
        if !(0.0..=1.0).contains(&self.sighting_radius_fraction) {
            return Err(FieldError::new(
                "obstacles.sighting_radius_fraction",
                "must be within 0..1",
            ));
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
                return Err(FieldError::new(
                    format!("obstacles.{name}"),
                    "must be finite and not negative",
                ));
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
        let merge = self.merge_radius_at(p);
        let nearest = self.nearest_same_size(p, radius_m, merge);
        // a sighting merges into a rock only (lander points have no sightings)
        let nearest =
            nearest.filter(|&(id, _)| may_start || self.obstacles[id as usize].sightings > 0);
        match nearest {
            Some((id, _)) => self.merge_into(id, p, z_m, radius_m, hits),
            None if !may_start => return false,
            None => self.start_obstacle(p, z_m, radius_m, hits),
        }
        self.max_radius_m = self.max_radius_m.max(radius_m);
        true
    }

    /// How far from a remembered obstacle a detection at `p` merges into it, metres
    /// (`near_merge_radius_m` near the rover).
    fn merge_radius_at(&self, p: Point2<f64>) -> f64 {
        let near = self.config.near_merge_radius_m > 0.0
            && self
                .rover
                .is_some_and(|r| (p - r).norm() <= self.config.near_range_m);
        if near {
            self.config
                .near_merge_radius_m
                .min(self.config.merge_radius_m)
        } else {
            self.config.merge_radius_m
        }
    }

    /// The nearest remembered obstacle within `merge` of `p` whose size fits `radius_m`
    /// (`merge_size_ratio`), and its distance.
    fn nearest_same_size(&self, p: Point2<f64>, radius_m: f64, merge: f64) -> Option<(u32, f64)> {
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
        nearest
    }

    /// Merge a detection at `p` (height `z_m`, measured `radius_m`, worth `hits`) into
    /// obstacle `id`: a running mean of its position, and its radii's quantile.
    fn merge_into(&mut self, id: u32, p: Point2<f64>, z_m: f64, radius_m: f64, hits: u32) {
        let (frame, window) = (self.frame, self.config.redetect_window_frames);
        let quantile = self.config.size_quantile;
        let o = &mut self.obstacles[id as usize];
        let radii = &mut self.radii[id as usize];
        if o.hits == 0 && o.sightings > 0 {
            reopen_refuted(o, radii, frame, window);
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

    /// Remember a new obstacle detected at `p` (height `z_m`, measured `radius_m`, worth
    /// `hits`).
    fn start_obstacle(&mut self, p: Point2<f64>, z_m: f64, radius_m: f64, hits: u32) {
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
            last_hit_frame: self.frame,
            sightings: u32::from(radius_m > 0.0),
            refuted_hits: 0,
        });
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

/// A refuted rock (`o`, its measured `radii`) detected again in `frame`: within `window`
/// frames of its last detection it gets its detections back; otherwise it starts afresh.
fn reopen_refuted(o: &mut Obstacle, radii: &mut Vec<f64>, frame: u64, window: u64) {
    if window > 0 && frame.saturating_sub(o.last_hit_frame) <= window {
        o.hits = o.refuted_hits;
    } else {
        radii.clear();
        o.sightings = 0;
        o.radius_m = 0.0;
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
mod tests {
    //! Tests of the obstacle memory.

    use super::*;

    #[test]
    fn reanchoring_moves_each_obstacle_with_its_frame() {
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        m.start_frame();
        m.add_rock(Point2::new(1.0, 0.0), 0.2);
        m.start_frame();
        m.add_rock(Point2::new(5.0, 0.0), 0.2);
        // frame 2's pose was 0.3 m off in y; frame 1's was right
        m.reanchor(|frame, p| {
            if frame == 2 {
                Point2::new(p.x, p.y + 0.3)
            } else {
                p
            }
        });
        assert_eq!(m.obstacles()[0].p, Point2::new(1.0, 0.0));
        assert_eq!(m.obstacles()[1].p, Point2::new(5.0, 0.3));
        // the index follows: a detection at the new place merges
        m.start_frame();
        m.add_rock(Point2::new(5.0, 0.31), 0.2);
        assert_eq!(m.obstacles().len(), 2);
    }

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
        // the merged rock, the lander point and the (unconfirmed, unrefuted) new rock
        let mut seen = 0;
        m.for_each_near(Point2::new(2.0, 0.5), 1.5, |_| seen += 1);
        assert_eq!(seen, 3);
    }

    #[test]
    fn stale_confirmed_rocks_are_dropped_only_when_asked() {
        let config = ObstacleConfig {
            refute_confirmed_after_views: 2,
            stale_after_frames: 10,
            ..ObstacleConfig::default()
        };
        let rock = Point2::new(2.0, 0.0);
        let look = |m: &mut ObstacleMemory, frames: usize| {
            for _ in 0..frames {
                m.start_frame();
                m.record_view(Pose2::new(0.5, 0.0, 0.0), 0.6, 0.5);
            }
        };
        for (config, kept) in [(config.clone(), false), (ObstacleConfig::default(), true)] {
            let mut m = ObstacleMemory::new(&config);
            m.start_frame();
            m.add_rock(rock, 0.1);
            m.start_frame();
            m.add_rock(rock, 0.1);
            // recently detected: views without it do not count yet
            look(&mut m, 9);
            assert_eq!(count_near(&m, rock), 1);
            assert_eq!(m.obstacles()[0].misses, 0);
            // old and in view twice without a detection: a stale copy, dropped
            look(&mut m, 2);
            assert_eq!(count_near(&m, rock), usize::from(kept));
        }
        // lander points are never dropped
        let mut m = ObstacleMemory::new(&config);
        m.add_point(rock);
        look(&mut m, 30);
        assert_eq!(count_near(&m, rock), 1);
    }

    fn count_near(m: &ObstacleMemory, p: Point2<f64>) -> usize {
        let mut n = 0;
        m.for_each_near(p, 0.5, |_| n += 1);
        n
    }

    #[test]
    fn unconfirmed_rocks_count_until_refuted_by_views() {
        let mut m = ObstacleMemory::new(&ObstacleConfig {
            refute_after_views: 2,
            ..ObstacleConfig::default()
        });
        let half_fov = 0.6;
        m.start_frame();
        let rock = Point2::new(2.0, 0.0);
        assert!(m.add_rock(rock, 0.1));
        // the frame that detected it does not count against it
        m.record_view(Pose2::new(0.0, 0.0, 0.0), half_fov, 0.5);
        assert_eq!(count_near(&m, rock), 1);
        // beside the camera, too far, or too near: no evidence
        m.start_frame();
        m.record_view(Pose2::new(0.0, 0.0, 1.2), half_fov, 0.5);
        m.record_view(Pose2::new(-1.0, 0.0, 0.0), half_fov, 0.5);
        m.record_view(Pose2::new(1.7, 0.0, 0.0), half_fov, 0.5);
        assert_eq!(m.obstacles()[0].misses, 0);
        // two views straight at it without a detection: refuted
        m.record_view(Pose2::new(0.5, 0.0, 0.0), half_fov, 0.5);
        assert_eq!(count_near(&m, rock), 1);
        m.start_frame();
        m.record_view(Pose2::new(0.5, 0.0, 0.0), half_fov, 0.5);
        assert_eq!(count_near(&m, rock), 0);
        // detected again: unconfirmed again (the refuted detection is gone), until a second
        // detection confirms it for good
        m.start_frame();
        assert!(m.add_rock(rock, 0.1));
        assert_eq!(m.obstacles()[0].hits, 1);
        assert_eq!(count_near(&m, rock), 1);
        m.start_frame();
        assert!(m.add_rock(rock, 0.1));
        for _ in 0..3 {
            m.start_frame();
            m.record_view(Pose2::new(0.5, 0.0, 0.0), half_fov, 0.5);
        }
        assert_eq!(count_near(&m, rock), 1);
        // unconfirmed rocks far from the rover do not count
        m.start_frame();
        let far = Point2::new(-3.0, 0.0);
        assert!(m.add_rock(far, 0.1));
        assert_eq!(count_near(&m, far), 1);
        m.set_rover_position(Point2::new(0.0, 0.0));
        assert_eq!(count_near(&m, far), 0);
        m.set_rover_position(Point2::new(-1.0, 0.0));
        assert_eq!(count_near(&m, far), 1);
        // without refutation, unconfirmed rocks never count
        let mut old = ObstacleMemory::new(&ObstacleConfig {
            refute_after_views: 0,
            ..ObstacleConfig::default()
        });
        old.start_frame();
        assert!(old.add_rock(rock, 0.1));
        assert_eq!(count_near(&old, rock), 0);
        // … and are not refuted: a second detection after a view confirms them
        old.start_frame();
        old.record_view(Pose2::new(0.5, 0.0, 0.0), half_fov, 0.5);
        old.start_frame();
        assert!(old.add_rock(rock, 0.1));
        assert_eq!(count_near(&old, rock), 1);
    }

    #[test]
    fn small_sightings_keep_a_rock_and_its_size_is_a_quantile() {
        let config = ObstacleConfig {
            sighting_radius_fraction: 0.5,
            size_quantile: 0.75,
            ..ObstacleConfig::default()
        };
        let rock = Point2::new(2.0, 0.0);
        let camera = Pose2::new(0.5, 0.0, 0.0);
        // a 0.085 m rock measured large once, then small: the small sightings are detections,
        // not misses, and confirm it
        let mut m = ObstacleMemory::new(&config);
        m.start_frame();
        assert!(m.add_rock(rock, 0.104));
        for r in [0.066, 0.08, 0.09] {
            m.start_frame();
            assert!(m.add_rock(rock, r));
            m.record_view(camera, 0.6, 0.5);
        }
        let o = m.obstacles()[0];
        assert_eq!((o.hits, o.misses, o.sightings), (4, 0, 4));
        // nearest rank 0.75 of [0.066, 0.08, 0.09, 0.104]
        assert!((o.radius_m - 0.09).abs() < 1e-12);
        assert_eq!(count_near(&m, rock), 1);
        // a small detection starts nothing on its own
        m.start_frame();
        assert!(!m.add_rock(Point2::new(-3.0, 0.0), 0.06));
        assert!(!m.add_rock(Point2::new(2.05, 0.0), 0.03));
        assert_eq!(m.obstacles().len(), 1);
        // a small rock measured large once and small since stops counting
        let mut m = ObstacleMemory::new(&config);
        m.start_frame();
        assert!(m.add_rock(rock, 0.07));
        for r in [0.05, 0.055, 0.06] {
            m.start_frame();
            assert!(m.add_rock(rock, r));
        }
        assert_eq!(count_near(&m, rock), 0);
        // without sightings small detections are ignored, and they are misses
        let mut old = ObstacleMemory::new(&ObstacleConfig {
            sighting_radius_fraction: 0.0,
            size_quantile: 1.0,
            ..ObstacleConfig::default()
        });
        old.start_frame();
        assert!(old.add_rock(rock, 0.104));
        old.start_frame();
        assert!(!old.add_rock(rock, 0.06));
        old.record_view(camera, 0.6, 0.5);
        assert_eq!(count_near(&old, rock), 0);
    }

    #[test]
    fn a_prompt_redetection_restores_the_detections() {
        let rock = Point2::new(2.0, 0.0);
        let camera = Pose2::new(0.5, 0.0, 0.0);
        let detect_miss_detect = |window: u64, gap: usize| {
            let mut m = ObstacleMemory::new(&ObstacleConfig {
                redetect_window_frames: window,
                ..ObstacleConfig::default()
            });
            m.start_frame();
            m.add_rock(rock, 0.1);
            for _ in 0..gap {
                m.start_frame();
                m.record_view(camera, 0.6, 0.5);
            }
            assert_eq!(count_near(&m, rock), 0, "refuted by the views");
            m.start_frame();
            m.add_rock(rock, 0.1);
            m.obstacles()[0].hits
        };
        // within the window the earlier detection comes back and confirms the rock
        assert_eq!(detect_miss_detect(5, 1), 2);
        // too late, or without the window: it starts afresh
        assert_eq!(detect_miss_detect(5, 8), 1);
        assert_eq!(detect_miss_detect(0, 1), 1);
    }

    #[test]
    fn a_rock_below_the_image_is_not_missed() {
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        m.start_frame();
        // a rock on the ground (centre 0.05 m up) detected once, 2 m ahead of a camera 0.3 m up
        let rock = Point3::new(2.0, 0.0, 0.05);
        assert!(m.add_rock_at(rock, 0.1));
        let camera_at = |x: f64| Isometry3::translation(x, 0.0, 0.3);
        let (half_fov, half_vertical_fov) = (0.61, 0.375);
        // 0.6 m away its centre lies 22° below the axis, below the image (21.5° half field of
        // view): no miss, it stays an obstacle
        m.start_frame();
        m.record_camera_view(&camera_at(1.4), half_fov, half_vertical_fov, 0.5);
        assert_eq!(m.obstacles()[0].misses, 0);
        assert_eq!(count_near(&m, rock.xy()), 1);
        // 1.5 m away it is well inside the image: a miss refutes it
        m.start_frame();
        m.record_camera_view(&camera_at(0.5), half_fov, half_vertical_fov, 0.5);
        assert_eq!(count_near(&m, rock.xy()), 0);
        // without the check, the first view had refuted it already
        let mut flat = ObstacleMemory::new(&ObstacleConfig {
            refute_within_image: false,
            ..ObstacleConfig::default()
        });
        flat.start_frame();
        assert!(flat.add_rock_at(rock, 0.1));
        flat.start_frame();
        flat.record_camera_view(&camera_at(1.4), half_fov, half_vertical_fov, 0.5);
        assert_eq!(count_near(&flat, rock.xy()), 0);
    }

    #[test]
    fn near_detections_merge_only_when_close() {
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        m.set_rover_position(Point2::new(0.0, 0.0));
        m.start_frame();
        // two rocks 0.25 m apart, 1 m from the rover: two obstacles that stay where they are
        assert!(m.add_rock(Point2::new(1.0, 0.0), 0.1));
        assert!(m.add_rock(Point2::new(1.0, 0.25), 0.1));
        m.start_frame();
        assert!(m.add_rock(Point2::new(1.0, 0.26), 0.1));
        assert_eq!(m.obstacles().len(), 2);
        assert_eq!(m.obstacles()[0].p, Point2::new(1.0, 0.0));
        // far from the rover the usual radius applies
        m.add_rock(Point2::new(5.0, 0.0), 0.1);
        m.add_rock(Point2::new(5.0, 0.25), 0.1);
        assert_eq!(m.obstacles().len(), 3);
        // without it, the near pair is one obstacle that wanders between the two
        let mut merged = ObstacleMemory::new(&ObstacleConfig {
            near_merge_radius_m: 0.0,
            ..ObstacleConfig::default()
        });
        merged.set_rover_position(Point2::new(0.0, 0.0));
        merged.add_rock(Point2::new(1.0, 0.0), 0.1);
        merged.add_rock(Point2::new(1.0, 0.25), 0.1);
        assert_eq!(merged.obstacles().len(), 1);
        assert!(merged.obstacles()[0].p.y > 0.1);
    }

    #[test]
    fn a_rock_of_another_size_is_another_rock() {
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        m.set_rover_position(Point2::new(0.0, 0.0));
        m.start_frame();
        // a small rock 5 m away, twice
        assert!(m.add_rock(Point2::new(5.0, 0.0), 0.07));
        assert!(m.add_rock(Point2::new(5.0, 0.0), 0.07));
        // a detection three times larger 0.2 m from it is a second rock ...
        m.start_frame();
        assert!(m.add_rock(Point2::new(5.0, 0.2), 0.21));
        assert_eq!(m.obstacles().len(), 2);
        assert_eq!(m.obstacles()[0].radius_m, 0.07);
        // ... and one of a similar size is the small rock again
        assert!(m.add_rock(Point2::new(5.0, 0.05), 0.1));
        assert_eq!(m.obstacles().len(), 2);
        assert_eq!(m.obstacles()[0].hits, 3);
        // any size merges when asked
        let mut any = ObstacleMemory::new(&ObstacleConfig {
            merge_size_ratio: 0.0,
            ..ObstacleConfig::default()
        });
        any.add_rock(Point2::new(5.0, 0.0), 0.07);
        any.add_rock(Point2::new(5.0, 0.2), 0.21);
        assert_eq!(any.obstacles().len(), 1);
    }

    #[test]
    fn known_rocks_count_until_replaced_and_are_never_refuted() {
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        let kept = m.set_known_rocks(&[
            (Point2::new(2.0, 0.0), 0.1),
            // too small to avoid, and not finite
            (Point2::new(3.0, 0.0), 0.03),
            (Point2::new(f64::NAN, 0.0), 0.2),
        ]);
        assert_eq!(kept, 1);
        assert!((m.max_radius_m() - 0.1).abs() < 1e-12);
        let near = |m: &ObstacleMemory| {
            let mut n = 0;
            m.for_each_near(Point2::new(1.5, 0.0), 1.0, |_| n += 1);
            n
        };
        assert_eq!(near(&m), 1);
        // a camera looking straight at it without detecting it, frame after frame
        for _ in 0..5 {
            m.start_frame();
            m.record_view(Pose2::new(0.5, 0.0, 0.0), 0.6, 0.3);
        }
        assert_eq!(near(&m), 1);
        assert!(m.obstacles().is_empty());
        // a new relocalization places them anew
        m.set_known_rocks(&[(Point2::new(2.0, 0.05), 0.1)]);
        assert_eq!(m.known_rocks().len(), 1);
        assert_eq!(m.known_rocks()[0].p, Point2::new(2.0, 0.05));
        assert_eq!(near(&m), 1);
    }
}
