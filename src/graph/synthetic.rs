//! Synthetic pose graphs and outlier injection, for tests and benchmarks.
//!
//! [`generate`] drives a rover on a bounded random walk over gently rolling terrain, so it
//! revisits places; odometry and loop closures between nearby poses are the true relative
//! poses perturbed by Gaussian noise. [`corrupt_loop_closures`] replaces a fraction of the
//! loop closures of a file with random relative poses, to test robust kernels.

use super::file::{FileEdge, FileFormat, FileVertex, GraphFile};
use super::se3;
use nalgebra::{Isometry3, Matrix6, Quaternion, Translation3, UnitQuaternion, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// Parameters of a synthetic trajectory and its graph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SyntheticConfig {
    /// Number of poses.
    pub poses: usize,
    /// Number of loop closures between nearby poses.
    pub loop_closures: usize,
    /// Random seed.
    pub seed: u64,
    /// Distance driven between poses.
    pub step_m: f64,
    /// Half-width of the square the rover stays in.
    pub half_width_m: f64,
    /// Standard deviation of the translation noise of every measurement.
    pub translation_sigma_m: f64,
    /// Standard deviation of the rotation noise of every measurement.
    pub rotation_sigma_rad: f64,
}

impl Default for SyntheticConfig {
    fn default() -> Self {
        Self {
            poses: 5000,
            loop_closures: 200,
            seed: 7,
            step_m: 1.0,
            half_width_m: 30.0,
            translation_sigma_m: 0.05,
            rotation_sigma_rad: 0.01,
        }
    }
}

/// A synthetic graph: ground truth and a file whose vertices are the chained odometry.
#[derive(Clone, Debug)]
pub struct SyntheticGraph {
    /// True poses `world_from_rover`, id = index.
    pub truth: Vec<Isometry3<f64>>,
    /// Noisy odometry and loop closures; vertices hold the dead-reckoned estimate.
    pub file: GraphFile,
}

impl SyntheticGraph {
    /// The odometry edges (`i → i + 1`), in order: entry `i` leads from pose `i` to `i + 1`.
    pub fn odometry(&self) -> Vec<&FileEdge> {
        let mut edges: Vec<&FileEdge> = (self.file.edges.iter())
            .filter(|e| e.to == e.from + 1)
            .collect();
        edges.sort_by_key(|e| e.from);
        edges
    }
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller; 1 − u keeps the logarithm finite.
    let u: f64 = 1.0 - rng.random::<f64>();
    let v: f64 = rng.random::<f64>();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn noisy(z: &Isometry3<f64>, rng: &mut ChaCha8Rng, sr: f64, st: f64) -> Isometry3<f64> {
    let xi = Vector6::new(
        sr * gaussian(rng),
        sr * gaussian(rng),
        sr * gaussian(rng),
        st * gaussian(rng),
        st * gaussian(rng),
        st * gaussian(rng),
    );
    z * se3::exp(&xi)
}

/// Generates a synthetic pose graph: a rover's wander over rolling ground, its noisy
/// odometry, loop closures between revisits, and the odometry's chained poses as the
/// initial guess.
pub fn generate(config: &SyntheticConfig) -> SyntheticGraph {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let n = config.poses.max(1);
    let truth = true_trajectory(config, n, &mut rng);
    let information = information(config);
    let (sr, st) = (config.rotation_sigma_rad, config.translation_sigma_m);
    let mut edges = Vec::with_capacity(n + config.loop_closures);
    let mut edge = |i: usize, j: usize, rng: &mut ChaCha8Rng| {
        edges.push(FileEdge {
            from: i as u64,
            to: j as u64,
            measured: noisy(&truth[i].inv_mul(&truth[j]), rng, sr, st),
            information,
            line: 0,
        });
    };
    for i in 1..n {
        edge(i - 1, i, &mut rng);
    }
    let candidates = revisits(&truth);
    let wanted = config.loop_closures.min(candidates.len());
    for k in 0..wanted {
        // Evenly spread over the candidates, with a random jitter inside each stride.
        let stride = candidates.len() as f64 / wanted as f64;
        let pick = ((k as f64 + rng.random::<f64>()) * stride) as usize;
        let (i, j) = candidates[pick.min(candidates.len() - 1)];
        edge(i, j, &mut rng);
    }
    let vertices = chained_odometry(&truth[0], &edges[..n - 1]);
    SyntheticGraph {
        truth,
        file: GraphFile {
            format: FileFormat::G2o,
            vertices,
            edges,
            fixed: vec![0],
            warnings: Vec::new(),
            repaired: Vec::new(),
        },
    }
}

/// The rover's true poses: a random-heading walk over rolling ground, turned back towards
/// the centre when it leaves the square.
fn true_trajectory(
    config: &SyntheticConfig,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Isometry3<f64>> {
    let ground = |x: f64, y: f64| 0.8 * (x / 9.0).sin() * (y / 7.0).cos();
    let mut truth = Vec::with_capacity(n);
    let (mut x, mut y, mut heading) = (0.0f64, 0.0f64, 0.0f64);
    for _ in 0..n {
        let z = ground(x, y);
        let pitch = -((ground(x + 0.5 * heading.cos(), y + 0.5 * heading.sin()) - z) / 0.5).atan();
        truth.push(Isometry3::from_parts(
            Translation3::new(x, y, z),
            se3::rotation_from_rpy(0.0, pitch, heading),
        ));
        heading += 0.25 * gaussian(rng);
        if x.abs() > config.half_width_m || y.abs() > config.half_width_m {
            // Turn back towards the centre.
            let to_centre = (-y).atan2(-x);
            let d = (to_centre - heading + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            heading += 0.5 * d;
        }
        x += config.step_m * heading.cos();
        y += config.step_m * heading.sin();
    }
    truth
}

/// Every edge's information matrix: the configured rotation and translation sigmas.
fn information(config: &SyntheticConfig) -> Matrix6<f64> {
    let mut m = Matrix6::zeros();
    for k in 0..3 {
        m[(k, k)] = 1.0 / config.rotation_sigma_rad.powi(2);
        m[(k + 3, k + 3)] = 1.0 / config.translation_sigma_m.powi(2);
    }
    m
}

/// Loop-closure candidates `(i, j)`: each pose `j` with its nearest earlier pose `i`
/// within 2 m and at least 20 steps back.
fn revisits(truth: &[Isometry3<f64>]) -> Vec<(usize, usize)> {
    let cell = 2.0;
    let key = |p: &Isometry3<f64>| {
        (
            (p.translation.x / cell).floor() as i64,
            (p.translation.y / cell).floor() as i64,
        )
    };
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    let mut candidates = Vec::new();
    for (j, p) in truth.iter().enumerate() {
        let (cx, cy) = key(p);
        let mut best: Option<(f64, usize)> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for &i in grid
                    .get(&(cx + dx, cy + dy))
                    .map(Vec::as_slice)
                    .unwrap_or(&[])
                {
                    let d = (truth[i].translation.vector - p.translation.vector).norm();
                    if i + 20 < j && d < 2.0 && best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, i));
                    }
                }
            }
        }
        if let Some((_, i)) = best {
            candidates.push((i, j));
        }
        grid.entry((cx, cy)).or_default().push(j);
    }
    candidates
}

/// The initial guess: the first true pose, then the odometry edges chained.
fn chained_odometry(first: &Isometry3<f64>, odometry: &[FileEdge]) -> Vec<FileVertex> {
    let mut pose = *first;
    let mut vertices = vec![FileVertex {
        id: 0,
        pose,
        line: 0,
    }];
    for e in odometry {
        pose *= e.measured;
        vertices.push(FileVertex {
            id: e.to,
            pose,
            line: 0,
        });
    }
    vertices
}

/// A uniformly random rotation and a translation uniform in `[-half_width, half_width]³`.
pub fn random_pose(rng: &mut impl Rng, half_width_m: f64) -> Isometry3<f64> {
    let q = loop {
        let q = Quaternion::new(
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
        );
        let n = q.norm();
        if n > 1e-3 && n <= 1.0 {
            break q;
        }
    };
    let t = Vector3::new(
        (rng.random::<f64>() * 2.0 - 1.0) * half_width_m,
        (rng.random::<f64>() * 2.0 - 1.0) * half_width_m,
        (rng.random::<f64>() * 2.0 - 1.0) * half_width_m,
    );
    Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_quaternion(q))
}

/// Replaces `round(fraction × loop closures)` randomly chosen loop closures (edges other
/// than `(i, i+1)`) with random relative poses ([`random_pose`] with `half_width_m`),
/// keeping their information matrices. Returns the indices of the replaced edges.
pub fn corrupt_loop_closures(
    edges: &mut [FileEdge],
    fraction: f64,
    half_width_m: f64,
    seed: u64,
) -> Vec<usize> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut loops: Vec<usize> = edges
        .iter()
        .enumerate()
        .filter(|(_, e)| e.to != e.from + 1)
        .map(|(k, _)| k)
        .collect();
    let count = ((fraction.clamp(0.0, 1.0) * loops.len() as f64).round() as usize).min(loops.len());
    // Partial Fisher–Yates shuffle.
    for k in 0..count {
        let pick = rng.random_range(k..loops.len());
        loops.swap(k, pick);
    }
    let mut chosen = loops[..count].to_vec();
    chosen.sort_unstable();
    for &k in &chosen {
        edges[k].measured = random_pose(&mut rng, half_width_m);
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generates_requested_sizes() {
        let g = generate(&SyntheticConfig {
            poses: 600,
            loop_closures: 30,
            ..SyntheticConfig::default()
        });
        assert_eq!(g.truth.len(), 600);
        assert_eq!(g.file.vertices.len(), 600);
        assert_eq!(g.file.edges.len(), 599 + 30);
    }

    #[test]
    fn corruption_replaces_the_requested_fraction_of_loop_closures() {
        let mut g = generate(&SyntheticConfig {
            poses: 600,
            loop_closures: 30,
            ..SyntheticConfig::default()
        });
        let before = g.file.edges.clone();
        let replaced = corrupt_loop_closures(&mut g.file.edges, 0.1, 10.0, 3);
        assert_eq!(replaced.len(), 3);
        for (k, (a, b)) in before.iter().zip(&g.file.edges).enumerate() {
            assert_eq!(a.measured != b.measured, replaced.contains(&k));
        }
    }
}
