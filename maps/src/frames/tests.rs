use super::*;
use nalgebra::UnitQuaternion;

const HEADER: &str = "{\"format\": \"segloc-frames\", \"version\": 1}";

/// A full frame, a minimal one and one with awkward numbers.
fn frames() -> Vec<StreamFrame> {
    let full = StreamFrame {
        t: 0.1,
        odom_from_rover: Isometry3::new(
            Vector3::new(-3.034147449137282, 4.9741238220042385, 0.3),
            Vector3::new(0.01, -0.02, 2.5),
        ),
        gravity_rover: Some(Vector3::new(0.1, -0.05, -1.62)),
        detections: vec![
            FrameDetection {
                p_rover: Point3::new(3.1, 0.4, -0.2),
                size_m: Some(0.42),
                cov_rover: Some(Matrix3::new(
                    4e-4, 1e-5, -2e-5, 1e-5, 3e-4, 0.0, -2e-5, 0.0, 9e-4,
                )),
            },
            FrameDetection {
                p_rover: Point3::new(7.0, -1.5, 0.0),
                size_m: None,
                cov_rover: None,
            },
        ],
        lander_points_rover: vec![Point3::new(10.0, 2.0, 0.5), Point3::new(10.5, 2.0, 1.5)],
        path: Some(FramePath {
            distance_m: 0.051,
            turned_rad: -0.01,
            turned_abs_rad: 0.02,
        }),
        step_cov: Some(Matrix6::from_fn(|r, c| {
            if r == c {
                [1e-6, 1e-6, 4e-6, 1e-5, 1e-5, 2e-5][r]
            } else {
                1e-8
            }
        })),
    };
    let minimal = StreamFrame::new(0.2, Isometry3::identity());
    let mut awkward = StreamFrame::new(
        1_700_000_000.123_456_7,
        Isometry3::new(Vector3::new(1e-300, -0.0, 1.7e308), Vector3::zeros()),
    );
    awkward.detections.push(FrameDetection {
        p_rover: Point3::new(5e-324, 0.1 + 0.2, -7.0),
        size_m: Some(0.0),
        cov_rover: None,
    });
    vec![full, minimal, awkward]
}

fn text() -> String {
    let mut s = format!("{HEADER}\n");
    for f in frames() {
        s.push_str(&frame_to_json_line(&f));
        s.push('\n');
    }
    s
}

fn parse(text: &str) -> Result<FramesFile, MapError> {
    parse_frames(text, "rec/drive.jsonl")
}

fn err(text: &str) -> String {
    parse(text).unwrap_err().to_string()
}

/// A frame line with `extra` fields after `t` and the pose.
fn line(t: f64, extra: &str) -> String {
    format!("{{\"t\": {t:?}, \"odom_from_rover\": [0, 0, 0, 0, 0, 0, 1]{extra}}}")
}

/// The error for a file whose second frame line is `bad`.
fn err2(bad: &str) -> String {
    err(&format!("{HEADER}\n{}\n{bad}\n", line(0.0, "")))
}

fn bits(f: &StreamFrame) -> Vec<u64> {
    let mut v = vec![f.t.to_bits()];
    v.extend(
        f.odom_from_rover
            .translation
            .vector
            .iter()
            .map(|x| x.to_bits()),
    );
    v.extend(
        f.odom_from_rover
            .rotation
            .coords
            .iter()
            .map(|x| x.to_bits()),
    );
    for d in &f.detections {
        v.extend(d.p_rover.iter().map(|x| x.to_bits()));
    }
    v
}

#[test]
fn round_trip_exact_through_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("drive.jsonl");
    write_frames(&p, &frames()).unwrap();
    let back = read_frames(&p).unwrap();
    assert_eq!(back.frames, frames());
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    for (a, b) in back.frames.iter().zip(frames()) {
        assert_eq!(bits(a), bits(&b), "bit-exact, -0.0 included");
    }
    assert_eq!(std::fs::read_to_string(&p).unwrap(), text());
}

#[test]
fn text_looks_as_documented() {
    let text = text();
    let lines: Vec<_> = text.lines().collect();
    assert_eq!(lines[0], HEADER);
    assert_eq!(
        lines[2],
        "{\"t\": 0.2, \"odom_from_rover\": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], \"detections\": []}"
    );
    assert!(
        lines[1].contains(
            "\"size_m\": 0.42, \"cov_rover\": [0.0004, 1e-5, -2e-5, 0.0003, 0.0, 0.0009]}"
        ),
        "{}",
        lines[1]
    );
    assert!(lines[1].contains(
        "\"path\": {\"distance_m\": 0.051, \"turned_rad\": -0.01, \"turned_abs_rad\": 0.02}"
    ));
    // the step covariance's upper triangle, row by row
    assert!(
        lines[1].ends_with(
            "\"step_cov\": [1e-6, 1e-8, 1e-8, 1e-8, 1e-8, 1e-8, 1e-6, 1e-8, 1e-8, 1e-8, 1e-8, \
             4e-6, 1e-8, 1e-8, 1e-8, 1e-5, 1e-8, 1e-8, 1e-5, 1e-8, 2e-5]}"
        ),
        "{}",
        lines[1]
    );
    assert!(lines[3].contains("\"p_rover\": [5e-324, 0.30000000000000004, -7.0]"));
    assert!(!frame_to_json_line(&frames()[0]).contains('\n'));
}

#[test]
fn header_is_optional() {
    let with = parse(&text()).unwrap();
    let without = text().split_once('\n').unwrap().1.to_string();
    assert_eq!(parse(&without).unwrap(), with);
    // blank lines, CRLF and a byte-order mark
    let messy = format!("\u{feff}\r\n{}\r\n\r\n\n", without.replace('\n', "\r\n\n"));
    assert_eq!(parse(&messy).unwrap(), with);
}

#[test]
fn other_versions_and_formats_are_refused() {
    let frame = line(0.0, "");
    let e = parse(&format!(
        "{{\"format\": \"segloc-frames\", \"version\": 2}}\n{frame}\n"
    ))
    .unwrap_err();
    assert!(matches!(e, MapError::UnsupportedVersion { found: 2, .. }));
    assert_eq!(
        e.to_string(),
        "frames file rec/drive.jsonl has format version 2; this segloc reads versions up to 1: upgrade segloc"
    );
    assert_eq!(
        err(&format!("\n{{\"format\": \"segloc-map\", \"version\": 1}}\n{frame}\n")),
        "rec/drive.jsonl:2: \"format\" is \"segloc-map\", expected \"segloc-frames\": not a segloc frames file"
    );
    assert_eq!(
        err("{\"format\": \"segloc-frames\", \"version\": 0}\n"),
        "rec/drive.jsonl:1: \"version\" 0 does not exist; versions start at 1"
    );
    assert!(err("{\"format\": \"segloc-frames\", \"version\": \"1\"}\n").starts_with(
        "rec/drive.jsonl:1: \"version\" is \"1\", expected a positive integer (this segloc reads version 1)"
    ));
    assert!(err("{\"format\": \"segloc-frames\"}\n")
        .contains("rec/drive.jsonl:1: the header has no \"version\""));
    assert!(err("{\"version\": 1}\n")
        .contains("rec/drive.jsonl:1: the header has \"version\" but no \"format\""));
    assert!(err(&format!("{frame}\n{HEADER}\n")).starts_with("rec/drive.jsonl:2: a header line"));
}

#[test]
fn empty_files_are_refused() {
    for text in ["", "\n\n  \n", HEADER, "\u{feff}"] {
        assert_eq!(
            err(text),
            "rec/drive.jsonl: no frames: expected one JSON object per camera frame"
        );
    }
}

#[test]
fn malformed_lines_name_line_and_field() {
    assert_eq!(
        err2("{\"t\": 1.0, \"odom_from_rover\": [0, 0, 0, 0, 0, 0, 1]"),
        "rec/drive.jsonl:3: the JSON ends early (truncated line?): EOF while parsing an object (column 51)"
    );
    assert!(err2("{\"t\": 1.0,, }").starts_with("rec/drive.jsonl:3: JSON syntax error: "));
    // the column counts from the start of the line, leading blanks included
    assert!(err2("  {\"t\": 1.0,, }").ends_with("(column 13)"));
    assert!(err2("{\"t\": 1.0} {}")
        .starts_with("rec/drive.jsonl:3: JSON syntax error: trailing characters"));
    assert_eq!(
        err2("[1, 2]"),
        "rec/drive.jsonl:3: expected a JSON object (one frame per line), got an array [1,2]"
    );
    assert_eq!(
        err2("{\"odom_from_rover\": [0, 0, 0, 0, 0, 0, 1]}"),
        "rec/drive.jsonl:3: \"t\" is missing"
    );
    assert_eq!(
        err2("{\"t\": 1}"),
        "rec/drive.jsonl:3: \"odom_from_rover\" is missing"
    );
    assert_eq!(
        err2("{\"t\": \"1.0\", \"odom_from_rover\": [0, 0, 0, 0, 0, 0, 1]}"),
        "rec/drive.jsonl:3: t: expected a number, got a string \"1.0\""
    );
    assert_eq!(
        err2("{\"t\": 1, \"odom_from_rover\": [0, 0, 0, 0, 0, 1]}"),
        "rec/drive.jsonl:3: odom_from_rover: expected 7 numbers, got 6"
    );
    assert_eq!(
        err2("{\"t\": 1, \"odom_from_rover\": [0, 0, null, 0, 0, 0, 1]}"),
        "rec/drive.jsonl:3: odom_from_rover[2]: expected a number, got null"
    );
    assert_eq!(
        err2(&line(1.0, ", \"gravity_rover\": [0, -1.6]")),
        "rec/drive.jsonl:3: gravity_rover: expected 3 numbers, got 2"
    );
    assert_eq!(
        err2(&line(1.0, ", \"detections\": {}")),
        "rec/drive.jsonl:3: detections: expected an array, got an object {}"
    );
    assert_eq!(
        err2(&line(
            1.0,
            ", \"detections\": [{\"p_rover\": [1, 2, 3]}, 7]"
        )),
        "rec/drive.jsonl:3: detections[1]: expected an object, got a number 7"
    );
    assert_eq!(
        err2(&line(1.0, ", \"detections\": [{\"size_m\": 1}]")),
        "rec/drive.jsonl:3: detections[0].p_rover is missing"
    );
    assert_eq!(
        err2(&line(
            1.0,
            ", \"detections\": [{\"p_rover\": [1, 2, 3, 4]}]"
        )),
        "rec/drive.jsonl:3: detections[0].p_rover: expected 3 numbers, got 4"
    );
    assert_eq!(
        err2(&line(
            1.0,
            ", \"detections\": [{\"p_rover\": [1, 2, 3], \"cov_rover\": [1, 0, 0, 1, 0]}]"
        )),
        "rec/drive.jsonl:3: detections[0].cov_rover: expected 6 numbers, got 5"
    );
    assert_eq!(
        err2(&line(1.0, ", \"lander_points_rover\": [[1, 2, 3], [1, 2]]")),
        "rec/drive.jsonl:3: lander_points_rover[1]: expected 3 numbers, got 2"
    );
    assert_eq!(
        err2(&line(
            1.0,
            ", \"path\": {\"distance_m\": 1, \"turned_rad\": 0}"
        )),
        "rec/drive.jsonl:3: path.turned_abs_rad is missing"
    );
    assert_eq!(
        err2(&line(1.0, ", \"path\": 3")),
        "rec/drive.jsonl:3: path: expected an object, got a number 3"
    );
}

#[test]
fn infinity_is_refused() {
    // serde_json reads 1e999 as infinity or refuses it as out of range: either way an error
    for bad in [
        "{\"t\": 1e999, \"odom_from_rover\": [0, 0, 0, 0, 0, 0, 1]}".to_string(),
        "{\"t\": 1, \"odom_from_rover\": [0, 0, -1e999, 0, 0, 0, 1]}".to_string(),
        line(
            1.0,
            ", \"detections\": [{\"p_rover\": [1, 2, 3], \"size_m\": 1e400}]",
        ),
        line(1.0, ", \"lander_points_rover\": [[1, 2, 1e999]]"),
    ] {
        let e = err2(&bad);
        assert!(e.starts_with("rec/drive.jsonl:3: "), "{e}");
        assert!(e.contains("finite"), "{e}");
    }
    assert_eq!(
        err2(&line(1.0, ", \"lander_points_rover\": [[1, 2, -1e999]]")),
        "rec/drive.jsonl:3: number -1e999 (column 90) is out of range; every value must be finite"
    );
}

#[test]
fn values_are_checked() {
    assert_eq!(
        err2(&line(0.0, "")),
        "rec/drive.jsonl:3: t = 0.0 is not after t = 0.0 of the previous frame (line 2); times must be strictly increasing"
    );
    assert!(err2(&line(-1.5, "")).contains("t = -1.5 is not after t = 0.0"));
    let e = err2("{\"t\": 1, \"odom_from_rover\": [0, 0, 0, 0, 0, 0, 1.01]}");
    assert!(
        e.starts_with("rec/drive.jsonl:3: odom_from_rover: quaternion"),
        "{e}"
    );
    assert!(e.contains("has norm 1.01, not 1"), "{e}");
    assert_eq!(
        err2(&line(1.0, ", \"gravity_rover\": [0, 0, 0]")),
        "rec/drive.jsonl:3: gravity_rover: [0.0, 0.0, 0.0] is not a usable gravity vector (its length must be finite and non-zero)"
    );
    assert!(err2(&line(1.0, ", \"gravity_rover\": [1e200, 1e200, 0]")).contains("gravity_rover"));
    assert_eq!(
        err2(&line(
            1.0,
            ", \"detections\": [{\"p_rover\": [1, 2, 3], \"size_m\": -0.1}]"
        )),
        "rec/drive.jsonl:3: detections[0].size_m: -0.1 is not a finite non-negative number"
    );
    let e = err2(&line(
        1.0,
        ", \"detections\": [{\"p_rover\": [1, 2, 3]}, {\"p_rover\": [1, 2, 3], \"cov_rover\": [0.01, 0.1, 0, 0.01, 0, 0.01]}]",
    ));
    assert!(
        e.starts_with(
            "rec/drive.jsonl:3: detections[1].cov_rover: covariance is not positive semi-definite"
        ),
        "{e}"
    );
    assert_eq!(
        err2(&line(
            1.0,
            ", \"detections\": [{\"p_rover\": [1, 2, 3], \"cov_rover\": [0.01, 0, 0, 0, 0, 0.01]}]"
        )),
        "rec/drive.jsonl:3: detections[0].cov_rover: variance yy = 0 must be positive"
    );
    assert!(err2(&line(
        1.0,
        ", \"detections\": [{\"p_rover\": [1, 2, 3], \"cov_rover\": [-1, 0, 0, 1, 0, 1]}]"
    ))
    .contains("detections[0].cov_rover: covariance has a negative variance xx"));
    // a step covariance: 21 numbers, positive definite
    let identity6 = "1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 1";
    assert!(parse(&line(1.0, &format!(", \"step_cov\": [{identity6}]"))).is_ok());
    assert_eq!(
        err2(&line(1.0, ", \"step_cov\": [1, 0, 0]")),
        "rec/drive.jsonl:3: step_cov: expected 21 numbers, got 3"
    );
    assert!(err2(&line(
        1.0,
        &format!(", \"step_cov\": [{}]", identity6.replacen('1', "-1", 1))
    ))
    .starts_with("rec/drive.jsonl:3: step_cov: the covariance is not positive definite"));
    assert_eq!(
        err2(&line(
            1.0,
            ", \"path\": {\"distance_m\": -1, \"turned_rad\": 0, \"turned_abs_rad\": 0}"
        )),
        "rec/drive.jsonl:3: path.distance_m: -1 is negative"
    );
    assert!(err2(&line(
        1.0,
        ", \"path\": {\"distance_m\": 1, \"turned_rad\": -0.5, \"turned_abs_rad\": 0.2}"
    ))
    .contains("path: turned_abs_rad = 0.2 must be ≥ 0 and ≥ |turned_rad| = 0.5"));
}

#[test]
fn unknown_fields_are_ignored_and_null_is_absent() {
    let text = format!(
        "{}\n",
        line(
            1.0,
            ", \"gravity_rover\": null, \"detections\": null, \"path\": null, \"wheel_slip\": [1, 2], \
             \"lander_points_rover\": null, \"camera\": {\"id\": \"front\"}"
        )
    );
    let f = parse(&text).unwrap();
    assert_eq!(f.frames, vec![StreamFrame::new(1.0, Isometry3::identity())]);
    let d = parse(&format!(
        "{}\n",
        line(
            1.0,
            ", \"detections\": [{\"p_rover\": [1, 2, 3], \"size_m\": null, \"score\": 0.9}]"
        )
    ))
    .unwrap();
    assert_eq!(d.frames[0].detections[0].size_m, None);
}

#[test]
fn slightly_off_quaternions_are_normalised_with_a_warning() {
    let text = format!(
        "{HEADER}\n{}\n{{\"t\": 1, \"odom_from_rover\": [1, 2, 3, 0, 0, 0, 1.0004]}}\n\
         {{\"t\": 2, \"odom_from_rover\": [0, 0, 0, 0.6, 0, 0, 0.8000001]}}\n",
        line(0.0, "")
    );
    let f = parse(&text).unwrap();
    assert_eq!(
        f.warnings,
        vec!["rec/drive.jsonl:3: quaternion norm 1.0004 normalised"]
    );
    assert_eq!(
        f.frames[1].odom_from_rover.rotation,
        UnitQuaternion::identity()
    );
    assert_eq!(
        f.frames[1].odom_from_rover.translation.vector,
        Vector3::new(1.0, 2.0, 3.0)
    );
    // print rounding (< 1e-6) is normalised without a warning
    assert!((f.frames[2].odom_from_rover.rotation.coords.norm() - 1.0).abs() < 1e-15);
}

#[test]
fn write_refuses_what_cannot_be_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("drive.jsonl");
    let e = write_frames(&p, &[]).unwrap_err().to_string();
    assert!(
        e.ends_with("drive.jsonl: no frames (a frames file holds at least one)"),
        "{e}"
    );
    let mut bad = frames();
    bad[2].t = 0.15;
    let e = write_frames(&p, &bad).unwrap_err().to_string();
    assert!(
        e.ends_with(
            "frame 2: t = 0.15 is not after t = 0.2 of frame 1; times must be strictly increasing"
        ),
        "{e}"
    );
    let mut bad = frames();
    bad[0].detections[1].p_rover.y = f64::NAN;
    let e = write_frames(&p, &bad).unwrap_err().to_string();
    assert!(
        e.ends_with("frame 0 (t = 0.1): detections[1].p_rover: a value is not finite"),
        "{e}"
    );
    let mut bad = frames();
    bad[1].gravity_rover = Some(Vector3::zeros());
    assert!(write_frames(&p, &bad).is_err());
    assert!(!p.exists());
}

#[test]
fn non_utf8_is_an_error_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("drive.jsonl");
    let mut bytes = text().into_bytes();
    bytes.extend_from_slice(b"{\"t\": 9, \"note\": \"\xff\"}\n");
    std::fs::write(&p, &bytes).unwrap();
    let e = read_frames(&p).unwrap_err();
    assert_eq!(e.line(), Some(5), "{e}");
    let e = read_frames(&dir.path().join("missing.jsonl")).unwrap_err();
    assert!(matches!(e, MapError::Io { .. }));
}

#[test]
fn five_thousand_frames_parse() {
    let mut frames = Vec::new();
    for k in 0..5000 {
        let mut f = frames_template(k);
        f.t = k as f64 * 0.1;
        frames.push(f);
    }
    let mut text = format!("{HEADER}\n");
    for f in &frames {
        text.push_str(&frame_to_json_line(f));
        text.push('\n');
    }
    let back = parse(&text).unwrap();
    assert_eq!(back.frames.len(), 5000);
    assert_eq!(back.frames, frames);
}

fn frames_template(k: usize) -> StreamFrame {
    let mut f = frames()[0].clone();
    f.detections.truncate(1 + k % 2);
    f
}

#[test]
fn no_prefix_of_a_valid_file_panics() {
    // a non-ASCII unknown field, so that some prefixes end inside a UTF-8 character
    let mut text = text();
    text.push_str(&line(1e10, ", \"note\": \"régolithe °\""));
    text.push('\n');
    let bytes = text.as_bytes();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("cut.jsonl");
    let mut complete = 0;
    for end in 0..=bytes.len() {
        match std::str::from_utf8(&bytes[..end]) {
            Ok(prefix) => complete += usize::from(parse(prefix).is_ok()),
            Err(_) => {
                // cut inside a character: through the file reader, which gets bytes
                std::fs::write(&p, &bytes[..end]).unwrap();
                let e = read_frames(&p).unwrap_err();
                assert_eq!(e.line(), Some(5), "{e}");
            }
        }
    }
    // the file reads at whole-line cuts and at cuts just after a frame's closing brace
    assert!(complete >= 4, "{complete}");
    for junk in [
        "{",
        "}",
        "[",
        "\"",
        "{\"t\":",
        "{\"t\": 1e",
        "null",
        "{\"detections\": [[[[",
        "\0",
    ] {
        let _ = parse(junk);
    }
    let deep = "[".repeat(100_000);
    assert!(parse(&deep).is_err());
}

#[test]
fn documented_examples_parse() {
    let format = include_str!("../../FORMAT.md");
    let section = format.split("## Frames file").nth(1).unwrap();
    let example = section
        .split("```text\n")
        .nth(1)
        .unwrap()
        .split("```")
        .next()
        .unwrap();
    let f = parse(example).unwrap();
    assert_eq!(f.frames.len(), 2);
    assert_eq!(f.frames[0].detections[0].size_m, Some(0.4));
    assert_eq!(f.frames[1].path.as_ref().unwrap().turned_abs_rad, 0.02);
    let module = include_str!("../frames.rs");
    let example: String = module
        .split("//! ```text\n")
        .nth(1)
        .unwrap()
        .split("//! ```")
        .next()
        .unwrap()
        .lines()
        .map(|l| format!("{}\n", l.trim_start_matches("//! ")))
        .collect();
    assert_eq!(parse(&example).unwrap().frames.len(), 2);
}
