use super::*;
use crate::association::exp_neg;
use crate::testutil::{problem, Mode};

fn distance(eps: f64, sigma: f64) -> Invariant {
    Invariant::Distance {
        epsilon: eps,
        sigma,
    }
}

fn gravity(eps: f64, sigma: f64) -> Invariant {
    Invariant::GravityAligned {
        epsilon: eps,
        sigma,
        epsilon_z: eps,
        sigma_z: sigma,
    }
}

/// Reference: test every pair with the exact function.
fn brute_force(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    assoc: &[Association],
    inv: &Invariant,
) -> ConsistencyGraph {
    let t = PairTest::new(inv).unwrap();
    let mut e = Vec::new();
    for u in 0..assoc.len() {
        for v in u + 1..assoc.len() {
            if let Some(x) = t.test_associations(prior, query, assoc[u], assoc[v]) {
                e.push((u as u32, v as u32, exp_neg(x)));
            }
        }
    }
    ConsistencyGraph::from_edge_list(assoc.len(), &e)
}

fn both(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    assoc: &[Association],
    inv: &Invariant,
) -> (ConsistencyGraph, ConsistencyGraph) {
    let j = ConsistencyGraph::build_with(prior, query, assoc, inv, BuildStrategy::Join).unwrap();
    let s = ConsistencyGraph::build_with(prior, query, assoc, inv, BuildStrategy::PairwiseScan)
        .unwrap();
    (j, s)
}

#[test]
fn join_and_scan_agree_with_brute_force() {
    let cases = [
        (problem(25, Mode::All, 0.05, false, 1), distance(0.3, 0.1)),
        (problem(25, Mode::All, 0.02, true, 2), gravity(0.1, 0.04)),
        (
            problem(
                60,
                Mode::Random {
                    n_assoc: 600,
                    outliers: 0.9,
                },
                0.05,
                false,
                3,
            ),
            distance(0.3, 0.1),
        ),
        (
            problem(
                60,
                Mode::Random {
                    n_assoc: 600,
                    outliers: 0.8,
                },
                0.02,
                true,
                4,
            ),
            gravity(0.1, 0.04),
        ),
        // huge epsilon: nearly complete graph
        (
            problem(12, Mode::All, 0.05, false, 5),
            distance(100.0, 10.0),
        ),
    ];
    for (k, (p, inv)) in cases.iter().enumerate() {
        let reference = brute_force(&p.prior, &p.query, &p.associations, inv);
        let (j, s) = both(&p.prior, &p.query, &p.associations, inv);
        assert!(reference.num_edges() > 0, "case {k}");
        assert_eq!(j, reference, "join, case {k}");
        assert_eq!(s, reference, "scan, case {k}");
    }
}

#[test]
fn join_and_scan_identical_on_larger_problems() {
    let p = problem(40, Mode::All, 0.05, false, 9);
    let (j, s) = both(&p.prior, &p.query, &p.associations, &distance(0.3, 0.1));
    assert_eq!(j, s);
    let p = problem(40, Mode::All, 0.02, true, 10);
    let (j, s) = both(&p.prior, &p.query, &p.associations, &gravity(0.1, 0.04));
    assert_eq!(j, s);
    // sparse list: the join falls back to a hash lookup when the table would be large
    let p = problem(
        300,
        Mode::Random {
            n_assoc: 1500,
            outliers: 0.9,
        },
        0.05,
        false,
        11,
    );
    let (j, s) = both(&p.prior, &p.query, &p.associations, &distance(0.3, 0.1));
    assert_eq!(j, s);
}

#[test]
fn coincident_and_far_points() {
    // repeated points (zero distances) and large coordinates
    let prior = vec![
        Point3::new(1e4, 1e4, 0.0),
        Point3::new(1e4, 1e4, 0.0),
        Point3::new(1e4 + 3.0, 1e4, 0.5),
        Point3::new(1e4, 1e4 + 4.0, 0.2),
    ];
    let query: Vec<_> = prior
        .iter()
        .map(|p| Point3::new(p.x - 2e4, p.y + 5e3, p.z + 100.0))
        .collect();
    let assoc: Vec<_> = (0..4)
        .flat_map(|i| (0..4).map(move |j| Association::new(i, j)))
        .collect();
    for inv in [distance(0.01, 0.005), gravity(0.01, 0.005)] {
        let reference = brute_force(&prior, &query, &assoc, &inv);
        let (j, s) = both(&prior, &query, &assoc, &inv);
        assert_eq!(j, reference);
        assert_eq!(s, reference);
        // (0,0)-(1,1): both pairs have distance 0 -> consistent
        assert!(s.has_edge(0, 5));
    }
}

#[test]
fn one_to_one_rule() {
    let p = problem(30, Mode::All, 0.05, false, 12);
    let g = ConsistencyGraph::build(&p.prior, &p.query, &p.associations, &distance(100.0, 1.0))
        .unwrap();
    for u in 0..g.num_vertices() {
        for &v in g.neighbors(u) {
            let (a, b) = (p.associations[u], p.associations[v as usize]);
            assert!(a.prior != b.prior && a.query != b.query);
        }
    }
    // with a huge epsilon every pair not sharing a point is an edge
    assert_eq!(g.num_edges(), 900 * (29 * 29) / 2);
}

#[test]
fn gravity_aligned_sign_handling() {
    // a yaw-only problem with height differences: the 4-DOF graph keeps every inlier pair
    // and has far fewer edges than the 6-DOF one
    let p = problem(30, Mode::All, 0.0, true, 13);
    let g4 = ConsistencyGraph::build(&p.prior, &p.query, &p.associations, &gravity(0.01, 0.005))
        .unwrap();
    let g6 = ConsistencyGraph::build(&p.prior, &p.query, &p.associations, &distance(0.01, 0.005))
        .unwrap();
    let inliers: Vec<u32> = (0..p.truth.len() as u32)
        .filter(|&k| p.truth[k as usize])
        .collect();
    assert!(g4.is_clique(&inliers));
    assert!(g4.num_edges() < g6.num_edges());
    // the mirrored problem (query heights negated) must lose the inlier edges in 4-DOF
    let mirrored: Vec<_> = p
        .query
        .iter()
        .map(|q| Point3::new(q.x, q.y, -q.z))
        .collect();
    let gm = ConsistencyGraph::build(&p.prior, &mirrored, &p.associations, &gravity(0.01, 0.005))
        .unwrap();
    let kept = inliers
        .iter()
        .enumerate()
        .flat_map(|(a, &u)| inliers[a + 1..].iter().map(move |&v| (u, v)))
        .filter(|&(u, v)| gm.has_edge(u as usize, v as usize))
        .count();
    assert!(kept < 30, "{kept} inlier edges survived mirroring");
}

#[test]
fn thread_count_does_not_change_the_graph() {
    let p = problem(
        200,
        Mode::Random {
            n_assoc: 2000,
            outliers: 0.9,
        },
        0.05,
        false,
        14,
    );
    let q = problem(30, Mode::All, 0.02, true, 15);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let inv = distance(0.3, 0.1);
            let a = ConsistencyGraph::build_with(
                &p.prior,
                &p.query,
                &p.associations,
                &inv,
                BuildStrategy::PairwiseScan,
            )
            .unwrap();
            let b = ConsistencyGraph::build_with(
                &q.prior,
                &q.query,
                &q.associations,
                &gravity(0.1, 0.04),
                BuildStrategy::Join,
            )
            .unwrap();
            (a, b)
        })
    };
    assert_eq!(run(1), run(2));
    assert_eq!(run(1), run(3));
}

#[test]
fn invalid_input_is_an_error() {
    let pts = vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0)];
    let nan = vec![Point3::new(0.0, 0.0, f64::INFINITY)];
    let a = vec![Association::new(0, 0)];
    let inv = distance(0.1, 0.1);
    assert!(matches!(
        ConsistencyGraph::build(&nan, &pts, &a, &inv),
        Err(ClipperError::NonFinitePoint { .. })
    ));
    assert!(matches!(
        ConsistencyGraph::build(&pts, &pts, &[Association::new(2, 0)], &inv),
        Err(ClipperError::IndexOutOfRange { .. })
    ));
    assert!(matches!(
        ConsistencyGraph::build(&pts, &pts, &a, &distance(-1.0, 0.1)),
        Err(ClipperError::InvalidParameter { .. })
    ));
    assert!(matches!(
        ConsistencyGraph::build(&pts, &pts, &[a[0], a[0]], &inv),
        Err(ClipperError::DuplicateAssociation { .. })
    ));
    // empty inputs are fine
    let g = ConsistencyGraph::build(&[], &[], &[], &inv).unwrap();
    assert_eq!(g.num_vertices(), 0);
}

#[test]
fn auto_strategy_choice() {
    // all-to-all with a selective invariant: the join's work follows the few edges
    let all = problem(100, Mode::All, 0.02, true, 16);
    assert_eq!(
        choose_strategy(
            &all.prior,
            &all.query,
            &all.associations,
            &gravity(0.1, 0.04)
        )
        .unwrap(),
        BuildStrategy::Join
    );
    // sparse random list: the scan
    let sparse = problem(
        500,
        Mode::Random {
            n_assoc: 5000,
            outliers: 0.9,
        },
        0.05,
        false,
        17,
    );
    let inv = distance(0.3, 0.1);
    assert_eq!(
        choose_strategy(&sparse.prior, &sparse.query, &sparse.associations, &inv).unwrap(),
        BuildStrategy::PairwiseScan
    );
}

#[test]
fn portable_and_simd_kernels_agree() {
    for (p, inv) in [
        (
            problem(
                150,
                Mode::Random {
                    n_assoc: 1503,
                    outliers: 0.9,
                },
                0.05,
                false,
                21,
            ),
            distance(0.3, 0.1),
        ),
        (problem(23, Mode::All, 0.02, true, 22), gravity(0.1, 0.04)),
    ] {
        let t = PairTest::new(&inv).unwrap();
        let a = scan::build(
            &p.prior,
            &p.query,
            &p.associations,
            &t,
            scan::Kernel::Portable,
        );
        assert!(a.num_edges() > 0);
        for kernel in scan::Kernel::available() {
            let b = scan::build(&p.prior, &p.query, &p.associations, &t, kernel);
            assert_eq!(a, b, "{kernel:?}");
        }
        assert_eq!(a, brute_force(&p.prior, &p.query, &p.associations, &inv));
    }
}

#[test]
fn hashed_lookup_and_empty_lists() {
    let p = problem(
        80,
        Mode::Random {
            n_assoc: 900,
            outliers: 0.8,
        },
        0.05,
        false,
        31,
    );
    let inv = distance(0.3, 0.1);
    let t = PairTest::new(&inv).unwrap();
    let dense = join::build(&p.prior, &p.query, &p.associations, &t);
    let hashed = join::build_with_table_limit(&p.prior, &p.query, &p.associations, &t, 0);
    assert_eq!(dense, hashed);
    assert_eq!(
        dense,
        brute_force(&p.prior, &p.query, &p.associations, &inv)
    );
    for strategy in [BuildStrategy::Join, BuildStrategy::PairwiseScan] {
        let g = ConsistencyGraph::build_with(&p.prior, &p.query, &[], &inv, strategy).unwrap();
        assert_eq!(g.num_vertices(), 0);
        let one = [Association::new(0, 0)];
        let g = ConsistencyGraph::build_with(&p.prior, &p.query, &one, &inv, strategy).unwrap();
        assert_eq!((g.num_vertices(), g.num_edges()), (1, 0));
    }
}

#[test]
fn extreme_scales_skip_the_prefilter_but_agree() {
    // huge coordinates and a huge epsilon: the f32 prefilter cannot represent them
    let base = problem(15, Mode::All, 0.05, false, 41);
    let scale = 1e17;
    let prior: Vec<_> = base.prior.iter().map(|p| p * scale).collect();
    let query: Vec<_> = base.query.iter().map(|p| p * scale).collect();
    let inv = distance(0.3 * scale, 0.1 * scale);
    let reference = brute_force(&prior, &query, &base.associations, &inv);
    let (j, s) = both(&prior, &query, &base.associations, &inv);
    assert!(reference.num_edges() > 0);
    assert_eq!(j, reference);
    assert_eq!(s, reference);
    let inv = distance(1e300, 1.0);
    let reference = brute_force(&base.prior, &base.query, &base.associations, &inv);
    let (j, s) = both(&base.prior, &base.query, &base.associations, &inv);
    assert_eq!(j, reference);
    assert_eq!(s, reference);
}

#[test]
fn a_site_much_larger_than_the_query_joins_as_brute_force() {
    // prior rocks over 40 m, the query's within 8 m: most prior pairs are farther apart than
    // any query pair and are skipped without a lookup
    let mut rng = crate::rng::SplitMix64::new(7);
    let prior: Vec<_> = (0..200)
        .map(|_| {
            let z = 0.3 * rng.next_open01();
            Point3::new(40.0 * rng.next_open01(), 40.0 * rng.next_open01(), z)
        })
        .collect();
    // the prior's rocks within an 8 m square, moved
    let query: Vec<_> = prior
        .iter()
        .filter(|p| p.x < 8.0 && p.y < 8.0)
        .map(|p| Point3::new(-p.x + 1.0, p.y + 2.0, p.z + 0.1))
        .collect();
    assert!(query.len() >= 3, "{}", query.len());
    let assoc: Vec<_> = (0..prior.len() as u32)
        .flat_map(|i| (0..query.len() as u32).map(move |j| Association::new(i, j)))
        .collect();
    for inv in [distance(0.1, 0.05), gravity(0.1, 0.05)] {
        let reference = brute_force(&prior, &query, &assoc, &inv);
        let (j, s) = both(&prior, &query, &assoc, &inv);
        assert_eq!(j, reference);
        assert_eq!(s, reference);
    }
}
