//! The recorded-stream ("frames") file: what a rover's odometry, IMU and boulder detector
//! reported at each camera frame, for replaying a drive through the online localizer.
//!
//! JSON Lines (`drive.jsonl`), one object per camera frame in time order, after an optional
//! header line:
//!
//! ```text
//! {"format": "segloc-frames", "version": 1}
//! {"t": 0.0, "odom_from_rover": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], "gravity_rover": [0.0, 0.0, -1.62], "detections": [{"p_rover": [3.1, 0.4, -0.2], "size_m": 0.4}]}
//! {"t": 0.1, "odom_from_rover": [0.05, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], "detections": [], "path": {"distance_m": 0.05, "turned_rad": 0.0, "turned_abs_rad": 0.0}}
//! ```
//!
//! - `t` (s, strictly increasing); `odom_from_rover` the odometry's pose of the rover,
//!   `[x, y, z, qx, qy, qz, qw]` (m, unit quaternion scalar last, as in TUM files).
//! - `gravity_rover` (optional): the IMU's gravity in the rover frame (x forward, y left,
//!   z up), any non-zero scale.
//! - `detections` (optional, default empty): boulders, each `p_rover` (m, rover frame),
//!   optional `size_m` (diameter, m, ≥ 0) and `cov_rover` (`[xx, xy, xz, yy, yz, zz]`, m²,
//!   PSD with a positive diagonal).
//! - `lander_points_rover` (optional): points on the lander, rover frame.
//! - `path` (optional): the odometry's path since the previous frame, `distance_m`,
//!   `turned_rad` (signed yaw), `turned_abs_rad` (absolute yaw); when absent the consumer
//!   derives them from consecutive poses.
//! - `step_cov` (optional): the covariance of the odometry's motion since the previous
//!   frame, 21 numbers, the upper triangle row by row of a 6 × 6 matrix over a right
//!   perturbation of `prev_from_rover` (rotation rx, ry, rz in rad, then translation x, y, z
//!   in m, in the previous frame's rover axes), positive definite; when absent the consumer
//!   uses its own noise model of the odometry.
//! - The header line may be absent (version 1). Blank lines are skipped; optional fields
//!   may also be `null`; unknown fields are ignored, so that a newer writer's additions do
//!   not break this reader (a misspelt optional field is therefore silently absent).
//! - A quaternion within 10⁻³ of unit norm is normalised (with a warning in
//!   [`FramesFile::warnings`] when it is off by more than print rounding, 10⁻⁶).
//!
//! Every value must be finite; every error names `file:line` and the field. The full
//! description is in `maps/FORMAT.md`.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, Translation3, Vector3};
use serde_json::{Map, Value};

mod json;

use json::{array, describe, json_message, number, numbers, optional, required};

use crate::atomic::{read_text, write_atomic};
use crate::error::{snippet, LineError};
use crate::landmark::{from_upper_triangle, upper_triangle};
use crate::tum::{unit_quaternion, QUAT_NORM_TOL};
use crate::{check_covariance, MapError};

/// The value of the `format` field of a frames file's header line.
pub const FRAMES_FORMAT_NAME: &str = "segloc-frames";

/// The frames file format version this build writes (and the newest it reads).
pub const FRAMES_FORMAT_VERSION: u32 = 1;

/// One camera frame of a recorded drive.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamFrame {
    /// Time, s.
    pub t: f64,
    /// The odometry's pose of the rover (maps rover coordinates into the odometry frame).
    pub odom_from_rover: Isometry3<f64>,
    /// The IMU's gravity vector in the rover frame (non-zero; any scale, m/s² typical).
    pub gravity_rover: Option<Vector3<f64>>,
    /// Boulders detected in this frame.
    pub detections: Vec<FrameDetection>,
    /// Points on the lander seen in this frame, rover frame, m.
    pub lander_points_rover: Vec<Point3<f64>>,
    /// The odometry's path since the previous frame, when it reports one.
    pub path: Option<FramePath>,
    /// Covariance of the odometry's motion since the previous frame, when it reports one:
    /// a right perturbation of `prev_from_rover`, (rotation rad, translation m) order,
    /// positive definite.
    pub step_cov: Option<Matrix6<f64>>,
}

impl StreamFrame {
    /// A frame with a time and a pose only (no gravity, detections, lander points or path).
    pub fn new(t: f64, odom_from_rover: Isometry3<f64>) -> Self {
        StreamFrame {
            t,
            odom_from_rover,
            gravity_rover: None,
            detections: Vec::new(),
            lander_points_rover: Vec::new(),
            path: None,
            step_cov: None,
        }
    }
}

/// One boulder detection of a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameDetection {
    /// Boulder centroid in the rover frame (x forward, y left, z up), m.
    pub p_rover: Point3<f64>,
    /// Boulder diameter, m (finite, ≥ 0), when estimated.
    pub size_m: Option<f64>,
    /// Covariance of `p_rover`, m² (symmetric PSD, positive diagonal), when known.
    pub cov_rover: Option<Matrix3<f64>>,
}

/// The odometry's path between the previous frame and this one (for odometry that runs
/// faster than the camera, where consecutive poses under-state the path).
#[derive(Clone, Debug, PartialEq)]
pub struct FramePath {
    /// Path length, m (≥ 0).
    pub distance_m: f64,
    /// Signed yaw turned (counter-clockwise positive), rad.
    pub turned_rad: f64,
    /// Sum of the absolute yaw increments, rad (≥ |`turned_rad`|).
    pub turned_abs_rad: f64,
}

/// A frames file as read: the frames in time order and the warnings the reader gave.
#[derive(Clone, Debug, PartialEq)]
pub struct FramesFile {
    /// The frames, times strictly increasing; never empty.
    pub frames: Vec<StreamFrame>,
    /// What the reader repaired, each `file:line: what`
    /// (`drive.jsonl:7: quaternion norm 1.0004 normalised`).
    pub warnings: Vec<String>,
}

/// Read a frames file (see the [module docs](self)).
pub fn read_frames(path: &Path) -> Result<FramesFile, MapError> {
    let text = read_text(path)?;
    parse_frames(&text, path)
}

/// Write a frames file atomically: the header line, then one line per frame
/// ([`frame_to_json_line`]). Numbers are written in shortest round-trip form, so
/// [`read_frames`] gives identical values back. Fails, writing nothing, if there is no frame
/// or a frame would not read back (non-finite value, times not strictly increasing,
/// quaternion off unit by more than 10⁻³, zero gravity, negative size, bad covariance or
/// path).
pub fn write_frames(path: &Path, frames: &[StreamFrame]) -> Result<(), MapError> {
    validate_frames(frames).map_err(|e| e.in_file(path))?;
    let mut text =
        format!("{{\"format\": \"{FRAMES_FORMAT_NAME}\", \"version\": {FRAMES_FORMAT_VERSION}}}\n");
    for frame in frames {
        text.push_str(&frame_to_json_line(frame));
        text.push('\n');
    }
    write_atomic(path, text.as_bytes())
}

/// One frame as a line of the frames file, without the line break. `gravity_rover`,
/// `lander_points_rover` (when empty), `path` and a detection's `size_m` / `cov_rover` are
/// left out when absent; `detections` is always written.
///
/// No validation: a non-finite number would make the line unreadable; [`write_frames`]
/// checks first.
pub fn frame_to_json_line(frame: &StreamFrame) -> String {
    let mut s = String::with_capacity(160 + frame.detections.len() * 64);
    let p = &frame.odom_from_rover.translation.vector;
    let q = &frame.odom_from_rover.rotation.coords; // [i, j, k, w]
                                                    // writing to a String cannot fail
    let _ = write!(s, "{{\"t\": {:?}, \"odom_from_rover\": ", frame.t);
    push_array(&mut s, &[p.x, p.y, p.z, q.x, q.y, q.z, q.w]);
    if let Some(g) = &frame.gravity_rover {
        s.push_str(", \"gravity_rover\": ");
        push_array(&mut s, g.as_slice());
    }
    s.push_str(", \"detections\": [");
    for (k, d) in frame.detections.iter().enumerate() {
        if k > 0 {
            s.push_str(", ");
        }
        s.push_str("{\"p_rover\": ");
        push_array(&mut s, d.p_rover.coords.as_slice());
        if let Some(size) = d.size_m {
            let _ = write!(s, ", \"size_m\": {size:?}");
        }
        if let Some(c) = &d.cov_rover {
            s.push_str(", \"cov_rover\": ");
            push_array(&mut s, &upper_triangle(c));
        }
        s.push('}');
    }
    s.push(']');
    if !frame.lander_points_rover.is_empty() {
        s.push_str(", \"lander_points_rover\": [");
        for (k, point) in frame.lander_points_rover.iter().enumerate() {
            if k > 0 {
                s.push_str(", ");
            }
            push_array(&mut s, point.coords.as_slice());
        }
        s.push(']');
    }
    if let Some(path) = &frame.path {
        let _ = write!(
            s,
            ", \"path\": {{\"distance_m\": {:?}, \"turned_rad\": {:?}, \"turned_abs_rad\": {:?}}}",
            path.distance_m, path.turned_rad, path.turned_abs_rad
        );
    }
    if let Some(c) = &frame.step_cov {
        s.push_str(", \"step_cov\": ");
        push_array(&mut s, &crate::landmark::upper_triangle6(c));
    }
    s.push('}');
    s
}

/// `[a, b, c]` with numbers in shortest round-trip form.
fn push_array(s: &mut String, values: &[f64]) {
    s.push('[');
    for (k, v) in values.iter().enumerate() {
        if k > 0 {
            s.push_str(", ");
        }
        let _ = write!(s, "{v:?}");
    }
    s.push(']');
}

/// Parse the text of a frames file; `source` names it in errors and warnings
/// (`source:line: ...`).
pub fn parse_frames(text: &str, source: impl AsRef<Path>) -> Result<FramesFile, MapError> {
    let source = source.as_ref();
    let mut file = FramesFile {
        frames: Vec::new(),
        warnings: Vec::new(),
    };
    let mut first_object = true;
    let mut previous: Option<(f64, usize)> = None;
    for (index, line) in text.lines().enumerate() {
        let line_no = index + 1;
        let start = line.trim_start_matches(|c: char| c.is_whitespace() || c == '\u{feff}');
        let json = start.trim_end();
        if json.is_empty() {
            continue;
        }
        let at = |message: String| MapError::parse_at(source, line_no, message);
        // bytes before the JSON, so that serde_json's column counts from the start of the line
        let lead = line.len() - start.len();
        let value: Value =
            serde_json::from_str(json).map_err(|e| at(json_message(&e, json, lead)))?;
        let Value::Object(object) = value else {
            return Err(at(format!(
                "expected a JSON object (one frame per line), got {}",
                describe(&value)
            )));
        };
        let is_first = std::mem::replace(&mut first_object, false);
        if is_header(&object) {
            if !is_first {
                return Err(at(format!(
                    "a header line ({{\"format\": \"{FRAMES_FORMAT_NAME}\", ...}}) may only \
                     be the first line; a frame needs \"t\""
                )));
            }
            check_header(&object, source, line_no)?;
            continue;
        }
        let (frame, norm) = parse_frame(&object).map_err(|e| at(e.message))?;
        if let Some(norm) = norm {
            file.warnings.push(format!(
                "{}:{line_no}: quaternion norm {} normalised",
                source.display(),
                format_norm(norm)
            ));
        }
        if let Some((t_prev, line_prev)) = previous {
            if frame.t <= t_prev {
                return Err(at(format!(
                    "t = {:?} is not after t = {t_prev:?} of the previous frame (line \
                     {line_prev}); times must be strictly increasing",
                    frame.t
                )));
            }
        }
        previous = Some((frame.t, line_no));
        file.frames.push(frame);
    }
    if file.frames.is_empty() {
        return Err(MapError::parse(
            source,
            "no frames: expected one JSON object per camera frame",
        ));
    }
    Ok(file)
}

/// Whether a line's object is the header (`format` / `version`, and no frame time).
fn is_header(object: &Map<String, Value>) -> bool {
    (object.contains_key("format") || object.contains_key("version")) && !object.contains_key("t")
}

/// Check the header line's format name and version.
fn check_header(object: &Map<String, Value>, source: &Path, line: usize) -> Result<(), MapError> {
    let at = |message: String| MapError::parse_at(source, line, message);
    match object.get("format") {
        Some(Value::String(name)) if name == FRAMES_FORMAT_NAME => {}
        Some(other) => {
            return Err(at(format!(
                "\"format\" is {}, expected \"{FRAMES_FORMAT_NAME}\": not a segloc frames file",
                snippet(&other.to_string(), 40)
            )))
        }
        None => {
            return Err(at(format!(
                "the header has \"version\" but no \"format\": \"{FRAMES_FORMAT_NAME}\""
            )))
        }
    }
    let version = object.get("version").ok_or_else(|| {
        at(format!(
            "the header has no \"version\" (this segloc reads version {FRAMES_FORMAT_VERSION})"
        ))
    })?;
    match version.as_u64() {
        Some(v) if v == u64::from(FRAMES_FORMAT_VERSION) => Ok(()),
        Some(0) => Err(at(
            "\"version\" 0 does not exist; versions start at 1".to_string()
        )),
        Some(found) => Err(MapError::UnsupportedVersion {
            what: "frames file",
            path: source.to_path_buf(),
            found,
            supported: FRAMES_FORMAT_VERSION,
        }),
        None => Err(at(format!(
            "\"version\" is {}, expected a positive integer (this segloc reads version \
             {FRAMES_FORMAT_VERSION})",
            snippet(&version.to_string(), 40)
        ))),
    }
}

/// One frame line's object; the quaternion norm when it was normalised with a warning.
fn parse_frame(object: &Map<String, Value>) -> Result<(StreamFrame, Option<f64>), LineError> {
    let t = number(required(object, "t")?, "t")?;
    let [x, y, z, qx, qy, qz, qw] =
        numbers::<7>(required(object, "odom_from_rover")?, "odom_from_rover")?;
    let (rotation, norm) =
        unit_quaternion([qx, qy, qz, qw]).map_err(|m| format!("odom_from_rover: {m}"))?;
    let odom_from_rover = Isometry3::from_parts(Translation3::new(x, y, z), rotation);
    let gravity_rover = match optional(object, "gravity_rover") {
        Some(v) => Some(Vector3::from(numbers::<3>(v, "gravity_rover")?)),
        None => None,
    };
    let mut detections = Vec::new();
    if let Some(list) = optional(object, "detections") {
        for (k, item) in array(list, "detections")?.iter().enumerate() {
            detections.push(parse_detection(item, &format!("detections[{k}]"))?);
        }
    }
    let mut lander_points_rover = Vec::new();
    if let Some(list) = optional(object, "lander_points_rover") {
        for (k, item) in array(list, "lander_points_rover")?.iter().enumerate() {
            let field = format!("lander_points_rover[{k}]");
            lander_points_rover.push(Point3::from(numbers::<3>(item, &field)?));
        }
    }
    let path = match optional(object, "path") {
        Some(v) => {
            let fields = v
                .as_object()
                .ok_or_else(|| format!("path: expected an object, got {}", describe(v)))?;
            let get = |key: &str| {
                let field = format!("path.{key}");
                fields
                    .get(key)
                    .ok_or_else(|| LineError::from(format!("{field} is missing")))
                    .and_then(|v| number(v, &field))
            };
            Some(FramePath {
                distance_m: get("distance_m")?,
                turned_rad: get("turned_rad")?,
                turned_abs_rad: get("turned_abs_rad")?,
            })
        }
        None => None,
    };
    let step_cov = match optional(object, "step_cov") {
        Some(v) => Some(crate::landmark::from_upper_triangle6(&numbers::<21>(
            v, "step_cov",
        )?)),
        None => None,
    };
    let frame = StreamFrame {
        t,
        odom_from_rover,
        gravity_rover,
        detections,
        lander_points_rover,
        path,
        step_cov,
    };
    check_frame(&frame)?;
    Ok((frame, norm))
}

/// One element of `detections`; `field` is its name in messages (`detections[2]`).
fn parse_detection(item: &Value, field: &str) -> Result<FrameDetection, LineError> {
    let object = item
        .as_object()
        .ok_or_else(|| format!("{field}: expected an object, got {}", describe(item)))?;
    let p = object
        .get("p_rover")
        .ok_or_else(|| format!("{field}.p_rover is missing"))?;
    let p_rover = Point3::from(numbers::<3>(p, &format!("{field}.p_rover"))?);
    let size_m = match optional(object, "size_m") {
        Some(v) => Some(number(v, &format!("{field}.size_m"))?),
        None => None,
    };
    let cov_rover = match optional(object, "cov_rover") {
        Some(v) => Some(from_upper_triangle(numbers::<6>(
            v,
            &format!("{field}.cov_rover"),
        )?)),
        None => None,
    };
    Ok(FrameDetection {
        p_rover,
        size_m,
        cov_rover,
    })
}

/// A quaternion norm for a warning: 6 decimals, trailing zeros dropped (`1.0004`).
fn format_norm(norm: f64) -> String {
    let s = format!("{norm:.6}");
    let s = s.trim_end_matches('0');
    s.strip_suffix('.').unwrap_or(s).to_string()
}

/// The checks of one frame beyond the JSON types, naming the field: every value finite,
/// quaternion unit within 10⁻³, gravity non-zero, sizes ≥ 0, covariances PSD with a
/// positive diagonal, path lengths ≥ 0 and |`turned_rad`| ≤ `turned_abs_rad`, the step
/// covariance positive definite.
fn check_frame(frame: &StreamFrame) -> Result<(), LineError> {
    let finite = |values: &[f64]| values.iter().all(|v| v.is_finite());
    if !frame.t.is_finite() {
        return Err(format!("t: {} is not a finite number", frame.t).into());
    }
    let pose = &frame.odom_from_rover;
    if !finite(pose.translation.vector.as_slice()) || !finite(pose.rotation.coords.as_slice()) {
        return Err("odom_from_rover: a value is not finite".into());
    }
    let norm = pose.rotation.coords.norm();
    if (norm - 1.0).abs() > QUAT_NORM_TOL {
        return Err(format!("odom_from_rover: quaternion norm {norm} is not 1").into());
    }
    if let Some(g) = &frame.gravity_rover {
        let n = g.norm();
        if !(n.is_finite() && n > 0.0) {
            return Err(format!(
                "gravity_rover: [{:?}, {:?}, {:?}] is not a usable gravity vector (its \
                 length must be finite and non-zero)",
                g.x, g.y, g.z
            )
            .into());
        }
    }
    for (k, d) in frame.detections.iter().enumerate() {
        if !finite(d.p_rover.coords.as_slice()) {
            return Err(format!("detections[{k}].p_rover: a value is not finite").into());
        }
        if let Some(size) = d.size_m {
            if !(size.is_finite() && size >= 0.0) {
                return Err(format!(
                    "detections[{k}].size_m: {size} is not a finite non-negative number"
                )
                .into());
            }
        }
        if let Some(c) = &d.cov_rover {
            check_covariance(c).map_err(|m| format!("detections[{k}].cov_rover: {m}"))?;
            for (axis, name) in ["xx", "yy", "zz"].iter().enumerate() {
                if c[(axis, axis)] <= 0.0 {
                    return Err(format!(
                        "detections[{k}].cov_rover: variance {name} = {} must be positive",
                        c[(axis, axis)]
                    )
                    .into());
                }
            }
        }
    }
    for (k, p) in frame.lander_points_rover.iter().enumerate() {
        if !finite(p.coords.as_slice()) {
            return Err(format!("lander_points_rover[{k}]: a value is not finite").into());
        }
    }
    if let Some(path) = &frame.path {
        if !finite(&[path.distance_m, path.turned_rad, path.turned_abs_rad]) {
            return Err("path: a value is not finite".into());
        }
        if path.distance_m < 0.0 {
            return Err(format!("path.distance_m: {} is negative", path.distance_m).into());
        }
        // |Σ Δyaw| ≤ Σ |Δyaw|, up to rounding
        let slack = 1e-9 * path.turned_abs_rad.max(1.0);
        if path.turned_abs_rad < 0.0 || path.turned_rad.abs() > path.turned_abs_rad + slack {
            return Err(format!(
                "path: turned_abs_rad = {} must be ≥ 0 and ≥ |turned_rad| = {}",
                path.turned_abs_rad,
                path.turned_rad.abs()
            )
            .into());
        }
    }
    if let Some(c) = &frame.step_cov {
        if c.iter().any(|v| !v.is_finite()) {
            return Err("step_cov: a value is not finite".into());
        }
        if c.cholesky().is_none() {
            return Err(
                "step_cov: the covariance is not positive definite (21 numbers: the upper \
                 triangle, row by row, of a 6 × 6 covariance)"
                    .into(),
            );
        }
    }
    Ok(())
}

/// Check frames for writing: at least one, each [checked](check_frame), times strictly
/// increasing.
fn validate_frames(frames: &[StreamFrame]) -> Result<(), MapError> {
    let bad = |message: String| MapError::InvalidData {
        what: "frames",
        message,
    };
    if frames.is_empty() {
        return Err(bad(
            "no frames (a frames file holds at least one)".to_string()
        ));
    }
    for (index, frame) in frames.iter().enumerate() {
        check_frame(frame).map_err(|m| bad(format!("frame {index} (t = {:?}): {m}", frame.t)))?;
        if index > 0 && frame.t <= frames[index - 1].t {
            return Err(bad(format!(
                "frame {index}: t = {:?} is not after t = {:?} of frame {}; times must be \
                 strictly increasing",
                frame.t,
                frames[index - 1].t,
                index - 1
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
