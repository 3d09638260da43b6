//! A Rerun recording (`.rrd`) of a mission (cargo feature `rerun`): the moon's terrain and
//! rocks, each session's true, estimated and odometry-only trajectories, the rover, the
//! boulders it detected frame by frame, session 1's map, every relocalization attempt in
//! a text log, the position errors over time, and the final LAC maps.
//!
//! Entity paths name their frame: everything under `world/` is in the world frame (the
//! LAC frame centred on the lander, z up). One timeline, `mission_time` (seconds): session
//! 1 runs from 0, session 2 starts where session 1 ended. Open the file with the viewer of
//! the same version: `pip install rerun-sdk==0.36.3 && rerun mission.rrd`.

use super::report::{Attempt, MissionOutput};
use super::trace::{SessionTrace, TraceFrame, TraceRock};
use nalgebra::{Isometry3, Point3};
use rerun::RecordingStream;
use std::path::Path;

/// Errors writing a recording.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The Rerun SDK failed.
    #[error("rerun recording {path}: {message}")]
    Rerun {
        /// The recording being written.
        path: String,
        /// What failed.
        message: String,
    },
    /// The finished recording could not be moved into place.
    #[error("cannot write {path}: {message}")]
    Io {
        /// The recording.
        path: String,
        /// Why.
        message: String,
    },
}

/// Which pose of a frame a trajectory line follows.
type PoseOf = fn(&TraceFrame) -> Isometry3<f64>;

const TIMELINE: &str = "mission_time";
/// Frames between two re-logs of the growing trajectory lines.
const TRAJECTORY_EVERY_FRAMES: usize = 5;

/// Write the recording of `output` to `path` (through a temporary file, then renamed:
/// never half written). `pictures` are PNG files logged as images at the end (missing
/// ones are skipped).
pub fn write_recording(
    output: &MissionOutput,
    path: &Path,
    pictures: &[(&str, &Path)],
) -> Result<(), RecordingError> {
    let tmp = path.with_extension("rrd.partial");
    let rerun_error = |e: &dyn std::fmt::Display| RecordingError::Rerun {
        path: path.display().to_string(),
        message: e.to_string(),
    };
    {
        let rec = rerun::RecordingStreamBuilder::new("segloc_mission")
            .save(&tmp)
            .map_err(|e| rerun_error(&e))?;
        log_mission(&rec, output, pictures).map_err(|e| rerun_error(&e))?;
        rec.flush_blocking().map_err(|e| rerun_error(&e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| RecordingError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

fn log_mission(
    rec: &RecordingStream,
    output: &MissionOutput,
    pictures: &[(&str, &Path)],
) -> rerun::RecordingStreamResult<()> {
    rec.log_static("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;
    log_terrain(rec, output)?;
    log_rocks(
        rec,
        "world/truth/rocks",
        &output.trace.rocks,
        [150, 110, 80],
    )?;
    rec.log_static(
        "world/truth/lander",
        &rerun::Boxes3D::from_centers_and_half_sizes([[0.0f32, 0.0, 1.0]], [[1.5f32, 1.5, 1.0]])
            .with_colors([rerun::Color::from_rgb(200, 200, 210)]),
    )?;
    log_rocks(
        rec,
        "world/session1/map",
        &output.trace.prior_landmarks,
        [30, 120, 255],
    )?;
    let mut offset_s = 0.0;
    for session in &output.trace.sessions {
        log_session(rec, output, session, offset_s)?;
        offset_s += session.frames.last().map_or(0.0, |f| f.time_s);
    }
    rec.set_duration_secs(TIMELINE, offset_s);
    for (name, file) in pictures {
        if let Ok(image) = rerun::EncodedImage::from_file(file) {
            rec.log(format!("maps/{name}"), &image)?;
        }
    }
    Ok(())
}

fn point(p: &Point3<f64>) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

fn log_terrain(rec: &RecordingStream, output: &MissionOutput) -> rerun::RecordingStreamResult<()> {
    let grid = &output.truth;
    let n = grid.cells_per_side;
    let mut positions = Vec::with_capacity(n * n);
    let mut colours = Vec::with_capacity(n * n);
    let (lo, hi) = grid
        .height
        .iter()
        .filter(|h| h.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &h| {
            (a.min(h), b.max(h))
        });
    let span = (hi - lo).max(1e-6);
    for i in 0..n {
        for j in 0..n {
            let (x, y) = grid.cell_center(i, j);
            let h = grid.height[grid.index(i, j)];
            let h = if h.is_finite() { h } else { lo };
            positions.push([x as f32, y as f32, h as f32]);
            let g = (60.0 + 150.0 * (h - lo) / span) as u8;
            colours.push(rerun::Color::from_rgb(g, g, g));
        }
    }
    let mut triangles = Vec::with_capacity(2 * (n - 1) * (n - 1));
    for i in 0..n.saturating_sub(1) {
        for j in 0..n.saturating_sub(1) {
            let v = |a: usize, b: usize| (a * n + b) as u32;
            triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    rec.log_static(
        "world/truth/terrain",
        &rerun::Mesh3D::new(positions)
            .with_triangle_indices(triangles)
            .with_vertex_colors(colours),
    )
}

fn log_rocks(
    rec: &RecordingStream,
    entity: &str,
    rocks: &[TraceRock],
    rgb: [u8; 3],
) -> rerun::RecordingStreamResult<()> {
    rec.log_static(
        entity,
        &rerun::Points3D::new(rocks.iter().map(|r| point(&r.p_world)))
            .with_radii(rocks.iter().map(|r| r.radius_m as f32))
            .with_colors([rerun::Color::from_rgb(rgb[0], rgb[1], rgb[2])]),
    )
}

fn transform(pose: &Isometry3<f64>) -> rerun::Transform3D {
    let t = pose.translation.vector;
    let q = pose.rotation.coords;
    rerun::Transform3D::from_translation_rotation(
        [t.x as f32, t.y as f32, t.z as f32],
        rerun::Quaternion::from_xyzw([q.x as f32, q.y as f32, q.z as f32, q.w as f32]),
    )
}

fn strip(frames: &[TraceFrame], pose: impl Fn(&TraceFrame) -> Isometry3<f64>) -> Vec<[f32; 3]> {
    frames
        .iter()
        .map(|f| point(&Point3::from(pose(f).translation.vector)))
        .collect()
}

fn log_session(
    rec: &RecordingStream,
    output: &MissionOutput,
    session: &SessionTrace,
    offset_s: f64,
) -> rerun::RecordingStreamResult<()> {
    let root = format!("world/session{}", session.session);
    log_rover_bodies(rec, &root)?;
    let mut attempts = output
        .report
        .attempts
        .iter()
        .filter(|a| a.session == session.session)
        .peekable();
    for (k, frame) in session.frames.iter().enumerate() {
        rec.set_duration_secs(TIMELINE, offset_s + frame.time_s);
        log_frame(rec, &root, session, k)?;
        while let Some(a) = attempts.next_if(|a| a.time_s <= frame.time_s + 1e-9) {
            log_attempt(rec, a)?;
        }
    }
    Ok(())
}

/// The two rover boxes of a session (true and estimated), static.
fn log_rover_bodies(rec: &RecordingStream, root: &str) -> rerun::RecordingStreamResult<()> {
    for body in ["rover_true", "rover_estimate"] {
        rec.log_static(
            format!("{root}/{body}/body"),
            &rerun::Boxes3D::from_centers_and_half_sizes(
                [[0.0f32, 0.0, 0.2]],
                [[0.3f32, 0.25, 0.15]],
            )
            .with_colors([if body == "rover_true" {
                rerun::Color::from_rgb(80, 80, 80)
            } else {
                rerun::Color::from_rgb(30, 120, 255)
            }]),
        )?;
    }
    Ok(())
}

/// Frame `k` of a session: the rover's poses, its detections, the position errors and,
/// every few frames, the trajectory lines so far.
fn log_frame(
    rec: &RecordingStream,
    root: &str,
    session: &SessionTrace,
    k: usize,
) -> rerun::RecordingStreamResult<()> {
    let frame = &session.frames[k];
    rec.log(
        format!("{root}/rover_true"),
        &transform(&frame.world_from_rover_true),
    )?;
    rec.log(
        format!("{root}/rover_estimate"),
        &transform(&frame.world_from_rover_estimate),
    )?;
    rec.log(
        format!("{root}/detections"),
        &rerun::Points3D::new(frame.p_world_boulders.iter().map(point))
            .with_radii([0.06f32])
            .with_colors([rerun::Color::from_rgb(255, 60, 60)]),
    )?;
    let error = |p: &Isometry3<f64>| {
        (p.translation.vector - frame.world_from_rover_true.translation.vector).norm()
    };
    rec.log(
        format!("errors/session{}/estimate_m", session.session),
        &rerun::Scalars::new([error(&frame.world_from_rover_estimate)]),
    )?;
    rec.log(
        format!("errors/session{}/odometry_m", session.session),
        &rerun::Scalars::new([error(&frame.world_from_rover_odometry)]),
    )?;
    let last = k + 1 == session.frames.len();
    if !k.is_multiple_of(TRAJECTORY_EVERY_FRAMES) && !last {
        return Ok(());
    }
    let lines: [(&str, [u8; 3], PoseOf); 3] = [
        ("trajectory_true", [60, 60, 60], |f| f.world_from_rover_true),
        ("trajectory_estimate", [30, 120, 255], |f| {
            f.world_from_rover_estimate
        }),
        ("trajectory_odometry", [255, 140, 0], |f| {
            f.world_from_rover_odometry
        }),
    ];
    for (name, rgb, pose) in &lines {
        rec.log(
            format!("{root}/{name}"),
            &rerun::LineStrips3D::new([strip(&session.frames[..=k], pose)])
                .with_radii([0.03f32])
                .with_colors([rerun::Color::from_rgb(rgb[0], rgb[1], rgb[2])]),
        )?;
    }
    Ok(())
}

/// A relocalization attempt in the text log: accepted (an error when wrong) or refused.
fn log_attempt(rec: &RecordingStream, a: &Attempt) -> rerun::RecordingStreamResult<()> {
    let text = if a.accepted {
        format!(
            "session {} t={:.0} s: accepted, {} inliers, error {:.1} cm / {:.2}°{}",
            a.session,
            a.time_s,
            a.inliers,
            100.0 * a.error_m.unwrap_or(f64::NAN),
            a.error_deg.unwrap_or(f64::NAN),
            if a.wrong { " (WRONG)" } else { "" }
        )
    } else {
        format!(
            "session {} t={:.0} s: refused ({})",
            a.session,
            a.time_s,
            a.refusal
                .as_ref()
                .map_or_else(|| "no reason".to_string(), |r| r.to_string())
        )
    };
    let level = match (a.accepted, a.wrong) {
        (true, false) => rerun::TextLogLevel::INFO,
        (true, true) => rerun::TextLogLevel::ERROR,
        (false, _) => rerun::TextLogLevel::WARN,
    };
    rec.log(
        "relocalizations",
        &rerun::TextLog::new(text).with_level(level),
    )
}
