//! The Lunar Autonomy Challenge score of a height / rock grid against the ground truth.
//!
//! The rules, for a grid of `n` cells (32,400 in the LAC):
//! - geometric map: 300 × (cells whose height is within 0.05 m of the truth) / n; an
//!   unfilled cell (NaN height) counts as wrong;
//! - rock map: 300 × F1 with F1 = 2TP / (2TP + FP + FN) over all n cells (an unfilled rock
//!   value is read as "no rock" by [`segloc_maps::read_grid_csv`], so it counts as such);
//! - mapping productivity: 250 × min((filled cells / mission seconds) / (n / 86,400), 1),
//!   only when the mission duration is known (0 otherwise);
//! - 150 for not using the lander fiducials (segloc never does).

use segloc_maps::LacGrid;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Points for the geometric map.
pub const GEOMETRIC_POINTS: f64 = 300.0;
/// Points for the rock map.
pub const ROCK_POINTS: f64 = 300.0;
/// Points for mapping productivity.
pub const PRODUCTIVITY_POINTS: f64 = 250.0;
/// Points for not using the fiducials.
pub const FIDUCIAL_POINTS: f64 = 150.0;
/// A height within this of the truth (m, strictly) is correct.
pub const HEIGHT_TOLERANCE_M: f64 = 0.05;
/// Seconds in which the LAC expects the whole map to be filled (a lunar day's allowance).
pub const PRODUCTIVITY_SECONDS: f64 = 86_400.0;

/// A grid's LAC score, with the counts behind it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LacScore {
    /// Geometric-map points (of 300).
    pub geometric: f64,
    /// Rock-map points (of 300).
    pub rocks: f64,
    /// Productivity points (of 250); 0 when no mission duration was given.
    pub productivity: f64,
    /// Fiducial points (150: fiducials are never used).
    pub fiducials: f64,
    /// Sum of the four.
    pub total: f64,
    /// Rock precision TP / (TP + FP) (1 when nothing was marked).
    pub rock_precision: f64,
    /// Rock recall TP / (TP + FN) (1 when the truth has no rock).
    pub rock_recall: f64,
    /// Rock F1 = 2TP / (2TP + FP + FN) (1 when both grids have no rock).
    pub rock_f1: f64,
    /// Fraction of all cells whose height is within 0.05 m of the truth.
    pub height_within_5cm_fraction: f64,
    /// Rock cells correctly marked.
    pub true_positives: usize,
    /// Cells marked as rock that are not.
    pub false_positives: usize,
    /// Rock cells not marked.
    pub false_negatives: usize,
    /// Cells with a height in the estimate.
    pub filled_cells: usize,
    /// Number of cells scored.
    pub cells: usize,
}

/// Why two grids cannot be scored against each other.
#[derive(Debug, Error, PartialEq)]
pub enum ScoreError {
    /// The grids differ in size or cell size.
    #[error(
        "grids differ: estimate has {estimate_cells} × {estimate_cells} cells of {estimate_cell_m} m, \
         truth has {truth_cells} × {truth_cells} cells of {truth_cell_m} m"
    )]
    Mismatch {
        /// Cells per side of the estimate.
        estimate_cells: usize,
        /// Cell size of the estimate, m.
        estimate_cell_m: f64,
        /// Cells per side of the truth.
        truth_cells: usize,
        /// Cell size of the truth, m.
        truth_cell_m: f64,
    },
    /// A grid's vectors do not match its size.
    #[error("{0} grid is inconsistent: {1}")]
    Invalid(&'static str, String),
    /// The mission duration is not a positive finite number.
    #[error("mission duration must be positive and finite, got {0} s")]
    BadDuration(f64),
}

/// Score `estimate` against `truth` by the LAC rules (see the module docs).
///
/// ```
/// use segloc::mapping::score;
/// use segloc_maps::LacGrid;
/// let mut truth = LacGrid::new(2, 0.15);
/// truth.height = vec![1.0; 4];
/// truth.rock[0] = true;
/// let mut est = truth.clone();
/// est.height[3] = 1.2; // off by 20 cm
/// let s = score(&est, &truth, None).unwrap();
/// assert_eq!(s.geometric, 225.0);
/// assert_eq!(s.rocks, 300.0);
/// assert_eq!(s.total, 225.0 + 300.0 + 150.0);
/// ```
pub fn score(
    estimate: &LacGrid,
    truth: &LacGrid,
    mission_seconds: Option<f64>,
) -> Result<LacScore, ScoreError> {
    if estimate.cells_per_side != truth.cells_per_side
        || (estimate.cell_size_m - truth.cell_size_m).abs() > 1e-9
    {
        return Err(ScoreError::Mismatch {
            estimate_cells: estimate.cells_per_side,
            estimate_cell_m: estimate.cell_size_m,
            truth_cells: truth.cells_per_side,
            truth_cell_m: truth.cell_size_m,
        });
    }
    estimate
        .validate()
        .map_err(|e| ScoreError::Invalid("estimate", e.to_string()))?;
    truth
        .validate()
        .map_err(|e| ScoreError::Invalid("truth", e.to_string()))?;
    if let Some(t) = mission_seconds {
        if !(t.is_finite() && t > 0.0) {
            return Err(ScoreError::BadDuration(t));
        }
    }
    let cells = truth.num_cells();
    let within = estimate
        .height
        .iter()
        .zip(&truth.height)
        .filter(|(e, t)| (*e - *t).abs() < HEIGHT_TOLERANCE_M) // NaN compares false
        .count();
    let (mut tp, mut fp, mut fn_) = (0usize, 0usize, 0usize);
    for (&e, &t) in estimate.rock.iter().zip(&truth.rock) {
        match (e, t) {
            (true, true) => tp += 1,
            (true, false) => fp += 1,
            (false, true) => fn_ += 1,
            (false, false) => {}
        }
    }
    let ratio = |num: usize, den: usize| {
        if den == 0 {
            1.0
        } else {
            num as f64 / den as f64
        }
    };
    let rock_f1 = ratio(2 * tp, 2 * tp + fp + fn_);
    let fraction = within as f64 / cells as f64;
    let filled_cells = estimate.filled_count();
    let productivity = match mission_seconds {
        Some(t) => {
            let rate = filled_cells as f64 / t;
            let expected = cells as f64 / PRODUCTIVITY_SECONDS;
            PRODUCTIVITY_POINTS * (rate / expected).min(1.0)
        }
        None => 0.0,
    };
    let geometric = GEOMETRIC_POINTS * fraction;
    let rocks = ROCK_POINTS * rock_f1;
    Ok(LacScore {
        geometric,
        rocks,
        productivity,
        fiducials: FIDUCIAL_POINTS,
        total: geometric + rocks + productivity + FIDUCIAL_POINTS,
        rock_precision: ratio(tp, tp + fp),
        rock_recall: ratio(tp, tp + fn_),
        rock_f1,
        height_within_5cm_fraction: fraction,
        true_positives: tp,
        false_positives: fp,
        false_negatives: fn_,
        filled_cells,
        cells,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 × 4 truth: heights 1.0, rocks at cells 0, 1, 2.
    fn truth() -> LacGrid {
        let mut g = LacGrid::new(4, 0.15);
        g.height = vec![1.0; 16];
        g.rock[0] = true;
        g.rock[1] = true;
        g.rock[2] = true;
        g
    }

    #[test]
    fn exact_numbers_on_a_hand_made_grid() {
        let t = truth();
        let mut e = LacGrid::new(4, 0.15);
        // 8 cells exact, 2 within 4.9 cm, 2 off by exactly 5 cm (wrong), 4 unfilled (wrong)
        for k in 0..8 {
            e.height[k] = 1.0;
        }
        e.height[8] = 1.049;
        e.height[9] = 0.951;
        e.height[10] = 1.0625; // 6.25 cm, exact in binary
        e.height[11] = 0.9375;
        // rocks: TP at 0 and 1, FN at 2, FP at 5 and 6
        e.rock[0] = true;
        e.rock[1] = true;
        e.rock[5] = true;
        e.rock[6] = true;
        let s = score(&e, &t, Some(100.0)).unwrap();
        assert_eq!(s.height_within_5cm_fraction, 10.0 / 16.0);
        assert_eq!(s.geometric, 300.0 * 10.0 / 16.0);
        assert_eq!(
            (s.true_positives, s.false_positives, s.false_negatives),
            (2, 2, 1)
        );
        assert_eq!(s.rock_f1, 4.0 / 7.0);
        assert_eq!(s.rocks, 300.0 * 4.0 / 7.0);
        assert_eq!(s.rock_precision, 0.5);
        assert_eq!(s.rock_recall, 2.0 / 3.0);
        // 12 filled cells in 100 s against 16 / 86400 per second: capped at 250
        assert_eq!(s.filled_cells, 12);
        assert_eq!(s.productivity, 250.0);
        assert_eq!(s.fiducials, 150.0);
        assert_eq!(s.total, s.geometric + s.rocks + 250.0 + 150.0);
        // a slow mission: 12 cells in 86,400 s → 250 × 12/16
        let slow = score(&e, &t, Some(86_400.0)).unwrap();
        assert!((slow.productivity - 187.5).abs() < 1e-9);
        // without a duration, no productivity points
        assert_eq!(score(&e, &t, None).unwrap().productivity, 0.0);
    }

    #[test]
    fn a_perfect_grid_and_an_empty_one() {
        let t = truth();
        let s = score(&t, &t, Some(1.0)).unwrap();
        assert_eq!((s.geometric, s.rocks, s.total), (300.0, 300.0, 1000.0));
        let empty = LacGrid::new(4, 0.15);
        let s = score(&empty, &t, None).unwrap();
        assert_eq!((s.geometric, s.rocks, s.total), (0.0, 0.0, 150.0));
        assert_eq!(s.rock_precision, 1.0);
        assert_eq!(s.rock_recall, 0.0);
        // no rock anywhere: F1 is 1
        let mut flat = t.clone();
        flat.rock = vec![false; 16];
        assert_eq!(score(&flat, &flat, None).unwrap().rock_f1, 1.0);
    }

    #[test]
    fn refuses_mismatched_or_broken_input() {
        let t = truth();
        let other = LacGrid::new(5, 0.15);
        assert!(matches!(
            score(&other, &t, None),
            Err(ScoreError::Mismatch { .. })
        ));
        let mut broken = t.clone();
        broken.rock.pop();
        assert!(matches!(
            score(&broken, &t, None),
            Err(ScoreError::Invalid("estimate", _))
        ));
        assert_eq!(score(&t, &t, Some(0.0)), Err(ScoreError::BadDuration(0.0)));
        assert!(score(&t, &t, Some(f64::NAN)).is_err());
    }
}
