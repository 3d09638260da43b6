//! Simulation: generated worlds for tests, examples and the built-in demo.
//!
//! - [`boulder_field`]: a flat boulder field and two looped sessions (relocalization tests);
//! - [`moon`]: the synthetic moon (terrain, craters, rocks, lander) and its LAC ground truth,
//!   built from [`value_noise`] and [`crater`], queried by ray casts in [`world_rays`];
//! - [`rover`]: the IPEX rover's differential drive following the terrain ([`ipex`] holds
//!   its geometry);
//! - [`sensors`]: stereo boulder detections and ground points ([`stereo_noise`]),
//!   [`visual_odometry`] and the IMU's gravity direction; [`gyro`], the IMU's angular rate
//!   for rendered drives, and [`wheel_odometry`], the distance the wheels count;
//! - [`session`]: one driving session with the planner ([`crate::planning`]), logged in a
//!   [`session_log::SessionLog`].
//!
//! [`ipex`] and [`stereo_noise`] live in lower layers (the rover's geometry in
//! [`crate::ipex`], the stereo noise model with the landmarks that weigh detections by it in
//! [`crate::landmarks::stereo_noise`]); they are re-exported here so that `sim::ipex::…` and
//! `sim::stereo_noise::…` keep working. See ARCHITECTURE.md.

pub mod boulder_field;
pub mod crater;
pub mod gyro;
pub mod moon;
pub mod render;
pub mod rendered_boulders;
pub mod rendered_odometry;
pub mod rendered_sensors;
pub mod rock_shape;
pub mod rover;
pub mod sensors;
pub mod session;
pub mod session_config;
pub mod session_log;
pub mod value_noise;
pub mod visual_odometry;
pub mod wheel_odometry;
pub mod world_rays;

pub use crate::ipex;
pub use crate::landmarks::stereo_noise;
