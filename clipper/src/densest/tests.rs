use super::*;
use crate::rng::SplitMix64;
use crate::testutil::{precision_recall, problem, Mode};
use crate::{max_clique, Invariant, MaxCliqueLimits};

fn clique_edges(vs: &[u32], w: f64) -> Vec<(u32, u32, f64)> {
    let mut e = Vec::new();
    for (a, &u) in vs.iter().enumerate() {
        for &v in &vs[a + 1..] {
            e.push((u, v, w));
        }
    }
    e
}

#[test]
fn empty_graph() {
    let g = ConsistencyGraph::from_edges(0, &[]).unwrap();
    let s = densest_clique(&g, &DensestCliqueConfig::default());
    assert!(s.vertices.is_empty());
    assert!(s.certified_maximum);
}

#[test]
fn hand_made_graph_with_overlapping_cliques() {
    // K6 {0..5}, K5 {5..9} sharing vertex 5, plus noise edges
    let mut e = clique_edges(&[0, 1, 2, 3, 4, 5], 0.8);
    e.extend(clique_edges(&[6, 7, 8, 9], 1.0));
    e.extend([(5, 6, 1.0), (5, 7, 1.0), (5, 8, 1.0), (5, 9, 1.0)]);
    e.extend([(9, 10, 1.0), (10, 11, 1.0), (0, 11, 1.0)]);
    let g = ConsistencyGraph::from_edges(12, &e).unwrap();
    for prune in [true, false] {
        let cfg = DensestCliqueConfig {
            prune_by_core: prune,
            ..Default::default()
        };
        let s = densest_clique(&g, &cfg);
        assert!(g.is_clique(&s.vertices));
        if prune {
            // certified by the bounds
            assert_eq!(s.vertices, vec![0, 1, 2, 3, 4, 5]);
            assert!(s.certified_maximum);
        } else {
            // the plain relaxation is local: either clique is a maximal dense one
            assert!(s.vertices.len() >= 5, "{:?}", s.vertices);
        }
    }
}

#[test]
fn weights_break_size_ties() {
    // two disjoint K4, the second heavier, not certified by size alone
    let mut e = clique_edges(&[0, 1, 2, 3], 0.5);
    e.extend(clique_edges(&[4, 5, 6, 7], 0.9));
    // tie the components together so the graph is connected
    e.push((3, 4, 1.0));
    let g = ConsistencyGraph::from_edges(8, &e).unwrap();
    let s = densest_clique(&g, &DensestCliqueConfig::default());
    assert_eq!(s.vertices.len(), 4);
    assert!(s.certified_maximum);
    let s2 = densest_clique(
        &g,
        &DensestCliqueConfig {
            prune_by_core: false,
            ..Default::default()
        },
    );
    assert_eq!(s2.vertices, vec![4, 5, 6, 7]);
}

/// A random graph with a planted clique; the planted clique is the maximum w.h.p.
fn planted(n: usize, p: f64, k: usize, seed: u64) -> (ConsistencyGraph, Vec<u32>) {
    let mut rng = SplitMix64::new(seed);
    let mut planted: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        planted.swap(i, rng.below(i + 1));
    }
    planted.truncate(k);
    planted.sort_unstable();
    let mut is_p = vec![false; n];
    for &v in &planted {
        is_p[v as usize] = true;
    }
    let mut e = Vec::new();
    for u in 0..n as u32 {
        for v in u + 1..n as u32 {
            let w = 0.5 + 0.5 * rng.next_open01();
            if (is_p[u as usize] && is_p[v as usize]) || rng.next_open01() < p {
                e.push((u, v, w));
            }
        }
    }
    (ConsistencyGraph::from_edges(n, &e).unwrap(), planted)
}

#[test]
fn densest_matches_max_clique_size_on_moderate_graphs() {
    for seed in 0..6 {
        let (g, planted) = planted(300, 0.1, 14, seed);
        let exact = max_clique(&g, &MaxCliqueLimits::default()).unwrap();
        let s = densest_clique(
            &g,
            &DensestCliqueConfig {
                seed,
                ..Default::default()
            },
        );
        assert!(g.is_clique(&s.vertices));
        assert_eq!(s.vertices.len(), exact.vertices.len(), "seed {seed}");
        assert_eq!(exact.vertices, planted);
        assert!(s.upper_bound >= exact.vertices.len());
    }
}

#[test]
fn relaxation_runs_when_not_certified() {
    // dense random part whose core bound exceeds the planted clique: optimiser needed
    let (g, planted) = planted(200, 0.3, 16, 42);
    let s = densest_clique(&g, &DensestCliqueConfig::default());
    assert_eq!(s.vertices, planted);
    assert!(s.outer_iterations > 0 || s.certified_maximum);
}

#[test]
fn deterministic_for_a_seed() {
    let (g, _) = planted(400, 0.2, 12, 7);
    let cfg = DensestCliqueConfig {
        seed: 99,
        ..Default::default()
    };
    let a = densest_clique(&g, &cfg);
    let b = densest_clique(&g, &cfg);
    assert_eq!(a, b);
}

#[test]
fn disconnected_components_do_not_depend_on_the_start() {
    // three disjoint cliques of sizes 5, 9, 7 with random weights
    let mut e = clique_edges(&[0, 1, 2, 3, 4], 1.0);
    e.extend(clique_edges(&(5..14).collect::<Vec<_>>(), 0.7));
    e.extend(clique_edges(&(14..21).collect::<Vec<_>>(), 1.0));
    let g = ConsistencyGraph::from_edges(21, &e).unwrap();
    for seed in 0..20 {
        let s = densest_clique(
            &g,
            &DensestCliqueConfig {
                seed,
                prune_by_core: true,
                ..Default::default()
            },
        );
        assert_eq!(s.vertices, (5..14).collect::<Vec<_>>(), "seed {seed}");
    }
}

#[test]
fn recovers_inliers_in_random_geometric_problems() {
    let inv = Invariant::Distance {
        epsilon: 0.3,
        sigma: 0.1,
    };
    for seed in 0..4 {
        let p = problem(
            100,
            Mode::Random {
                n_assoc: 1000,
                outliers: 0.9,
            },
            0.05,
            false,
            100 + seed,
        );
        let g = ConsistencyGraph::build(&p.prior, &p.query, &p.associations, &inv).unwrap();
        let s = densest_clique(&g, &DensestCliqueConfig::default());
        let (precision, recall) = precision_recall(&s.vertices, &p.truth);
        assert!(precision >= 0.99, "seed {seed}: precision {precision}");
        assert!(recall >= 0.95, "seed {seed}: recall {recall}");
    }
    // all-to-all, gravity aligned
    let inv4 = Invariant::GravityAligned {
        epsilon: 0.1,
        sigma: 0.04,
        epsilon_z: 0.1,
        sigma_z: 0.04,
    };
    for seed in 0..3 {
        let p = problem(60, Mode::All, 0.02, true, 200 + seed);
        let g = ConsistencyGraph::build(&p.prior, &p.query, &p.associations, &inv4).unwrap();
        let s = densest_clique(&g, &DensestCliqueConfig::default());
        let (precision, recall) = precision_recall(&s.vertices, &p.truth);
        assert!(precision >= 0.99, "seed {seed}: precision {precision}");
        assert!(recall >= 0.95, "seed {seed}: recall {recall}");
    }
}

#[test]
fn polish_prefers_the_heavier_of_two_maximum_cliques() {
    // base clique {0..7}; 8 and 9 both complete it (not adjacent to each other), 9 heavier
    let mut e = clique_edges(&(0..8).collect::<Vec<_>>(), 0.8);
    for b in 0..8 {
        e.push((b, 8, 0.2));
        e.push((b, 9, 0.9));
    }
    let g = ConsistencyGraph::from_edges(10, &e).unwrap();
    let plain = densest_clique(
        &g,
        &DensestCliqueConfig {
            polish: false,
            ..Default::default()
        },
    );
    assert_eq!(plain.vertices.len(), 9);
    assert!(plain.certified_maximum);
    let s = densest_clique(&g, &DensestCliqueConfig::default());
    assert_eq!(s.vertices, vec![0, 1, 2, 3, 4, 5, 6, 7, 9]);
    assert!(s.certified_maximum);
    let exact = max_clique(&g, &MaxCliqueLimits::default()).unwrap();
    assert_eq!(exact.vertices, s.vertices);
}

#[test]
fn close_point_pairs_do_not_swap_associations() {
    // all-to-all, 6-DOF, with two pairs of prior points 0.15 m apart: the swapped
    // associations are consistent with almost everything but fit worse
    use nalgebra::{Point3, Rotation3, Vector3};
    let mut rng = SplitMix64::new(77);
    let n = 40;
    let mut prior: Vec<Point3<f64>> = (0..n)
        .map(|_| {
            Point3::new(
                30.0 * rng.next_open01(),
                30.0 * rng.next_open01(),
                rng.next_open01(),
            )
        })
        .collect();
    prior[1] = prior[0] + Vector3::new(0.15, 0.0, 0.0);
    prior[3] = prior[2] + Vector3::new(0.0, 0.12, 0.02);
    let r = Rotation3::from_euler_angles(0.3, -0.2, 1.1);
    let t = Vector3::new(4.0, -7.0, 0.5);
    let query: Vec<Point3<f64>> = prior
        .iter()
        .map(|p| {
            r * p
                + t
                + Vector3::new(
                    0.03 * crate::testutil::gauss(&mut rng),
                    0.03 * crate::testutil::gauss(&mut rng),
                    0.03 * crate::testutil::gauss(&mut rng),
                )
        })
        .collect();
    let assoc: Vec<_> = (0..n as u32)
        .flat_map(|i| (0..n as u32).map(move |j| crate::Association::new(i, j)))
        .collect();
    let inv = Invariant::Distance {
        epsilon: 0.3,
        sigma: 0.1,
    };
    let g = ConsistencyGraph::build(&prior, &query, &assoc, &inv).unwrap();
    let truth: Vec<bool> = assoc.iter().map(|a| a.prior == a.query).collect();
    // (without the polish the greedy clique here holds swapped associations: precision 0.95)
    for s in [
        densest_clique(&g, &DensestCliqueConfig::default()),
        max_clique(&g, &MaxCliqueLimits::default()).unwrap(),
    ] {
        let (precision, recall) = precision_recall(&s.vertices, &truth);
        assert_eq!((precision, recall), (1.0, 1.0), "{:?}", s.vertices);
    }
}

#[test]
fn odd_settings_still_return_a_clique() {
    let (g, planted) = planted(120, 0.3, 10, 9);
    for cfg in [
        DensestCliqueConfig {
            max_outer_iterations: 0,
            ..Default::default()
        },
        DensestCliqueConfig {
            max_inner_iterations: 0,
            support_tolerance: -1.0,
            step_shrink: 2.0,
            ..Default::default()
        },
        DensestCliqueConfig {
            initial_step: f64::NAN,
            max_line_search_steps: 0,
            polish: false,
            ..Default::default()
        },
        DensestCliqueConfig {
            prune_by_core: false,
            max_outer_iterations: 1,
            ..Default::default()
        },
    ] {
        let s = densest_clique(&g, &cfg);
        assert!(g.is_clique(&s.vertices), "{cfg:?}");
        assert!(!s.vertices.is_empty());
        assert!(s.vertices.len() <= planted.len().max(s.upper_bound));
    }
}

#[test]
fn relaxation_is_thread_count_independent() {
    let (g, _) = planted(5000, 0.004, 12, 21);
    let cfg = DensestCliqueConfig {
        prune_by_core: false,
        max_outer_iterations: 3,
        ..Default::default()
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| densest_clique(&g, &cfg))
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn many_small_components() {
    // 3000 disjoint 5-cycles (clique number 2, colouring bound 3) and one triangle
    let mut e = Vec::new();
    for c in 0..3000u32 {
        for k in 0..5 {
            e.push((5 * c + k, 5 * c + (k + 1) % 5, 1.0));
        }
    }
    e.extend([
        (15000, 15001, 1.0),
        (15001, 15002, 1.0),
        (15000, 15002, 1.0),
    ]);
    let g = ConsistencyGraph::from_edges(15003, &e).unwrap();
    let s = densest_clique(&g, &DensestCliqueConfig::default());
    assert_eq!(s.vertices, vec![15000, 15001, 15002]);
    assert!(s.certified_maximum);
    // and with the triangle absent: a clique of two, not certified by the bounds
    let g = ConsistencyGraph::from_edges(15000, &e[..15000]).unwrap();
    let s = densest_clique(&g, &DensestCliqueConfig::default());
    assert_eq!(s.vertices.len(), 2);
    assert!(g.is_clique(&s.vertices));
}
