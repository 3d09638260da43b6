//! `segloc demo [--seed S] [--out DIR] [--json]`: the main job on built-in data — the
//! two-session mission of `segloc mission` with a progress bar, its report and pictures
//! (and with the cargo feature `rerun`, a recording) written to `--out`.

use super::mission::MissionArgs;
use anyhow::Result;
use clap::Args;
use segloc::relocalize::RelocalizeConfig;
use std::path::PathBuf;

/// Arguments of `segloc demo`.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Seed of the synthetic moon and of both sessions.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Folder for report.json, the pictures and the recording.
    #[arg(long, value_name = "DIR", default_value = "segloc-demo")]
    pub out: PathBuf,
    /// Print the report as one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Mission configuration (TOML, as printed by `segloc config print --mission`).
    #[arg(long, value_name = "FILE")]
    pub mission_config: Option<PathBuf>,
    /// Run the coverage mission (both sessions 600 s on the LAC coverage loops; by default
    /// only session 1 is).
    #[arg(long)]
    pub coverage: bool,
}

/// Run the demo; exit code 0, or 2 on bad input.
pub fn run(args: &DemoArgs, config: &RelocalizeConfig, global_config_given: bool) -> Result<i32> {
    if !args.json {
        println!(
            "segloc demo (seed {}): session 1 maps a synthetic lunar site from a known start; \
             session 2 starts elsewhere with a wrong pose guess and finds itself from the boulders",
            args.seed
        );
    }
    let mission = MissionArgs::for_demo(
        args.seed,
        args.out.clone(),
        args.json,
        args.mission_config.clone(),
        args.coverage,
    );
    super::mission::run(&mission, config, global_config_given)
}
