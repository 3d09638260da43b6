//! Subcommands of the `segloc` binary, one file each.

mod bench;
mod bench_detect;
mod bench_render;
mod config;
mod demo;
mod detect;
mod eval;
mod eval_grid;
mod eval_render;
mod eval_segmenter;
mod graph;
mod graph_stereo;
mod grid;
mod localize;
mod map;
mod mission;
mod relocalize;
mod sim;
mod sim_export;
mod sim_field;
mod sim_render;
mod vo;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use segloc::relocalize::RelocalizeConfig;
use std::path::{Path, PathBuf};

/// segloc: relocalize a lunar rover from the boulders it has seen before.
#[derive(Parser, Debug)]
#[command(name = "segloc", version, about, propagate_version = true)]
pub struct Cli {
    /// Configuration file (TOML, as printed by `segloc config print`); defaults otherwise.
    #[arg(long, global = true, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// The main job on built-in data: a two-session mission on the synthetic moon (session 1
    /// maps, session 2 starts lost and finds itself from the boulders), LAC maps scored,
    /// report and pictures written to `--out`.
    Demo(demo::DemoArgs),
    /// Find `prior_from_query` between two maps (map files or detection / traverse CSVs).
    Relocalize(relocalize::RelocalizeArgs),
    /// A recorded drive (a frames file, or stereo images: `--lac`, `--images`) through the
    /// online localizer, against a prior map or as a mapping session: the trajectory as TUM,
    /// the session's map with `--map-out`.
    Localize(localize::LocalizeArgs),
    /// Build and inspect object maps.
    #[command(subcommand)]
    Map(map::MapCommand),
    /// Evaluate on real data.
    #[command(subcommand)]
    Eval(eval::EvalCommand),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// SE(3) pose graph: optimise g2o / TORO files, benchmark, corrupt, compare.
    Graph(graph::GraphArgs),
    /// Find boulders in stereo images (one pair, or a `.lac` recording).
    Detect(detect::DetectArgs),
    /// Print or check the configuration.
    #[command(subcommand)]
    Config(config::ConfigCommand),
    /// LAC height / rock grids: build the rock map from real detections, score a grid.
    #[command(subcommand)]
    Grid(grid::GridCommand),
    /// Simulation on the synthetic moon.
    #[command(subcommand)]
    Sim(sim::SimCommand),
    /// The two-session mission on the synthetic moon: map, relocalize, LAC maps scored.
    Mission(mission::MissionArgs),
    /// Stereo visual odometry: a stereo sequence to the left camera's trajectory (TUM).
    Vo(vo::VoArgs),
}

/// Run a parsed command line; returns the exit code.
pub fn run(cli: Cli) -> Result<i32> {
    let config = load_config(cli.config.as_deref())?;
    match cli.command {
        Command::Demo(args) => demo::run(&args, &config, cli.config.is_some()),
        Command::Relocalize(args) => relocalize::run(&args, &config),
        Command::Localize(args) => localize::run(&args),
        Command::Map(cmd) => map::run(&cmd, &config),
        Command::Eval(cmd) => eval::run(&cmd, &config),
        Command::Bench(cmd) => bench::run(&cmd, &config),
        Command::Config(cmd) => config::run(&cmd, &config),
        Command::Graph(args) => graph::run(&args),
        Command::Grid(cmd) => grid::run(&cmd),
        Command::Detect(args) => detect::run(&args),
        Command::Sim(cmd) => sim::run(&cmd, &config),
        Command::Mission(args) => mission::run(&args, &config, cli.config.is_some()),
        Command::Vo(args) => vo::run(&args),
    }
}

/// A configuration from a TOML file, or `T::default()` without one, checked by `validate`;
/// every error names the file, as `what` (e.g. "localizer config") and its path.
pub fn load_toml<T, E>(
    path: Option<&Path>,
    what: &str,
    validate: impl Fn(&T) -> std::result::Result<(), E>,
) -> Result<T>
where
    T: Default + serde::de::DeserializeOwned,
    E: std::error::Error + Send + Sync + 'static,
{
    let Some(path) = path else {
        return Ok(T::default());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read {what} {}", path.display()))?;
    let config: T = toml::from_str(&text).with_context(|| format!("{what} {}", path.display()))?;
    validate(&config).with_context(|| format!("{what} {}", path.display()))?;
    Ok(config)
}

/// The configuration from `path`, or the defaults.
pub fn load_config(path: Option<&Path>) -> Result<RelocalizeConfig> {
    let Some(path) = path else {
        return Ok(RelocalizeConfig::default());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read config file {}", path.display()))?;
    let config: RelocalizeConfig =
        toml::from_str(&text).with_context(|| format!("config file {}", path.display()))?;
    config
        .landmarks
        .validate()
        .map_err(|m| anyhow::anyhow!("config file {}: [landmarks] {m}", path.display()))?;
    config
        .refine
        .tilt
        .validate()
        .map_err(|m| anyhow::anyhow!("config file {}: [refine] {m}", path.display()))?;
    Ok(config)
}

/// Print `value` as one line of JSON on stdout.
pub fn print_json(value: &impl serde::Serialize) -> Result<()> {
    println!("{}", serde_json::to_string(value)?);
    Ok(())
}

/// What the binary prints for a failed command: the error and its causes, outermost
/// first, joined by ": " (anyhow's `{:#}`), leaving out a cause whose text the message
/// already holds (a library error that spells out its own source in its message).
pub fn error_message(error: &anyhow::Error) -> String {
    let mut message = error.to_string();
    for cause in error.chain().skip(1) {
        let text = cause.to_string();
        if !message.contains(&text) {
            message.push_str(": ");
            message.push_str(&text);
        }
    }
    message
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_is_printed_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file");
        let read = segloc_maps::MapError::read_io(Path::new("/x/g.csv"), io);
        let error = anyhow::Error::from(read).context("ground truth");
        assert_eq!(
            error_message(&error),
            "ground truth: cannot read /x/g.csv: No such file"
        );
        let plain = anyhow::anyhow!("inner").context("outer");
        assert_eq!(error_message(&plain), "outer: inner");
    }
}
