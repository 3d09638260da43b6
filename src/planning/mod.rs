//! Planning for the simulated rover: where to go ([`waypoints`]: the LAC patterns around the
//! lander), what is in the way ([`obstacles`]: detected rocks and lander points), how to get
//! there ([`arc_planner`]: constant-curvature arcs checked with parry2d) and the state
//! machine around it ([`navigator`]: waypoint sequencing, point turns, stall detection and a
//! backup manoeuvre, and [`lander_glance`]: turning to look at the lander for an absolute
//! fix), with [`visibility`] keeping track of the ground the cameras have
//! seen (unseen ground counts as blocked). The rover it plans for is the differential drive
//! of [`kinematics`]: velocity commands, drive limits and the planar state they integrate.
//!
//! Everything here works in the rover's *session frame* (the frame its odometry estimate
//! lives in); waypoints and the lander are given in the *nav frame* (what the rover believes
//! is the world frame) and mapped through `session_from_nav`.

pub mod arc_planner;
pub mod kinematics;
pub mod lander_glance;
pub mod navigator;
pub mod obstacles;
pub mod route;
pub mod visibility;
pub mod waypoints;

/// A planar pose: position and heading.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pose2 {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// Heading, radians.
    pub yaw: f64,
}

impl Pose2 {
    /// A pose.
    pub fn new(x: f64, y: f64, yaw: f64) -> Self {
        Self { x, y, yaw }
    }

    /// The planar part of a 3D pose (position x, y and yaw).
    pub fn from_isometry3(pose: &nalgebra::Isometry3<f64>) -> Self {
        let (_, _, yaw) = pose.rotation.euler_angles();
        Self::new(pose.translation.x, pose.translation.y, yaw)
    }

    /// As a 2D isometry.
    pub fn to_isometry2(self) -> nalgebra::Isometry2<f64> {
        nalgebra::Isometry2::new(nalgebra::Vector2::new(self.x, self.y), self.yaw)
    }
}
