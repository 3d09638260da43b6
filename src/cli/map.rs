//! `segloc map build|info`.

use super::print_json;
use anyhow::{Context, Result};
use clap::Subcommand;
use segloc::io::load_map;
use segloc::relocalize::RelocalizeConfig;
use segloc_maps::{read_map, write_map};
use serde_json::json;
use std::path::PathBuf;

/// Map commands.
#[derive(Subcommand, Debug)]
pub enum MapCommand {
    /// Fuse detections (a LunarLoc traverse CSV or a segloc detections CSV) into a map file.
    Build {
        /// The detections.
        input: PathBuf,
        /// The map file to write (atomically).
        #[arg(short, long)]
        output: PathBuf,
        /// Session id to record (default: from the input).
        #[arg(long)]
        session: Option<String>,
        /// Print a JSON summary.
        #[arg(long)]
        json: bool,
    },
    /// Describe a map file.
    Info {
        /// The map file.
        map: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
}

/// Run a map command.
pub fn run(cmd: &MapCommand, config: &RelocalizeConfig) -> Result<i32> {
    match cmd {
        MapCommand::Build {
            input,
            output,
            session,
            json,
        } => {
            let (mut map, _) = load_map(input, &config.landmarks)?;
            if let Some(s) = session {
                map.session = s.clone();
            }
            map.notes
                .insert("source".into(), input.display().to_string());
            write_map(&map, output).with_context(|| "writing the map")?;
            if *json {
                print_json(
                    &json!({"output": output, "landmarks": map.len(), "session": map.session}),
                )?;
            } else {
                println!(
                    "{} landmarks from {} -> {}",
                    map.len(),
                    input.display(),
                    output.display()
                );
            }
            Ok(0)
        }
        MapCommand::Info { map, json } => {
            let m = read_map(map)?;
            let observations: u32 = m.landmarks.iter().map(|l| l.observations).sum();
            let (lo, hi) = bounds(&m);
            if *json {
                print_json(&json!({
                    "frame": m.frame, "session": m.session, "gravity_aligned": m.gravity_aligned,
                    "landmarks": m.len(), "observations": observations,
                    "bounds_min": lo, "bounds_max": hi, "notes": m.notes,
                }))?;
            } else {
                println!("map {}", map.display());
                println!(
                    "  frame {}, session {}, gravity-aligned: {}",
                    m.frame, m.session, m.gravity_aligned
                );
                println!("  {} landmarks from {} detections", m.len(), observations);
                println!(
                    "  extent ({:.2}, {:.2}, {:.2}) .. ({:.2}, {:.2}, {:.2}) m",
                    lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
                );
                for (k, v) in &m.notes {
                    println!("  {k}: {v}");
                }
            }
            Ok(0)
        }
    }
}

fn bounds(m: &segloc_maps::ObjectMap) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for l in &m.landmarks {
        for k in 0..3 {
            lo[k] = lo[k].min(l.position[k]);
            hi[k] = hi[k].max(l.position[k]);
        }
    }
    if m.is_empty() {
        return ([0.0; 3], [0.0; 3]);
    }
    (lo, hi)
}
