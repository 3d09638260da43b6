//! How often a short submap fools the relocalizer: the SLAM loop-closure use, on real data.
//!
//! Every LunarLoc traverse (from `SEGLOC_DATA`, default `../shared/data`) is cut into
//! windows of `WINDOW` simulator frames (default 600, 30 s at 20 Hz). Each window's
//! detections are fused into a submap, mirrored in x (so that no rigid motion aligns it
//! with any traverse), moved by a random 4-DOF transform and relocalized against the full
//! map of every traverse. Every acceptance is a false accept. With `positives` instead,
//! the windows are not mirrored and are relocalized against the other traverses' maps; an
//! acceptance off by more than 10 cm or 1° (measured at the lander, the prior frame's
//! origin) is reported with its inlier count and spread.
//!
//! Run with `cargo run --release --example submap_negatives -- [WINDOW] [positives]`.
#![warn(clippy::too_many_lines)]

use nalgebra::Isometry3;
use rand::SeedableRng;
use segloc::align::Dof;
use segloc::eval::lunarloc::{random_transform, FALSE_ACCEPT_DEG, FALSE_ACCEPT_M, TRAVERSES};
use segloc::eval::{mirrored_x, transform_error, traverse_path};
use segloc::landmarks::{fuse_detections, FusionConfig};
use segloc::relocalize::{Relocalization, RelocalizeConfig, Relocalizer};
use segloc_maps::read_lunarloc_traverse;
use std::collections::BTreeMap;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let data = std::env::var_os("SEGLOC_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    let mut args = std::env::args().skip(1);
    let window: u64 = match args.next() {
        Some(w) => w.parse().map_err(|e| format!("WINDOW {w:?}: {e}"))?,
        None => 600,
    };
    let negatives = args.next().as_deref() != Some("positives");
    let fusion = FusionConfig::default();
    let config = RelocalizeConfig::default();
    let traverses = (1..=TRAVERSES)
        .map(|n| read_lunarloc_traverse(&traverse_path(&data, n)))
        .collect::<Result<Vec<_>, _>>()?;
    let relocalizers = traverses
        .iter()
        .map(|t| Relocalizer::new(fuse_detections(&t.detections(), &fusion), config.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut tally = Tally::default();
    for (q, traverse) in traverses.iter().enumerate() {
        let last = traverse.frames.last().map_or(0, |f| f.frame);
        let all = traverse.detections();
        for start in (0..=last.saturating_sub(window)).step_by(window.max(1) as usize) {
            let mut set = all.clone();
            set.detections
                .retain(|d| d.frame >= start && d.frame < start + window);
            if negatives {
                set = mirrored_x(&set);
            }
            let truth = random_transform(&mut rng, Dof::Four);
            let submap = fuse_detections(&set.transformed(&truth.inverse(), "submap"), &fusion);
            if submap.len() < 6 {
                continue;
            }
            for (p, relocalizer) in relocalizers.iter().enumerate() {
                if !negatives && p == q {
                    continue;
                }
                let answer = relocalizer.relocalize(&submap)?;
                let window_of = (q + 1, start, start + window, p + 1);
                tally.count(&answer, &truth, negatives, window_of, submap.len());
            }
        }
    }
    let kind = if negatives { "mirrored" } else { "true" };
    tally.print(kind, window);
    Ok(())
}

/// The attempts' counts.
#[derive(Default)]
struct Tally {
    tried: usize,
    accepted: usize,
    wrong: usize,
    /// Best hypothesis' inliers (12 = 12 or more) → attempts.
    inliers: BTreeMap<usize, usize>,
    /// Accepted true answers: rotation error over the reported 1σ yaw.
    normalised: Vec<f64>,
}

impl Tally {
    /// Counts one attempt (the window of traverse `q` from frame `start` to `end` against
    /// traverse `p`, 1-based); prints a wrong acceptance.
    fn count(
        &mut self,
        answer: &Relocalization,
        truth: &Isometry3<f64>,
        negatives: bool,
        (q, start, end, p): (usize, u64, u64, usize),
        landmarks: usize,
    ) {
        self.tried += 1;
        let best = answer.diagnostics.hypotheses.first();
        *self
            .inliers
            .entry(best.map_or(0, |h| h.inlier_count).min(12))
            .or_default() += 1;
        let Some(found) = answer.accepted() else {
            return;
        };
        self.accepted += 1;
        let (t, r) = transform_error(&found.prior_from_query, truth);
        let yaw_sigma_deg = found
            .information
            .try_inverse()
            .map_or(f64::INFINITY, |c| c[(2, 2)].max(0.0).sqrt().to_degrees());
        if !negatives {
            self.normalised.push(r / yaw_sigma_deg);
        }
        if negatives || t > FALSE_ACCEPT_M || r > FALSE_ACCEPT_DEG {
            self.wrong += 1;
            println!(
                "traverse {q} frames {start}..{end}: against {p}: {} inliers of {landmarks} landmarks, spread {:.2} m, error {:.3} m / {:.2}° (reported yaw σ {:.2}°)",
                best.map_or(0, |h| h.inlier_count),
                best.map_or(0.0, |h| h.spread_m),
                t,
                r,
                yaw_sigma_deg
            );
        }
    }

    /// The summary lines.
    fn print(mut self, kind: &str, window: u64) {
        let (tried, accepted, wrong) = (self.tried, self.accepted, self.wrong);
        println!(
            "{kind} submaps of {window} frames: {tried} attempts, {accepted} accepted, {wrong} wrong"
        );
        println!(
            "best hypothesis' inliers (12 = 12 or more) → attempts: {:?}",
            self.inliers
        );
        let normalised = &mut self.normalised;
        if !normalised.is_empty() {
            normalised.sort_by(f64::total_cmp);
            let quantile = |q: f64| normalised[((normalised.len() - 1) as f64 * q) as usize];
            let within = |k: f64| normalised.iter().filter(|&&x| x <= k).count();
            println!(
                "rotation error / reported yaw σ over the {} accepted: median {:.2}, 90 % {:.2}, max {:.2}; within 2σ {}, within 3σ {}",
                normalised.len(),
                quantile(0.5),
                quantile(0.9),
                quantile(1.0),
                within(2.0),
                within(3.0)
            );
        }
    }
}
