//! `segloc map build|merge|from-grid|info`.

use super::print_json;
use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use segloc::io::load_map;
use segloc::landmarks::from_grid::coarsened;
use segloc::landmarks::{map_from_grid, map_from_raster, GridRocksConfig};
use segloc::merge::{merge_maps, MapStatus, MergeConfig};
use segloc::relocalize::RelocalizeConfig;
use segloc_maps::{
    read_grid_csv, read_heights_into, read_map, read_rock_mask, write_map, ObjectMap,
};
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
    /// Cluster the rock cells of a LAC grid CSV (`i,j,x,y,height,rock`), or of a rock raster
    /// (a PNG or CSV mask with `--cell-size` and `--origin`), into rocks and write them as a
    /// prior map: 8-connected rock cells are one rock, its landmark at their mean centre and
    /// height, with the cell quantisation as its covariance.
    FromGrid(FromGridArgs),
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
        MapCommand::FromGrid(args) => from_grid(args),
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

/// `segloc map from-grid`.
#[derive(Args, Debug)]
pub struct FromGridArgs {
    /// The LAC grid CSV, or a rock mask (PNG: bright pixels are rock; CSV: rows of 0/1, top
    /// row first) when `--cell-size` is given.
    grid: PathBuf,
    /// The map file to write (atomically).
    #[arg(short, long)]
    output: PathBuf,
    /// Rocks of fewer cells are left out.
    #[arg(long, default_value_t = 1)]
    min_cells: usize,
    /// Coarsen the grid first by OR-ing this many cells per side (1: as it is; LAC grids
    /// only).
    #[arg(long, default_value_t = 1)]
    coarsen: usize,
    /// Read the input as a rock mask with cells of this size (metres).
    #[arg(long)]
    cell_size: Option<f64>,
    /// The mask's top-left corner in the world, `X,Y` metres (row 0 is the top, at the
    /// largest y; column 0 the left).
    #[arg(long, value_parser = parse_xy, allow_hyphen_values = true)]
    origin: Option<(f64, f64)>,
    /// Terrain heights of the mask's cells (CSV, metres, the mask's shape); without it every
    /// rock sits at height 0.
    #[arg(long)]
    heights: Option<PathBuf>,
    /// Session id to record.
    #[arg(long, default_value = "grid")]
    session: String,
    /// Print a JSON summary.
    #[arg(long)]
    json: bool,
}

fn parse_xy(text: &str) -> std::result::Result<(f64, f64), String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let number = |s: &str| s.parse::<f64>().ok().filter(|v| v.is_finite());
    match parts.as_slice() {
        [x, y] => match (number(x), number(y)) {
            (Some(x), Some(y)) => Ok((x, y)),
            _ => Err(format!("expected two finite numbers X,Y, got '{text}'")),
        },
        _ => Err(format!("expected X,Y (two numbers), got '{text}'")),
    }
}

/// What a rock grid or raster was, for the summary.
struct GridSummary {
    rock_cells: usize,
    cell_size_m: f64,
    shape: (usize, usize),
    /// Whether the rocks' heights came from a height layer (else all 0).
    heights: bool,
}

fn from_grid(a: &FromGridArgs) -> Result<i32> {
    let config = GridRocksConfig {
        min_cells: a.min_cells,
        ..GridRocksConfig::default()
    };
    let (mut map, summary) = match (a.cell_size, a.origin) {
        (None, None) => lac_grid_map(a, &config)?,
        (Some(cell_size_m), Some(origin)) => raster_map(a, cell_size_m, origin, &config)?,
        _ => anyhow::bail!(
            "{}: a rock mask needs both --cell-size and --origin (a LAC grid CSV neither)",
            a.grid.display()
        ),
    };
    map.notes
        .insert("grid".into(), a.grid.display().to_string());
    write_map(&map, &a.output).with_context(|| "writing the map")?;
    if a.json {
        print_json(&json!({
            "output": a.output, "landmarks": map.len(), "rock_cells": summary.rock_cells,
            "cell_size_m": summary.cell_size_m, "cells": [summary.shape.0, summary.shape.1],
            "cells_per_side": (summary.shape.0 == summary.shape.1).then_some(summary.shape.0),
            "heights": summary.heights, "session": map.session,
        }))?;
    } else {
        println!(
            "{} rocks from {} rock cells of {} m in {} -> {}",
            map.len(),
            summary.rock_cells,
            summary.cell_size_m,
            a.grid.display(),
            a.output.display()
        );
    }
    Ok(0)
}

fn lac_grid_map(a: &FromGridArgs, config: &GridRocksConfig) -> Result<(ObjectMap, GridSummary)> {
    if a.coarsen == 0 {
        anyhow::bail!("--coarsen must be at least 1");
    }
    if a.heights.is_some() {
        anyhow::bail!("--heights is for a rock mask; a LAC grid CSV has its own heights");
    }
    let mut grid = read_grid_csv(&a.grid)?;
    if a.coarsen > 1 {
        grid = coarsened(&grid, a.coarsen);
    }
    let map = map_from_grid(&grid, config, &a.session)
        .map_err(|e| e.in_file(&a.grid))
        .with_context(|| format!("building rocks from {}", a.grid.display()))?;
    let summary = GridSummary {
        rock_cells: grid.rock_count(),
        cell_size_m: grid.cell_size_m,
        shape: (grid.cells_per_side, grid.cells_per_side),
        heights: true,
    };
    Ok((map, summary))
}

fn raster_map(
    a: &FromGridArgs,
    cell_size_m: f64,
    origin: (f64, f64),
    config: &GridRocksConfig,
) -> Result<(ObjectMap, GridSummary)> {
    if a.coarsen != 1 {
        anyhow::bail!("--coarsen is for LAC grids; give a rock mask at the cell size wanted");
    }
    let mut raster = read_rock_mask(&a.grid, cell_size_m, origin)?;
    match &a.heights {
        Some(path) => read_heights_into(&mut raster, path)?,
        None => eprintln!(
            "warning: {}: no --heights: every rock is placed at height 0",
            a.grid.display()
        ),
    }
    let map = map_from_raster(&raster, config, &a.session)
        .map_err(|e| e.in_file(&a.grid))
        .with_context(|| format!("building rocks from {}", a.grid.display()))?;
    let summary = GridSummary {
        rock_cells: raster.rock_count(),
        cell_size_m,
        shape: (raster.rows, raster.columns),
        heights: raster.has_heights(),
    };
    Ok((map, summary))
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
