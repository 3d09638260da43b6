//! `segloc map build|merge|from-grid|info`.

use super::print_json;
use anyhow::{Context, Result};
use clap::Subcommand;
use segloc::io::load_map;
use segloc::landmarks::from_grid::coarsened;
use segloc::landmarks::{map_from_grid, GridRocksConfig};
use segloc::merge::{merge_maps, MapStatus, MergeConfig};
use segloc::relocalize::RelocalizeConfig;
use segloc_maps::{read_grid_csv, read_map, write_map};
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
    /// Merge maps of several agents / sessions (map files, detection or traverse CSVs)
    /// into the frame of one of them.
    Merge {
        /// The input maps.
        #[arg(required = true, num_args = 2..)]
        inputs: Vec<PathBuf>,
        /// The merged map file to write (atomically).
        #[arg(short, long)]
        output: PathBuf,
        /// Index (0-based, in the order given) of the map whose frame is the reference.
        #[arg(long, default_value_t = 0)]
        reference: usize,
        /// Write every map that could not be joined to the reference here, on its own.
        #[arg(long, value_name = "DIR")]
        disconnected_dir: Option<PathBuf>,
        /// Viewpoint-bias correction (m) for detection / traverse inputs with rover
        /// positions: each detection is pushed this far from the rover along its line of
        /// sight before fusion (default: the value measured on the LunarLoc traverses;
        /// 0 = none; map-file inputs are used as they are).
        #[arg(long, default_value_t = segloc::landmarks::view_bias::LUNARLOC_VIEW_BIAS_M)]
        view_bias_m: f64,
        /// Boulder-to-boulder spread (m) of that bias, modelled in the landmark covariances
        /// along each landmark's mean line of sight (0 = not modelled).
        #[arg(long, default_value_t = segloc::landmarks::view_bias::LUNARLOC_VIEW_BIAS_SIGMA_M)]
        view_bias_sigma_m: f64,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Cluster the rock cells of a LAC grid CSV (`i,j,x,y,height,rock`) into rocks and
    /// write them as a prior map: 8-connected rock cells are one rock, its landmark at their
    /// mean centre and height, with the cell quantisation as its covariance.
    FromGrid {
        /// The grid CSV.
        grid: PathBuf,
        /// The map file to write (atomically).
        #[arg(short, long)]
        output: PathBuf,
        /// Rocks of fewer cells are left out.
        #[arg(long, default_value_t = 1)]
        min_cells: usize,
        /// Coarsen the grid first by OR-ing this many cells per side (1: as it is).
        #[arg(long, default_value_t = 1)]
        coarsen: usize,
        /// Session id to record.
        #[arg(long, default_value = "grid")]
        session: String,
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
        MapCommand::Merge {
            inputs,
            output,
            reference,
            disconnected_dir,
            view_bias_m,
            view_bias_sigma_m,
            json,
        } => merge(
            inputs,
            output,
            *reference,
            disconnected_dir.as_deref(),
            (*view_bias_m, *view_bias_sigma_m),
            *json,
            config,
        ),
        MapCommand::FromGrid {
            grid,
            output,
            min_cells,
            coarsen,
            session,
            json,
        } => from_grid(grid, output, *min_cells, *coarsen, session, *json),
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

fn from_grid(
    grid_path: &std::path::Path,
    output: &std::path::Path,
    min_cells: usize,
    coarsen: usize,
    session: &str,
    json: bool,
) -> Result<i32> {
    if coarsen == 0 {
        anyhow::bail!("--coarsen must be at least 1");
    }
    let mut grid = read_grid_csv(grid_path)?;
    if coarsen > 1 {
        grid = coarsened(&grid, coarsen);
    }
    let config = GridRocksConfig {
        min_cells,
        ..GridRocksConfig::default()
    };
    let mut map = map_from_grid(&grid, &config, session)
        .map_err(|e| e.in_file(grid_path))
        .with_context(|| format!("building rocks from {}", grid_path.display()))?;
    map.notes
        .insert("grid".into(), grid_path.display().to_string());
    write_map(&map, output).with_context(|| "writing the map")?;
    if json {
        print_json(&json!({
            "output": output, "landmarks": map.len(), "rock_cells": grid.rock_count(),
            "cell_size_m": grid.cell_size_m, "cells_per_side": grid.cells_per_side,
            "session": map.session,
        }))?;
    } else {
        println!(
            "{} rocks from {} rock cells of {} m in {} -> {}",
            map.len(),
            grid.rock_count(),
            grid.cell_size_m,
            grid_path.display(),
            output.display()
        );
    }
    Ok(0)
}

fn merge(
    inputs: &[PathBuf],
    output: &std::path::Path,
    reference: usize,
    disconnected_dir: Option<&std::path::Path>,
    (view_bias_m, view_bias_sigma_m): (f64, f64),
    json: bool,
    config: &RelocalizeConfig,
) -> Result<i32> {
    // Load everything first: a bad input stops the merge before anything is written.
    let mut fusion = config.landmarks.clone();
    fusion.view_bias_m = view_bias_m;
    fusion.view_bias_sigma_m = view_bias_sigma_m;
    let mut maps = Vec::with_capacity(inputs.len());
    for path in inputs {
        let (mut map, _) = load_map(path, &fusion)?;
        if map.session.is_empty() {
            map.session = path.display().to_string();
        }
        maps.push(map);
    }
    let report = merge_maps(&maps, reference, config, &MergeConfig::default())?;
    write_map(&report.merged, output).with_context(|| "writing the merged map")?;
    if let Some(dir) = disconnected_dir {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for placement in report
            .maps
            .iter()
            .filter(|m| m.status == MapStatus::Disconnected)
        {
            let name = inputs[placement.index]
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| format!("map_{}", placement.index));
            write_map(
                &maps[placement.index],
                &dir.join(format!("{name}.disconnected.json")),
            )?;
        }
    }
    if json {
        let mut value = serde_json::to_value(&report)?;
        for (entry, path) in value["maps"]
            .as_array_mut()
            .into_iter()
            .flatten()
            .zip(inputs)
        {
            entry["input"] = json!(path);
        }
        value["output"] = json!(output);
        value["config"] = json!(config);
        print_json(&value)?;
    } else {
        println!(
            "merged {} maps into the frame of {}:",
            inputs.len(),
            inputs[reference].display()
        );
        for m in &report.maps {
            let status = match m.status {
                MapStatus::Merged => "merged",
                MapStatus::Disconnected => "DISCONNECTED",
            };
            println!(
                "  [{}] {:<40} {:>5} landmarks, {:>2} accepted pairs: {status}",
                m.index,
                inputs[m.index].display().to_string(),
                m.landmarks,
                m.accepted_pairs
            );
        }
        let accepted = report.pairs.iter().filter(|p| p.accepted).count();
        let outvoted = report.pairs.iter().filter(|p| p.outvoted).count();
        println!(
            "  {} pairs: {accepted} accepted, {outvoted} out-voted; {} landmarks ({} fused); frame residual {:.2} cm; {:.0} ms",
            report.pairs.len(),
            report.landmarks,
            report.fused,
            report.frame_residual_rmse_m * 100.0,
            report.time_ms
        );
        println!("  wrote {}", output.display());
    }
    Ok(0)
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
