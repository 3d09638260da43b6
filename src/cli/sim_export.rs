//! `segloc sim export`: a session of the mission as a recorded drive, so the localizer's
//! command line is tried on the same data as the mission: the frames file, the true
//! trajectory (TUM) and, for session 2, session 1's map (its prior).

use anyhow::{bail, Result};
use clap::Args;
use segloc::mission::stream::frame_input;
use segloc::mission::{drive_sessions, MissionConfig, Silent};
use segloc::sim::session::SessionLog;
use segloc_maps::frames::write_frames;
use segloc_maps::tum::write_tum;
use std::path::PathBuf;

/// Arguments of `segloc sim export`.
#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Seed of the mission.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The session to export: 1 (mapping, known start) or 2 (lost, against session 1's map).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    session: u8,
    /// Simulated seconds of the exported session (default: the mission's); session 2's
    /// prior is always session 1 of the mission's default length.
    #[arg(long)]
    seconds: Option<f64>,
    /// Where to write the frames file.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Where to write the true `world_from_rover` of every frame (TUM).
    #[arg(long, value_name = "FILE")]
    truth: Option<PathBuf>,
    /// Where to write session 1's map, the prior of session 2 (world frame).
    #[arg(long, value_name = "FILE")]
    prior_map: Option<PathBuf>,
}

/// Run `segloc sim export`.
pub fn run(args: &ExportArgs) -> Result<i32> {
    let mut config = MissionConfig::default();
    if let Some(seconds) = args.seconds {
        if !(seconds.is_finite() && seconds > 0.0 && seconds <= 1e5) {
            bail!("--seconds must be within (0, 1e5]");
        }
        if args.session == 1 {
            config.seconds_per_session = seconds;
        } else {
            config.seconds_session_2 = Some(seconds);
        }
    }
    let sessions = drive_sessions(args.seed, &config, &Silent)?;
    let log = if args.session == 1 {
        &sessions.one.log
    } else {
        &sessions.two.log
    };
    let (frames, truth) = stream_of(log);
    write_frames(&args.output, &frames)?;
    if let Some(path) = &args.truth {
        write_tum(path, &truth)?;
    }
    if let Some(path) = &args.prior_map {
        segloc_maps::write_map(&sessions.one.map, path)?;
    }
    eprintln!(
        "session {} of seed {}: {} frames written to {}",
        args.session,
        args.seed,
        frames.len(),
        args.output.display()
    );
    Ok(0)
}

/// The frames of `log` (with the IMU's gravity) and the true pose of each.
fn stream_of(
    log: &SessionLog,
) -> (
    Vec<segloc_maps::frames::StreamFrame>,
    Vec<(f64, nalgebra::Isometry3<f64>)>,
) {
    let mut frames = Vec::with_capacity(log.frames.len());
    let mut truth = Vec::with_capacity(log.frames.len());
    for k in 0..log.frames.len() {
        let (Some(frame), Some(tick)) =
            (frame_input(log, k, true), log.ticks.get(log.frames[k].tick))
        else {
            continue;
        };
        truth.push((frame.t, tick.world_from_rover));
        frames.push(frame);
    }
    (frames, truth)
}
