//! Map merging end to end: generated agents, real traverses, the CLI and bad input.

mod common;

use common::{assert_refused, assert_success, segloc};
use segloc::eval::merge::{evaluate_merge, MergeEvalOptions};
use segloc::landmarks::view_bias::{
    estimate_view_bias, LUNARLOC_VIEW_BIAS_M, LUNARLOC_VIEW_BIAS_SIGMA_M,
};
use segloc::landmarks::FusionConfig;
use segloc::merge::{merge_maps, MapStatus, MergeConfig};
use segloc::relocalize::RelocalizeConfig;
use segloc::sim::boulder_field::{two_sessions, FieldConfig};

#[test]
fn three_generated_agents_merge_and_a_stranger_stays_out() {
    let (a, b, _) = two_sessions(&FieldConfig::default(), 21);
    let (c, _, _) = two_sessions(&FieldConfig::default(), 21); // same field, same world frame as a
    let (stranger, _, _) = two_sessions(&FieldConfig::default(), 99);
    let report = merge_maps(
        &[a, b, c, stranger],
        0,
        &RelocalizeConfig::default(),
        &MergeConfig::default(),
    )
    .unwrap();
    let status: Vec<_> = report.maps.iter().map(|m| m.status).collect();
    assert_eq!(
        status,
        [
            MapStatus::Merged,
            MapStatus::Merged,
            MapStatus::Merged,
            MapStatus::Disconnected
        ]
    );
    assert!(report.fused > 20);
    // Map c is map a's session again in the same frame: it must land on the identity.
    let c_pose = report.maps[2].reference_from_map.unwrap();
    assert!(c_pose.translation.vector.norm() < 0.01);
}

#[test]
fn real_agents_are_placed_within_centimetres_and_decoys_never() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let options = MergeEvalOptions {
        agents: 5,
        decoys: 1,
        trials: 4,
        seed: 3,
        view_bias_m: LUNARLOC_VIEW_BIAS_M,
        view_bias_sigma_m: LUNARLOC_VIEW_BIAS_SIGMA_M,
    };
    let report = evaluate_merge(&data, &options, &RelocalizeConfig::default(), |_, _| {}).unwrap();
    assert_eq!(report.decoys_placed, 0);
    assert_eq!(report.placed, report.agents, "a real agent was left out");
    // The bound: 1 cm and 0.1° for every placed agent.
    assert_eq!(report.placed_outside_1cm_0p1deg, 0);
    assert!(
        report.translation_error_m.max <= 0.01,
        "{:?}",
        report.translation_error_m
    );
    assert!(
        report.rotation_error_deg.max <= 0.1,
        "{:?}",
        report.rotation_error_deg
    );
}

#[test]
fn cli_merge_writes_a_map_and_reports_each_input() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("merged.json");
    let t = |n: usize| data.join(format!("lunarloc/traverse_{n}.csv"));
    let out = segloc()
        .args(["map", "merge", "--json", "-o"])
        .arg(&out_path)
        .args([t(3), t(5), t(12)])
        .output()
        .unwrap();
    assert_success(&out);
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let maps = r["maps"].as_array().unwrap();
    assert_eq!(maps.len(), 3);
    assert!(maps.iter().all(|m| m["status"] == "merged"));
    assert_eq!(maps[0]["reference_from_map"][0][0], 1.0);
    assert!(r["fused"].as_u64().unwrap() > 10);
    assert!(r["time_ms"].as_f64().is_some());
    assert!(out_path.exists());
}

#[test]
fn a_bad_input_stops_the_merge_before_anything_is_written() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "frame,x,y,z,detections,boulders\n1,0,0\n").unwrap();
    let out_path = dir.path().join("merged.json");
    let out = segloc()
        .args(["map", "merge", "-o"])
        .arg(&out_path)
        .arg(data.join("lunarloc/traverse_3.csv"))
        .arg(&bad)
        .output()
        .unwrap();
    assert_refused(&out, "bad.csv:2");
    assert!(!out_path.exists());
}

#[test]
fn mixed_gravity_conventions_are_refused() {
    let (a, mut b, _) = two_sessions(&FieldConfig::default(), 4);
    b.gravity_aligned = false;
    let err = merge_maps(
        &[a, b],
        0,
        &RelocalizeConfig::default(),
        &MergeConfig::default(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("dof 6"), "{err}");
}

#[test]
fn the_viewpoint_bias_estimated_from_the_traverses_matches_the_constant() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let sets: Vec<_> = (1..=17)
        .map(|n| {
            segloc_maps::read_lunarloc_traverse(&data.join(format!("lunarloc/traverse_{n}.csv")))
                .unwrap()
                .detections()
        })
        .collect();
    let config = FusionConfig::default();
    let all = estimate_view_bias(&sets, &config).unwrap();
    assert!(all.boulders > 100, "{all:?}");
    assert!((all.bias_m - LUNARLOC_VIEW_BIAS_M).abs() < 0.002, "{all:?}");
    assert!(
        (all.sigma_m - LUNARLOC_VIEW_BIAS_SIGMA_M).abs() < 0.003,
        "{all:?}"
    );
    assert!(all.pooled_bias_m > all.bias_m, "{all:?}");
    // Each half of the traverses on its own gives about the same value.
    let (odd, even): (Vec<_>, Vec<_>) = sets.into_iter().enumerate().partition(|(k, _)| k % 2 == 0);
    for half in [odd, even] {
        let sets: Vec<_> = half.into_iter().map(|(_, s)| s).collect();
        let e = estimate_view_bias(&sets, &config).unwrap();
        assert!((e.bias_m - LUNARLOC_VIEW_BIAS_M).abs() < 0.003, "{e:?}");
    }
}
