//! Self-calibration of the size-proportional viewpoint bias of boulder detections.
//!
//! A detection's centroid comes from stereo points on the face the camera sees, so it sits
//! in front of the boulder's centre by a distance that grows with the boulder: a fraction
//! `f` of its size. Model: `p = c − f · s · u + noise`, with `c` the centre, `s` the
//! detection's size (diameter) and `u` the horizontal unit line of sight from the rover.
//! Left in, the bias shifts every map made from one side of its boulders, and two passes
//! that see the same boulders from opposite sides disagree by twice it — a loop closure
//! between an inner and an outer ring then pulls the outer ring toward the lander by a few
//! centimetres.
//!
//! A rover passing a boulder sees it first ahead (front camera) and then behind (back
//! camera): within one pass the line of sight turns round while the centre stays put, and
//! that separates `f` from `c`. Within a pass the poses are good to millimetres but for a
//! scale: a distance driven that comes out 0.1 % short moves the detections from behind
//! toward those from ahead just as a bias does (a few millimetres over the 5–10 m between
//! them). So the model has a second unknown, the relative scale error `κ` of the rover
//! positions: `p = c − f · s · u + κ · r`, with `r` the rover's position. This module
//! gathers the evidence per stretch of detections (each placed with its own stretch's
//! poses) and solves the pooled least squares for `f` and `κ`, the centres eliminated
//! boulder by boulder.

use super::cluster::cluster_points;
use super::FusionConfig;
use nalgebra::Vector2;
use segloc_maps::Detection;
use serde::{Deserialize, Serialize};

/// Least-squares evidence on the size fraction `f` and the position scale error `κ`, summed
/// over boulders.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SizeBiasEvidence {
    /// Normal matrix `Σ [da·da, da·dr, dr·dr]` over each boulder's detections, with
    /// `a = s u`, `r` the rover position and `d` the deviation from the boulder's mean.
    pub normal: [f64; 3],
    /// Right-hand side `Σ [da·dp, dr·dp]`.
    pub rhs: [f64; 2],
    /// `Σ |dp|²`: with the normal equations, the residual sum of squares of any solution.
    pub deviation: f64,
    /// Detections of the counted boulders.
    pub detections: usize,
    /// Boulders seen from directions diverse enough to count (mean line of sight shorter
    /// than [`MAX_MEAN_RAY`]).
    pub boulders: usize,
}

/// Boulders whose detections' mean line of sight is longer than this (all seen from nearly
/// one direction) carry little evidence and are left out.
pub const MAX_MEAN_RAY: f64 = 0.8;

impl SizeBiasEvidence {
    /// The evidence of one stretch of detections that share accurate relative poses (one
    /// pass of the rover): the detections within `config`'s range gates, with a size and a
    /// rover position, clustered with its cluster radius after a provisional correction by
    /// `guess` (a fraction of the size). The two sides of a large boulder can lie farther
    /// apart than the cluster radius; clustered uncorrected they split, and the evidence
    /// then underestimates the fraction, so a caller iterates with its latest estimate.
    pub fn from_detections(detections: &[Detection], config: &FusionConfig, guess: f64) -> Self {
        let mut points = Vec::new();
        let mut corrected = Vec::new();
        let mut sizes = Vec::new();
        let mut rays = Vec::new();
        let mut rovers = Vec::new();
        for d in detections {
            let (Some(rover), Some(size)) = (d.rover_position, d.size_m) else {
                continue;
            };
            let sight = (d.p_world - rover).xy();
            let range = sight.norm();
            if !(range >= config.min_range_m && range <= config.max_range_m && size.is_finite()) {
                continue;
            }
            let u = sight / range;
            points.push(d.p_world);
            corrected.push(d.p_world + (u * (guess * size)).push(0.0));
            rays.push(u);
            rovers.push(rover.coords.xy());
            sizes.push(size);
        }
        let mut evidence = Self::default();
        for members in cluster_points(&corrected, config.cluster_radius_m) {
            if members.len() < 2 {
                continue;
            }
            let n = members.len() as f64;
            let mean = |v: &dyn Fn(usize) -> Vector2<f64>| {
                members.iter().map(|&i| v(i as usize)).sum::<Vector2<f64>>() / n
            };
            if mean(&|i| rays[i]).norm() > MAX_MEAN_RAY {
                continue;
            }
            // the boulder's size as the mean of its detections' (each is 15 % off or so):
            // per-detection sizes in the regressor would attenuate the estimate
            let size = members.iter().map(|&i| sizes[i as usize]).sum::<f64>() / n;
            let scaled_ray = |i: usize| rays[i] * size;
            let a_bar = mean(&scaled_ray);
            let r_bar = mean(&|i| rovers[i]);
            let p_bar = mean(&|i| points[i].coords.xy());
            for &i in &members {
                let i = i as usize;
                let (da, dr) = (scaled_ray(i) - a_bar, rovers[i] - r_bar);
                let dp = points[i].coords.xy() - p_bar;
                evidence.normal[0] += da.dot(&da);
                evidence.normal[1] += da.dot(&dr);
                evidence.normal[2] += dr.dot(&dr);
                evidence.rhs[0] += da.dot(&dp);
                evidence.rhs[1] += dr.dot(&dp);
                evidence.deviation += dp.norm_squared();
            }
            evidence.detections += members.len();
            evidence.boulders += 1;
        }
        evidence
    }

    /// Adds another stretch's evidence.
    pub fn add(&mut self, other: &SizeBiasEvidence) {
        for (a, b) in self.normal.iter_mut().zip(other.normal) {
            *a += b;
        }
        for (a, b) in self.rhs.iter_mut().zip(other.rhs) {
            *a += b;
        }
        self.deviation += other.deviation;
        self.detections += other.detections;
        self.boulders += other.boulders;
    }

    /// The least-squares `(f, κ)`: `f` the fraction of the size by which detections sit
    /// toward the camera (the value for [`FusionConfig::view_bias_size_fraction`]), `κ`
    /// the relative scale error of the rover positions; `None` with fewer than
    /// `min_boulders` boulders of evidence or a singular system.
    pub fn solve(&self, min_boulders: usize) -> Option<(f64, f64)> {
        let [aa, ar, rr] = self.normal;
        let det = aa * rr - ar * ar;
        let regular = det.is_finite() && det > 1e-12 * aa * rr;
        if self.boulders < min_boulders.max(1) || !regular {
            return None;
        }
        let beta = (rr * self.rhs[0] - ar * self.rhs[1]) / det;
        let kappa = (aa * self.rhs[1] - ar * self.rhs[0]) / det;
        Some((-beta, kappa))
    }

    /// The fraction `f` of [`SizeBiasEvidence::solve`].
    pub fn fraction(&self, min_boulders: usize) -> Option<f64> {
        self.solve(min_boulders).map(|(f, _)| f)
    }

    /// The standard error of `f` at the least-squares solution, from the residuals (two
    /// per detection, less each boulder's centre and the two unknowns); `None` when there
    /// is no solution or no residual degree of freedom.
    pub fn fraction_standard_error(&self) -> Option<f64> {
        let (f, kappa) = self.solve(1)?;
        let dof = (2 * self.detections).checked_sub(2 * self.boulders + 2)?;
        if dof == 0 {
            return None;
        }
        let [aa, ar, rr] = self.normal;
        // residual sum of squares at the solution: Σ|dp|² − xᵀ b, with x = (−f, κ)
        let rss = (self.deviation - (-f * self.rhs[0] + kappa * self.rhs[1])).max(0.0);
        let variance = rss / dof as f64;
        Some((variance * rr / (aa * rr - ar * ar)).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};

    /// Boulders of `sizes` along a line, passed by a rover driving along y = −2: each seen
    /// from 6 m before to 6 m after it, every metre, drawn `fraction × size` toward the
    /// rover.
    fn pass_of(fraction: f64, sizes: &[f64]) -> Vec<Detection> {
        let mut out = Vec::new();
        for (b, &size) in sizes.iter().enumerate() {
            let centre = Point3::new(3.0 * b as f64, 0.0, 0.1);
            for step in -6..=6 {
                let rover = Point3::new(centre.x + step as f64, -2.0, 0.3);
                let u = (centre - rover).xy().normalize();
                let p = centre - Vector3::new(u.x, u.y, 0.0) * (fraction * size);
                out.push(Detection {
                    frame: step as u64,
                    p_world: p,
                    rover_position: Some(rover),
                    size_m: Some(size),
                    score: None,
                });
            }
        }
        out
    }

    /// Eight boulders of 0.1–0.45 m.
    fn pass(fraction: f64) -> Vec<Detection> {
        let sizes: Vec<f64> = (0..8).map(|b| 0.1 + 0.05 * b as f64).collect();
        pass_of(fraction, &sizes)
    }

    #[test]
    fn recovers_the_fraction_from_one_pass() {
        let config = FusionConfig::default();
        for fraction in [0.0, 1.0 / 6.0, 0.3] {
            let evidence = SizeBiasEvidence::from_detections(&pass(fraction), &config, 0.0);
            assert_eq!(evidence.boulders, 8);
            let f = evidence.fraction(1).unwrap();
            assert!((f - fraction).abs() < 1e-9, "{f} vs {fraction}");
        }
    }

    /// The same pass with the rover positions (and so the detections placed from them)
    /// scaled by `1 + kappa` about the origin, as a drifted odometry places them.
    fn scaled_pass(fraction: f64, kappa: f64) -> Vec<Detection> {
        pass(fraction)
            .into_iter()
            .map(|d| {
                let rover = d.rover_position.unwrap();
                let moved = Point3::from(rover.coords * (1.0 + kappa));
                Detection {
                    p_world: d.p_world + (moved - rover),
                    rover_position: Some(moved),
                    ..d
                }
            })
            .collect()
    }

    #[test]
    fn separates_the_bias_from_a_scale_error_of_the_positions() {
        let config = FusionConfig::default();
        let evidence = SizeBiasEvidence::from_detections(&scaled_pass(0.15, 0.002), &config, 0.15);
        let (f, kappa) = evidence.solve(1).unwrap();
        assert!((f - 0.15).abs() < 1e-6, "{f}");
        // noise-free: no residual
        assert!(evidence.fraction_standard_error().unwrap() < 1e-6);
        // relative to the drifted positions: κ / (1 + κ)
        assert!((kappa - 0.002 / 1.002).abs() < 1e-9, "{kappa}");
    }

    #[test]
    fn the_guess_keeps_both_sides_of_a_large_boulder_together() {
        // 1.2 m boulders: their sides 0.4 m apart, more than the cluster radius
        let big = pass_of(1.0 / 6.0, &[1.2, 1.2, 1.2]);
        let config = FusionConfig::default();
        let guessed = SizeBiasEvidence::from_detections(&big, &config, 1.0 / 6.0);
        assert_eq!(guessed.boulders, 3);
        assert!((guessed.fraction(1).unwrap() - 1.0 / 6.0).abs() < 1e-6);
        let unguessed = SizeBiasEvidence::from_detections(&big, &config, 0.0);
        assert!(unguessed.boulders < 3, "{unguessed:?}");
    }

    #[test]
    fn the_standard_error_matches_the_noise() {
        // ±1 cm of deterministic pseudo-noise on every detection: the estimate stays within
        // a few standard errors, which are a small fraction of the value
        let mut noisy = pass(1.0 / 6.0);
        for (k, d) in noisy.iter_mut().enumerate() {
            let (a, b) = ((k as f64 * 12.9898).sin(), (k as f64 * 78.233).sin());
            d.p_world += Vector3::new(0.01 * a, 0.01 * b, 0.0);
        }
        let evidence = SizeBiasEvidence::from_detections(&noisy, &FusionConfig::default(), 0.0);
        let f = evidence.fraction(1).unwrap();
        let se = evidence.fraction_standard_error().unwrap();
        assert!(se > 1e-3 && se < 0.05, "{se}");
        assert!((f - 1.0 / 6.0).abs() < 4.0 * se, "{f} ± {se}");
    }

    #[test]
    fn noisy_detected_sizes_do_not_shrink_the_estimate() {
        // every detection's size 15 % off (alternating), its position biased by the true
        // size: with per-detection sizes in the regressor the estimate came out low
        let detections: Vec<Detection> = pass(1.0 / 6.0)
            .into_iter()
            .enumerate()
            .map(|(k, d)| Detection {
                size_m: d.size_m.map(|s| s * if k % 2 == 0 { 1.15 } else { 0.85 }),
                ..d
            })
            .collect();
        let evidence =
            SizeBiasEvidence::from_detections(&detections, &FusionConfig::default(), 0.0);
        let f = evidence.fraction(1).unwrap();
        assert!((f - 1.0 / 6.0).abs() < 0.003, "{f}");
    }

    #[test]
    fn pooled_evidence_and_its_minimum() {
        let config = FusionConfig::default();
        let one = SizeBiasEvidence::from_detections(&pass(0.2), &config, 0.0);
        let mut two = one;
        two.add(&one);
        assert_eq!(two.boulders, 16);
        assert!((two.fraction(16).unwrap() - 0.2).abs() < 1e-9);
        assert!(one.fraction(9).is_none());
        assert!(SizeBiasEvidence::default().fraction(0).is_none());
    }

    #[test]
    fn boulders_seen_from_one_side_or_without_a_size_give_no_evidence() {
        let config = FusionConfig::default();
        // only the approach: every line of sight points the same way within ±37°
        let ahead: Vec<Detection> = pass(0.2)
            .into_iter()
            .filter(|d| d.rover_position.is_some_and(|r| r.x <= d.p_world.x - 2.0))
            .collect();
        assert_eq!(
            SizeBiasEvidence::from_detections(&ahead, &config, 0.0).boulders,
            0
        );
        let sizeless: Vec<Detection> = pass(0.2)
            .into_iter()
            .map(|d| Detection { size_m: None, ..d })
            .collect();
        let evidence = SizeBiasEvidence::from_detections(&sizeless, &config, 0.0);
        assert_eq!(evidence, SizeBiasEvidence::default());
    }
}
