//! Relocalization on generated boulder fields: known transforms, outliers, and layouts
//! that must be refused.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use segloc::eval::transform_error;
use segloc::relocalize::{relocalize, Refusal, RelocalizeConfig};
use segloc::sim::boulder_field::{two_sessions, FieldConfig};
use segloc_maps::{Landmark, ObjectMap};

fn map_of(points: &[Point3<f64>], session: &str) -> ObjectMap {
    let mut map = ObjectMap::new(session, session, true);
    for (k, p) in points.iter().enumerate() {
        map.landmarks
            .push(Landmark::new(k as u32, *p, Matrix3::identity() * 1e-4));
    }
    map
}

#[test]
fn generated_sessions_relocalize_to_the_truth() {
    for seed in 1..=6 {
        let (prior, query, truth) = two_sessions(&FieldConfig::default(), seed);
        let answer = relocalize(&prior, &query, &RelocalizeConfig::default()).unwrap();
        let accepted = match &answer.outcome {
            Ok(accepted) => accepted,
            Err(refusal) => panic!("seed {seed} refused: {refusal}"),
        };
        let (t, r) = transform_error(&accepted.prior_from_query, &truth);
        assert!(t < 0.03 && r < 0.3, "seed {seed}: error {t} m, {r} deg");
        assert!(accepted.information.trace() > 0.0);
    }
}

#[test]
fn sessions_of_different_fields_are_refused() {
    for seed in 1..=4 {
        let (prior, _, _) = two_sessions(&FieldConfig::default(), seed);
        let (_, query, _) = two_sessions(&FieldConfig::default(), seed + 100);
        let answer = relocalize(&prior, &query, &RelocalizeConfig::default()).unwrap();
        assert!(
            !answer.is_accepted(),
            "seed {seed}: accepted a transform between unrelated fields"
        );
        assert!(answer.refusal().is_some());
    }
}

#[test]
fn collinear_landmarks_are_refused() {
    let line: Vec<_> = (0..20)
        .map(|k| Point3::new(0.7 * k as f64, 0.0, 0.1 * ((k * 7) % 3) as f64))
        .collect();
    let truth = Isometry3::new(Vector3::new(2.0, 1.0, 0.0), Vector3::new(0.0, 0.0, 0.8));
    let moved: Vec<_> = line.iter().map(|p| truth.inverse() * p).collect();
    let answer = relocalize(
        &map_of(&line, "a"),
        &map_of(&moved, "b"),
        &RelocalizeConfig::default(),
    )
    .unwrap();
    assert!(!answer.is_accepted());
}

#[test]
fn a_symmetric_grid_is_refused_as_ambiguous() {
    // A square lattice looks the same after 90° turns and one-step shifts.
    let mut grid = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            grid.push(Point3::new(1.5 * i as f64, 1.5 * j as f64, 0.0));
        }
    }
    let truth = Isometry3::new(Vector3::new(1.0, -2.0, 0.0), Vector3::new(0.0, 0.0, 0.3));
    let moved: Vec<_> = grid.iter().map(|p| truth.inverse() * p).collect();
    let answer = relocalize(
        &map_of(&grid, "a"),
        &map_of(&moved, "b"),
        &RelocalizeConfig::default(),
    )
    .unwrap();
    assert!(
        !answer.is_accepted(),
        "accepted {:?}",
        answer.prior_from_query()
    );
    assert!(
        matches!(answer.refusal(), Some(Refusal::Ambiguous { .. })),
        "{:?}",
        answer.refusal()
    );
}

#[test]
fn too_few_landmarks_is_an_input_error() {
    let two = [Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0)];
    let err = relocalize(
        &map_of(&two, "a"),
        &map_of(&two, "b"),
        &RelocalizeConfig::default(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("at least 3"), "{err}");
}

/// A query map tilted by a residual roll and pitch it does not declare (an IMU's error):
/// the default (`auto`) estimates the tilt and lands on the truth; `--dof 4` cannot.
#[test]
fn a_tilted_query_is_aligned_with_its_tilt_by_default() {
    use nalgebra::UnitQuaternion;
    use segloc::align::Dof;
    for (seed, roll_deg, pitch_deg) in [(1, 0.6, -0.4), (2, -0.5, 0.5), (3, 0.3, 0.7)] {
        let (prior, query, truth) = two_sessions(&FieldConfig::default(), seed);
        let tilt = Isometry3::from_parts(
            nalgebra::Translation3::identity(),
            UnitQuaternion::from_euler_angles(
                f64::to_radians(roll_deg),
                f64::to_radians(pitch_deg),
                0.0,
            ),
        );
        // query' = tilt · query, so prior_from_query' = truth · tilt⁻¹
        let tilted = query.transformed(&tilt, "query");
        assert!(tilted.gravity_aligned);
        let truth = truth * tilt.inverse();
        let answer = relocalize(&prior, &tilted, &RelocalizeConfig::default()).unwrap();
        let accepted = match &answer.outcome {
            Ok(accepted) => accepted,
            Err(refusal) => panic!("seed {seed} refused: {refusal}"),
        };
        let (t, r) = transform_error(&accepted.prior_from_query, &truth);
        let best = &answer.diagnostics.hypotheses[0];
        let diag = best.tilt.expect("auto reports its tilt decision");
        assert!(diag.applied, "seed {seed}: {diag:?}");
        assert!(t < 0.02 && r < 0.1, "seed {seed}: error {t} m, {r} deg");
        // the information says the tilt is known, far better than gravity alone (σ 1°)
        let covariance = accepted.information.try_inverse().expect("invertible");
        assert!(covariance[(0, 0)].sqrt().to_degrees() < 0.3, "{covariance}");

        let four = RelocalizeConfig {
            dof: Some(Dof::Four),
            ..RelocalizeConfig::default()
        };
        let answer4 = relocalize(&prior, &tilted, &four).unwrap();
        if let Some(estimate4) = answer4.prior_from_query() {
            let (_, r4) = transform_error(&estimate4, &truth);
            assert!(r4 > 3.0 * r, "seed {seed}: 4-DOF {r4} deg vs auto {r} deg");
        }
    }
}

#[test]
fn a_query_too_small_is_a_refusal_with_its_code() {
    let (prior, query, _) = two_sessions(&FieldConfig::default(), 1);
    let mut tiny = query.clone();
    tiny.landmarks.truncate(2);
    let answer = relocalize(&prior, &tiny, &RelocalizeConfig::default()).unwrap();
    let refusal = answer.refusal().expect("refused");
    assert_eq!(refusal.code(), "too_few_landmarks");
    assert!(refusal.to_string().contains("2 landmarks"), "{refusal}");
    assert_eq!(answer.diagnostics.query_landmarks, 2);
}
