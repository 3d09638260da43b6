//! Terrain-relative height alignment of the sessions' trajectories before the height map is
//! built.
//!
//! The visual odometry's vertical random walk is barely observed by the boulder factors
//! (stereo centroids are noisy in height) and not at all by the lander factors (vertical
//! sides), so the optimised poses can be several centimetres off in height — as much as the
//! LAC's 5 cm tolerance (measured on the coverage mission: with the optimised horizontal
//! poses and the *true* heights the geometric score is within 2 points of the true-pose
//! score, with the optimised heights up to 70 points lower). The ground itself observes it:
//! wherever two frames (of either session) measured ground points in the same cell, their
//! heights must agree.
//!
//! One linear least-squares problem in the height corrections `dz` of the frames (piecewise
//! linear between knots every `knot_spacing_frames` frames): every ground point `z` of frame
//! `k` in cell `c` gives `z + dz_k = H_c` (the cell heights `H_c` eliminated per cell),
//! consecutive knots differ by the odometry's vertical noise, the first frame of the first
//! session (the known start) is held, and every knot is weakly held at 0. Huber
//! reweighting (a few rounds) keeps stereo outliers and slopes seen with horizontal error
//! from pulling. Only sensor data is used.

use nalgebra::{DMatrix, DVector, Isometry3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

use crate::sim::session::SessionLog;

/// Parameters of the height alignment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TerrainHeightConfig {
    /// Align the heights at all.
    pub enabled: bool,
    /// Frames between knots of the piecewise-linear correction.
    pub knot_spacing_frames: usize,
    /// Cell size used to compare ground points, metres.
    pub cell_m: f64,
    /// Ground point height noise at zero range, 1 σ, metres.
    pub point_sigma_m: f64,
    /// … plus this times the squared horizontal range (metres per square metre; stereo
    /// depth noise grows with the square of the range).
    pub point_sigma_per_range2: f64,
    /// Ground points farther than this from the rover are not used, metres.
    pub max_range_m: f64,
    /// Vertical odometry noise per metre driven between knots, 1 σ (plus 1 mm per knot).
    pub step_sigma_m_per_m: f64,
    /// Weak prior holding every correction near 0, 1 σ, metres.
    pub prior_sigma_m: f64,
    /// Hold of the first frame (the known start), 1 σ, metres.
    pub anchor_sigma_m: f64,
    /// Huber threshold, in point σ.
    pub huber_k: f64,
    /// Solve-and-reweight rounds.
    pub rounds: usize,
}

impl Default for TerrainHeightConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            knot_spacing_frames: 4,
            cell_m: 0.15,
            point_sigma_m: 0.01,
            point_sigma_per_range2: 0.001,
            max_range_m: 5.0,
            step_sigma_m_per_m: 0.008,
            prior_sigma_m: 0.2,
            anchor_sigma_m: 0.001,
            huber_k: 2.0,
            rounds: 3,
        }
    }
}

/// One ground point for the alignment: its knot interpolation, height and weight.
struct Sample {
    /// Lower knot index (global) and the weight of the upper knot.
    knot: usize,
    frac: f64,
    z: f64,
    weight: f64,
}

/// Knot weights of frame `k` (of a session whose knots start at `first_knot`).
fn knot_of(k: usize, spacing: usize, first_knot: usize, last_knot: usize) -> (usize, f64) {
    let knot = first_knot + k / spacing;
    if knot >= last_knot {
        return (last_knot, 0.0);
    }
    (knot, (k % spacing) as f64 / spacing as f64)
}

/// The height corrections of every frame of `sessions` (one `world_from_rover` per frame),
/// in session order; all zero when disabled or nothing overlaps.
pub fn height_corrections(
    sessions: &[(&SessionLog, &[Isometry3<f64>])],
    config: &TerrainHeightConfig,
) -> Vec<Vec<f64>> {
    let zeros = || sessions.iter().map(|(_, p)| vec![0.0; p.len()]).collect();
    if !config.enabled || config.cell_m <= 0.0 {
        return zeros();
    }
    let knots = Knots::new(sessions, config.knot_spacing_frames.max(1));
    if knots.count == 0 {
        return zeros();
    }
    let cells = overlapping_cells(sessions, &knots, config);
    let Some(dz) = solve_reweighted(sessions, &cells, &knots, config) else {
        return zeros();
    };
    sessions
        .iter()
        .enumerate()
        .map(|(s, (_, poses))| {
            (0..poses.len())
                .map(|k| {
                    let (knot, frac) = knots.of_frame(s, k, poses.len());
                    interpolate(&dz, knot, frac)
                })
                .collect()
        })
        .collect()
}

/// The knots of all sessions, numbered globally in session order.
struct Knots {
    /// Frames between knots.
    spacing: usize,
    /// The first knot of each session.
    first: Vec<usize>,
    /// Knots in all.
    count: usize,
}

impl Knots {
    /// Per session: ceil((frames - 1) / spacing) + 1 knots.
    fn new(sessions: &[(&SessionLog, &[Isometry3<f64>])], spacing: usize) -> Self {
        let mut first = Vec::new();
        let mut count = 0;
        for (_, poses) in sessions {
            first.push(count);
            count += poses.len().saturating_sub(1).div_ceil(spacing) + 1;
        }
        Knots {
            spacing,
            first,
            count,
        }
    }

    /// Knot weights of frame `k` of session `s` (of `frames` frames).
    fn of_frame(&self, s: usize, k: usize, frames: usize) -> (usize, f64) {
        let last_knot = self.first[s] + frames.saturating_sub(1).div_ceil(self.spacing);
        knot_of(k, self.spacing, self.first[s], last_knot)
    }
}

/// The ground points in range, by cell, of the cells seen by frames far enough apart (on
/// different knots) to tell anything beyond the odometry.
fn overlapping_cells(
    sessions: &[(&SessionLog, &[Isometry3<f64>])],
    knots: &Knots,
    config: &TerrainHeightConfig,
) -> Vec<Vec<Sample>> {
    let mut cells: HashMap<(i64, i64), Vec<Sample>> = HashMap::new();
    for (s, (log, poses)) in sessions.iter().enumerate() {
        for (k, (frame, pose)) in log.frames.iter().zip(poses.iter()).enumerate() {
            let (knot, frac) = knots.of_frame(s, k, poses.len());
            for g in &frame.ground {
                let range = g.p_rover.coords.xy().norm();
                if range > config.max_range_m {
                    continue;
                }
                let p = pose * g.p_rover;
                let sigma = config.point_sigma_m + config.point_sigma_per_range2 * range * range;
                let key = (
                    (p.x / config.cell_m).floor() as i64,
                    (p.y / config.cell_m).floor() as i64,
                );
                cells.entry(key).or_default().push(Sample {
                    knot,
                    frac,
                    z: p.z,
                    weight: 1.0 / (sigma * sigma),
                });
            }
        }
    }
    cells
        .into_values()
        .filter(|c| {
            let (lo, hi) = c.iter().fold((usize::MAX, 0), |(lo, hi), s| {
                (lo.min(s.knot), hi.max(s.knot))
            });
            hi > lo
        })
        .collect()
}

/// The knots' corrections: solve, then reweight every point (Huber on its residual against
/// its cell's mean), `rounds` times; `None` when the system is singular.
fn solve_reweighted(
    sessions: &[(&SessionLog, &[Isometry3<f64>])],
    cells: &[Vec<Sample>],
    knots: &Knots,
    config: &TerrainHeightConfig,
) -> Option<DVector<f64>> {
    let n_knots = knots.count;
    let mut robust: Vec<Vec<f64>> = cells.iter().map(|c| vec![1.0; c.len()]).collect();
    let mut dz = DVector::zeros(n_knots);
    for _ in 0..config.rounds.max(1) {
        let mut h = DMatrix::<f64>::zeros(n_knots, n_knots);
        let mut b = DVector::<f64>::zeros(n_knots);
        for (cell, rw) in cells.iter().zip(&robust) {
            accumulate_cell(cell, rw, &mut h, &mut b);
        }
        add_priors(
            sessions,
            &knots.first,
            knots.spacing,
            config,
            &mut h,
            &mut b,
        );
        dz = h.cholesky()?.solve(&(-b));
        for (cell, rw) in cells.iter().zip(robust.iter_mut()) {
            huber_weights(cell, &dz, config.huber_k, rw);
        }
    }
    Some(dz)
}

/// Huber weights (threshold `huber_k` point σ) of a cell's points on their residuals
/// against the cell's mean corrected height (weighted by the current weights `rw`).
fn huber_weights(cell: &[Sample], dz: &DVector<f64>, huber_k: f64, rw: &mut [f64]) {
    let value = |s: &Sample| s.z + interpolate(dz, s.knot, s.frac);
    let (sw, swz) = cell
        .iter()
        .zip(rw.iter())
        .fold((0.0, 0.0), |(a, b), (s, r)| {
            (a + s.weight * r, b + s.weight * r * value(s))
        });
    let mean = swz / sw.max(1e-12);
    for (s, r) in cell.iter().zip(rw.iter_mut()) {
        let e = (value(s) - mean).abs() * s.weight.sqrt();
        *r = if e <= huber_k { 1.0 } else { huber_k / e };
    }
}

fn interpolate(dz: &DVector<f64>, knot: usize, frac: f64) -> f64 {
    let lo = dz[knot];
    if frac == 0.0 {
        lo
    } else {
        lo * (1.0 - frac) + dz[knot + 1] * frac
    }
}

/// Add one cell's points, its height eliminated: Σ w (z + dz − H)² minimised over H leaves
/// the quadratic Σ w (z + dz)² − (Σ w (z + dz))² / Σ w in the knots.
fn accumulate_cell(cell: &[Sample], robust: &[f64], h: &mut DMatrix<f64>, b: &mut DVector<f64>) {
    // per knot: a = Σ w·coef, the linear term and the sum of weights
    let mut a: Vec<(usize, f64)> = Vec::new();
    let (mut sw, mut swz) = (0.0, 0.0);
    for (s, r) in cell.iter().zip(robust) {
        let w = s.weight * r;
        sw += w;
        swz += w * s.z;
        for (knot, coef) in [(s.knot, 1.0 - s.frac), (s.knot + 1, s.frac)] {
            if coef == 0.0 {
                continue;
            }
            // diagonal-block part: Σ w (coef·dz)² and Σ w·z·coef·dz
            match a.iter_mut().find(|(k, _)| *k == knot) {
                Some(e) => e.1 += w * coef,
                None => a.push((knot, w * coef)),
            }
            b[knot] += w * s.z * coef;
        }
        // the exact per-point quadratic w (Σ coef dz)²
        let terms = [(s.knot, 1.0 - s.frac), (s.knot + 1, s.frac)];
        for (i, ci) in terms {
            for (j, cj) in terms {
                if ci != 0.0 && cj != 0.0 {
                    h[(i, j)] += w * ci * cj;
                }
            }
        }
    }
    if sw <= 0.0 {
        return;
    }
    let mean = swz / sw;
    for &(i, ai) in &a {
        b[i] -= ai * mean;
        for &(j, aj) in &a {
            h[(i, j)] -= ai * aj / sw;
        }
    }
}

/// The start anchor, the smoothness between consecutive knots and the weak zero prior.
fn add_priors(
    sessions: &[(&SessionLog, &[Isometry3<f64>])],
    first_knots: &[usize],
    spacing: usize,
    config: &TerrainHeightConfig,
    h: &mut DMatrix<f64>,
    _b: &mut DVector<f64>,
) {
    let n = h.nrows();
    let prior = 1.0 / (config.prior_sigma_m * config.prior_sigma_m);
    for i in 0..n {
        h[(i, i)] += prior;
    }
    if let Some(&first) = first_knots.first() {
        h[(first, first)] += 1.0 / (config.anchor_sigma_m * config.anchor_sigma_m);
    }
    for (s, (_, poses)) in sessions.iter().enumerate() {
        let knots = poses.len().saturating_sub(1).div_ceil(spacing) + 1;
        for q in 1..knots {
            let (from, to) = ((q - 1) * spacing, (q * spacing).min(poses.len() - 1));
            let distance: f64 = (from..to)
                .map(|k| (poses[k + 1].translation.vector - poses[k].translation.vector).norm())
                .sum();
            let sigma = config.step_sigma_m_per_m * distance + 1e-3;
            let w = 1.0 / (sigma * sigma);
            let (i, j) = (first_knots[s] + q - 1, first_knots[s] + q);
            h[(i, i)] += w;
            h[(j, j)] += w;
            h[(i, j)] -= w;
            h[(j, i)] -= w;
        }
    }
}

/// `poses` with their heights corrected by `dz` (one per pose).
pub fn apply(poses: &[Isometry3<f64>], dz: &[f64]) -> Vec<Isometry3<f64>> {
    poses
        .iter()
        .zip(dz)
        .map(|(p, d)| {
            let mut p = *p;
            p.translation.vector.z += d;
            p
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::moon::{Moon, MoonConfig};
    use crate::sim::session::{run_session, SessionConfig};

    #[test]
    fn finds_a_height_offset_between_two_passes_over_the_same_ground() {
        let moon = Moon::generate(&MoonConfig::default(), 3).unwrap();
        let (x, y) = moon.nearest_clear_position(4.5, 0.0, 1.0, 0.08);
        let config = SessionConfig {
            duration_s: 40.0,
            start: [x, y, 1.5],
            ..SessionConfig::default()
        };
        let log = run_session(&moon, &config, 1).unwrap();
        let truth: Vec<Isometry3<f64>> = log
            .frames
            .iter()
            .map(|f| log.ticks[f.tick].world_from_rover)
            .collect();
        // the same drive seen as a second session placed 5 cm too high
        let high = apply(&truth, &vec![0.05; truth.len()]);
        let dz = height_corrections(
            &[(&log, &truth), (&log, &high)],
            &TerrainHeightConfig::default(),
        );
        assert_eq!(dz.len(), 2);
        assert!(dz[0].iter().all(|d| d.abs() < 0.005), "{:?}", dz[0]);
        assert!(
            dz[1].iter().all(|d| (d + 0.05).abs() < 0.005),
            "{:?}",
            dz[1]
        );
        // disabled: nothing moves
        let off = TerrainHeightConfig {
            enabled: false,
            ..TerrainHeightConfig::default()
        };
        let none = height_corrections(&[(&log, &truth)], &off);
        assert!(none[0].iter().all(|d| *d == 0.0));
    }
}
