//! What the localizer tells its caller: each relocalization attempt with its outcome, the
//! events of a frame, and the summary of a whole drive. Nothing here can carry a true pose:
//! the caller that knows the truth (the mission, an evaluation) compares it with these.

use nalgebra::{Isometry3, Matrix6};
use serde::Serialize;

/// The outcome of one relocalization attempt (or loop closure).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "status", content = "reason", rename_all = "snake_case")]
pub enum AttemptStatus {
    /// The relocalizer accepted and the gate confirmed it: it is in the pose graph.
    Accepted,
    /// The relocalizer refused (or failed): why.
    Refused(String),
    /// The relocalizer accepted but the gate has not confirmed it (yet): why.
    Unconfirmed(String),
}

impl AttemptStatus {
    /// A short stable code: `accepted`, `unconfirmed`, or the refusal's first words
    /// (`too few inliers`, `ambiguous`, …) up to a colon.
    pub fn code(&self) -> String {
        match self {
            AttemptStatus::Accepted => "accepted".into(),
            AttemptStatus::Unconfirmed(_) => "unconfirmed".into(),
            AttemptStatus::Refused(reason) => reason
                .split([':', '('])
                .next()
                .unwrap_or(reason)
                .trim()
                .to_string(),
        }
    }
}

/// What an accepted relocalization measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Measurement {
    /// Frame `k`'s pose in the prior map.
    Prior {
        /// The frame it is anchored at.
        k: usize,
        /// Measured `prior_from_rover`.
        prior_from_rover: Isometry3<f64>,
    },
    /// A loop closure: frame `k` measured from the earlier frame `j`.
    Closure {
        /// The earlier frame.
        j: usize,
        /// The recent frame.
        k: usize,
        /// Measured `j_from_k`.
        j_from_k: Isometry3<f64>,
    },
}

/// One relocalization attempt.
#[derive(Clone, Debug, PartialEq)]
pub struct AttemptRecord {
    /// Time of the submap's last frame, seconds.
    pub t: f64,
    /// The submap's last frame.
    pub frame: usize,
    /// Landmarks in the submap.
    pub query_landmarks: usize,
    /// Inlier associations.
    pub inliers: usize,
    /// The relocalizer's yaw standard deviation (from its information), degrees.
    pub yaw_sigma_deg: Option<f64>,
    /// The outcome.
    pub status: AttemptStatus,
    /// What the relocalizer measured, when it accepted (confirmed or not).
    pub measurement: Option<Measurement>,
}

impl AttemptRecord {
    /// An attempt whose outcome is filled in once the relocalizer has answered.
    pub fn pending(t: f64, frame: usize, query_landmarks: usize) -> Self {
        Self {
            t,
            frame,
            query_landmarks,
            inliers: 0,
            yaw_sigma_deg: None,
            status: AttemptStatus::Refused("not attempted".into()),
            measurement: None,
        }
    }

    /// Whether it entered the pose graph.
    pub fn accepted(&self) -> bool {
        self.status == AttemptStatus::Accepted
    }

    /// Why it did not enter the pose graph (`None` when it did).
    pub fn refusal(&self) -> Option<&str> {
        match &self.status {
            AttemptStatus::Accepted => None,
            AttemptStatus::Refused(r) | AttemptStatus::Unconfirmed(r) => Some(r),
        }
    }
}

/// Something that happened while the localizer took a frame.
#[derive(Clone, Debug, PartialEq)]
pub enum LocalizerEvent {
    /// A relocalization was attempted: its index in [`super::Localizer::attempts`] (the
    /// record's status may still change to accepted when a later result confirms it).
    Attempt(usize),
    /// A fix entered the pose graph: the attempt's index, the frame it is anchored at, its
    /// inliers and its information (right perturbation, rotation then translation).
    Fix {
        /// Index of the attempt.
        attempt: usize,
        /// The frame the fix is anchored at.
        frame: usize,
        /// Inlier associations.
        inliers: usize,
        /// Information of the measurement.
        information: Box<Matrix6<f64>>,
    },
    /// The pose graph was re-optimised (fixes, lander factors or calibration changed it).
    Reoptimized,
}

/// What the localizer returns for each frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameOutput {
    /// Index of the frame.
    pub frame: usize,
    /// The current estimate of the rover's pose in the prior map's frame, once it is known
    /// (a mapping session: in its own frame, anchored at its first frame).
    pub prior_from_rover: Option<Isometry3<f64>>,
    /// What happened during this frame.
    pub events: Vec<LocalizerEvent>,
    /// Wall time of the call, milliseconds.
    pub time_ms: f64,
}

impl FrameOutput {
    /// Whether a relocalization was attempted during this frame.
    pub fn attempted(&self) -> bool {
        self.events
            .iter()
            .any(|e| matches!(e, LocalizerEvent::Attempt(_)))
    }
}
