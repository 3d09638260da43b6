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

use rand::SeedableRng;
use segloc::align::Dof;
use segloc::eval::lunarloc::{random_transform, FALSE_ACCEPT_DEG, FALSE_ACCEPT_M, TRAVERSES};
use segloc::eval::{mirrored_x, transform_error, traverse_path};
use segloc::landmarks::{fuse_detections, FusionConfig};
use segloc::relocalize::{RelocalizeConfig, Relocalizer};
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
    let (mut tried, mut accepted, mut wrong) = (0, 0, 0);
    // best hypothesis' inliers (12 = 12 or more) → attempts
    let mut inliers: BTreeMap<usize, usize> = BTreeMap::new();
    // accepted true answers: rotation error over the reported 1σ yaw, sorted at the end
    let mut normalised: Vec<f64> = Vec::new();
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
                tried += 1;
                let best = answer.diagnostics.hypotheses.first();
                *inliers
                    .entry(best.map_or(0, |h| h.inlier_count).min(12))
                    .or_default() += 1;
                let Some(found) = answer.accepted() else {
                    continue;
                };
                accepted += 1;
                let (t, r) = transform_error(&found.prior_from_query, &truth);
                let yaw_sigma_deg = found
                    .information
                    .try_inverse()
                    .map_or(f64::INFINITY, |c| c[(2, 2)].max(0.0).sqrt().to_degrees());
                if !negatives {
                    normalised.push(r / yaw_sigma_deg);
                }
                if negatives || t > FALSE_ACCEPT_M || r > FALSE_ACCEPT_DEG {
                    wrong += 1;
                    println!(
                        "traverse {} frames {start}..{}: against {}: {} inliers of {} landmarks, spread {:.2} m, error {:.3} m / {:.2}° (reported yaw σ {:.2}°)",
                        q + 1,
                        start + window,
                        p + 1,
                        best.map_or(0, |h| h.inlier_count),
                        submap.len(),
                        best.map_or(0.0, |h| h.spread_m),
                        t,
                        r,
                        yaw_sigma_deg
                    );
                }
            }
        }
    }
    let kind = if negatives { "mirrored" } else { "true" };
    println!(
        "{kind} submaps of {window} frames: {tried} attempts, {accepted} accepted, {wrong} wrong"
    );
    println!("best hypothesis' inliers (12 = 12 or more) → attempts: {inliers:?}");
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
    Ok(())
}
