//! GTSAM's stereo visual-odometry example files (`VO_calibration.txt`,
//! `VO_camera_poses*.txt`, `VO_stereo_factors*.txt` in the gtsam wheel's `Data/`), read into
//! a bundle-adjustment problem on the pose graph.
//!
//! * calibration: one line `fx fy skew cx cy baseline_m`;
//! * poses: `id` then the 4 × 4 matrix `world_from_camera` row by row (16 numbers);
//! * factors: `pose landmark u_left u_right v X Y Z`, the pixels and the point in the
//!   camera's frame.
//!
//! [`StereoProblem::build_graph`] makes the problem of GTSAM's `StereoVOExample_large`: a
//! landmark starts where its first observing camera puts it, every observation has isotropic
//! pixel noise, the first pose is fixed.

use super::file::LineError;
use super::stereo::StereoCalibration;
use super::{GraphError, PoseGraph, RobustKernel, VarKey};
use nalgebra::Vector3;
use nalgebra::{Isometry3, Matrix3, Matrix4, Point3, Rotation3, Translation3, UnitQuaternion};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// One stereo measurement of the factors file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoObservation {
    /// Camera pose id.
    pub pose: u64,
    /// Landmark id.
    pub landmark: u64,
    /// `(u_left, u_right, v)`, pixels.
    pub uv: Vector3<f64>,
    /// The point in the camera's frame as the file gives it.
    pub p_camera: Point3<f64>,
}

/// A stereo bundle-adjustment problem as read from the three files.
#[derive(Clone, Debug)]
pub struct StereoProblem {
    /// The stereo camera.
    pub calibration: StereoCalibration,
    /// Camera poses `world_from_camera` in file order.
    pub poses: Vec<(u64, Isometry3<f64>)>,
    /// Measurements in file order.
    pub observations: Vec<StereoObservation>,
}

fn parse_error(path: &Path, line: usize, message: impl Into<String>) -> GraphError {
    GraphError::Parse {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

fn read_text(path: &Path) -> Result<String, GraphError> {
    std::fs::read_to_string(path).map_err(|source| GraphError::Io {
        path: PathBuf::from(path),
        source,
    })
}

/// The numbers of a line, or an error naming the line.
fn numbers(path: &Path, line: usize, text: &str, count: usize) -> Result<Vec<f64>, GraphError> {
    let values: Vec<f64> = text
        .split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| parse_error(path, line, format!("'{t}' is not a number")))
        })
        .collect::<Result<_, _>>()?;
    if values.len() != count {
        return Err(parse_error(
            path,
            line,
            format!("expected {count} numbers, found {}", values.len()),
        ));
    }
    if let Some(v) = values.iter().find(|v| !v.is_finite()) {
        return Err(parse_error(path, line, format!("non-finite value {v}")));
    }
    Ok(values)
}

/// An id (a non-negative integer written as a number).
fn id_of(path: &Path, line: usize, value: f64, what: &str) -> Result<u64, GraphError> {
    if value < 0.0 || value.fract() != 0.0 || value > 1e15 {
        return Err(parse_error(
            path,
            line,
            format!("{what} id {value} is not a non-negative integer"),
        ));
    }
    Ok(value as u64)
}

/// Non-empty, non-comment lines with their 1-based numbers.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// Reads a calibration file `fx fy skew cx cy baseline_m`.
pub fn read_calibration(path: &Path) -> Result<StereoCalibration, GraphError> {
    let text = read_text(path)?;
    let Some((line, content)) = content_lines(&text).next() else {
        return Err(parse_error(path, 1, "empty calibration file"));
    };
    let v = numbers(path, line, content, 6)?;
    let calibration = StereoCalibration {
        fx: v[0],
        fy: v[1],
        skew: v[2],
        cx: v[3],
        cy: v[4],
        baseline_m: v[5],
    };
    calibration
        .validate()
        .map_err(|e| parse_error(path, line, e.to_string()))?;
    Ok(calibration)
}

/// Reads a poses file (`id` and a row-major 4 × 4 matrix per line).
pub fn read_poses(path: &Path) -> Result<Vec<(u64, Isometry3<f64>)>, GraphError> {
    let text = read_text(path)?;
    let mut poses = Vec::new();
    let mut seen = HashMap::new();
    for (line, content) in content_lines(&text) {
        let v = numbers(path, line, content, 17)?;
        let id = id_of(path, line, v[0], "pose")?;
        if let Some(first) = seen.insert(id, line) {
            return Err(parse_error(
                path,
                line,
                format!("pose {id} already defined on line {first}"),
            ));
        }
        let m = Matrix4::from_row_slice(&v[1..17]);
        let pose = isometry_of(&m).map_err(|e| parse_error(path, line, e.to_string()))?;
        poses.push((id, pose));
    }
    if poses.is_empty() {
        return Err(parse_error(path, 1, "no pose in the file"));
    }
    Ok(poses)
}

/// The isometry of a homogeneous matrix whose rotation is orthonormal to 1e-3 (files print
/// a few digits); the rotation is projected onto SO(3).
fn isometry_of(m: &Matrix4<f64>) -> Result<Isometry3<f64>, LineError> {
    let bottom = m.fixed_view::<1, 4>(3, 0);
    if (bottom - nalgebra::RowVector4::new(0.0, 0.0, 0.0, 1.0))
        .abs()
        .max()
        > 1e-9
    {
        return Err(LineError::NotAPose("the matrix's last row is not 0 0 0 1"));
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    if (r.transpose() * r - Matrix3::identity()).abs().max() > 1e-3 || r.determinant() <= 0.0 {
        return Err(LineError::NotAPose("the rotation block is not a rotation"));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&r));
    let t = m.fixed_view::<3, 1>(0, 3).into_owned();
    Ok(Isometry3::from_parts(Translation3::from(t), rotation))
}

/// Reads a factors file (`pose landmark u_left u_right v X Y Z` per line).
pub fn read_observations(path: &Path) -> Result<Vec<StereoObservation>, GraphError> {
    let text = read_text(path)?;
    let mut observations = Vec::new();
    for (line, content) in content_lines(&text) {
        let v = numbers(path, line, content, 8)?;
        observations.push(StereoObservation {
            pose: id_of(path, line, v[0], "pose")?,
            landmark: id_of(path, line, v[1], "landmark")?,
            uv: Vector3::new(v[2], v[3], v[4]),
            p_camera: Point3::new(v[5], v[6], v[7]),
        });
    }
    if observations.is_empty() {
        return Err(parse_error(path, 1, "no measurement in the file"));
    }
    Ok(observations)
}

/// Counts of the graph [`StereoProblem::build_graph`] made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StereoGraphSize {
    /// Camera poses.
    pub poses: usize,
    /// Landmarks.
    pub landmarks: usize,
    /// Stereo factors.
    pub factors: usize,
}

impl StereoProblem {
    /// Reads the three files; every observation must name a pose of the poses file.
    pub fn read(calibration: &Path, poses: &Path, factors: &Path) -> Result<Self, GraphError> {
        let problem = Self {
            calibration: read_calibration(calibration)?,
            poses: read_poses(poses)?,
            observations: read_observations(factors)?,
        };
        let known: std::collections::HashSet<u64> = problem.poses.iter().map(|p| p.0).collect();
        let text = read_text(factors)?;
        for ((line, _), o) in content_lines(&text).zip(&problem.observations) {
            if !known.contains(&o.pose) {
                return Err(parse_error(
                    factors,
                    line,
                    format!("pose {} is not in {}", o.pose, poses.display()),
                ));
            }
        }
        Ok(problem)
    }

    /// The bundle-adjustment graph: poses at their file values (the first one fixed),
    /// landmarks where their first observing camera puts them, one stereo factor per
    /// measurement with isotropic noise `sigma_px` and the given kernel.
    pub fn build_graph(
        &self,
        sigma_px: f64,
        kernel: RobustKernel,
    ) -> Result<(PoseGraph, StereoGraphSize), GraphError> {
        if !(sigma_px.is_finite() && sigma_px > 0.0) {
            return Err(GraphError::InvalidConfig(format!(
                "pixel noise must be positive, got {sigma_px}"
            )));
        }
        let mut graph = PoseGraph::new();
        let mut world_from_camera = HashMap::new();
        for (id, pose) in &self.poses {
            graph.add_pose(*id, *pose)?;
            world_from_camera.insert(*id, *pose);
        }
        if let Some((first, _)) = self.poses.first() {
            graph.fix(VarKey::Pose(*first))?;
        }
        let information = Matrix3::identity() / (sigma_px * sigma_px);
        let mut landmarks = 0;
        for o in &self.observations {
            let key = VarKey::Point(o.landmark);
            if !graph.contains(key) {
                let pose = world_from_camera
                    .get(&o.pose)
                    .ok_or(GraphError::UnknownVariable(VarKey::Pose(o.pose)))?;
                graph.add_point(o.landmark, pose * o.p_camera)?;
                landmarks += 1;
            }
            graph.add_stereo_observation(
                o.pose,
                o.landmark,
                o.uv,
                self.calibration,
                information,
                kernel,
            )?;
        }
        let size = StereoGraphSize {
            poses: self.poses.len(),
            landmarks,
            factors: self.observations.len(),
        };
        Ok((graph, size))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::SolverConfig;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn a_small_problem_is_solved_to_zero_cost() {
        let dir = tempfile::tempdir().unwrap();
        let cal = write(dir.path(), "cal.txt", "700 700 0 320 240 0.5\n");
        let poses = write(
            dir.path(),
            "poses.txt",
            "1 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n2 1 0 0 0.02 0 1 0 0 0 0 1 1.05 0 0 0 1\n",
        );
        let calibration = read_calibration(&cal).unwrap();
        let truth = Isometry3::translation(0.0, 0.0, 1.0);
        let mut lines = String::new();
        for l in 0..12u64 {
            let p = Point3::new(l as f64 * 0.7 - 4.0, (l % 3) as f64 - 1.0, 8.0 + l as f64);
            for (id, pose) in [(1u64, Isometry3::identity()), (2, truth)] {
                let q = pose.inverse() * p;
                let uv = calibration.project(&q.coords).unwrap();
                lines += &format!(
                    "{id} {l} {} {} {} {} {} {}\n",
                    uv.x, uv.y, uv.z, q.x, q.y, q.z
                );
            }
        }
        let factors = write(dir.path(), "factors.txt", &lines);
        let problem = StereoProblem::read(&cal, &poses, &factors).unwrap();
        let (mut graph, size) = problem.build_graph(1.0, RobustKernel::None).unwrap();
        assert_eq!((size.poses, size.landmarks, size.factors), (2, 12, 24));
        assert!(graph.cost() > 1.0);
        graph.optimize(&SolverConfig::default()).unwrap();
        assert!(graph.cost() < 1e-12, "cost {}", graph.cost());
        let moved = graph.pose(2).unwrap().translation.vector - truth.translation.vector;
        assert!(moved.norm() < 1e-6);
    }

    #[test]
    fn bad_files_name_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let cal = write(dir.path(), "cal.txt", "700 700 0 320 240 -0.5\n");
        let e = read_calibration(&cal).unwrap_err().to_string();
        assert!(e.contains("cal.txt:1") && e.contains("baseline"), "{e}");
        let poses = write(
            dir.path(),
            "p.txt",
            "1 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n1 2\n",
        );
        let e = read_poses(&poses).unwrap_err().to_string();
        assert!(e.contains("p.txt:2") && e.contains("17 numbers"), "{e}");
        let factors = write(dir.path(), "f.txt", "1 3 200 190 x 1 2 3\n");
        let e = read_observations(&factors).unwrap_err().to_string();
        assert!(e.contains("f.txt:1") && e.contains("'x'"), "{e}");
    }
}
