//! The online localizer: segloc's engine fed one camera frame at a time, as a rover or a
//! recorded stream gives them (odometry, the IMU's gravity, boulder detections and lander
//! points, all in the rover frame), with no simulator behind it.
//!
//! One stateful object, one call per frame, in the manner of KISS-ICP's `RegisterFrame`:
//!
//! ```no_run
//! use segloc::localizer::{Localizer, LocalizerConfig};
//! # fn frames() -> Vec<segloc::localizer::FrameInput> { Vec::new() }
//! # let prior_map = segloc::maps::ObjectMap::new("world", "s1", true);
//! let mut localizer = Localizer::new(Some(prior_map), LocalizerConfig::default())?;
//! for frame in frames() {
//!     let out = localizer.push_frame(&frame)?;
//!     if let Some(prior_from_rover) = out.prior_from_rover {
//!         println!("{:.2} s: {}", frame.t, prior_from_rover.translation.vector);
//!     }
//! }
//! let session = localizer.finish()?;
//! println!("{} fixes", session.attempts.iter().filter(|a| a.accepted()).count());
//! # Ok::<(), segloc::localizer::LocalizerError>(())
//! ```
//!
//! With a prior map (a earlier session's boulder map) the localizer relocalizes a submap of
//! its recent detections every period, gates the results ([`fix_gate`]), adds the confirmed
//! ones to its pose graph as global factors, calibrates the odometry's biases
//! ([`odometry_bias`]) and adds the lander's and gravity's factors. Without one it maps: the
//! trajectory anchored at its first frame, loop closures against its own map
//! ([`loop_closure`]). Either way [`Localizer::finish`] solves the session's poses and
//! boulders together ([`boulder_adjustment`]) and returns the session's map.
//!
//! Stages, one file each: [`frame_log`] (the frames kept), [`trajectory`] (the pose graph),
//! [`relocalization`] and [`loop_closure`] (the attempts), [`fix_gate`], [`odometry_bias`],
//! the gravity factors ([`crate::graph::gravity`]), [`lander_factor`], [`view_bias`], [`boulder_adjustment`], [`submap`],
//! [`report`] (what the caller is told), [`config`].

pub mod boulder_adjustment;
pub mod config;
pub mod fix_gate;
pub mod frame_log;
pub mod lander_factor;
pub mod loop_closure;
pub mod odometry_bias;
pub mod relocalization;
pub mod report;
pub mod submap;
pub mod trajectory;
pub mod view_bias;

mod session;

pub use crate::field_error::FieldError;
pub use config::LocalizerConfig;
pub use report::{
    AttemptRecord, AttemptRefusal, AttemptStatus, Confirmation, FrameOutput, LocalizerEvent,
    Measurement,
};
pub use segloc_maps::frames::{FrameDetection, FramePath, StreamFrame as FrameInput};
pub use session::{Localizer, SessionResult, VIEW_BIAS_NOTE};

use crate::graph::GraphError;
use crate::relocalize::RelocalizeError;

/// Errors of the localizer.
#[derive(Debug, thiserror::Error)]
pub enum LocalizerError {
    /// A configuration value is out of range.
    #[error("invalid localizer configuration: {0}")]
    Config(#[from] FieldError),
    /// A frame was refused (its time, or a value that is not finite).
    #[error("frame {index} (t = {t} s): {problem}")]
    Frame {
        /// Index of the frame.
        index: usize,
        /// Its time.
        t: f64,
        /// What is wrong.
        problem: String,
    },
    /// The pose graph failed.
    #[error("pose graph: {0}")]
    Graph(#[from] GraphError),
    /// The prior map could not be prepared for relocalization.
    #[error(transparent)]
    Relocalize(#[from] RelocalizeError),
}
