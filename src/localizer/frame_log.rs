//! The frames a localizer has been given, as it keeps them: each frame's odometry pose and
//! the step from the previous frame, its attitude (with the IMU's roll and pitch), its
//! boulder detections and its lander points, all in the rover frame. No true pose anywhere.

use super::odometry_bias::OdometryStep;
use crate::graph::se3;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use segloc_maps::frames::{FrameDetection, StreamFrame};
use segloc_maps::{Detection, DetectionSet};

/// One frame as the localizer keeps it.
#[derive(Clone, Debug, PartialEq)]
pub struct KeptFrame {
    /// Time, seconds.
    pub t: f64,
    /// The odometry's pose of the rover (its own frame, `odom`).
    pub odom_from_rover: Isometry3<f64>,
    /// `odom_from_rover` with roll and pitch from the IMU's gravity when the frame had one:
    /// the attitude the gravity factor holds.
    pub attitude: Isometry3<f64>,
    /// The odometry from the previous frame (identity for the first frame).
    pub step: OdometryStep,
    /// Boulder detections, rover frame.
    pub detections: Vec<FrameDetection>,
    /// Points measured on the lander, rover frame.
    pub lander_points_rover: Vec<Point3<f64>>,
}

/// Roll and pitch of a rover whose IMU measures `gravity_rover` (any scale; the rover's z
/// axis points up, so gravity at rest is −z).
pub fn roll_pitch_from_gravity(gravity_rover: &Vector3<f64>) -> (f64, f64) {
    let g = gravity_rover;
    let roll = (-g.y).atan2(-g.z);
    let pitch = g.x.atan2(g.y.hypot(g.z));
    (roll, pitch)
}

/// The frames given so far, in order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameLog {
    /// Every frame kept.
    pub frames: Vec<KeptFrame>,
}

impl FrameLog {
    /// Keep `input` as the next frame.
    pub fn push(&mut self, input: &StreamFrame) {
        let step = match self.frames.last() {
            Some(prev) => step_between(&prev.odom_from_rover, input),
            None => OdometryStep {
                measured: Isometry3::identity(),
                distance_m: 0.0,
                turned_rad: 0.0,
                turned_abs_rad: 0.0,
                reported_cov: None,
            },
        };
        let attitude = match input.gravity_rover {
            Some(g) => {
                let (roll, pitch) = roll_pitch_from_gravity(&g);
                let (_, _, yaw) = se3::rpy_from_rotation(&input.odom_from_rover.rotation);
                Isometry3::from_parts(
                    input.odom_from_rover.translation,
                    UnitQuaternion::from_euler_angles(roll, pitch, yaw),
                )
            }
            None => input.odom_from_rover,
        };
        self.frames.push(KeptFrame {
            t: input.t,
            odom_from_rover: input.odom_from_rover,
            attitude,
            step,
            detections: input.detections.clone(),
            lander_points_rover: input.lander_points_rover.clone(),
        });
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether no frame was given.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Time of the last frame (0 with none).
    pub fn last_t(&self) -> f64 {
        self.frames.last().map_or(0.0, |f| f.t)
    }

    /// The boulder detections of `frames` placed with `poses` (one per frame,
    /// `x_from_rover`), as a detection set in frame `frame_name`: each detection's `frame`
    /// is the frame's index, `rover_position` the pose's position.
    pub fn detections_with_poses(
        &self,
        poses: &[Isometry3<f64>],
        frames: std::ops::Range<usize>,
        session: &str,
        frame_name: &str,
    ) -> DetectionSet {
        let mut set = DetectionSet::new(session, frame_name, true);
        for k in frames {
            let (Some(f), Some(pose)) = (self.frames.get(k), poses.get(k)) else {
                continue;
            };
            set.detections.extend(placed_detections(k, f, pose));
        }
        set
    }
}

/// Frame `k`'s detections placed with `x_from_rover`.
pub fn placed_detections<'a>(
    k: usize,
    frame: &'a KeptFrame,
    x_from_rover: &'a Isometry3<f64>,
) -> impl Iterator<Item = Detection> + 'a {
    let rover = Point3::from(x_from_rover.translation.vector);
    frame.detections.iter().map(move |d| Detection {
        frame: k as u64,
        p_world: x_from_rover * d.p_rover,
        rover_position: Some(rover),
        size_m: d.size_m,
        score: None,
    })
}

/// The odometry from `prev` to `input`'s pose, with the path the frame reports or, without
/// one, the straight line and the yaw between the two poses.
fn step_between(prev: &Isometry3<f64>, input: &StreamFrame) -> OdometryStep {
    let measured = prev.inverse() * input.odom_from_rover;
    match &input.path {
        Some(path) => OdometryStep {
            measured,
            distance_m: path.distance_m,
            turned_rad: path.turned_rad,
            turned_abs_rad: path.turned_abs_rad,
            reported_cov: input.step_cov,
        },
        None => {
            let yaw = measured.rotation.euler_angles().2;
            OdometryStep {
                measured,
                distance_m: measured.translation.vector.norm(),
                turned_rad: yaw,
                turned_abs_rad: yaw.abs(),
                reported_cov: input.step_cov,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(t: f64, x: f64, yaw: f64) -> StreamFrame {
        StreamFrame {
            t,
            odom_from_rover: Isometry3::new(Vector3::new(x, 0.0, 0.0), Vector3::z() * yaw),
            gravity_rover: None,
            detections: vec![FrameDetection {
                p_rover: Point3::new(2.0, 0.0, 0.1),
                size_m: Some(0.3),
                cov_rover: None,
            }],
            lander_points_rover: Vec::new(),
            path: None,
            step_cov: None,
        }
    }

    #[test]
    fn steps_from_consecutive_poses() {
        let mut log = FrameLog::default();
        log.push(&frame(0.0, 0.0, 0.0));
        log.push(&frame(1.0, 0.5, 0.1));
        let s = log.frames[1].step;
        assert!((s.distance_m - 0.5).abs() < 1e-12);
        assert!((s.turned_rad - 0.1).abs() < 1e-12);
        let set = log.detections_with_poses(
            &[Isometry3::identity(), Isometry3::translation(1.0, 0.0, 0.0)],
            0..2,
            "s",
            "odom",
        );
        assert_eq!(set.detections.len(), 2);
        assert!((set.detections[1].p_world.x - 3.0).abs() < 1e-12);
    }

    #[test]
    fn gravity_sets_roll_and_pitch() {
        let mut f = frame(0.0, 0.0, 0.3);
        // rover pitched nose-down by 0.1 rad: gravity has a +x component in the rover frame
        let pitched = UnitQuaternion::from_euler_angles(0.0, 0.1, 0.0);
        f.gravity_rover = Some(pitched.inverse() * Vector3::new(0.0, 0.0, -1.62));
        let mut log = FrameLog::default();
        log.push(&f);
        let (roll, pitch, yaw) = se3::rpy_from_rotation(&log.frames[0].attitude.rotation);
        assert!(roll.abs() < 1e-12);
        assert!((pitch - 0.1).abs() < 1e-12, "{pitch}");
        assert!((yaw - 0.3).abs() < 1e-12);
    }
}
