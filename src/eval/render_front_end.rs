//! The perception front end on rendered frames, against the renderer's ground truth.
//!
//! Pipeline per (seed, sun elevation): drive the mission's mapping session on the moon of the
//! seed → render the front stereo pair every `every_ticks` ticks ([`Renderer`]) → run the
//! front end ([`FrontEnd`]) on the pair → score its boulders against the frame's visible
//! rocks ([`score_frame`]) → aggregate recall, precision and centroid error, overall, by
//! range band and by sun elevation ([`summarize`]).
//!
//! What counts as a true detection, and the scoring itself, live in
//! [`crate::sim::render::scoring`] (the mission on rendered images scores with them too);
//! they are re-exported here.

use crate::mission::mapping_session::map_session;
use crate::mission::{MissionConfig, MissionError, Silent};
use crate::perception::{FrameResult, FrontEnd, PerceptionError};
use crate::sim::moon::Moon;
use crate::sim::render::{RenderConfig, RenderError, Renderer, StereoFrame};

pub use crate::sim::render::scoring::{
    score_frame, summarize, DetectionOutcome, FrameScore, MatchConfig, RockOutcome, Summary,
};

/// Errors of the evaluation.
#[derive(Debug, thiserror::Error)]
pub enum RenderEvalError {
    /// The drive could not be simulated.
    #[error("drive of seed {seed}: {source}")]
    Drive {
        /// The seed.
        seed: u64,
        /// Why.
        source: MissionError,
    },
    /// The renderer refused its configuration.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The front end failed on a frame.
    #[error("front end: {0}")]
    FrontEnd(#[from] PerceptionError),
    /// A configuration value is out of range.
    #[error("invalid render evaluation configuration: {0}")]
    Config(String),
}

/// What to evaluate.
#[derive(Clone, Debug)]
pub struct RenderEvalOptions {
    /// Seeds of the moons and drives.
    pub seeds: Vec<u64>,
    /// Sun elevations, degrees.
    pub sun_elevations_deg: Vec<f64>,
    /// Seconds of the mapping session driven per seed.
    pub seconds: f64,
    /// Render every this many simulator ticks (20 Hz).
    pub every_ticks: usize,
    /// The renderer (its sun elevation is replaced by each of `sun_elevations_deg`).
    pub render: RenderConfig,
    /// What counts and matches.
    pub matching: MatchConfig,
}

/// One evaluated frame as the callback of [`evaluate_render`] sees it.
pub struct EvaluatedFrame<'a> {
    /// The moon rendered.
    pub moon: &'a Moon,
    /// The rendered pair and its truth.
    pub frame: &'a StereoFrame,
    /// The front end's output on it.
    pub result: &'a FrameResult,
    /// Its score.
    pub score: &'a FrameScore,
}

/// Run the front end on rendered frames of every seed and sun; `front_end` is reused.
pub fn evaluate_render(
    options: &RenderEvalOptions,
    front_end: &mut FrontEnd,
    mut on_frame: impl FnMut(&EvaluatedFrame<'_>),
) -> Result<Vec<FrameScore>, RenderEvalError> {
    if options.every_ticks == 0 || !(options.seconds > 0.0 && options.seconds.is_finite()) {
        return Err(RenderEvalError::Config(
            "every_ticks must be ≥ 1 and seconds positive".into(),
        ));
    }
    let mut scores = Vec::new();
    for &seed in &options.seeds {
        let (moon, poses) = drive(seed, options.seconds)?;
        for &sun in &options.sun_elevations_deg {
            let render = RenderConfig {
                sun_elevation_deg: sun,
                ..options.render.clone()
            };
            let renderer = Renderer::new(&moon, &render, seed)?;
            for (tick, world_from_rover) in poses.iter().enumerate().step_by(options.every_ticks) {
                let frame = renderer.render_stereo(world_from_rover, tick as u64);
                let result = front_end.process(&frame.left, &frame.right)?;
                let mut score = score_frame(&frame, &result.boulders, &options.matching);
                (score.seed, score.sun_elevation_deg, score.tick) = (seed, sun, tick);
                score.front_end_ms = result.timing.total_ms;
                on_frame(&EvaluatedFrame {
                    moon: &moon,
                    frame: &frame,
                    result: &result,
                    score: &score,
                });
                scores.push(score);
            }
        }
    }
    Ok(scores)
}

/// The moon of `seed` and the true rover poses of its mapping session (as `segloc sim
/// render --session 1` drives it).
pub fn drive(
    seed: u64,
    seconds: f64,
) -> Result<(Moon, Vec<nalgebra::Isometry3<f64>>), RenderEvalError> {
    let err = |source: MissionError| RenderEvalError::Drive { seed, source };
    let config = MissionConfig {
        seconds_per_session: seconds,
        ..MissionConfig::default()
    };
    config.validate().map_err(err)?;
    let moon = Moon::generate(&config.moon, seed).map_err(|e| err(e.into()))?;
    let min_rock = config.session.collision_min_rock_radius_m;
    let s = config.start_1;
    let (x, y) = moon.nearest_clear_position(s[0], s[1], 1.0, min_rock);
    let one =
        map_session(&moon, &config, [x, y, s[2]], seed.wrapping_mul(2), &Silent).map_err(err)?;
    let poses = one.log.ticks.iter().map(|t| t.world_from_rover).collect();
    Ok((moon, poses))
}
