//! `segloc graph …` end to end: results, files and bad input (exit code 2, no panic).

mod common;

use std::path::Path;
use std::process::Output;

fn segloc(args: &[&str]) -> Output {
    common::segloc().args(args).output().expect("run segloc")
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_string_lossy().into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const INFO: &str = "1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1";

/// A 4-pose square with a slightly inconsistent loop closure, TORO, no vertices.
fn square_toro() -> String {
    let h = std::f64::consts::FRAC_PI_2;
    let mut s = String::new();
    for i in 0..3 {
        s += &format!("EDGE3 {i} {} 1 0 0 0 0 {h} {INFO}\n", i + 1);
    }
    s += &format!("EDGE3 3 0 1.1 0 0 0 0 {h} {INFO}\n");
    s
}

#[test]
fn optimize_prints_one_json_object_with_the_costs() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "square.graph", &square_toro());
    let o = segloc(&["graph", "optimize", &input, "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "poses",
        "factors",
        "initial_cost",
        "final_cost",
        "iterations",
        "time_ms",
    ] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert_eq!(v["poses"], 4);
    assert_eq!(v["factors"], 4);
    let (c0, c1) = (
        v["initial_cost"].as_f64().unwrap(),
        v["final_cost"].as_f64().unwrap(),
    );
    assert!(c1 < c0 && c1 > 0.0, "{c0} -> {c1}");
}

#[test]
fn output_round_trips_in_both_formats() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "square.graph", &square_toro());
    for out_name in ["out.g2o", "out.graph"] {
        let out = dir.path().join(out_name).to_string_lossy().into_owned();
        let o = segloc(&["graph", "optimize", &input, "-o", &out, "--json"]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let first: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        // Re-optimising the written optimum starts (and stays) at the same cost.
        let o = segloc(&["graph", "optimize", &out, "--json", "--init", "chained"]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let again: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let c = first["final_cost"].as_f64().unwrap();
        let c2 = again["initial_cost"].as_f64().unwrap();
        assert!(
            (c - c2).abs() <= 1e-9 * c.max(1.0),
            "{out_name}: {c} vs {c2}"
        );
        let text = std::fs::read_to_string(&out).unwrap();
        let tag = if out_name.ends_with(".g2o") {
            "VERTEX_SE3:QUAT"
        } else {
            "VERTEX3"
        };
        assert!(
            text.starts_with(tag),
            "{out_name}: {}",
            &text[..40.min(text.len())]
        );
    }
}

#[test]
fn unknown_tags_are_skipped_with_one_warning() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!("FOO 1 2 3\n{}BAR x\nFOO 4\n", square_toro());
    let input = write(dir.path(), "tags.graph", &text);
    let o = segloc(&["graph", "optimize", &input, "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let err = stderr(&o);
    assert_eq!(err.matches("warning").count(), 1, "{err}");
    assert!(err.contains("FOO") && err.contains("BAR"), "{err}");
}

#[test]
fn bad_input_exits_with_code_2_and_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let good = "VERTEX3 0 0 0 0 0 0 0\nVERTEX3 1 1 0 0 0 0 0\n";
    let cases = [
        (
            "malformed",
            format!("{good}EDGE3 0 1 1 0 0 0 0\n"),
            "missing EDGE3 value",
        ),
        (
            "not_a_number",
            format!("{good}EDGE3 0 1 1 zero 0 0 0 0 {INFO}\n"),
            "not a number",
        ),
        (
            "nan",
            format!("{good}EDGE3 0 1 1 NaN 0 0 0 0 {INFO}\n"),
            "NaN",
        ),
        (
            "missing_vertex",
            format!("{good}EDGE3 0 7 1 0 0 0 0 0 {INFO}\n"),
            "missing vertex 7",
        ),
        (
            "g2o_zero_quaternion",
            "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n".to_string(),
            "quaternion",
        ),
    ];
    for (name, text, needle) in cases {
        let input = write(dir.path(), &format!("{name}.graph"), &text);
        let o = segloc(&["graph", "optimize", &input]);
        common::assert_refused(&o, needle);
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{name}: {err}");
        if name != "g2o_zero_quaternion" {
            assert!(err.contains(&format!("{name}.graph:3:")), "{name}: {err}");
        }
    }
}

#[test]
fn missing_files_and_bad_options_exit_with_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "square.graph", &square_toro());
    let missing = dir.path().join("nope.g2o").to_string_lossy().into_owned();
    for args in [
        vec!["graph", "optimize", missing.as_str()],
        vec!["graph", "optimize", input.as_str(), "--robust", "sometimes"],
        vec![
            "graph",
            "optimize",
            input.as_str(),
            "--robust",
            "cauchy",
            "--robust-scale",
            "-1",
        ],
        vec!["graph", "optimize"],
        vec![
            "graph",
            "corrupt",
            input.as_str(),
            "-o",
            "x.graph",
            "--fraction",
            "2",
        ],
    ] {
        let o = segloc(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{args:?}");
    }
}

#[test]
fn robust_kernels_run_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "square.graph", &square_toro());
    for kernel in ["none", "huber", "cauchy", "gnc"] {
        let o = segloc(&["graph", "optimize", &input, "--robust", kernel, "--json"]);
        assert_eq!(o.status.code(), Some(0), "{kernel}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["robust"], kernel);
        assert_eq!(v["converged"], true, "{kernel}: {v}");
    }
}

#[test]
fn corrupt_and_ate_subcommands_work() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "square.graph", &square_toro());
    let out = dir.path().join("bad.graph").to_string_lossy().into_owned();
    let o = segloc(&["graph", "corrupt", &input, "-o", &out, "--fraction", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("replaced 1 of 4"), "{}", stderr(&o));
    let o = segloc(&["graph", "ate", &input, &input, "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["matched"], 4);
    assert!(v["position_rmse_m"].as_f64().unwrap() < 1e-12);
}

#[test]
fn solver_config_prints_and_loads_back() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "square.graph", &square_toro());
    let o = segloc(&["graph", "optimize", &input, "--print-config"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let printed = String::from_utf8_lossy(&o.stdout).replace(
        "single_precision_regime = 0.01",
        "single_precision_regime = inf",
    );
    assert!(
        printed.contains("single_precision_regime = inf"),
        "{printed}"
    );
    let config = write(dir.path(), "solver.toml", &printed);
    let o = segloc(&[
        "graph",
        "optimize",
        &input,
        "--solver-config",
        &config,
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["single_precision_factorizations"], 0);
    // A bad value names the file and exits 2.
    let bad = write(dir.path(), "bad.toml", "max_iterations = \"many\"\n");
    let o = segloc(&["graph", "optimize", &input, "--solver-config", &bad]);
    common::assert_refused(&o, "bad.toml");
}

/// The square with vertices away from the optimum, and one loop closure whose information
/// matrix has a negative entry on its diagonal (line 8).
fn square_with_bad_information() -> String {
    let mut s = String::new();
    for (i, (x, y)) in [(0.0, 0.0), (1.2, 0.1), (0.9, 1.1), (-0.1, 0.8)]
        .iter()
        .enumerate()
    {
        let yaw = std::f64::consts::FRAC_PI_2 * i as f64 + 0.1;
        s += &format!("VERTEX3 {i} {x} {y} 0 0 0 {yaw}\n");
    }
    let lines: Vec<String> = square_toro().lines().map(str::to_string).collect();
    s += &format!("{}\n{}\n{}\n", lines[0], lines[1], lines[2]);
    s += &lines[3].replace(" 1 0 0 1 0 1", " 1 0 0 -1 0 1");
    s += "\n";
    s
}

#[test]
fn indefinite_information_is_repaired_with_a_warning_unless_strict() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "bad_info.graph", &square_with_bad_information());
    let o = segloc(&["graph", "optimize", &input, "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("repaired 1 information matrices") && err.contains("bad_info.graph:8"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["repaired_information"]["count"], 1, "{v}");
    assert_eq!(
        v["repaired_information"]["first_lines"],
        serde_json::json!([8])
    );
    assert_eq!(v["converged"], true, "{v}");
    // --strict keeps the refusal, naming the line.
    let o = segloc(&["graph", "optimize", &input, "--strict"]);
    common::assert_refused(&o, "bad_info.graph:8:");
    common::assert_refused(&o, "positive definite");
    // A clean file reports zero repairs.
    let clean = write(dir.path(), "square.graph", &square_toro());
    let o = segloc(&["graph", "optimize", &clean, "--json", "--strict"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["repaired_information"]["count"], 0);
}

#[test]
fn init_choice_is_used_and_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let text = square_with_bad_information().replace(" 1 0 0 -1 0 1", " 1 0 0 1 0 1");
    let input = write(dir.path(), "vertices.graph", &text);
    let run = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec!["graph", "optimize", input.as_str(), "--json"];
        args.extend_from_slice(extra);
        let o = segloc(&args);
        assert_eq!(o.status.code(), Some(0), "{extra:?}: {}", stderr(&o));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let default = run(&[]);
    assert_eq!(default["init"], "chordal");
    let robust = run(&["--robust", "huber"]);
    assert_eq!(robust["init"], "file");
    let mut optimum = None;
    let mut starts = Vec::new();
    for init in ["chordal", "file", "odometry"] {
        let v = run(&["--init", init]);
        assert_eq!(v["init"], init);
        let c = v["final_cost"].as_f64().unwrap();
        let c0 = *optimum.get_or_insert(c);
        assert!((c - c0).abs() <= 1e-9 * c0, "{init}: {c} vs {c0}");
        starts.push(v["initial_cost"].as_f64().unwrap());
    }
    // The initial cost is reported at the file's vertices before chordal initialisation;
    // chained odometry starts elsewhere.
    assert_eq!(starts[0], starts[1]);
    assert!(starts[2] != starts[1], "{starts:?}");
    // --init file needs vertices.
    let no_vertices = write(dir.path(), "square.graph", &square_toro());
    let o = segloc(&["graph", "optimize", &no_vertices, "--init", "file"]);
    common::assert_refused(&o, "square.graph");
    let o = segloc(&[
        "graph",
        "optimize",
        &no_vertices,
        "--init",
        "odometry",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

#[test]
fn a_file_with_nothing_readable_exits_with_code_2() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [("tags.g2o", "FOO 1 2 3\nBAR x\n"), ("empty.g2o", "")] {
        let input = write(dir.path(), name, text);
        let o = segloc(&["graph", "optimize", &input, "--json"]);
        common::assert_refused(&o, name);
        common::assert_refused(&o, "no vertex or edge");
        assert!(o.stdout.is_empty(), "{name}");
    }
}
