//! CLIPPER-class continuous relaxation of the densest-clique problem.
//!
//! Maximises `F(u) = uᵀMu − d·uᵀ(11ᵀ − C)u` over `u ≥ 0`, `‖u‖ = 1`, where `M` is the weighted
//! affinity with unit diagonal, `C` its binary pattern with unit diagonal and `d` a penalty on
//! non-adjacent pairs that the outer loop raises until the support of `u` is a clique.

use rayon::prelude::*;

use crate::rng::SplitMix64;
use crate::{ConsistencyGraph, DensestCliqueConfig};

/// Result of one relaxation run.
pub(crate) struct RelaxOutcome {
    /// Final iterate (unit norm, non-negative; entries not above the support tolerance are 0).
    pub u: Vec<f64>,
    /// Outer iterations (penalty updates) run.
    pub outer_iterations: usize,
    /// Inner (gradient) iterations run, summed over the outer loop.
    pub inner_iterations: usize,
}

/// `Mu`, `Cu` and the sum of `u`, from one pass over the CSR rows.
struct Products {
    mu: Vec<f64>,
    /// `((11ᵀ − C)u)_i = sum(u) − u_i − Σ_{j∈N(i)} u_j`.
    du: Vec<f64>,
}

/// Rows per parallel task of [`products`]; each row is summed sequentially, so the result
/// does not depend on the number of threads.
const ROWS_PER_TASK: usize = 2048;

fn products(graph: &ConsistencyGraph, u: &[f64], out: &mut Products) {
    let total: f64 = u.iter().sum();
    let offsets = graph.offsets();
    let nbrs = graph.all_neighbors();
    let wts = graph.all_weights();
    let rows = |first: usize, mu: &mut [f64], du: &mut [f64]| {
        for (k, (mu, du)) in mu.iter_mut().zip(du.iter_mut()).enumerate() {
            let i = first + k;
            let (a, b) = (offsets[i], offsets[i + 1]);
            let mut wsum = 0.0f64;
            let mut csum = 0.0f64;
            for (&j, &w) in nbrs[a..b].iter().zip(&wts[a..b]) {
                let uj = u[j as usize];
                wsum += w as f64 * uj;
                csum += uj;
            }
            *mu = u[i] + wsum;
            // clamp: rounding could leave a tiny negative value
            *du = (total - u[i] - csum).max(0.0);
        }
    };
    if u.len() <= ROWS_PER_TASK {
        rows(0, &mut out.mu, &mut out.du);
    } else {
        out.mu
            .par_chunks_mut(ROWS_PER_TASK)
            .zip(out.du.par_chunks_mut(ROWS_PER_TASK))
            .enumerate()
            .for_each(|(t, (mu, du))| rows(t * ROWS_PER_TASK, mu, du));
    }
}

fn objective(u: &[f64], p: &Products, d: f64) -> f64 {
    u.iter()
        .zip(&p.mu)
        .zip(&p.du)
        .map(|((&ui, &mi), &di)| ui * (mi - d * di))
        .sum()
}

/// Mean of `(Mu)_i / ((11ᵀ−C)u)_i` over indices with `u_i > tol` and `((11ᵀ−C)u)_i > tol`;
/// `None` when there is no such index (the support is a clique).
fn penalty_step(u: &[f64], p: &Products, tol: f64) -> Option<f64> {
    let mut sum = 0.0;
    let mut count = 0usize;
    for ((&ui, &mi), &di) in u.iter().zip(&p.mu).zip(&p.du) {
        if ui > tol && di > tol {
            sum += mi / di;
            count += 1;
        }
    }
    (count > 0).then(|| sum / count as f64)
}

fn normalise(u: &mut [f64]) -> bool {
    let norm = u.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm > 0.0 && norm.is_finite() {
        for x in u.iter_mut() {
            *x /= norm;
        }
        true
    } else {
        false
    }
}

/// Zeroes entries not above `tol` and renormalises.
fn threshold(u: &mut [f64], tol: f64) {
    for x in u.iter_mut() {
        if *x <= tol {
            *x = 0.0;
        }
    }
    normalise(u);
}

/// Runs the relaxation on `graph` from a seeded random start.
pub(crate) fn relax(
    graph: &ConsistencyGraph,
    config: &DensestCliqueConfig,
    seed: u64,
) -> RelaxOutcome {
    let n = graph.num_vertices();
    let mut u = vec![0.0; n];
    if n == 0 {
        return RelaxOutcome {
            u,
            outer_iterations: 0,
            inner_iterations: 0,
        };
    }
    // tolerate odd settings: negative tolerances act as zero
    let tol = config.support_tolerance.max(0.0);
    let mut p = Products::zeros(n);
    random_start(graph, seed, &mut u, &mut p);
    let mut d = match penalty_step(&u, &p, tol) {
        Some(step) => step,
        None => {
            threshold(&mut u, tol);
            return RelaxOutcome {
                u,
                outer_iterations: 0,
                inner_iterations: 0,
            };
        }
    };
    let mut ascent = Ascent::new(graph, config, n);
    let mut inner_total = 0usize;
    let mut outer = 0usize;
    while outer < config.max_outer_iterations {
        outer += 1;
        inner_total += ascent.run(&mut u, &mut p, d);
        threshold(&mut u, tol);
        products(graph, &u, &mut p);
        match penalty_step(&u, &p, tol) {
            Some(step) => d += step,
            None => break,
        }
    }
    RelaxOutcome {
        u,
        outer_iterations: outer,
        inner_iterations: inner_total,
    }
}

impl Products {
    fn zeros(n: usize) -> Self {
        Products {
            mu: vec![0.0; n],
            du: vec![0.0; n],
        }
    }
}

/// The start: `u0` random in (0, 1), one power step `u = (M + I) u0`, normalised; `p` its
/// products.
fn random_start(graph: &ConsistencyGraph, seed: u64, u: &mut [f64], p: &mut Products) {
    let mut rng = SplitMix64::new(seed);
    for x in u.iter_mut() {
        *x = rng.next_open01();
    }
    products(graph, u, p);
    for (ui, &mi) in u.iter_mut().zip(&p.mu) {
        *ui += mi;
    }
    normalise(u);
    products(graph, u, p);
}

/// Projected gradient ascent on `F` for a fixed penalty, with its scratch buffers.
struct Ascent<'a> {
    graph: &'a ConsistencyGraph,
    config: &'a DensestCliqueConfig,
    /// The line search's step factor (a bad setting acts as 0.25).
    shrink: f64,
    trial: Vec<f64>,
    p_trial: Products,
    grad: Vec<f64>,
}

impl<'a> Ascent<'a> {
    fn new(graph: &'a ConsistencyGraph, config: &'a DensestCliqueConfig, n: usize) -> Self {
        let shrink = if config.step_shrink > 0.0 && config.step_shrink < 1.0 {
            config.step_shrink
        } else {
            0.25
        };
        Ascent {
            graph,
            config,
            shrink,
            trial: vec![0.0; n],
            p_trial: Products::zeros(n),
            grad: vec![0.0; n],
        }
    }

    /// Ascends from `u` (products `p`, both updated) under penalty `d` until stationary or
    /// converged; returns the iterations run.
    fn run(&mut self, u: &mut Vec<f64>, p: &mut Products, d: f64) -> usize {
        let config = self.config;
        let mut iterations = 0;
        let mut f = objective(u, p, d);
        for _ in 0..config.max_inner_iterations {
            iterations += 1;
            for ((g, &mi), &di) in self.grad.iter_mut().zip(&p.mu).zip(&p.du) {
                *g = 2.0 * (mi - d * di);
            }
            let Some(f_new) = self.line_search(u, f, d) else {
                break; // no ascent step found: stationary for this d
            };
            let du_norm = u
                .iter()
                .zip(&self.trial)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            std::mem::swap(u, &mut self.trial);
            std::mem::swap(p, &mut self.p_trial);
            let df = (f_new - f).abs();
            f = f_new;
            if du_norm < config.tolerance_u || df < config.tolerance_f {
                break;
            }
        }
        iterations
    }

    /// Backtracking along the gradient from `u` (objective `f`): the first step that does not
    /// decrease `F`, left in `trial` (and `p_trial`); its objective.
    fn line_search(&mut self, u: &[f64], f: f64, d: f64) -> Option<f64> {
        let mut alpha = self.config.initial_step;
        for _ in 0..self.config.max_line_search_steps {
            for ((t, &ui), &g) in self.trial.iter_mut().zip(u).zip(&self.grad) {
                *t = (ui + alpha * g).max(0.0);
            }
            if normalise(&mut self.trial) {
                products(self.graph, &self.trial, &mut self.p_trial);
                let f_trial = objective(&self.trial, &self.p_trial, d);
                if f_trial >= f {
                    return Some(f_trial);
                }
            }
            alpha *= self.shrink;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn converges_to_planted_clique() {
        // clique {0..5} plus a sparse fringe
        let mut e = Vec::new();
        for u in 0..6u32 {
            for v in u + 1..6 {
                e.push((u, v, 0.9));
            }
        }
        e.extend([
            (5, 6, 1.0),
            (6, 7, 1.0),
            (7, 8, 1.0),
            (0, 8, 1.0),
            (8, 9, 1.0),
        ]);
        let g = ConsistencyGraph::from_edges(10, &e).unwrap();
        let out = relax(&g, &DensestCliqueConfig::default(), 1);
        let support: Vec<usize> = (0..10).filter(|&i| out.u[i] > 0.0).collect();
        assert_eq!(support, vec![0, 1, 2, 3, 4, 5]);
    }

    #[test]
    fn complete_graph_stops_at_once() {
        let g = ConsistencyGraph::from_edges(3, &[(0, 1, 1.0), (1, 2, 1.0), (0, 2, 1.0)]).unwrap();
        let out = relax(&g, &DensestCliqueConfig::default(), 5);
        assert_eq!(out.outer_iterations, 0);
        assert!(out.u.iter().all(|&x| x > 0.0));
    }
}
