//! TUM trajectories: one pose per line, `t tx ty tz qx qy qz qw`.
//!
//! The format of the TUM RGB-D benchmark, read by `evo` and most SLAM evaluation tools:
//!
//! ```text
//! # t tx ty tz qx qy qz qw
//! 0.0 1.0 2.0 0.0 0.0 0.0 0.0 1.0
//! 0.5 1.25 2.0 0.0 0.0 0.0 0.0499791692706783 0.9987502603949663
//! ```
//!
//! - Fields are separated by spaces or tabs; `t` in seconds, the translation in metres, the
//!   rotation a unit quaternion `qx qy qz qw` (scalar last). The pose maps the body frame
//!   into the trajectory's frame (`world_from_body`).
//! - `#` lines and blank lines are skipped.
//! - Times must be strictly increasing; every value finite.
//! - A quaternion whose norm is within 10⁻¹² of 1 is taken as written (so that round trips
//!   are bit-exact); within 10⁻³ it is normalised; a larger error is refused.
//!
//! The writer uses Rust's shortest round-trip form for numbers (`0.1`, `-7.0`, `1e-300`), so
//! reading back gives identical values. The full description is in `maps/FORMAT.md`.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use crate::atomic::{read_text, write_atomic};
use crate::error::{snippet, LineError};
use crate::MapError;

/// The comment line segloc writes at the top of a TUM file.
pub const TUM_HEADER: &str = "# t tx ty tz qx qy qz qw";

/// The eight fields of a TUM line, for messages.
const FIELDS: [&str; 8] = ["t", "tx", "ty", "tz", "qx", "qy", "qz", "qw"];

/// Largest |‖q‖ − 1| of a quaternion that is normalised rather than refused.
pub(crate) const QUAT_NORM_TOL: f64 = 1e-3;

/// Largest |‖q‖ − 1| that is print rounding (6+ significant digits): normalised silently.
const QUAT_ROUNDING_TOL: f64 = 1e-6;

/// Largest |‖q‖ − 1| of a quaternion taken exactly as written (one written from an `f64`
/// unit quaternion is within a few ulps of 1), so that a round trip gives identical values.
const QUAT_EXACT_TOL: f64 = 1e-12;

/// A unit quaternion from `[qx, qy, qz, qw]` (finite values), under segloc's rule:
///
/// - |‖q‖ − 1| ≤ 10⁻¹²: taken as written (bit-exact round trips);
/// - ≤ 10⁻⁶ (print rounding): normalised;
/// - ≤ 10⁻³: normalised, and the norm is returned so that the caller can warn;
/// - larger: an error naming the norm.
pub(crate) fn unit_quaternion(
    q: [f64; 4],
) -> Result<(UnitQuaternion<f64>, Option<f64>), LineError> {
    let [x, y, z, w] = q;
    let quat = Quaternion::new(w, x, y, z);
    let norm = quat.norm();
    let off = (norm - 1.0).abs();
    if off.is_nan() || off > QUAT_NORM_TOL {
        return Err(format!(
            "quaternion [qx, qy, qz, qw] = [{x}, {y}, {z}, {w}] has norm {norm}, not 1 \
             (at most {QUAT_NORM_TOL} off is normalised)"
        )
        .into());
    }
    if off <= QUAT_EXACT_TOL {
        Ok((UnitQuaternion::new_unchecked(quat), None))
    } else if off <= QUAT_ROUNDING_TOL {
        Ok((UnitQuaternion::new_normalize(quat), None))
    } else {
        Ok((UnitQuaternion::new_normalize(quat), Some(norm)))
    }
}

/// Check poses for writing: every value finite, quaternions unit (within 10⁻³), times
/// strictly increasing. The message names the pose by index and time.
fn validate_poses(poses: &[(f64, Isometry3<f64>)]) -> Result<(), MapError> {
    let bad = |message: String| MapError::InvalidData {
        what: "trajectory",
        message,
    };
    for (index, (t, pose)) in poses.iter().enumerate() {
        let [_, x, y, z, qx, qy, qz, qw] = pose_values(*t, pose);
        if !t.is_finite() {
            return Err(bad(format!("pose {index}: time {t} is not finite")));
        }
        if ![x, y, z, qx, qy, qz, qw].iter().all(|v| v.is_finite()) {
            return Err(bad(format!(
                "pose {index} (t = {t:?}): a value is not finite"
            )));
        }
        unit_quaternion([qx, qy, qz, qw])
            .map_err(|m| bad(format!("pose {index} (t = {t:?}): {m}")))?;
        if index > 0 && *t <= poses[index - 1].0 {
            return Err(bad(format!(
                "pose {index}: t = {t:?} is not after t = {:?} of pose {}; times must be \
                 strictly increasing",
                poses[index - 1].0,
                index - 1
            )));
        }
    }
    Ok(())
}

/// `[t, tx, ty, tz, qx, qy, qz, qw]` of a pose.
fn pose_values(t: f64, pose: &Isometry3<f64>) -> [f64; 8] {
    let p = &pose.translation.vector;
    let q = &pose.rotation.coords; // [i, j, k, w]
    [t, p.x, p.y, p.z, q.x, q.y, q.z, q.w]
}

/// Write a TUM trajectory atomically, with a [`TUM_HEADER`] comment line. Fails (writing
/// nothing) if a value is not finite, a quaternion is not unit or the times do not strictly
/// increase. Numbers are written in shortest round-trip form, so reading back with
/// [`read_tum`] gives identical values.
pub fn write_tum(path: &Path, poses: &[(f64, Isometry3<f64>)]) -> Result<(), MapError> {
    validate_poses(poses).map_err(|e| e.in_file(path))?;
    write_atomic(path, tum_to_string(poses).as_bytes())
}

/// The text of a TUM trajectory (no validation; see [`write_tum`]).
pub fn tum_to_string(poses: &[(f64, Isometry3<f64>)]) -> String {
    let mut s = String::with_capacity(32 + poses.len() * 160);
    s.push_str(TUM_HEADER);
    s.push('\n');
    for (t, pose) in poses {
        for (k, v) in pose_values(*t, pose).iter().enumerate() {
            if k > 0 {
                s.push(' ');
            }
            // writing to a String cannot fail
            let _ = write!(s, "{v:?}");
        }
        s.push('\n');
    }
    s
}

/// Read a TUM trajectory (see the [module docs](self)). An empty trajectory (no pose line)
/// is valid and gives an empty list.
pub fn read_tum(path: &Path) -> Result<Vec<(f64, Isometry3<f64>)>, MapError> {
    let text = read_text(path)?;
    parse_tum(&text, path)
}

/// Parse the text of a TUM trajectory; `source` names it in errors (`source:line: ...`).
pub fn parse_tum(
    text: &str,
    source: impl AsRef<Path>,
) -> Result<Vec<(f64, Isometry3<f64>)>, MapError> {
    let source = source.as_ref();
    let mut poses: Vec<(f64, Isometry3<f64>)> = Vec::new();
    let mut previous: Option<(f64, usize)> = None;
    for (index, line) in text.lines().enumerate() {
        let line_no = index + 1;
        let line = line.trim_start_matches('\u{feff}').trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (t, pose) = parse_tum_line(line).map_err(|m| MapError::parse_at(source, line_no, m))?;
        if let Some((t_prev, line_prev)) = previous {
            if t <= t_prev {
                return Err(MapError::parse_at(
                    source,
                    line_no,
                    format!(
                        "t = {t:?} is not after t = {t_prev:?} on line {line_prev}; times must \
                         be strictly increasing"
                    ),
                ));
            }
        }
        previous = Some((t, line_no));
        poses.push((t, pose));
    }
    Ok(poses)
}

/// One pose line, `t tx ty tz qx qy qz qw`.
fn parse_tum_line(line: &str) -> Result<(f64, Isometry3<f64>), LineError> {
    let mut v = [0.0; 8];
    let mut n = 0;
    for field in line.split_whitespace() {
        if n == 8 {
            return Err(format!(
                "expected 8 numbers (t tx ty tz qx qy qz qw), got more: '{}'",
                snippet(line, 80)
            )
            .into());
        }
        let value: f64 = field.parse().map_err(|_| {
            format!(
                "{}: expected a number, got '{}'",
                FIELDS[n],
                snippet(field, 30)
            )
        })?;
        if !value.is_finite() {
            return Err(format!(
                "{}: '{}' is not a finite number",
                FIELDS[n],
                snippet(field, 30)
            )
            .into());
        }
        v[n] = value;
        n += 1;
    }
    if n < 8 {
        return Err(format!("expected 8 numbers (t tx ty tz qx qy qz qw), got {n}").into());
    }
    let (rotation, _) = unit_quaternion([v[4], v[5], v[6], v[7]])?;
    let pose = Isometry3::from_parts(Translation3::new(v[1], v[2], v[3]), rotation);
    Ok((v[0], pose))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn poses() -> Vec<(f64, Isometry3<f64>)> {
        vec![
            (0.0, Isometry3::identity()),
            (
                0.1,
                Isometry3::new(
                    Vector3::new(1.0, -2.5, 1e-300),
                    Vector3::new(0.1, 0.2, -0.3),
                ),
            ),
            (
                1_700_000_000.123_456_7,
                Isometry3::new(
                    Vector3::new(-3.034147449137282, 4.9741238220042385, 0.3),
                    Vector3::new(0.0, 0.0, 3.0),
                ),
            ),
        ]
    }

    fn parse(text: &str) -> Result<Vec<(f64, Isometry3<f64>)>, MapError> {
        parse_tum(text, "out/traj.tum")
    }

    fn err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn round_trip_exact_through_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("traj.tum");
        write_tum(&p, &poses()).unwrap();
        let back = read_tum(&p).unwrap();
        assert_eq!(back, poses());
        for ((_, a), (_, b)) in back.iter().zip(poses()) {
            // bit-exact, not just equal
            assert_eq!(
                a.rotation.coords.map(f64::to_bits),
                b.rotation.coords.map(f64::to_bits)
            );
        }
        write_tum(&p, &[]).unwrap();
        assert_eq!(read_tum(&p).unwrap(), vec![]);
    }

    #[test]
    fn text_looks_as_documented() {
        let text = tum_to_string(&poses()[..2]);
        let lines: Vec<_> = text.lines().collect();
        assert_eq!(lines[0], TUM_HEADER);
        assert_eq!(lines[1], "0.0 0.0 0.0 0.0 0.0 0.0 0.0 1.0");
        assert!(lines[2].starts_with("0.1 1.0 -2.5 1e-300 "), "{}", lines[2]);
        assert!(text.ends_with('\n'));
    }

    #[test]
    fn reads_comments_tabs_and_crlf() {
        let t = parse("# ground truth\r\n\r\n1.0\t2 3 4 0 0 0 1\r\n  # more\n2 0 0 0 0 0 1 0\n")
            .unwrap();
        assert_eq!(t.len(), 2);
        assert_eq!(t[0].0, 1.0);
        assert_eq!(t[0].1.translation.vector, Vector3::new(2.0, 3.0, 4.0));
        assert_eq!(t[1].1.rotation.coords.z, 1.0);
    }

    #[test]
    fn quaternion_rule() {
        // within 1e-3: normalised
        let t = parse("0 0 0 0 0 0 0 1.0004\n").unwrap();
        assert_eq!(t[0].1.rotation.coords.w, 1.0);
        let t = parse("0 0 0 0 0.6 0 0 0.8000001\n").unwrap();
        assert!((t[0].1.rotation.coords.norm() - 1.0).abs() < 1e-15);
        // beyond: refused, naming the norm
        let e = err("# c\n0 0 0 0 0 0 0 1.01\n");
        assert!(e.starts_with("out/traj.tum:2: quaternion"), "{e}");
        assert!(e.contains("norm 1.01"), "{e}");
        assert!(err("0 0 0 0 0 0 0 0\n").contains("norm 0"));
    }

    #[test]
    fn bad_lines_name_line_and_field() {
        assert_eq!(
            err("0 0 0 0 0 0 0 1\n1 2 3\n"),
            "out/traj.tum:2: expected 8 numbers (t tx ty tz qx qy qz qw), got 3"
        );
        assert!(err("0 0 0 0 0 0 0 1 9\n").starts_with("out/traj.tum:1: expected 8 numbers"));
        assert_eq!(
            err("0 0 x 0 0 0 0 1\n"),
            "out/traj.tum:1: ty: expected a number, got 'x'"
        );
        assert_eq!(
            err("0 0 0 NaN 0 0 0 1\n"),
            "out/traj.tum:1: tz: 'NaN' is not a finite number"
        );
        assert_eq!(
            err("inf 0 0 0 0 0 0 1\n"),
            "out/traj.tum:1: t: 'inf' is not a finite number"
        );
        assert!(err("0 0 0 1e999 0 0 0 1\n").contains("tz: '1e999' is not a finite"));
        assert!(err("0 0 0 0 0,0 0 1\n").contains("qx: expected a number"));
    }

    #[test]
    fn times_must_increase() {
        let e = err("1.5 0 0 0 0 0 0 1\n\n1.5 0 0 0 0 0 0 1\n");
        assert_eq!(
            e,
            "out/traj.tum:3: t = 1.5 is not after t = 1.5 on line 1; times must be strictly increasing"
        );
        assert!(err("2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n").contains("t = 1.0 is not after t = 2.0"));
    }

    #[test]
    fn write_refuses_what_cannot_be_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("traj.tum");
        let mut bad = poses();
        bad[2].0 = 0.05;
        let e = write_tum(&p, &bad).unwrap_err().to_string();
        assert!(
            e.contains("pose 2: t = 0.05 is not after t = 0.1 of pose 1"),
            "{e}"
        );
        let mut bad = poses();
        bad[1].1.translation.vector.y = f64::NAN;
        let e = write_tum(&p, &bad).unwrap_err().to_string();
        assert!(
            e.contains("traj.tum: pose 1 (t = 0.1): a value is not finite"),
            "{e}"
        );
        assert!(!p.exists());
    }

    #[test]
    fn never_panics_on_prefixes_or_garbage() {
        let text = tum_to_string(&poses());
        for end in 0..=text.len() {
            if let Some(prefix) = text.get(..end) {
                let _ = parse(prefix);
            }
        }
        for junk in ["\u{feff}", "#", " \t ", "0 0 0 0 0 0 0", "-", "1e", "\0"] {
            let _ = parse(junk);
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bin.tum");
        std::fs::write(&p, b"0 0 0 0 0 0 0 1\n\xff\xfe\n").unwrap();
        assert_eq!(read_tum(&p).unwrap_err().line(), Some(2));
    }
}
