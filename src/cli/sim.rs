//! `segloc sim session`: drive one simulated session on the synthetic moon and summarise it;
//! `segloc sim field`: the two-session boulder field ([`super::sim_field`]).

use super::print_json;
use anyhow::{bail, Result};
use clap::Subcommand;
use segloc::relocalize::RelocalizeConfig;
use segloc::sim::moon::{Moon, MoonConfig};
use segloc::sim::session::{run_session, SessionConfig};

/// Simulation commands.
#[derive(Subcommand, Debug)]
pub enum SimCommand {
    /// Drive one session (planner, sensors, odometry) and print a summary.
    Session {
        /// Seed of the moon and of the session.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Simulated duration, seconds.
        #[arg(long, default_value_t = 300.0)]
        seconds: f64,
        /// Start position x, y (world frame, metres); moved to the nearest clear ground.
        #[arg(long, num_args = 2, value_names = ["X", "Y"], allow_negative_numbers = true, default_values_t = [4.5, 0.0])]
        start: Vec<f64>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// A generated boulder field seen by two sessions, fused into maps and relocalized:
    /// writes detection CSVs and maps to play with.
    Field(super::sim_field::FieldArgs),
    /// A session of the mission as a recorded drive: the frames file, its true trajectory
    /// (TUM) and session 1's map, for `segloc localize`.
    Export(super::sim_export::ExportArgs),
    /// A drive of the mission's planner rendered as stereo images with ground truth
    /// (depth, rock instances, visible rocks), for perception and visual odometry.
    Render(super::sim_render::RenderArgs),
}

/// Run a `sim` subcommand; exit code 0, or 2 on bad input.
pub fn run(command: &SimCommand, relocalize: &RelocalizeConfig) -> Result<i32> {
    match command {
        SimCommand::Field(args) => super::sim_field::run(args, relocalize),
        SimCommand::Export(args) => super::sim_export::run(args),
        SimCommand::Render(args) => super::sim_render::run(args),
        SimCommand::Session {
            seed,
            seconds,
            start,
            json,
        } => {
            if !(seconds.is_finite() && *seconds > 0.0 && *seconds <= 1e6) {
                bail!("--seconds must be within (0, 1e6]");
            }
            let (sx, sy) = (
                start.first().copied().unwrap_or(4.5),
                start.get(1).copied().unwrap_or(0.0),
            );
            let moon = Moon::generate(&MoonConfig::default(), *seed)?;
            let defaults = SessionConfig::default();
            let (x, y) =
                moon.nearest_clear_position(sx, sy, 1.0, defaults.collision_min_rock_radius_m);
            let config = SessionConfig {
                duration_s: *seconds,
                start: [x, y, y.atan2(x) + std::f64::consts::FRAC_PI_2],
                ..defaults
            };
            let log = run_session(&moon, &config, *seed)?;
            let s = log.summary();
            if *json {
                print_json(&s)?;
            } else {
                println!(
                    "seed {}: {:.0} s simulated, {:.1} m driven, {} frames, {} detections ({} spurious, {} distinct rocks), {} ground points",
                    s.seed, s.duration_s, s.distance_m, s.frames, s.detections, s.spurious_detections, s.distinct_rocks, s.ground_points
                );
                println!(
                    "collisions {} ({} ticks), out of bounds {} ticks, odometry drift {:.2} % ({:.3} m), waypoints {} reached / {} skipped, {} backups",
                    s.collisions, s.collision_ticks, s.out_of_bounds_ticks, 100.0 * s.odometry_drift_fraction, s.odometry_end_error_m, s.waypoints_reached, s.waypoints_skipped, s.backups
                );
                println!(
                    "realtime factor {:.0}× ({:.2} s wall)",
                    s.realtime_factor, s.wall_time_s
                );
            }
            Ok(0)
        }
    }
}
