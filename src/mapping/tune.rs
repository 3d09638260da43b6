//! Honest tuning of the rock-evidence thresholds against a ground-truth grid.
//!
//! The grid is cut into `folds` angular sectors around the origin (the lander); for each
//! sector the thresholds are chosen on the other sectors' cells and the F1 is counted on
//! the held-out one. Pooling the held-out counts gives an F1 no threshold was fitted to.
//! [`sensitivity`] gives the F1 of every threshold pair on the whole grid.

use segloc_maps::LacGrid;
use serde::{Deserialize, Serialize};

use super::rock_evidence::RockEvidence;

/// Counts and F1 of one threshold pair.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThresholdResult {
    /// Minimum detections per cell.
    pub min_hits: u32,
    /// Minimum detections per unit of exposure.
    pub min_rate: f64,
    /// True positives.
    pub tp: usize,
    /// False positives.
    pub fp: usize,
    /// False negatives.
    pub fn_: usize,
    /// Precision.
    pub precision: f64,
    /// Recall.
    pub recall: f64,
    /// F1.
    pub f1: f64,
}

/// The result of a cross-validation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CrossValidation {
    /// Pooled held-out counts (`min_hits` / `min_rate` of the first fold).
    pub held_out: ThresholdResult,
    /// The thresholds chosen for each fold.
    pub chosen: Vec<(u32, f64)>,
    /// Number of folds.
    pub folds: usize,
}

fn counts(
    evidence: &RockEvidence,
    repeated: &[f64],
    truth: &LacGrid,
    min_hits: u32,
    min_rate: f64,
    keep: impl Fn(usize) -> bool,
) -> (usize, usize, usize) {
    let (mut tp, mut fp, mut fn_) = (0, 0, 0);
    for (k, (&repeated, &truth_rock)) in repeated.iter().zip(&truth.rock).enumerate() {
        if !keep(k) {
            continue;
        }
        match (
            evidence.is_rock_with(k, repeated, min_hits, min_rate),
            truth_rock,
        ) {
            (true, true) => tp += 1,
            (true, false) => fp += 1,
            (false, true) => fn_ += 1,
            _ => {}
        }
    }
    (tp, fp, fn_)
}

fn result(min_hits: u32, min_rate: f64, (tp, fp, fn_): (usize, usize, usize)) -> ThresholdResult {
    let r = |a: usize, b: usize| if b == 0 { 1.0 } else { a as f64 / b as f64 };
    ThresholdResult {
        min_hits,
        min_rate,
        tp,
        fp,
        fn_,
        precision: r(tp, tp + fp),
        recall: r(tp, tp + fn_),
        f1: r(2 * tp, 2 * tp + fp + fn_),
    }
}

/// F1 of every (min_hits, min_rate) pair on the whole grid.
pub fn sensitivity(
    evidence: &RockEvidence,
    truth: &LacGrid,
    hits: &[u32],
    rates: &[f64],
) -> Vec<ThresholdResult> {
    let repeated = evidence.repeated_counts();
    let mut out = Vec::new();
    for &h in hits {
        for &r in rates {
            out.push(result(
                h,
                r,
                counts(evidence, &repeated, truth, h, r, |_| true),
            ));
        }
    }
    out
}

/// The angular sector (0..folds) of cell `k` around the grid's centre.
fn sector(grid: &LacGrid, k: usize, folds: usize) -> usize {
    let n = grid.cells_per_side;
    let (x, y) = grid.cell_center(k / n, k % n);
    let a = y.atan2(x) + std::f64::consts::PI; // [0, 2π]
    ((a / std::f64::consts::TAU * folds as f64) as usize).min(folds - 1)
}

/// Sector cross-validation of the thresholds (see the module docs); `folds` ≥ 2.
pub fn cross_validate(
    evidence: &RockEvidence,
    truth: &LacGrid,
    hits: &[u32],
    rates: &[f64],
    folds: usize,
) -> CrossValidation {
    let folds = folds.max(2);
    let repeated = evidence.repeated_counts();
    let sectors: Vec<usize> = (0..truth.num_cells())
        .map(|k| sector(truth, k, folds))
        .collect();
    let mut pooled = (0, 0, 0);
    let mut chosen = Vec::new();
    for f in 0..folds {
        let mut best: Option<(f64, u32, f64)> = None;
        for &h in hits {
            for &r in rates {
                let c = counts(evidence, &repeated, truth, h, r, |k| sectors[k] != f);
                let f1 = result(h, r, c).f1;
                if best.is_none_or(|(b, _, _)| f1 > b) {
                    best = Some((f1, h, r));
                }
            }
        }
        let Some((_, h, r)) = best else {
            continue;
        };
        chosen.push((h, r));
        let c = counts(evidence, &repeated, truth, h, r, |k| sectors[k] == f);
        pooled = (pooled.0 + c.0, pooled.1 + c.1, pooled.2 + c.2);
    }
    let (h0, r0) = chosen.first().copied().unwrap_or((0, 0.0));
    CrossValidation {
        held_out: result(h0, r0, pooled),
        chosen,
        folds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::RockEvidenceConfig;

    #[test]
    fn picks_the_separating_threshold() {
        let mut truth = LacGrid::new(10, 0.15);
        let mut ev = RockEvidence::new(&truth, &RockEvidenceConfig::default());
        for k in 0..100 {
            ev.exposure[k] = 10.0;
            // rocks: 5 hits; others: 1 hit on every third cell
            if k % 7 == 0 {
                truth.rock[k] = true;
                ev.hits[k] = 5.0;
            } else if k % 3 == 0 {
                ev.hits[k] = 1.0;
            }
        }
        let cv = cross_validate(&ev, &truth, &[1, 2], &[0.05, 0.2, 0.6], 4);
        assert_eq!(cv.held_out.f1, 1.0);
        assert_eq!(cv.chosen.len(), 4);
        let s = sensitivity(&ev, &truth, &[1], &[0.05]);
        assert_eq!(s[0].tp, truth.rock_count());
        assert!(s[0].f1 < 1.0);
    }
}
