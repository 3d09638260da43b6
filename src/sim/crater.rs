//! Crater profile: a parabolic bowl inside the rim and a raised rim decaying outside it.

use serde::{Deserialize, Serialize};

/// One crater: centre, rim radius and shape.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Crater {
    /// Centre x, metres.
    pub x: f64,
    /// Centre y, metres.
    pub y: f64,
    /// Rim radius, metres.
    pub radius_m: f64,
    /// Floor depth below the surrounding terrain, metres.
    pub depth_m: f64,
    /// Rim height above the surrounding terrain, metres.
    pub rim_height_m: f64,
}

impl Crater {
    /// A crater of `radius_m` whose freshness in (0, 1] scales a fresh crater's shape
    /// (depth 0.2 R, rim 0.08 R); old craters are shallower.
    pub fn new(x: f64, y: f64, radius_m: f64, freshness: f64) -> Self {
        Self {
            x,
            y,
            radius_m,
            depth_m: 0.2 * radius_m * freshness,
            rim_height_m: 0.08 * radius_m * freshness,
        }
    }

    /// Distance from the centre beyond which the crater leaves the terrain alone: where the
    /// rim's fall-off drops below 1 mm, between 1 and 3 radii.
    pub fn reach_m(&self) -> f64 {
        // rim · r⁻³ < 1 mm  ⇔  r > (rim / 1 mm)^(1/3)
        let r = (self.rim_height_m / 1e-3).cbrt().clamp(1.0, 3.0);
        r * self.radius_m
    }

    /// Height offset (metres) the crater adds at (x, y): the bowl `rim + (depth + rim)(ρ² − 1)`
    /// inside (ρ = distance / radius < 1), the rim falling off as `rim · ρ⁻³` outside.
    pub fn offset_at(&self, x: f64, y: f64) -> f64 {
        let rho = (x - self.x).hypot(y - self.y) / self.radius_m;
        if rho < 1.0 {
            self.rim_height_m + (self.depth_m + self.rim_height_m) * (rho * rho - 1.0)
        } else if rho * self.radius_m < self.reach_m() {
            self.rim_height_m / (rho * rho * rho)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bowl_rim_and_falloff() {
        let c = Crater::new(1.0, -2.0, 2.0, 1.0);
        assert!((c.offset_at(1.0, -2.0) + 0.4).abs() < 1e-12);
        assert!((c.offset_at(3.0, -2.0) - 0.16).abs() < 1e-12);
        assert!(c.offset_at(5.0, -2.0) < 0.03);
        assert_eq!(c.offset_at(20.0, -2.0), 0.0);
        // continuous at the rim
        let inside = c.offset_at(3.0 - 1e-9, -2.0);
        let outside = c.offset_at(3.0 + 1e-9, -2.0);
        assert!((inside - outside).abs() < 1e-6);
    }
}
