//! Tests of [`super`]: the evidence grid, repeated hits, the viewpoint bias, validation.
use super::*;
use segloc_maps::TraverseFrame;

#[test]
fn exposure_covers_the_view_wedge_only() {
    let grid = LacGrid::new(100, 0.15);
    let mut e = RockEvidence::new(&grid, &RockEvidenceConfig::default());
    e.add_view(&Point3::new(-5.0, 0.0, 0.0), 0.0, &[]);
    let at = |x: f64, y: f64| {
        let (i, j) = grid.cell_of(x, y).unwrap();
        e.exposure[grid.index(i, j)]
    };
    assert!((at(-3.0, 0.0) - 1.0).abs() < 0.2); // 2 m ahead: weight about 1
    assert!(at(-1.0, 0.0) > 0.0 && at(-1.0, 0.0) < 0.2); // 4 m: (2/4)^3
    assert_eq!(at(-7.0, 0.0), 0.0); // behind
    assert_eq!(at(-4.5, 0.0), 0.0); // too close
    assert_eq!(at(-3.0, 2.0), 0.0); // 45° off the heading
    assert_eq!(at(2.0, 0.0), 0.0); // too far
    assert_eq!(e.views, 1);
}

#[test]
fn repeated_detections_make_a_rock_and_a_single_one_does_not() {
    let grid = LacGrid::new(100, 0.15);
    let mut e = RockEvidence::new(&grid, &RockEvidenceConfig::default());
    let rock = Point3::new(-3.0, 0.02, 0.1);
    let stray = Point3::new(-3.0, 0.5, 0.1);
    for k in 0..10 {
        let dets = if k == 3 {
            vec![rock, stray]
        } else {
            vec![rock]
        };
        e.add_view(&Point3::new(-5.0, 0.0, 0.0), 0.0, &dets);
    }
    let g = e.rock_grid();
    assert_eq!(g.rock_count(), 1);
    let (i, j) = grid.cell_of(rock.x, rock.y).unwrap();
    assert!(g.rock[grid.index(i, j)]);
    assert_eq!(g.filled_count(), 0);
}

#[test]
fn only_repeated_hits_count() {
    let grid = LacGrid::new(100, 0.15);
    let config = RockEvidenceConfig {
        view_bias_m: Some(0.0),
        ..RockEvidenceConfig::default()
    };
    let mut e = RockEvidence::new(&grid, &config);
    let (x, y) = grid.cell_center(60, 50);
    let rover = Point3::new(x - 3.0, y, 0.0);
    // three detections of one face within a few millimetres, two scattered over the cell
    let dets = [
        (0.002, 0.0),
        (-0.001, 0.003),
        (0.0, -0.002),
        (0.05, 0.05),
        (-0.06, 0.04),
    ];
    for (dx, dy) in dets {
        e.add_view(&rover, 0.0, &[Point3::new(x + dx, y + dy, 0.1)]);
    }
    let k = grid.index(60, 50);
    assert_eq!(e.hits[k], 5.0);
    assert_eq!(e.votes(k).len(), 5);
    assert_eq!(e.repeated_hits(k), 3.0);
    assert!((e.rate(k) - 3.0 / e.exposure[k]).abs() < 1e-12);
    // without the repeat test every hit counts
    let all = RockEvidence {
        config: RockEvidenceConfig {
            repeat_radius_m: 0.0,
            ..config.clone()
        },
        ..e.clone()
    };
    assert_eq!(all.repeated_hits(k), 5.0);
    // a cell whose votes all scatter has no repeated pair beyond its median one
    let mut scattered = RockEvidence::new(&grid, &config);
    for (dx, dy) in [(0.05, 0.05), (-0.05, 0.0), (0.0, -0.06)] {
        scattered.add_view(&rover, 0.0, &[Point3::new(x + dx, y + dy, 0.1)]);
    }
    assert_eq!(scattered.repeated_hits(k), 0.0);
    assert!(!scattered.is_rock(k, 2, 0.0));
    assert!(e.is_rock(k, 2, 0.0) && !e.is_rock(k, 4, 0.0));
}

#[test]
fn median_of_odd_and_even_counts() {
    assert_eq!(median([3.0, 1.0, 2.0].into_iter()), 2.0);
    assert_eq!(median([4.0, 1.0, 2.0, 3.0].into_iter()), 2.5);
    assert_eq!(median(std::iter::empty()), 0.0);
}

#[test]
fn the_viewpoint_bias_moves_a_vote_back_along_the_line_of_sight() {
    let grid = LacGrid::new(100, 0.15);
    // a detection 1 cm in front of a cell edge, seen from 3 m along +x
    let (edge_x, _) = grid.cell_center(60, 50);
    let edge_x = edge_x + 0.075;
    let detection = Point3::new(edge_x - 0.01, 0.0, 0.1);
    let rover = Point3::new(edge_x - 3.0, 0.0, 0.0);
    let vote = |bias: Option<f64>| {
        let config = RockEvidenceConfig {
            view_bias_m: bias,
            ..RockEvidenceConfig::default()
        };
        let mut e = RockEvidence::new(&grid, &config);
        e.add_view(&rover, 0.0, &[detection]);
        let k = e.hits.iter().position(|&h| h > 0.0).unwrap();
        (k / grid.cells_per_side, k % grid.cells_per_side)
    };
    assert_eq!(vote(None), (60, 50));
    assert_eq!(vote(Some(0.0)), (60, 50));
    assert_eq!(vote(Some(0.02)), (61, 50)); // pushed 2 cm away from the rover
    assert_eq!(vote(Some(-0.1)), (60, 50));
}

#[test]
fn the_viewpoint_bias_is_estimated_from_boulders_seen_from_both_sides() {
    // two traverses pass a row of boulders, one on each side; every detection lies
    // 1.5 cm in front of its boulder
    let boulders: Vec<Point3<f64>> = (0..20)
        .map(|k| Point3::new(0.5 * k as f64, 0.0, 0.1))
        .collect();
    let pass = |name: &str, side: f64| {
        let frames = (0..100u64)
            .map(|f| {
                let rover = Point3::new(0.1 * f as f64, 3.0 * side, 0.0);
                let seen = boulders
                    .iter()
                    .filter(|b| (b.xy() - rover.xy()).norm() < 5.0)
                    .map(|b| {
                        let u = (rover.xy() - b.xy()).normalize();
                        Point3::new(b.x + 0.015 * u.x, b.y + 0.015 * u.y, b.z)
                    })
                    .collect();
                TraverseFrame {
                    frame: f,
                    rover_position: rover,
                    boulders: seen,
                }
            })
            .collect();
        Traverse {
            name: name.into(),
            frames,
        }
    };
    let traverses = [pass("north", 1.0), pass("south", -1.0)];
    let config = RockEvidenceConfig::default().with_view_bias_from(&traverses);
    let bias = config.view_bias_m.unwrap();
    assert!((bias - 0.015).abs() < 0.002, "bias {bias}");
    let fixed = RockEvidenceConfig {
        view_bias_m: Some(0.0),
        ..RockEvidenceConfig::default()
    };
    assert_eq!(fixed.with_view_bias_from(&traverses).view_bias_m, Some(0.0));
    // one traverse: no boulder is seen by two, nothing to estimate from
    let one = RockEvidenceConfig::default().with_view_bias_from(&traverses[..1]);
    assert_eq!(one.view_bias_m, Some(0.0));
}

#[test]
fn validate_names_the_bad_field() {
    assert!(RockEvidenceConfig::default().validate().is_ok());
    let bad = |c: RockEvidenceConfig| c.validate().unwrap_err();
    let d = RockEvidenceConfig::default;
    assert!(bad(RockEvidenceConfig {
        min_rate: -1.0,
        ..d()
    })
    .contains("min_rate"));
    assert!(bad(RockEvidenceConfig {
        max_range_m: f64::NAN,
        ..d()
    })
    .contains("max_range_m"));
    assert!(bad(RockEvidenceConfig {
        min_range_m: 7.0,
        ..d()
    })
    .contains("min_range_m"));
    let far = RockEvidenceConfig {
        view_bias_m: Some(2.0),
        ..d()
    };
    assert!(bad(far).contains("view_bias_m"));
}
