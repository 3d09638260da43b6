//! Where the mission's LAC points are lost: the same two sessions' maps scored with the
//! optimised poses (as the mission does) and with the *true* poses, split into observed and
//! interpolated cells, and the rock map with one session on its true poses.
//!
//! `cargo run --release --example mission_diagnose -- SEED [--coverage | --config FILE]`
//! prints one JSON line (`FILE`: a mission configuration as `segloc config print --mission`
//! writes it).
//! On stderr, when set: `NAV=1` where each session's time went (seconds per navigator mode,
//! a trace every second of a mode change), `COLLISIONS=1` the 20 s before every collision,
//! `ROCKS_NEAR=x,y,r` the true rocks within r of (x, y), `DUMP_Z=1` every frame's pose error.
#![warn(clippy::too_many_lines)]

use nalgebra::Isometry3;
use segloc::mapping::{score, HeightMapBuilder};
use segloc::mission::lost_session::LocalizedSession;
use segloc::mission::mapping_session::MappedSession;
use segloc::mission::{lost_session, mapping_session, maps, MissionConfig, Silent};
use segloc::sim::moon::Moon;
use segloc::sim::session::SessionLog;
use segloc_maps::LacGrid;

fn true_poses(log: &SessionLog) -> Vec<Isometry3<f64>> {
    log.frames
        .iter()
        .map(|f| {
            log.ticks
                .get(f.tick)
                .map_or_else(Isometry3::identity, |t| t.world_from_rover)
        })
        .collect()
}

/// Cells observed, and within 5 cm among observed / interpolated cells.
fn height_split(sessions: &[(&SessionLog, &[Isometry3<f64>])], truth: &LacGrid) -> [usize; 4] {
    let mut b = HeightMapBuilder::new(truth.clone());
    let mut seen = vec![false; truth.num_cells()];
    for (log, poses) in sessions {
        for (f, pose) in log.frames.iter().zip(poses.iter()) {
            for g in &f.ground {
                let p = pose * g.p_rover;
                b.add_point(&p);
                if let Some((i, j)) = truth.cell_of(p.x, p.y) {
                    seen[truth.index(i, j)] = true;
                }
            }
        }
    }
    let grid = b.build();
    let (mut obs, mut obs_ok, mut int_ok) = (0, 0, 0);
    for (k, seen) in seen.iter().enumerate() {
        let ok = (grid.height[k] - truth.height[k]).abs() < 0.05;
        if *seen {
            obs += 1;
            obs_ok += ok as usize;
        } else {
            int_ok += ok as usize;
        }
    }
    [obs, obs_ok, truth.num_cells() - obs, int_ok]
}

/// RMS of the horizontal and vertical position error, metres.
fn rmse_xy_z(log: &SessionLog, poses: &[Isometry3<f64>]) -> [f64; 2] {
    let truth = true_poses(log);
    let (mut xy, mut z) = (0.0, 0.0);
    for (t, e) in truth.iter().zip(poses) {
        let d = e.translation.vector - t.translation.vector;
        xy += d.x * d.x + d.y * d.y;
        z += d.z * d.z;
    }
    let n = truth.len().max(1) as f64;
    [(xy / n).sqrt(), (z / n).sqrt()]
}

/// RMS tilt error (angle between the true and estimated up axes), degrees.
fn tilt_deg(log: &SessionLog, poses: &[Isometry3<f64>]) -> f64 {
    let truth = true_poses(log);
    let up = nalgebra::Vector3::z();
    let s: f64 = truth
        .iter()
        .zip(poses)
        .map(|(t, e)| {
            (t.rotation * up)
                .angle(&(e.rotation * up))
                .to_degrees()
                .powi(2)
        })
        .sum();
    (s / truth.len().max(1) as f64).sqrt()
}

type Poses<'a> = (&'a SessionLog, &'a [Isometry3<f64>]);

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seed: u64 = args.get(1).map_or(Ok(1), |s| s.parse())?;
    let config = read_config(&args)?;
    let moon = Moon::generate(&config.moon, seed)?;
    let Sessions {
        config,
        s1,
        s2,
        rmse_graph,
    } = run_sessions(&moon, config, seed)?;
    if std::env::var("DUMP_Z").is_ok() {
        dump_z(&[(&s1.log, &s1.poses), (&s2.log, &s2.poses)]);
    }
    if std::env::var("NAV").is_ok() {
        print_navigation(&[&s1.log, &s2.log]);
    }
    if let Ok(at) = std::env::var("ROCKS_NEAR") {
        print_rocks_near(&moon, &at);
    }
    if std::env::var("COLLISIONS").is_ok() {
        for (n, log) in [(1, &s1.log), (2, &s2.log)] {
            print_collisions(&moon, n, log, &s1);
        }
    }
    let mut out = score_maps(&moon, &config, [(&s1.log, &s1.poses), (&s2.log, &s2.poses)])?;
    out["seed"] = seed.into();
    out["view_bias_size_fraction"] = config.localizer.fusion.view_bias_size_fraction.into();
    out["rmse"] = serde_json::json!([
        segloc::mission::stream::rmse_m(&s1.log, &s1.poses),
        segloc::mission::stream::rmse_m(&s2.log, &s2.poses)
    ]);
    out["rmse_xy_z_graph"] = serde_json::json!(rmse_graph);
    out["tilt_deg"] =
        serde_json::json!([tilt_deg(&s1.log, &s1.poses), tilt_deg(&s2.log, &s2.poses)]);
    out["rmse_xy_z"] =
        serde_json::json!([rmse_xy_z(&s1.log, &s1.poses), rmse_xy_z(&s2.log, &s2.poses)]);
    out["dist"] = serde_json::json!([s1.log.distance_m(), s2.log.distance_m()]);
    out["collisions"] =
        serde_json::json!([s1.log.summary().collisions, s2.log.summary().collisions]);
    println!("{out}");
    Ok(())
}

/// The mission configuration: `--config FILE`, `--coverage` or the default.
fn read_config(args: &[String]) -> Result<MissionConfig, Box<dyn std::error::Error>> {
    let config_file = args
        .iter()
        .position(|a| a == "--config")
        .map(|k| args.get(k + 1));
    Ok(match config_file {
        Some(Some(path)) => toml::from_str(&std::fs::read_to_string(path)?)?,
        Some(None) => return Err("--config needs a file".into()),
        None if args.iter().any(|a| a == "--coverage") => MissionConfig::lac_coverage(),
        None => MissionConfig::default(),
    })
}

/// The mission's two sessions, as the mission runs them.
struct Sessions {
    /// The configuration calibrated by session 1.
    config: MissionConfig,
    /// The mapping session, terrain-height correction applied.
    s1: MappedSession,
    /// The lost session, terrain-height correction applied.
    s2: LocalizedSession,
    /// Horizontal and vertical RMS errors of each session's graph poses before the
    /// correction, metres.
    rmse_graph: [[f64; 2]; 2],
}

fn run_sessions(
    moon: &Moon,
    config: MissionConfig,
    seed: u64,
) -> Result<Sessions, Box<dyn std::error::Error>> {
    let min_rock = config.session.collision_min_rock_radius_m;
    let clear = |s: [f64; 3]| {
        let (x, y) = moon.nearest_clear_position(s[0], s[1], 1.0, min_rock);
        [x, y, s[2]]
    };
    let (start_1, start_2) = (clear(config.start_1), clear(config.start_2));
    let e = config.guess_error_2;
    let guess_2 = [start_2[0] + e[0], start_2[1] + e[1], start_2[2] + e[2]];
    let s1 = mapping_session::map_session(moon, &config, start_1, seed * 2, &Silent)?;
    let config = s1.calibrated(&config);
    let s2 = lost_session::localize_session(
        moon,
        &config,
        &s1.map,
        (start_2, guess_2),
        seed * 2 + 1,
        &Silent,
    )?;
    let (mut s1, mut s2) = (s1, s2);
    let rmse_graph = [rmse_xy_z(&s1.log, &s1.poses), rmse_xy_z(&s2.log, &s2.poses)];
    let dz = segloc::mission::terrain_height::height_corrections(
        &[(&s1.log, &s1.poses), (&s2.log, &s2.poses)],
        &config.terrain_height,
    );
    s1.poses = segloc::mission::terrain_height::apply(&s1.poses, &dz[0]);
    s2.poses = segloc::mission::terrain_height::apply(&s2.poses, &dz[1]);
    Ok(Sessions {
        config,
        s1,
        s2,
        rmse_graph,
    })
}

/// `DUMP_Z`: every frame's pose error (z, x, y) and true position.
fn dump_z(sessions: &[Poses<'_>]) {
    for (log, poses) in sessions {
        let t = true_poses(log);
        for (k, (a, b)) in t.iter().zip(poses.iter()).enumerate() {
            eprintln!(
                "{k} {:.4} {:.4} {:.4} {:.2} {:.2}",
                b.translation.z - a.translation.z,
                b.translation.x - a.translation.x,
                b.translation.y - a.translation.y,
                a.translation.x,
                a.translation.y
            );
        }
    }
}

/// `NAV`: where each session's time went (seconds per navigator mode) and a trace every
/// second of a mode change.
fn print_navigation(logs: &[&SessionLog]) {
    for (n, log) in (1..).zip(logs) {
        eprintln!(
            "session {n} (reached, skipped, backups) {:?}",
            log.navigation_counts
        );
        // seconds in each mode, and driving at a reduced speed
        let mut modes = std::collections::BTreeMap::new();
        for t in &log.ticks {
            let slow = t.command.speed_mps > 0.0 && t.command.speed_mps < 0.4;
            *modes
                .entry(format!("{:?}{}", t.mode, if slow { " slow" } else { "" }))
                .or_insert(0.0) += 0.05;
        }
        eprintln!("session {n} seconds by mode {modes:?}");
        let mut last = None;
        for t in log.ticks.iter().step_by(20) {
            if last != Some(t.mode) || t.time_s % 20.0 < 1e-9 {
                let p = t.world_from_rover.translation;
                eprintln!(
                    "  {n} t {:.0} {:?} at ({:.1}, {:.1}) cmd {:.2} {:.2}",
                    t.time_s, t.mode, p.x, p.y, t.command.speed_mps, t.command.yaw_rate_rps
                );
                last = Some(t.mode);
            }
        }
    }
}

/// `ROCKS_NEAR=x,y,r`: the true rocks within r of (x, y).
fn print_rocks_near(moon: &Moon, at: &str) {
    let v: Vec<f64> = at.split(',').filter_map(|x| x.parse().ok()).collect();
    if let [x, y, r] = v[..] {
        for (i, rock) in moon.rocks().iter().enumerate() {
            let d = (rock.center.x - x).hypot(rock.center.y - y);
            if d < r {
                eprintln!(
                    "rock {i} at ({:.2}, {:.2}) r {:.3} dist {:.2}",
                    rock.center.x, rock.center.y, rock.radius_m, d
                );
            }
        }
    }
}

/// `COLLISIONS`: each collision of session `n` with a rock (once per rock in a row), with
/// the rock's detections and the 20 s before the hit.
fn print_collisions(moon: &Moon, n: usize, log: &SessionLog, s1: &MappedSession) {
    let mut last = None;
    for t in log.collision_ticks() {
        let Some(segloc::sim::session::Obstruction::Rock(i)) = t.collision else {
            eprintln!("session {n} t {:.1} lander", t.time_s);
            continue;
        };
        if last == Some(i) {
            continue;
        }
        last = Some(i);
        let rock = &moon.rocks()[i];
        let ground = moon.height_at(rock.center.x, rock.center.y);
        let seen: Vec<String> = log
            .frames
            .iter()
            .filter(|f| f.time_s <= t.time_s)
            .flat_map(|f| f.boulders.iter().map(move |b| (f, b)))
            .filter(|(_, b)| b.rock == Some(i))
            .map(|(f, b)| {
                format!(
                    "{:.0}s r{:.3} d{:.1}",
                    f.time_s,
                    b.radius_m,
                    b.p_rover.coords.norm()
                )
            })
            .collect();
        let s1_seen = s1
            .log
            .frames
            .iter()
            .flat_map(|f| f.boulders.iter())
            .filter(|b| b.rock == Some(i))
            .count();
        let in_map = s1
            .map
            .landmarks
            .iter()
            .filter(|l| (l.position.x - rock.center.x).hypot(l.position.y - rock.center.y) < 0.2)
            .map(|l| format!("obs {} size {:?}", l.observations, l.size_m))
            .collect::<Vec<_>>();
        eprintln!("  session 1 detections of it: {s1_seen}, in its map: {in_map:?}");
        eprintln!(
            "session {n} t {:.1} rock {i} r {:.3} top above ground {:.3} mode {:?} seen {:?}",
            t.time_s,
            rock.radius_m,
            rock.center.z + rock.radius_m - ground,
            t.mode,
            seen
        );
        print_approach(moon, log, i, t.time_s);
    }
}

/// The 20 s before the hit of rock `i` at `hit_s`, once a second: where the rock was
/// relative to the rover (true poses), whether a camera saw it and what the rover did.
fn print_approach(moon: &Moon, log: &SessionLog, i: usize, hit_s: f64) {
    let rock = &moon.rocks()[i];
    for f in log
        .frames
        .iter()
        .filter(|f| f.time_s <= hit_s && f.time_s >= hit_s - 20.0)
    {
        let tick = &log.ticks[f.tick];
        let q = tick.world_from_rover.inverse() * rock.center;
        let det: Vec<String> = f
            .boulders
            .iter()
            .filter(|b| b.rock == Some(i))
            .map(|b| format!("{:?} r{:.3}", b.camera, b.radius_m))
            .collect();
        // the front camera's line of sight to the rock's upper face
        let cam = tick.world_from_rover * segloc::sim::sensors::cameras()[0].rover_from_camera;
        let origin = nalgebra::Point3::from(cam.translation.vector);
        let target = rock.center + nalgebra::Vector3::new(0.0, 0.0, 0.5 * rock.radius_m);
        let to = target - origin;
        let ray = moon
            .cast_ray(&origin, &(to / to.norm()), to.norm() + rock.radius_m, None)
            .map(|h| format!("{:?} at {:.2} of {:.2}", h.target, h.distance_m, to.norm()));
        let uv = segloc::sim::sensors::project(&(cam.inverse() * rock.center).coords)
            .map(|(u, v)| format!("u {u:.0} v {v:.0}"));
        eprintln!("      front ray {ray:?} centre px {uv:?}");
        eprintln!(
            "    t {:.0} rock at range {:.2} bearing {:.0} deg, mode {:?} cmd {:.2} {:.2} detected {:?}",
            f.time_s,
            q.x.hypot(q.y),
            q.y.atan2(q.x).to_degrees(),
            tick.mode,
            tick.command.speed_mps,
            tick.command.yaw_rate_rps,
            det
        );
    }
}

/// The optimised poses with the true heights.
fn with_true_z(log: &SessionLog, poses: &[Isometry3<f64>]) -> Vec<Isometry3<f64>> {
    true_poses(log)
        .iter()
        .zip(poses)
        .map(|(t, e)| {
            let mut p = *e;
            p.translation.vector.z = t.translation.vector.z;
            p
        })
        .collect()
}

/// The LAC maps scored with the estimated poses, with the true ones, with one session on
/// its true poses, with the true heights, and the coverage ceiling.
fn score_maps(
    moon: &Moon,
    config: &MissionConfig,
    est: [Poses<'_>; 2],
) -> Result<serde_json::Value, Box<dyn std::error::Error>> {
    let truth = moon.ground_truth_grid();
    let [(l1, p1), (l2, p2)] = est;
    let (t1, t2) = (true_poses(l1), true_poses(l2));
    let tru: [Poses<'_>; 2] = [(l1, &t1), (l2, &t2)];
    let secs: f64 = config.session_seconds().iter().sum();
    let m_est = maps::build_maps(&est, &truth, secs, config)?;
    let m_tru = maps::build_maps(&tru, &truth, secs, config)?;
    // one session on its true poses, the other on its estimate: whose error costs the points
    let m_s1_true = maps::build_maps(&[(l1, &t1), (l2, p2)], &truth, secs, config)?;
    let m_s2_true = maps::build_maps(&[(l1, p1), (l2, &t2)], &truth, secs, config)?;
    // the optimised poses with the true height: how much of the loss is z
    let (z1, z2) = (with_true_z(l1, p1), with_true_z(l2, p2));
    let m_z = maps::build_maps(&[(l1, &z1), (l2, &z2)], &truth, secs, config)?;
    let h_est = height_split(&est, &truth);
    let h_tru = height_split(&tru, &truth);
    let ceiling = coverage_ceiling(&tru, &truth)?;
    Ok(serde_json::json!({
        "geometric": [m_est.score.geometric, m_z.score.geometric, m_tru.score.geometric, ceiling],
        "rocks": [m_est.score.rocks, m_tru.score.rocks],
        "rocks_s1_true_s2_true": [m_s1_true.score.rocks, m_s2_true.score.rocks],
        "rock_pr_est": [m_est.score.rock_precision, m_est.score.rock_recall],
        "rock_pr_true": [m_tru.score.rock_precision, m_tru.score.rock_recall],
        "cells_observed_ok_unobserved_ok_est": h_est,
        "cells_observed_ok_unobserved_ok_true": h_tru,
    }))
}

/// Perfect heights on observed cells, interpolation elsewhere: the coverage ceiling of the
/// geometric score.
fn coverage_ceiling(tru: &[Poses<'_>], truth: &LacGrid) -> Result<f64, Box<dyn std::error::Error>> {
    let mut perfect = HeightMapBuilder::new(truth.clone());
    for (log, poses) in tru {
        for (f, pose) in log.frames.iter().zip(poses.iter()) {
            for g in &f.ground {
                let p = pose * g.p_rover;
                if let Some((i, j)) = truth.cell_of(p.x, p.y) {
                    let (x, y) = truth.cell_center(i, j);
                    perfect.add_point(&nalgebra::Point3::new(
                        x,
                        y,
                        truth.height[truth.index(i, j)],
                    ));
                }
            }
        }
    }
    Ok(score(&perfect.build(), truth, None)?.geometric)
}
