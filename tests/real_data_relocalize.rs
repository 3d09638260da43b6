//! Relocalization on the real LunarLoc traverses: the paper pairs must pass.

mod common;

use segloc::align::Dof;
use segloc::eval::lunarloc::{evaluate, EvalOptions, PAPER_PAIRS};
use segloc::relocalize::RelocalizeConfig;

fn run(dof: Dof, trials: usize) -> segloc::eval::lunarloc::EvalReport {
    let data = common::data_dir().expect("data");
    let config = RelocalizeConfig {
        dof: Some(dof),
        ..RelocalizeConfig::default()
    };
    let options = EvalOptions {
        pairs: PAPER_PAIRS.to_vec(),
        trials,
        seed: 1,
        dof,
    };
    evaluate(&data, &options, &config, |_, _| {}).expect("evaluation runs")
}

#[test]
fn paper_pairs_4dof_all_succeed_within_a_centimetre() {
    if common::data_dir().is_none() {
        return;
    }
    let report = run(Dof::Four, 20);
    let t = &report.totals;
    for p in &report.pairs {
        assert_eq!(
            p.successes,
            p.trials.len(),
            "pair ({}, {}) failed: {:?}",
            p.prior,
            p.query,
            p.trials.iter().find(|t| !t.correct)
        );
    }
    assert_eq!(t.false_accepts, 0);
    assert!(
        t.translation_error_m.mean <= 0.005,
        "mean translation error {} m",
        t.translation_error_m.mean
    );
    assert!(
        t.translation_error_m.max <= 0.010,
        "max translation error {} m",
        t.translation_error_m.max
    );
    assert!(
        t.rotation_error_deg.max <= 0.1,
        "max rotation error {} deg",
        t.rotation_error_deg.max
    );
}

#[test]
fn paper_pairs_6dof_all_succeed_within_two_centimetres() {
    if common::data_dir().is_none() {
        return;
    }
    let report = run(Dof::Six, 5);
    let t = &report.totals;
    for p in &report.pairs {
        assert_eq!(
            p.successes,
            p.trials.len(),
            "pair ({}, {}) failed: {:?}",
            p.prior,
            p.query,
            p.trials.iter().find(|t| !t.correct)
        );
    }
    assert_eq!(t.false_accepts, 0);
    assert!(
        t.translation_error_m.max <= 0.02,
        "max translation error {} m",
        t.translation_error_m.max
    );
}
