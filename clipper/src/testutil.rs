//! Random geometric association problems for tests.

use nalgebra::{Point3, Quaternion, Rotation3, UnitQuaternion, Vector3};

use crate::rng::SplitMix64;
use crate::Association;

/// A generated problem: query = R prior + t + noise, `truth[k]` true if association k is right.
pub(crate) struct Problem {
    pub prior: Vec<Point3<f64>>,
    pub query: Vec<Point3<f64>>,
    pub associations: Vec<Association>,
    pub truth: Vec<bool>,
}

pub(crate) fn gauss(rng: &mut SplitMix64) -> f64 {
    let u1 = rng.next_open01();
    let u2 = rng.next_open01();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// How associations are chosen.
pub(crate) enum Mode {
    /// `n_assoc` associations, a fraction `outliers` of them wrong.
    Random { n_assoc: usize, outliers: f64 },
    /// Every (prior, query) pair.
    All,
}

/// Points uniform in a 30 x 30 x 1 box, `n` per map; query = R p + t + N(0, noise²), shuffled.
pub(crate) fn problem(n: usize, mode: Mode, noise: f64, yaw_only: bool, seed: u64) -> Problem {
    let mut rng = SplitMix64::new(seed);
    let prior: Vec<Point3<f64>> = (0..n)
        .map(|_| {
            Point3::new(
                30.0 * rng.next_open01(),
                30.0 * rng.next_open01(),
                rng.next_open01(),
            )
        })
        .collect();
    let rot = if yaw_only {
        Rotation3::from_axis_angle(&Vector3::z_axis(), 6.0 * rng.next_open01() - 3.0)
    } else {
        let q = Quaternion::new(
            gauss(&mut rng),
            gauss(&mut rng),
            gauss(&mut rng),
            gauss(&mut rng),
        );
        UnitQuaternion::from_quaternion(q).to_rotation_matrix()
    };
    let t = Vector3::new(
        40.0 * rng.next_open01() - 20.0,
        40.0 * rng.next_open01() - 20.0,
        2.0 * rng.next_open01() - 1.0,
    );
    let mut perm: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        perm.swap(i, rng.below(i + 1));
    }
    let mut query = vec![Point3::origin(); n];
    for (i, p) in prior.iter().enumerate() {
        let e = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * noise;
        query[perm[i] as usize] = rot * p + t + e;
    }
    let associations: Vec<Association> = match mode {
        Mode::All => (0..n as u32)
            .flat_map(|i| (0..n as u32).map(move |j| Association::new(i, j)))
            .collect(),
        Mode::Random { n_assoc, outliers } => {
            let n_in = ((n_assoc as f64) * (1.0 - outliers)).round() as usize;
            let mut set = std::collections::HashSet::new();
            let mut list = Vec::new();
            let mut idx: Vec<u32> = (0..n as u32).collect();
            for i in (1..n).rev() {
                idx.swap(i, rng.below(i + 1));
            }
            for &i in idx.iter().take(n_in.min(n)) {
                let a = Association::new(i, perm[i as usize]);
                set.insert(a);
                list.push(a);
            }
            while list.len() < n_assoc {
                let a = Association::new(rng.below(n) as u32, rng.below(n) as u32);
                if a.query != perm[a.prior as usize] && set.insert(a) {
                    list.push(a);
                }
            }
            for i in (1..list.len()).rev() {
                list.swap(i, rng.below(i + 1));
            }
            list
        }
    };
    let truth = associations
        .iter()
        .map(|a| perm[a.prior as usize] == a.query)
        .collect();
    Problem {
        prior,
        query,
        associations,
        truth,
    }
}

/// Precision and recall of a selected vertex set against the truth.
pub(crate) fn precision_recall(selected: &[u32], truth: &[bool]) -> (f64, f64) {
    let tp = selected.iter().filter(|&&v| truth[v as usize]).count() as f64;
    let n_true = truth.iter().filter(|&&t| t).count() as f64;
    let precision = if selected.is_empty() {
        0.0
    } else {
        tp / selected.len() as f64
    };
    let recall = if n_true == 0.0 { 1.0 } else { tp / n_true };
    (precision, recall)
}
