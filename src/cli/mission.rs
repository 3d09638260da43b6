//! `segloc mission`: the two-session mission on the synthetic moon of a seed — session 1
//! maps, session 2 starts lost and relocalizes against it — with the LAC maps scored.

use super::print_json;
use anyhow::{bail, Context, Result};
use clap::Args;
use segloc::mission::{run_mission, MissionConfig};
use segloc::relocalize::RelocalizeConfig;
use std::path::PathBuf;

/// Arguments of `segloc mission`.
#[derive(Args, Debug)]
pub struct MissionArgs {
    /// Seed of the moon and of both sessions.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated seconds per session (default: the mission configuration's,
    /// `seconds_per_session`).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write report.json and the pictures into this directory.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Mission configuration (TOML, fields of `MissionConfig`); defaults otherwise. Its
    /// `relocalize` table is replaced by the global `--config` when that is given.
    #[arg(long, value_name = "FILE")]
    pub mission_config: Option<PathBuf>,
}

/// Run the mission; exit code 0, or 2 on bad input.
pub fn run(
    args: &MissionArgs,
    relocalize: &RelocalizeConfig,
    global_config_given: bool,
) -> Result<i32> {
    if args
        .seconds
        .is_some_and(|s| !(s.is_finite() && s > 0.0 && s <= 1e5))
    {
        bail!("--seconds must be within (0, 1e5]");
    }
    let base = match &args.mission_config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            toml::from_str(&text).with_context(|| format!("mission config {}", path.display()))?
        }
        None => MissionConfig::default(),
    };
    let config = MissionConfig {
        seconds_per_session: args.seconds.unwrap_or(base.seconds_per_session),
        relocalize: if global_config_given {
            relocalize.clone()
        } else {
            base.relocalize.clone()
        },
        ..base
    };
    let output = run_mission(args.seed, &config)?;
    if let Some(dir) = &args.out {
        output.write(dir)?;
    }
    let r = &output.report;
    if args.json {
        print_json(r)?;
    } else {
        for s in &r.sessions {
            println!(
                "session {}: {:.0} s, {:.1} m, RMSE {:.3} m (odometry only {:.3} m), {} collisions",
                s.session,
                s.duration_s,
                s.distance_m,
                s.rmse_m,
                s.rmse_without_global_m,
                s.collisions
            );
        }
        println!(
            "relocalizations: {} accepted, {} refused, {} wrong accepted",
            r.relocalizations.accepted, r.relocalizations.refused, r.relocalizations.wrong_accepted
        );
        println!(
            "LAC: geometric {:.1}, rocks {:.1}, productivity {:.1}, total {:.1}",
            r.lac.geometric, r.lac.rocks, r.lac.productivity, r.lac.total
        );
        println!(
            "{:.1} s wall, {:.0}× real time",
            r.wall_s, r.realtime_factor
        );
    }
    Ok(0)
}
