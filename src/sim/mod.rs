//! Simulation: generated worlds for tests, examples and the built-in demo.
//!
//! - [`boulder_field`]: a flat boulder field and two looped sessions (relocalization tests);
//! - [`moon`]: the synthetic moon (terrain, craters, rocks, lander) and its LAC ground truth,
//!   built from [`value_noise`] and [`crater`], queried by ray casts in [`world_rays`];
//! - [`rover`]: the IPEX rover's differential drive following the terrain ([`ipex`] holds
//!   its geometry);
//! - [`sensors`]: stereo boulder detections and ground points ([`stereo_noise`]),
//!   [`visual_odometry`] and the IMU's gravity direction;
//! - [`session`]: one driving session with the planner ([`crate::planning`]), logged in a
//!   [`session_log::SessionLog`].

pub mod boulder_field;
pub mod crater;
pub mod ipex;
pub mod moon;
pub mod rover;
pub mod sensors;
pub mod session;
pub mod session_config;
pub mod session_log;
pub mod stereo_noise;
pub mod value_noise;
pub mod visual_odometry;
pub mod world_rays;
