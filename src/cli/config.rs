//! `segloc config print|check`.

use anyhow::Result;
use clap::Subcommand;
use segloc::mapping::RockEvidenceConfig;
use segloc::mission::MissionConfig;
use segloc::relocalize::RelocalizeConfig;

/// Configuration commands.
#[derive(Subcommand, Debug)]
pub enum ConfigCommand {
    /// Print the configuration in effect (defaults, or `--config FILE`) as TOML.
    Print {
        /// Print the whole mission configuration (`segloc mission|demo --mission-config`)
        /// instead of the relocalizer's; its `relocalize` table is the configuration in
        /// effect.
        #[arg(long, conflicts_with = "evidence")]
        mission: bool,
        /// Print the defaults of the real-data rock map (`segloc grid rocks
        /// --evidence-config`) instead.
        #[arg(long)]
        evidence: bool,
    },
    /// Load `--config FILE` and report whether it is valid.
    Check,
}

/// Run a config command.
pub fn run(cmd: &ConfigCommand, config: &RelocalizeConfig) -> Result<i32> {
    match cmd {
        ConfigCommand::Print { evidence: true, .. } => print!(
            "{}",
            toml::to_string_pretty(&RockEvidenceConfig::default())?
        ),
        ConfigCommand::Print { mission: false, .. } => {
            print!("{}", toml::to_string_pretty(config)?)
        }
        ConfigCommand::Print { mission: true, .. } => {
            let mut mission = MissionConfig::default();
            mission.localizer.relocalize = config.clone();
            print!("{}", toml::to_string_pretty(&mission)?)
        }
        ConfigCommand::Check => println!("configuration is valid"),
    }
    Ok(0)
}
