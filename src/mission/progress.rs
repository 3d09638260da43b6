//! Progress of a running mission, for a display such as the CLI's progress bar.

/// Where a mission is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MissionStage {
    /// Session `session` (1-based) has simulated `time_s` of its `duration_s`.
    Driving {
        /// Session number.
        session: usize,
        /// Simulated seconds so far.
        time_s: f64,
        /// Simulated seconds in all.
        duration_s: f64,
    },
    /// Both sessions are done; the maps are being built and scored.
    Mapping,
}

/// Receives the stages of a mission as it runs.
pub trait MissionProgress {
    /// Called often (every simulation tick while driving): keep it cheap.
    fn update(&self, stage: MissionStage);
}

/// No display.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl MissionProgress for Silent {
    fn update(&self, _stage: MissionStage) {}
}

impl<F: Fn(MissionStage)> MissionProgress for F {
    fn update(&self, stage: MissionStage) {
        self(stage)
    }
}
