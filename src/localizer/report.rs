//! What the localizer tells its caller: each relocalization attempt with its outcome, the
//! events of a frame, and the summary of a whole drive. Nothing here can carry a true pose:
//! the caller that knows the truth (the mission, an evaluation) compares it with these.

use crate::relocalize::Refusal;
use nalgebra::{Isometry3, Matrix6};
use serde::Serialize;

/// The outcome of one relocalization attempt (or loop closure). In JSON: `status`
/// (`accepted`, `refused`, `unconfirmed`), `code` (stable, see [`AttemptStatus::code`]) and
/// `reason` (a sentence).
#[derive(Clone, Debug, PartialEq)]
pub enum AttemptStatus {
    /// The relocalizer accepted and the gate confirmed it: it is in the pose graph.
    Accepted,
    /// The relocalizer refused, could not run, or its answer failed the gate's own tests.
    Refused(AttemptRefusal),
    /// The relocalizer accepted but the gate has not confirmed it (yet).
    Unconfirmed(Confirmation),
}

/// Why an attempt was refused.
#[derive(Clone, Debug, PartialEq)]
pub enum AttemptRefusal {
    /// Not attempted (yet).
    NotAttempted,
    /// The relocalizer refused.
    Relocalizer(Refusal),
    /// The relocalizer could not run on this input.
    Error(String),
    /// The relocalizer accepted, but its yaw σ is over the gate's `max_yaw_sigma_deg`.
    YawUndetermined {
        /// The answer's yaw standard deviation, degrees.
        sigma_deg: f64,
        /// The gate's limit, degrees.
        max_deg: f64,
    },
}

/// What an accepted but unconfirmed answer waits for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Confirmation {
    /// The pose graph's prediction or the next relocalization.
    NextRelocalization,
    /// The pose graph's prediction or the next loop closure.
    NextLoopClosure,
}

impl AttemptStatus {
    /// A short stable code: `accepted`, `unconfirmed`, or the refusal's
    /// ([`AttemptRefusal::code`]).
    pub fn code(&self) -> &'static str {
        match self {
            AttemptStatus::Accepted => "accepted",
            AttemptStatus::Unconfirmed(_) => "unconfirmed",
            AttemptStatus::Refused(refusal) => refusal.code(),
        }
    }
}

impl AttemptRefusal {
    /// A short stable code: `not_attempted`, `error`, `yaw_undetermined`, or the
    /// relocalizer's own ([`Refusal::code`]: `too_few_inliers`, `ambiguous`, …).
    pub fn code(&self) -> &'static str {
        match self {
            AttemptRefusal::NotAttempted => "not_attempted",
            AttemptRefusal::Relocalizer(refusal) => refusal.code(),
            AttemptRefusal::Error(_) => "error",
            AttemptRefusal::YawUndetermined { .. } => "yaw_undetermined",
        }
    }
}

impl std::fmt::Display for AttemptRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AttemptRefusal::NotAttempted => write!(f, "not attempted"),
            AttemptRefusal::Relocalizer(refusal) => write!(f, "{refusal}"),
            AttemptRefusal::Error(message) => write!(f, "error: {message}"),
            AttemptRefusal::YawUndetermined { sigma_deg, max_deg } => {
                write!(f, "yaw undetermined: σ {sigma_deg:.2}° over {max_deg:.2}°")
            }
        }
    }
}

impl std::fmt::Display for Confirmation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let next = match self {
            Confirmation::NextRelocalization => "relocalization",
            Confirmation::NextLoopClosure => "loop closure",
        };
        write!(f, "not confirmed by the pose graph or the next {next}")
    }
}

impl std::fmt::Display for AttemptStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AttemptStatus::Accepted => write!(f, "accepted"),
            AttemptStatus::Refused(refusal) => write!(f, "{refusal}"),
            AttemptStatus::Unconfirmed(waiting) => write!(f, "{waiting}"),
        }
    }
}

impl Serialize for AttemptStatus {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let status = match self {
            AttemptStatus::Accepted => "accepted",
            AttemptStatus::Refused(_) => "refused",
            AttemptStatus::Unconfirmed(_) => "unconfirmed",
        };
        let mut map = s.serialize_map(Some(3))?;
        map.serialize_entry("status", status)?;
        map.serialize_entry("code", self.code())?;
        if !matches!(self, AttemptStatus::Accepted) {
            map.serialize_entry("reason", &self.to_string())?;
        }
        map.end()
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
            status: AttemptStatus::Refused(AttemptRefusal::NotAttempted),
            measurement: None,
        }
    }

    /// Whether it entered the pose graph.
    pub fn accepted(&self) -> bool {
        self.status == AttemptStatus::Accepted
    }

    /// Why it did not enter the pose graph (`None` when it did): the status itself, whose
    /// `code()` is stable and whose `Display` is a sentence.
    pub fn refusal(&self) -> Option<&AttemptStatus> {
        (self.status != AttemptStatus::Accepted).then_some(&self.status)
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
