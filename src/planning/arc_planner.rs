//! Arc sampling: each control cycle, a fan of constant-curvature arcs (fixed speed, yaw rates
//! evenly spread over ±`max_yaw_rate_rps`, `horizon_s` long) is checked for collisions with
//! parry2d (each arc a chain of `Segment`s, each remembered obstacle a point that must stay
//! `clearance_m` + its radius away, the lander a `Cuboid`), and the free arc whose end —
//! taken where the arc has covered the straight-line distance to the goal — lies nearest the
//! goal wins.
//!
//! An arc that starts inside an obstacle's clearance (a rock detected late) is still allowed
//! if it never gets closer to that obstacle than the rover already is, so the rover can
//! always move away.

use crate::planning::obstacles::ObstacleMemory;
use crate::planning::visibility::SeenGrid;
use crate::planning::Pose2;
use nalgebra::{Isometry2, Point2, Vector2};
use parry2d_f64::math::{Pose, Vector};
use parry2d_f64::query::PointQuery;
use parry2d_f64::shape::{Cuboid, Segment};
use serde::{Deserialize, Serialize};

/// Parameters of the arc fan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ArcPlannerConfig {
    /// Number of arcs (odd, so that one goes straight).
    pub arcs: usize,
    /// Largest |yaw rate| of an arc, rad/s.
    pub max_yaw_rate_rps: f64,
    /// Arc duration, seconds.
    pub horizon_s: f64,
    /// Forward speed along every arc, m/s.
    pub speed_mps: f64,
    /// Time between the points an arc is checked at, seconds.
    pub sample_dt_s: f64,
    /// Distance kept between the rover's centre and an obstacle's centre, metres (the
    /// "rover radius" of the LAC planners).
    pub clearance_m: f64,
    /// For large rocks, at least this much is kept between the rover's centre and the rock's
    /// edge: the footprint's radius plus a margin, metres.
    pub body_clearance_m: f64,
    /// Arcs must stay within |x|, |y| ≤ this in the nav frame, metres.
    pub site_half_extent_m: f64,
    /// Lateral offset of the extra seen-ground checks beside each arc point, metres: the
    /// wheels' outer edges (0.27 m from the centre line) and a margin.
    pub unseen_check_offset_m: f64,
    /// Arc points closer than this to the rover skip the seen-ground check, metres. 0 (the
    /// default): none do. A disc that travels with the rover let it creep into ground no
    /// camera saw, on the fan's tightest arcs, each wholly inside the disc (a rock hidden
    /// behind a crest, then below the image); without it the ground taken on trust is the
    /// session's start ([`crate::sim::session::SessionConfig::start_clear_radius_m`]) and
    /// the footprint the rover stood on.
    pub known_radius_m: f64,
    /// When no arc is free over `horizon_s`, halve the horizon (down to this, seconds) and
    /// look again: in a narrow gap (between the lander and a rock, say) every 3.6 m arc
    /// touches something while a shorter one leads out, and the rover otherwise turns on
    /// the spot there for the rest of the session. Equal to `horizon_s`: no fallback.
    pub min_horizon_s: f64,
    /// In the fallback, halve the *speed* instead of the horizon (down to the same shortest
    /// arc, `speed_mps · min_horizon_s`): the arcs shrink alike, but the rover approaches
    /// ground it has not seen (past a crest, say) slowly, so the cameras get more frames
    /// of it before the rover is there.
    pub fallback_slows_down: bool,
}

impl Default for ArcPlannerConfig {
    fn default() -> Self {
        Self {
            arcs: 41,
            max_yaw_rate_rps: 0.8,
            horizon_s: 8.0,
            speed_mps: 0.4,
            sample_dt_s: 0.25,
            clearance_m: 0.75,
            body_clearance_m: 0.65,
            site_half_extent_m: 19.0,
            unseen_check_offset_m: 0.4,
            known_radius_m: 0.0,
            min_horizon_s: 8.0,
            fallback_slows_down: true,
        }
    }
}

/// The lander as the planner sees it: a box in the session frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LanderBox {
    /// Pose of the lander's centre in the session frame.
    pub session_from_lander: Isometry2<f64>,
    /// Half-width in x and y, metres.
    pub half_extent_m: f64,
}

impl LanderBox {
    /// Distance from the session-frame point `p` to the box (0 inside), metres.
    pub fn distance_m(&self, p: Point2<f64>) -> f64 {
        let t = self.session_from_lander.translation.vector;
        let cuboid = Cuboid::new(Vector::new(self.half_extent_m, self.half_extent_m));
        let pose = Pose::new(
            Vector::new(t.x, t.y),
            self.session_from_lander.rotation.angle(),
        );
        cuboid.distance_to_point(&pose, Vector::new(p.x, p.y), true)
    }
}

/// The chosen arc.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcChoice {
    /// Forward speed, m/s.
    pub speed_mps: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_rps: f64,
    /// Distance from the arc's end to the goal, metres.
    pub goal_distance_m: f64,
    /// Arcs checked for collisions until this one was found free, nearest the goal first
    /// (1: the arc nearest the goal was free).
    pub arcs_checked: usize,
}

/// The pose after `t_s` seconds on the arc (speed `v`, yaw rate `w`) from `start`.
pub fn arc_pose(start: Pose2, v: f64, w: f64, t_s: f64) -> Pose2 {
    pose_on_arc(start, start.yaw.sin_cos(), v, w, t_s)
}

/// [`arc_pose`] with the start's sine and cosine given.
fn pose_on_arc(start: Pose2, (sin0, cos0): (f64, f64), v: f64, w: f64, t_s: f64) -> Pose2 {
    if w.abs() < 1e-9 {
        Pose2::new(
            start.x + v * t_s * cos0,
            start.y + v * t_s * sin0,
            start.yaw,
        )
    } else {
        let yaw = start.yaw + w * t_s;
        let (sin, cos) = yaw.sin_cos();
        Pose2::new(
            start.x + v / w * (sin - sin0),
            start.y + v / w * (cos0 - cos),
            yaw,
        )
    }
}

/// `steps + 1` poses evenly spaced in time over `horizon_s` seconds of the arc from
/// `start` ([`arc_pose`], the start's sine and cosine computed once: the planner samples
/// some 40 arcs of 33 points each control cycle).
fn arc_points(start: Pose2, v: f64, w: f64, horizon_s: f64, steps: usize) -> Vec<Pose2> {
    let start_sin_cos = start.yaw.sin_cos();
    (0..=steps)
        .map(|s| {
            pose_on_arc(
                start,
                start_sin_cos,
                v,
                w,
                s as f64 * horizon_s / steps as f64,
            )
        })
        .collect()
}

/// Everything an arc is checked against.
pub struct Scene<'a> {
    /// Remembered obstacles, session frame.
    pub obstacles: &'a ObstacleMemory,
    /// The lander, if known.
    pub lander: Option<LanderBox>,
    /// Maps session-frame points to the nav frame (for the site bounds).
    pub nav_from_session: Isometry2<f64>,
    /// Ground seen by the cameras; when given, arcs must run over seen ground (their
    /// points and the points `unseen_check_offset_m` to either side).
    pub seen: Option<&'a SeenGrid>,
}

impl ArcPlannerConfig {
    /// Yaw rate of arc `k`.
    pub fn yaw_rate(&self, k: usize) -> f64 {
        if self.arcs <= 1 {
            0.0
        } else {
            -self.max_yaw_rate_rps + 2.0 * self.max_yaw_rate_rps * k as f64 / (self.arcs - 1) as f64
        }
    }

    /// Distance to keep between the rover's centre and the centre of an obstacle of
    /// `radius_m`: `max(clearance, body_clearance + radius)`.
    pub fn required_m(&self, radius_m: f64) -> f64 {
        self.clearance_m.max(self.body_clearance_m + radius_m)
    }

    /// Whether driving `speed_mps` at `yaw_rate_rps` from `pose` for the horizon stays clear.
    pub fn arc_is_free(
        &self,
        pose: Pose2,
        speed_mps: f64,
        yaw_rate_rps: f64,
        scene: &Scene,
    ) -> bool {
        let steps =
            ((self.horizon_s / self.sample_dt_s.max(1e-3)).ceil() as usize).clamp(1, 10_000);
        let points = arc_points(pose, speed_mps, yaw_rate_rps, self.horizon_s, steps);
        self.path_is_free(pose, &points, scene)
    }

    fn path_is_free(&self, pose: Pose2, points: &[Pose2], scene: &Scene) -> bool {
        let here = Point2::new(pose.x, pose.y);
        // site bounds (nav frame)
        let bound = self.site_half_extent_m;
        for p in points {
            let q = scene.nav_from_session * Point2::new(p.x, p.y);
            if q.x.abs() > bound || q.y.abs() > bound {
                let q0 = scene.nav_from_session * here;
                // allowed only while heading back in
                if q.x.abs().max(q.y.abs()) > q0.x.abs().max(q0.y.abs()) {
                    return false;
                }
            }
        }
        // unseen ground
        if let Some(seen) = scene.seen {
            let off = self.unseen_check_offset_m;
            // the rover's surroundings (below the cameras' view while turning on the spot) are
            // taken as known: it drove there, or started on clear ground
            for p in points
                .iter()
                .filter(|p| (p.x - here.x).hypot(p.y - here.y) > self.known_radius_m)
            {
                let (s, c) = p.yaw.sin_cos();
                if !seen.is_seen(p.x, p.y)
                    || !seen.is_seen(p.x - s * off, p.y + c * off)
                    || !seen.is_seen(p.x + s * off, p.y - c * off)
                {
                    return false;
                }
            }
        }
        // lander box
        if let Some(lander) = scene.lander {
            let now = lander.distance_m(here);
            for p in points {
                let dp = lander.distance_m(Point2::new(p.x, p.y));
                if dp < self.clearance_m && dp < now - 1e-3 {
                    return false;
                }
            }
        }
        // rocks and lander points
        let (mut lo, mut hi) = (
            Vector2::new(f64::MAX, f64::MAX),
            Vector2::new(f64::MIN, f64::MIN),
        );
        for p in points {
            lo = lo.inf(&Vector2::new(p.x, p.y));
            hi = hi.sup(&Vector2::new(p.x, p.y));
        }
        let reach = self.required_m(scene.obstacles.max_radius_m());
        let centre = Point2::from((lo + hi) / 2.0);
        let half_diag = (hi - lo).norm() / 2.0;
        let mut near = Vec::new();
        scene
            .obstacles
            .for_each_near(centre, half_diag + reach, |o| {
                let r = reach;
                if o.p.x >= lo.x - r && o.p.x <= hi.x + r && o.p.y >= lo.y - r && o.p.y <= hi.y + r
                {
                    near.push(*o);
                }
            });
        if near.is_empty() {
            return true;
        }
        let segments: Vec<Segment> = points
            .windows(2)
            .map(|w| Segment::new(Vector::new(w[0].x, w[0].y), Vector::new(w[1].x, w[1].y)))
            .collect();
        for o in near {
            let required = self.required_m(o.radius_m);
            let q = Vector::new(o.p.x, o.p.y);
            let d = segments
                .iter()
                .map(|s| s.distance_to_local_point(q, true))
                .fold(f64::INFINITY, f64::min);
            if d < required {
                let now = (o.p - here).norm();
                // allowed only if it never gets closer than now
                let closest = points
                    .iter()
                    .map(|p| (o.p - Point2::new(p.x, p.y)).norm())
                    .fold(f64::INFINITY, f64::min);
                if closest < now - 1e-3 {
                    return false;
                }
            }
        }
        true
    }

    /// The free arc from `pose` whose end lies nearest `goal` (session frame), if any.
    pub fn choose(&self, pose: Pose2, goal: Point2<f64>, scene: &Scene) -> Option<ArcChoice> {
        let v = self.speed_mps;
        let goal_dist = (goal - Point2::new(pose.x, pose.y)).norm();
        let t_end = if v > 0.0 {
            (goal_dist / v).min(self.horizon_s)
        } else {
            self.horizon_s
        };
        // the arcs by how near their ends come to the goal (ties: the lower index), checked
        // for collisions in that order: the first free one is the choice
        let mut order: Vec<(f64, usize)> = (0..self.arcs.max(1))
            .map(|k| {
                let end = arc_pose(pose, v, self.yaw_rate(k), t_end);
                ((goal - Point2::new(end.x, end.y)).norm(), k)
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let best = order
            .iter()
            .enumerate()
            .find(|(_, &(_, k))| self.arc_is_free(pose, v, self.yaw_rate(k), scene))
            .map(|(checked, &(d, k))| ArcChoice {
                speed_mps: v,
                yaw_rate_rps: self.yaw_rate(k),
                goal_distance_m: d,
                arcs_checked: checked + 1,
            });
        if best.is_none() && self.horizon_s > self.min_horizon_s + 1e-9 {
            let half = (0.5 * self.horizon_s).max(self.min_horizon_s);
            if !self.fallback_slows_down {
                let shorter = ArcPlannerConfig {
                    horizon_s: half,
                    ..self.clone()
                };
                return shorter.choose(pose, goal, scene);
            }
            // the same arcs, driven over the whole horizon at the reduced speed (the
            // horizon's factor is carried by `min_horizon_s`)
            let slower = ArcPlannerConfig {
                speed_mps: self.speed_mps * half / self.horizon_s,
                min_horizon_s: self.min_horizon_s * self.horizon_s / half,
                ..self.clone()
            };
            return slower.choose(pose, goal, scene);
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::obstacles::ObstacleConfig;

    #[test]
    fn arc_points_are_arc_poses() {
        let start = Pose2::new(1.0, -2.0, 0.7);
        for w in [0.0, 0.3, -0.8] {
            let points = arc_points(start, 0.4, w, 8.0, 80);
            assert_eq!(points.len(), 81);
            for (s, p) in points.iter().enumerate() {
                let q = arc_pose(start, 0.4, w, s as f64 * 0.1);
                assert!((p.x - q.x).abs() < 1e-12 && (p.y - q.y).abs() < 1e-12);
                assert!((p.yaw - q.yaw).abs() < 1e-12);
            }
        }
    }

    fn scene(obstacles: &ObstacleMemory) -> Scene<'_> {
        Scene {
            obstacles,
            lander: None,
            nav_from_session: Isometry2::identity(),
            seen: None,
        }
    }

    #[test]
    fn goes_straight_to_a_goal_ahead_and_turns_toward_one_aside() {
        let c = ArcPlannerConfig::default();
        let m = ObstacleMemory::new(&ObstacleConfig::default());
        let s = scene(&m);
        let a = c
            .choose(Pose2::new(0.0, 0.0, 0.0), Point2::new(5.0, 0.0), &s)
            .unwrap();
        assert_eq!(a.yaw_rate_rps, 0.0);
        assert_eq!(
            a.arcs_checked, 1,
            "nothing in the way: the straight arc is free"
        );
        let b = c
            .choose(Pose2::new(0.0, 0.0, 0.0), Point2::new(2.0, 2.0), &s)
            .unwrap();
        assert!(b.yaw_rate_rps > 0.15, "{b:?}");
    }

    #[test]
    fn avoids_a_rock_in_the_way() {
        let c = ArcPlannerConfig::default();
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        m.add_rock(Point2::new(2.0, 0.0), 0.2);
        m.add_rock(Point2::new(2.0, 0.0), 0.2);
        let s = scene(&m);
        let a = c
            .choose(Pose2::new(0.0, 0.0, 0.0), Point2::new(5.0, 0.0), &s)
            .unwrap();
        assert!(a.yaw_rate_rps.abs() > 0.0);
        assert!(c.arc_is_free(Pose2::new(0.0, 0.0, 0.0), 0.4, a.yaw_rate_rps, &s));
        assert!(!c.arc_is_free(Pose2::new(0.0, 0.0, 0.0), 0.4, 0.0, &s));
        // every point of the chosen arc keeps clear
        for i in 0..=32 {
            let p = arc_pose(Pose2::default(), 0.4, a.yaw_rate_rps, i as f64 * 0.25);
            assert!((Point2::new(p.x, p.y) - Point2::new(2.0, 0.0)).norm() >= 0.85 - 1e-9);
        }
    }

    #[test]
    fn avoids_the_lander_and_site_edge() {
        let c = ArcPlannerConfig::default();
        let m = ObstacleMemory::new(&ObstacleConfig::default());
        let s = Scene {
            obstacles: &m,
            lander: Some(LanderBox {
                session_from_lander: Isometry2::identity(),
                half_extent_m: 1.5,
            }),
            nav_from_session: Isometry2::identity(),
            seen: None,
        };
        assert!(!c.arc_is_free(Pose2::new(-4.0, 0.0, 0.0), 0.4, 0.0, &s));
        assert!(c.arc_is_free(Pose2::new(-4.0, 0.0, std::f64::consts::PI), 0.4, 0.0, &s));
        assert!(!c.arc_is_free(Pose2::new(17.0, 5.0, 0.0), 0.4, 0.0, &s));
    }

    #[test]
    fn unseen_ground_blocks() {
        let c = ArcPlannerConfig::default();
        let m = ObstacleMemory::new(&ObstacleConfig::default());
        let mut seen = SeenGrid::new(0.25);
        seen.mark_view(Pose2::new(0.0, 0.0, 0.0), 0.6, 0.0, 6.0);
        // the rover's start (as the session marks it)
        seen.mark_disc(0.0, 0.0, 1.0);
        let s = Scene {
            seen: Some(&seen),
            ..scene(&m)
        };
        assert!(c.arc_is_free(Pose2::new(0.0, 0.0, 0.0), 0.4, 0.0, &s));
        assert!(!c.arc_is_free(Pose2::new(0.0, 0.0, 0.0), 0.4, 0.4, &s));
    }

    #[test]
    fn tight_arcs_do_not_creep_into_unseen_ground() {
        // ground seen up to x = 2 m only; the rover stands at x = 1.8 m facing +x
        let m = ObstacleMemory::new(&ObstacleConfig::default());
        let mut seen = SeenGrid::new(0.25);
        seen.mark_view(Pose2::new(-4.0, 0.0, 0.0), 0.6, 0.0, 6.0);
        seen.mark_disc(1.8, 0.0, 0.46);
        let s = Scene {
            seen: Some(&seen),
            ..scene(&m)
        };
        let here = Pose2::new(1.8, 0.0, 0.0);
        // the tightest arc at the fallback speed stays within 0.6 m of the rover
        let exempt = ArcPlannerConfig {
            known_radius_m: 1.0,
            ..ArcPlannerConfig::default()
        };
        assert!(exempt.arc_is_free(here, 0.225, 0.8, &s));
        assert!(!ArcPlannerConfig::default().arc_is_free(here, 0.225, 0.8, &s));
    }

    #[test]
    fn falls_back_to_shorter_arcs_slowly_or_quickly() {
        // a ring of rocks 2.7 m around: no 3.6 m arc is free, 1.8 m ones are
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        for k in 0..72 {
            let a = k as f64 * std::f64::consts::TAU / 72.0;
            let p = Point2::new(2.7 * a.cos(), 2.7 * a.sin());
            m.add_rock(p, 0.1);
            m.add_rock(p, 0.1);
        }
        let s = scene(&m);
        let slow = ArcPlannerConfig {
            speed_mps: 0.45,
            max_yaw_rate_rps: 0.2,
            min_horizon_s: 2.0,
            ..ArcPlannerConfig::default()
        };
        let a = slow
            .choose(Pose2::default(), Point2::new(5.0, 0.0), &s)
            .unwrap();
        assert!((a.speed_mps - 0.225).abs() < 1e-12, "{a:?}");
        let quick = ArcPlannerConfig {
            fallback_slows_down: false,
            ..slow.clone()
        };
        let b = quick
            .choose(Pose2::default(), Point2::new(5.0, 0.0), &s)
            .unwrap();
        assert!((b.speed_mps - 0.45).abs() < 1e-12, "{b:?}");
        // no fallback at all
        let none = ArcPlannerConfig {
            min_horizon_s: 8.0,
            ..slow
        };
        assert!(none
            .choose(Pose2::default(), Point2::new(5.0, 0.0), &s)
            .is_none());
    }

    #[test]
    fn can_back_away_from_a_late_rock() {
        let c = ArcPlannerConfig::default();
        let mut m = ObstacleMemory::new(&ObstacleConfig::default());
        m.add_rock(Point2::new(0.6, 0.0), 0.1);
        m.add_rock(Point2::new(0.6, 0.0), 0.1);
        let s = scene(&m);
        assert!(!c.arc_is_free(Pose2::new(0.0, 0.0, 0.0), 0.4, 0.0, &s));
        assert!(c.arc_is_free(Pose2::new(0.0, 0.0, std::f64::consts::PI), 0.4, 0.0, &s));
    }
}
