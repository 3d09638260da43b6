//! High-level waypoints in the patterns that worked in the Lunar Autonomy Challenge: a small
//! loop around the lander first, then square rings growing outward — either one continuous
//! square spiral or nested square loops — each ring close enough to the previous one that
//! the cameras see ground they mapped before, so loop closures keep happening.

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

/// Which pattern follows the first loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Pattern {
    /// One square spiral whose half-side grows by `ring_spacing_m` per turn.
    Spiral,
    /// Closed square loops of growing half-side, one after the other.
    NestedLoops,
}

/// Parameters of the waypoint pattern (nav frame: the lander at the origin).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WaypointConfig {
    /// Pattern after the first loop.
    pub pattern: Pattern,
    /// Half-side of the first square loop around the lander, metres.
    pub first_loop_half_side_m: f64,
    /// Growth of the half-side per ring, metres.
    pub ring_spacing_m: f64,
    /// Largest half-side, metres.
    pub max_half_side_m: f64,
    /// Distance between consecutive waypoints along a ring, metres.
    pub waypoint_spacing_m: f64,
    /// Counter-clockwise if true.
    pub counter_clockwise: bool,
}

impl Default for WaypointConfig {
    fn default() -> Self {
        Self {
            pattern: Pattern::Spiral,
            first_loop_half_side_m: 3.5,
            ring_spacing_m: 2.0,
            max_half_side_m: 13.5,
            waypoint_spacing_m: 1.5,
            counter_clockwise: true,
        }
    }
}

impl WaypointConfig {
    /// The mission's coverage pattern: the loop around the lander (half-side 3.5 m), then
    /// loops 4.5 m apart out to 12.5 m, whose camera strips (±3.5 m at 5 m depth) overlap
    /// (loop closures) and reach the LAC grid's edge (±13.5 m).
    pub fn lac_coverage() -> Self {
        Self {
            pattern: Pattern::NestedLoops,
            first_loop_half_side_m: 3.5,
            ring_spacing_m: 4.5,
            max_half_side_m: 12.5,
            ..Self::default()
        }
    }

    /// Session 2's loops: half-side 9.5 m, where session 1's coverage loops (3.5, 8 and
    /// 12.5 m) leave the most unmapped, then 12.5 m (over session 1's outer one) and the
    /// site's edge, 13.5 m; in 300 s session 2 drives about the first.
    pub fn outer_loops() -> Self {
        Self {
            pattern: Pattern::NestedLoops,
            first_loop_half_side_m: 9.5,
            ring_spacing_m: 3.0,
            ..Self::default()
        }
    }
}

/// The point at perimeter parameter `t` ∈ [0, 1) of the square of half-side `h`, starting
/// at angle `start_rad` (the square's boundary point in that direction) and going round.
fn square_point(h: f64, t: f64, start_rad: f64, ccw: bool) -> Vector2<f64> {
    let dir = if ccw { 1.0 } else { -1.0 };
    let angle = start_rad + dir * t * 2.0 * std::f64::consts::PI;
    let (c, s) = (angle.cos(), angle.sin());
    // radial projection of the direction onto the square: max-norm scaling
    let scale = h / c.abs().max(s.abs()).max(1e-12);
    Vector2::new(c * scale, s * scale)
}

/// Waypoints for a rover starting at `start` (nav frame): the first loop begins at the
/// ring point in the start's direction from the lander.
///
/// ```
/// use segloc::planning::waypoints::{waypoints, WaypointConfig};
/// let w = waypoints(&WaypointConfig::default(), nalgebra::Vector2::new(4.0, 0.0));
/// assert!(w.len() > 50);
/// assert!(w.iter().all(|p| p.x.abs() <= 13.5 + 1e-9 && p.y.abs() <= 13.5 + 1e-9));
/// ```
pub fn waypoints(config: &WaypointConfig, start: Vector2<f64>) -> Vec<Vector2<f64>> {
    let start_rad = start.y.atan2(start.x);
    let spacing = config.waypoint_spacing_m.max(0.1);
    let h0 = config.first_loop_half_side_m.max(0.5);
    let h_max = config.max_half_side_m.max(h0);
    let ring = config.ring_spacing_m.max(0.1);
    let ccw = config.counter_clockwise;
    let mut out = Vec::new();
    let push_ring = |h: f64, grow: f64, out: &mut Vec<Vector2<f64>>| {
        let perimeter = 8.0 * (h + grow / 2.0);
        let n = ((perimeter / spacing).ceil() as usize).clamp(4, 100_000);
        for k in 0..n {
            let t = k as f64 / n as f64;
            out.push(square_point(h + grow * t, t, start_rad, ccw));
        }
    };
    push_ring(h0, 0.0, &mut out);
    let mut h = h0;
    while h < h_max - 1e-9 {
        let grow = ring.min(h_max - h);
        match config.pattern {
            Pattern::Spiral => push_ring(h, grow, &mut out),
            Pattern::NestedLoops => push_ring(h + grow, 0.0, &mut out),
        }
        h += grow;
    }
    push_ring(h_max, 0.0, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spiral_grows_and_stays_in_bounds() {
        let config = WaypointConfig {
            pattern: Pattern::Spiral,
            ring_spacing_m: 2.0,
            max_half_side_m: 13.5,
            ..WaypointConfig::default()
        };
        let w = waypoints(&config, Vector2::new(0.0, -5.0));
        let r = |p: &Vector2<f64>| p.x.abs().max(p.y.abs());
        assert!((r(&w[0]) - 3.5).abs() < 1e-9);
        assert!((r(w.last().unwrap()) - 13.5).abs() < 0.5);
        for pair in w.windows(2) {
            assert!((pair[1] - pair[0]).norm() < 2.5, "{:?}", pair);
        }
        // starts in the start's direction
        assert!(w[0].y < -3.0 && w[0].x.abs() < 1e-9);
    }

    #[test]
    fn nested_loops_are_closed_rings() {
        // the default: the loop around the lander, then loops 4.5 m apart out to 12.5 m,
        // whose camera strips (±3.5 m at 5 m depth) overlap and reach the grid's edge
        let config = WaypointConfig::lac_coverage();
        assert_eq!(config.pattern, Pattern::NestedLoops);
        let w = waypoints(&config, Vector2::new(1.0, 0.0));
        let r = |p: &Vector2<f64>| p.x.abs().max(p.y.abs());
        let rings: Vec<f64> = w.iter().map(r).collect();
        assert!(rings
            .iter()
            .all(|h| [3.5, 8.0, 12.5].iter().any(|x| (x - h).abs() < 1e-9)));
        for h in [3.5, 8.0, 12.5] {
            assert!(rings.iter().any(|x| (x - h).abs() < 1e-9), "no ring at {h}");
        }
        // within the grid (±13.5 m) with a margin for the rover's clearance
        assert!(rings.iter().all(|h| *h <= 13.5 - 0.75));
    }

    #[test]
    fn session_two_loops_lie_outside_session_one_s_middle_ring() {
        // 9.5 m, 12.5 m, then the site's edge (the pattern's 13.5 m bound); in 300 s
        // session 2 drives about the first
        let w = waypoints(&WaypointConfig::outer_loops(), Vector2::new(-4.5, 0.0));
        let r = |p: &Vector2<f64>| p.x.abs().max(p.y.abs());
        let rings = [9.5, 12.5, 13.5];
        for h in rings {
            assert!(w.iter().any(|p| (r(p) - h).abs() < 1e-9), "no ring at {h}");
        }
        assert!(w
            .iter()
            .all(|p| rings.iter().any(|h| (r(p) - h).abs() < 1e-9)));
        assert!((r(&w[0]) - 9.5).abs() < 1e-9);
    }
}
