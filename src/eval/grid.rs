//! Global localization against the rock grid: every LunarLoc traverse (and every 60 s
//! submap of one) relocalized against the LAC ground-truth grid's rocks, with no prior
//! session.
//!
//! The prior map is [`map_from_grid`] of the ground-truth grid, coarsened by OR-ing cells
//! for the larger cell sizes ([`coarsened`]). Each query — a whole traverse, or the
//! detections of one 60 s window of it — is moved by a random rigid transform (any yaw,
//! ±20 m, ±1 m in z; [`random_transform`]), fused into landmarks and relocalized; the
//! traverses are in the grid's world frame, so the truth is the applied transform. With
//! negatives, each whole traverse is mirrored in x first: no answer is right.

use super::lunarloc::{random_transform, FALSE_ACCEPT_DEG, FALSE_ACCEPT_M};
use super::stream::median;
use super::{mirrored_x, transform_error, traverse_path};
use crate::align::Dof;
use crate::landmarks::from_grid::coarsened;
use crate::landmarks::{fuse_detections, map_from_grid, GridRocksConfig};
use crate::relocalize::{RelocalizeConfig, Relocalizer, Timings};
use nalgebra::Isometry3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use segloc_maps::{read_grid_csv, read_lunarloc_traverse, DetectionSet, MapError, Traverse};
use serde::Serialize;
use std::path::Path;

/// The ground-truth grid under a data folder.
pub const GRID_FILE: &str = "lac-groundtruth/moon_map_01_preset_1.csv";

/// Frames per second of the LunarLoc traverses.
const FRAME_RATE_HZ: f64 = 20.0;

/// What to evaluate.
#[derive(Clone, Debug)]
pub struct GridEvalOptions {
    /// Traverse numbers (1..=17).
    pub traverses: Vec<usize>,
    /// Cell size (m) of the prior grid: 0.15 (the ground truth) or a multiple of it.
    pub cell_size_m: f64,
    /// Random transforms per whole traverse.
    pub trials: usize,
    /// Also query every `submap_s` window of each traverse (one transform each).
    pub submaps: bool,
    /// Length (s) of a submap.
    pub submap_s: f64,
    /// Also query every whole traverse mirrored in x (`trials` transforms each).
    pub negatives: bool,
    /// Seed of the transforms.
    pub seed: u64,
    /// Synthetic rocks added to the prior (a larger site's density, for timing): single-cell
    /// rocks at random positions of the grid, at least two cells from any other rock.
    pub extra_rocks: usize,
    /// Grid cells → rock landmarks.
    pub grid_rocks: GridRocksConfig,
}

/// What kind of query a trial ran.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum QueryKind {
    /// A whole traverse.
    Traverse,
    /// One window of a traverse.
    Submap,
    /// A whole traverse mirrored in x (no answer is right).
    Negative,
}

/// One query's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct GridTrial {
    /// Traverse number.
    pub traverse: usize,
    /// What was queried.
    pub kind: QueryKind,
    /// Submaps: start of the window (s from the traverse's first frame).
    pub start_s: f64,
    /// Whether a transform was accepted.
    pub accepted: bool,
    /// Accepted within 5 cm and 0.3°.
    pub within_5cm: bool,
    /// Accepted within 15 cm and 1°.
    pub within_15cm: bool,
    /// Accepted but wrong: off by more than max(10 cm, a third of a cell) or 1°, or any
    /// acceptance of a negative. Whole traverses are judged by the translation error,
    /// submaps by the rover error (where the rover is placed).
    pub wrong: bool,
    /// Translation error (m), when accepted: the displacement of the world origin (the
    /// lander, up to ~15 m from the rover), as in `eval lunarloc`.
    pub translation_error_m: Option<f64>,
    /// Rover error (m), when accepted: the largest displacement of the query's own rover
    /// positions (a submap's window).
    pub rover_error_m: Option<f64>,
    /// Rotation error (degrees), when accepted.
    pub rotation_error_deg: Option<f64>,
    /// The rotation error's tilt (degrees): the angle by which it turns the vertical, the
    /// part a gravity-aligned prior could have pinned (the rest is yaw).
    pub tilt_error_deg: Option<f64>,
    /// The rotation error's yaw (degrees, signed, about the prior's vertical): a bias shared
    /// by every traverse shows here as one sign.
    pub yaw_error_deg: Option<f64>,
    /// RMS residual (m) of the best hypothesis' inliers.
    pub rmse_m: f64,
    /// Inliers of the best hypothesis.
    pub inliers: usize,
    /// The best hypothesis' yaw standard deviation (degrees) from its inliers' covariances,
    /// as the yaw gate reads it (grid priors).
    pub yaw_sigma_deg: Option<f64>,
    /// Refusal reason (or input error), when not accepted.
    pub refusal: Option<String>,
    /// Landmarks of the query map.
    pub query_landmarks: usize,
    /// Candidate associations.
    pub associations: usize,
    /// Largest pair tolerance used (m).
    pub epsilon_max_m: f64,
    /// Relocalization time (ms), query map given: wall clock.
    pub time_ms: f64,
    /// Relocalization time (ms): the process's CPU time (run with `RAYON_NUM_THREADS=1` for
    /// the one-thread cost, which a busy machine does not inflate as it does wall time).
    pub cpu_ms: f64,
    /// Edges of the consistency graph.
    pub graph_edges: usize,
    /// Wall time (ms) of each stage (see [`Timings`]).
    pub timings: Timings,
}

/// Counts over one kind of query.
#[derive(Clone, Debug, Default, Serialize)]
pub struct KindSummary {
    /// Queries run.
    pub queries: usize,
    /// Accepted.
    pub accepted: usize,
    /// Accepted within 5 cm and 0.3°.
    pub within_5cm: usize,
    /// Accepted within 15 cm and 1°.
    pub within_15cm: usize,
    /// Accepted but wrong.
    pub wrong: usize,
    /// Refused (including queries too small to relocalize).
    pub refused: usize,
    /// Traverses every one of whose queries was placed within 5 cm / 0.3°.
    pub traverses_all_within_5cm: usize,
    /// Traverses every one of whose queries was placed within 15 cm / 1°.
    pub traverses_all_within_15cm: usize,
    /// Median relocalization CPU time (ms; see [`GridTrial::cpu_ms`]).
    pub cpu_ms_median: f64,
    /// Median and largest relocalization time (ms).
    pub time_ms_median: f64,
    /// See `time_ms_median`.
    pub time_ms_max: f64,
    /// Largest translation error (m) of an accepted, not wrong answer.
    pub max_error_m: f64,
    /// Largest rotation error (degrees) of an accepted, not wrong answer.
    pub max_error_deg: f64,
}

/// The evaluation's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct GridReport {
    /// Cell size (m) of the prior grid.
    pub cell_size_m: f64,
    /// Rock landmarks in the prior map.
    pub prior_landmarks: usize,
    /// Random transforms per whole traverse.
    pub trials: usize,
    /// Seed of the transforms.
    pub seed: u64,
    /// Whole traverses.
    pub traverses: KindSummary,
    /// Submaps.
    pub submaps: KindSummary,
    /// Mirrored traverses.
    pub negatives: KindSummary,
    /// Every query.
    pub queries: Vec<GridTrial>,
    /// The configuration used.
    pub config: RelocalizeConfig,
}

/// The prior map of the grid evaluation at `cell_size_m` (a multiple of the ground truth's
/// 0.15 m), from the grid under `data`, its rocks made by `rocks`.
pub fn grid_prior(
    data: &Path,
    cell_size_m: f64,
    rocks: &GridRocksConfig,
    extra_rocks: usize,
    seed: u64,
) -> Result<segloc_maps::ObjectMap, MapError> {
    let path = data.join(GRID_FILE);
    let truth = read_grid_csv(&path)?;
    let factor = (cell_size_m / truth.cell_size_m).round();
    if !(factor >= 1.0 && (factor * truth.cell_size_m - cell_size_m).abs() < 1e-6) {
        return Err(MapError::InvalidData {
            what: "evaluation",
            message: format!(
                "cell size {cell_size_m} m is not a multiple of the grid's {} m",
                truth.cell_size_m
            ),
        });
    }
    let grid = coarsened(&truth, factor as usize);
    let mut map = map_from_grid(&grid, rocks, "grid").map_err(|e| e.in_file(&path))?;
    add_synthetic_rocks(
        &mut map,
        extra_rocks,
        grid.half_extent_m(),
        grid.cell_size_m,
        seed,
    );
    Ok(map)
}

/// Add `count` single-cell rocks at random places within `half_extent_m` of the origin, at
/// least two cells from every rock, at the height of the nearest rock (the terrain's, so
/// that the height test prunes them no more than real rocks); each copies the first rock's
/// covariance.
fn add_synthetic_rocks(
    map: &mut segloc_maps::ObjectMap,
    count: usize,
    half_extent_m: f64,
    cell_m: f64,
    seed: u64,
) {
    use rand::Rng;
    let Some(template) = map.landmarks.first().cloned() else {
        return;
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0005_10c5);
    let mut placed = 0;
    while placed < count {
        let x = rng.random_range(-half_extent_m..half_extent_m);
        let y = rng.random_range(-half_extent_m..half_extent_m);
        let nearest = map.landmarks.iter().min_by(|a, b| {
            let d =
                |l: &segloc_maps::Landmark| (l.position.x - x).powi(2) + (l.position.y - y).powi(2);
            d(a).total_cmp(&d(b))
        });
        let Some(nearest) = nearest else {
            return;
        };
        let (dx, dy) = (nearest.position.x - x, nearest.position.y - y);
        if dx * dx + dy * dy < (2.0 * cell_m).powi(2) {
            continue;
        }
        let z = nearest.position.z;
        let mut rock = template.clone();
        rock.id = map.next_id();
        rock.position = nalgebra::Point3::new(x, y, z);
        rock.size_m = Some(cell_m);
        map.landmarks.push(rock);
        placed += 1;
    }
}

/// Run the evaluation on the data under `data` (holding `lunarloc/` and `lac-groundtruth/`).
pub fn evaluate_grid(
    data: &Path,
    options: &GridEvalOptions,
    config: &RelocalizeConfig,
    mut progress: impl FnMut(usize, usize),
) -> Result<GridReport, MapError> {
    let prior = grid_prior(
        data,
        options.cell_size_m,
        &options.grid_rocks,
        options.extra_rocks,
        options.seed,
    )?;
    let prior_landmarks = prior.len();
    let mut config = config.clone();
    config.dof = Some(Dof::Auto);
    let relocalizer =
        Relocalizer::new(prior, config.clone()).map_err(|e| MapError::InvalidData {
            what: "map",
            message: format!("grid prior: {e}"),
        })?;
    let mut queries = Vec::new();
    for (k, &n) in options.traverses.iter().enumerate() {
        progress(k, options.traverses.len());
        let traverse = read_lunarloc_traverse(&traverse_path(data, n))?;
        let mut rng = ChaCha8Rng::seed_from_u64(options.seed ^ ((n as u64) << 32));
        let world = traverse.detections();
        let mut run = |detections: &DetectionSet, kind: QueryKind, start_s: f64| {
            let truth = random_transform(&mut rng, Dof::Auto);
            let mut trial = run_query(&relocalizer, detections, &truth, &config);
            trial.judge(kind, options.cell_size_m);
            trial.traverse = n;
            trial.kind = kind;
            trial.start_s = start_s;
            queries.push(trial);
        };
        for _ in 0..options.trials {
            run(&world, QueryKind::Traverse, 0.0);
        }
        if options.submaps {
            for (start_s, window) in submaps(&traverse, options.submap_s) {
                run(&window.detections(), QueryKind::Submap, start_s);
            }
        }
        if options.negatives {
            let mirrored = mirrored_x(&world);
            for _ in 0..options.trials {
                run(&mirrored, QueryKind::Negative, 0.0);
            }
        }
    }
    progress(options.traverses.len(), options.traverses.len());
    let summary = |kind| summarize(&queries, kind);
    Ok(GridReport {
        cell_size_m: options.cell_size_m,
        prior_landmarks,
        trials: options.trials,
        seed: options.seed,
        traverses: summary(QueryKind::Traverse),
        submaps: summary(QueryKind::Submap),
        negatives: summary(QueryKind::Negative),
        queries,
        config,
    })
}

/// The windows of `traverse` of `length_s` seconds each (the last may be shorter), with
/// their start times (s).
pub fn submaps(traverse: &Traverse, length_s: f64) -> Vec<(f64, Traverse)> {
    let Some(first) = traverse.frames.first().map(|f| f.frame) else {
        return Vec::new();
    };
    let frames_per_window = (length_s * FRAME_RATE_HZ).round().max(1.0) as u64;
    let mut out: Vec<(f64, Traverse)> = Vec::new();
    for frame in &traverse.frames {
        let window = (frame.frame.saturating_sub(first)) / frames_per_window;
        let start_s = (window * frames_per_window) as f64 / FRAME_RATE_HZ;
        if out.last().is_none_or(|(s, _)| *s != start_s) {
            out.push((
                start_s,
                Traverse {
                    name: format!("{}@{start_s}s", traverse.name),
                    frames: Vec::new(),
                },
            ));
        }
        if let Some((_, t)) = out.last_mut() {
            t.frames.push(frame.clone());
        }
    }
    out
}

impl GridTrial {
    /// Decide placed / wrong from the errors (see the fields).
    fn judge(&mut self, kind: QueryKind, cell_size_m: f64) {
        let (Some(origin), Some(rover), Some(r)) = (
            self.translation_error_m,
            self.rover_error_m,
            self.rotation_error_deg,
        ) else {
            return;
        };
        let t = if kind == QueryKind::Submap {
            rover
        } else {
            origin
        };
        self.within_5cm = kind != QueryKind::Negative && t <= 0.05 && r <= 0.3;
        self.within_15cm = kind != QueryKind::Negative && t <= 0.15 && r <= FALSE_ACCEPT_DEG;
        self.wrong = kind == QueryKind::Negative
            || t > FALSE_ACCEPT_M.max(cell_size_m / 3.0)
            || r > FALSE_ACCEPT_DEG;
    }
}

/// Move `world` by `truth⁻¹`, fuse, relocalize, compare.
fn run_query(
    relocalizer: &Relocalizer,
    world: &DetectionSet,
    truth: &Isometry3<f64>,
    config: &RelocalizeConfig,
) -> GridTrial {
    let mut detections = world.transformed(&truth.inverse(), "query");
    detections.gravity_aligned = true;
    let query_map = fuse_detections(&detections, &config.landmarks);
    let started = std::time::Instant::now();
    let cpu_started = process_cpu_ms();
    let outcome = relocalizer.relocalize(&query_map);
    let cpu_ms = process_cpu_ms() - cpu_started;
    let time_ms = started.elapsed().as_secs_f64() * 1e3;
    let mut trial = GridTrial {
        traverse: 0,
        kind: QueryKind::Traverse,
        start_s: 0.0,
        accepted: false,
        within_5cm: false,
        within_15cm: false,
        wrong: false,
        translation_error_m: None,
        rover_error_m: None,
        rotation_error_deg: None,
        tilt_error_deg: None,
        yaw_error_deg: None,
        rmse_m: f64::NAN,
        inliers: 0,
        yaw_sigma_deg: None,
        refusal: None,
        query_landmarks: query_map.len(),
        associations: 0,
        epsilon_max_m: 0.0,
        time_ms,
        cpu_ms,
        graph_edges: 0,
        timings: Timings::default(),
    };
    let answer = match outcome {
        Ok(answer) => answer,
        Err(e) => {
            trial.refusal = Some(e.to_string());
            return trial;
        }
    };
    trial.accepted = answer.is_accepted();
    trial.rmse_m = answer.rmse_m;
    trial.associations = answer.diagnostics.associations;
    trial.graph_edges = answer.diagnostics.graph_edges;
    trial.timings = answer.diagnostics.timings.clone();
    trial.epsilon_max_m = answer.diagnostics.tolerances.epsilon_max_m;
    trial.inliers = answer
        .diagnostics
        .hypotheses
        .first()
        .map_or(0, |h| h.inlier_count);
    trial.yaw_sigma_deg = answer
        .diagnostics
        .hypotheses
        .first()
        .and_then(|h| h.yaw_sigma_deg);
    trial.refusal = answer.refusal().map(|r| r.to_string());
    if let Some(estimate) = answer.prior_from_query().filter(|_| trial.accepted) {
        let (t, r) = transform_error(&estimate, truth);
        trial.translation_error_m = Some(t);
        trial.rotation_error_deg = Some(r);
        let error = estimate * truth.inverse();
        let up = nalgebra::Vector3::z();
        trial.tilt_error_deg = Some((error.rotation * up).angle(&up).to_degrees());
        trial.yaw_error_deg = Some(error.rotation.euler_angles().2.to_degrees());
        trial.rover_error_m = Some(
            world
                .detections
                .iter()
                .filter_map(|d| d.rover_position)
                .map(|p| (error * p - p).norm())
                .fold(0.0, f64::max),
        );
    }
    trial
}

/// CPU time (ms) this process has used, all threads.
pub fn process_cpu_ms() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    let ok = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) } == 0;
    if ok {
        t.tv_sec as f64 * 1e3 + t.tv_nsec as f64 * 1e-6
    } else {
        f64::NAN
    }
}

fn summarize(queries: &[GridTrial], kind: QueryKind) -> KindSummary {
    let of_kind: Vec<&GridTrial> = queries.iter().filter(|q| q.kind == kind).collect();
    let mut traverses: Vec<usize> = of_kind.iter().map(|q| q.traverse).collect();
    traverses.dedup();
    let all_of = |n: usize, test: fn(&GridTrial) -> bool| {
        of_kind.iter().filter(|q| q.traverse == n).all(|q| test(q))
    };
    let times: Vec<f64> = of_kind.iter().map(|q| q.time_ms).collect();
    let cpu: Vec<f64> = of_kind.iter().map(|q| q.cpu_ms).collect();
    let good = || of_kind.iter().filter(|q| q.accepted && !q.wrong);
    KindSummary {
        queries: of_kind.len(),
        accepted: of_kind.iter().filter(|q| q.accepted).count(),
        within_5cm: of_kind.iter().filter(|q| q.within_5cm).count(),
        within_15cm: of_kind.iter().filter(|q| q.within_15cm).count(),
        wrong: of_kind.iter().filter(|q| q.wrong).count(),
        refused: of_kind.iter().filter(|q| !q.accepted).count(),
        traverses_all_within_5cm: traverses
            .iter()
            .filter(|&&n| all_of(n, |q| q.within_5cm))
            .count(),
        traverses_all_within_15cm: traverses
            .iter()
            .filter(|&&n| all_of(n, |q| q.within_15cm))
            .count(),
        cpu_ms_median: if cpu.is_empty() { 0.0 } else { median(&cpu) },
        time_ms_median: if times.is_empty() {
            0.0
        } else {
            median(&times)
        },
        time_ms_max: times.iter().copied().fold(0.0, f64::max),
        max_error_m: good()
            .filter_map(|q| q.translation_error_m)
            .fold(0.0, f64::max),
        max_error_deg: good()
            .filter_map(|q| q.rotation_error_deg)
            .fold(0.0, f64::max),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;
    use segloc_maps::TraverseFrame;

    #[test]
    fn submaps_cut_the_traverse_into_windows() {
        let frames = (0..50)
            .map(|k| TraverseFrame {
                frame: 100 + 20 * k,
                rover_position: Point3::origin(),
                boulders: vec![],
            })
            .collect();
        let t = Traverse {
            name: "t".into(),
            frames,
        };
        // 50 frames a second apart: windows of 20 s hold 20, 20 and 10 frames
        let windows = submaps(&t, 20.0);
        let sizes: Vec<usize> = windows.iter().map(|(_, w)| w.frames.len()).collect();
        assert_eq!(sizes, vec![20, 20, 10]);
        assert_eq!(windows[2].0, 40.0);
    }
}
