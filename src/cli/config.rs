//! `segloc config print|check`.

use anyhow::Result;
use clap::Subcommand;
use segloc::relocalize::RelocalizeConfig;

/// Configuration commands.
#[derive(Subcommand, Debug)]
pub enum ConfigCommand {
    /// Print the configuration in effect (defaults, or `--config FILE`) as TOML.
    Print,
    /// Load `--config FILE` and report whether it is valid.
    Check,
}

/// Run a config command.
pub fn run(cmd: &ConfigCommand, config: &RelocalizeConfig) -> Result<i32> {
    match cmd {
        ConfigCommand::Print => print!("{}", toml::to_string_pretty(config)?),
        ConfigCommand::Check => println!("configuration is valid"),
    }
    Ok(0)
}
