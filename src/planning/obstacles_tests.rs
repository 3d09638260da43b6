//! Tests of the obstacle memory.

use super::*;

#[test]
fn reanchoring_moves_each_obstacle_with_its_frame() {
    let mut m = ObstacleMemory::new(&ObstacleConfig::default());
    m.start_frame();
    m.add_rock(Point2::new(1.0, 0.0), 0.2);
    m.start_frame();
    m.add_rock(Point2::new(5.0, 0.0), 0.2);
    // frame 2's pose was 0.3 m off in y; frame 1's was right
    m.reanchor(|frame, p| {
        if frame == 2 {
            Point2::new(p.x, p.y + 0.3)
        } else {
            p
        }
    });
    assert_eq!(m.obstacles()[0].p, Point2::new(1.0, 0.0));
    assert_eq!(m.obstacles()[1].p, Point2::new(5.0, 0.3));
    // the index follows: a detection at the new place merges
    m.start_frame();
    m.add_rock(Point2::new(5.0, 0.31), 0.2);
    assert_eq!(m.obstacles().len(), 2);
}

#[test]
fn merges_and_filters() {
    let mut m = ObstacleMemory::new(&ObstacleConfig::default());
    assert!(!m.add_rock(Point2::new(1.0, 1.0), 0.03));
    assert!(m.add_rock(Point2::new(1.0, 1.0), 0.1));
    assert!(m.add_rock(Point2::new(1.1, 1.0), 0.12));
    assert!(!m.add_rock(Point2::new(f64::NAN, 1.0), 0.2));
    assert_eq!(m.obstacles().len(), 1);
    let o = m.obstacles()[0];
    assert_eq!(o.hits, 2);
    assert!((o.p.x - 1.05).abs() < 1e-12 && (o.radius_m - 0.12).abs() < 1e-12);
    // later detections weigh at least `recent_weight`
    m.add_rock(Point2::new(1.05, 1.0), 0.1);
    m.add_rock(Point2::new(1.3, 1.0), 0.1);
    assert!((m.obstacles()[0].p.x - 1.15).abs() < 1e-12);
    assert!(m.add_point(Point2::new(3.0, 0.0)));
    assert!(m.add_rock(Point2::new(2.0, 1.0), 0.2));
    // the merged rock, the lander point and the (unconfirmed, unrefuted) new rock
    let mut seen = 0;
    m.for_each_near(Point2::new(2.0, 0.5), 1.5, |_| seen += 1);
    assert_eq!(seen, 3);
}

#[test]
fn stale_confirmed_rocks_are_dropped_only_when_asked() {
    let config = ObstacleConfig {
        refute_confirmed_after_views: 2,
        stale_after_frames: 10,
        ..ObstacleConfig::default()
    };
    let rock = Point2::new(2.0, 0.0);
    let look = |m: &mut ObstacleMemory, frames: usize| {
        for _ in 0..frames {
            m.start_frame();
            m.record_view(Pose2::new(0.5, 0.0, 0.0), 0.6, 0.5);
        }
    };
    for (config, kept) in [(config.clone(), false), (ObstacleConfig::default(), true)] {
        let mut m = ObstacleMemory::new(&config);
        m.start_frame();
        m.add_rock(rock, 0.1);
        m.start_frame();
        m.add_rock(rock, 0.1);
        // recently detected: views without it do not count yet
        look(&mut m, 9);
        assert_eq!(count_near(&m, rock), 1);
        assert_eq!(m.obstacles()[0].misses, 0);
        // old and in view twice without a detection: a stale copy, dropped
        look(&mut m, 2);
        assert_eq!(count_near(&m, rock), usize::from(kept));
    }
    // lander points are never dropped
    let mut m = ObstacleMemory::new(&config);
    m.add_point(rock);
    look(&mut m, 30);
    assert_eq!(count_near(&m, rock), 1);
}

fn count_near(m: &ObstacleMemory, p: Point2<f64>) -> usize {
    let mut n = 0;
    m.for_each_near(p, 0.5, |_| n += 1);
    n
}

#[test]
fn unconfirmed_rocks_count_until_refuted_by_views() {
    let mut m = ObstacleMemory::new(&ObstacleConfig {
        refute_after_views: 2,
        ..ObstacleConfig::default()
    });
    let half_fov = 0.6;
    m.start_frame();
    let rock = Point2::new(2.0, 0.0);
    assert!(m.add_rock(rock, 0.1));
    // the frame that detected it does not count against it
    m.record_view(Pose2::new(0.0, 0.0, 0.0), half_fov, 0.5);
    assert_eq!(count_near(&m, rock), 1);
    // beside the camera, too far, or too near: no evidence
    m.start_frame();
    m.record_view(Pose2::new(0.0, 0.0, 1.2), half_fov, 0.5);
    m.record_view(Pose2::new(-1.0, 0.0, 0.0), half_fov, 0.5);
    m.record_view(Pose2::new(1.7, 0.0, 0.0), half_fov, 0.5);
    assert_eq!(m.obstacles()[0].misses, 0);
    // two views straight at it without a detection: refuted
    m.record_view(Pose2::new(0.5, 0.0, 0.0), half_fov, 0.5);
    assert_eq!(count_near(&m, rock), 1);
    m.start_frame();
    m.record_view(Pose2::new(0.5, 0.0, 0.0), half_fov, 0.5);
    assert_eq!(count_near(&m, rock), 0);
    // detected again: unconfirmed again (the refuted detection is gone), until a second
    // detection confirms it for good
    m.start_frame();
    assert!(m.add_rock(rock, 0.1));
    assert_eq!(m.obstacles()[0].hits, 1);
    assert_eq!(count_near(&m, rock), 1);
    m.start_frame();
    assert!(m.add_rock(rock, 0.1));
    for _ in 0..3 {
        m.start_frame();
        m.record_view(Pose2::new(0.5, 0.0, 0.0), half_fov, 0.5);
    }
    assert_eq!(count_near(&m, rock), 1);
    // unconfirmed rocks far from the rover do not count
    m.start_frame();
    let far = Point2::new(-3.0, 0.0);
    assert!(m.add_rock(far, 0.1));
    assert_eq!(count_near(&m, far), 1);
    m.set_rover_position(Point2::new(0.0, 0.0));
    assert_eq!(count_near(&m, far), 0);
    m.set_rover_position(Point2::new(-1.0, 0.0));
    assert_eq!(count_near(&m, far), 1);
    // without refutation, unconfirmed rocks never count
    let mut old = ObstacleMemory::new(&ObstacleConfig {
        refute_after_views: 0,
        ..ObstacleConfig::default()
    });
    old.start_frame();
    assert!(old.add_rock(rock, 0.1));
    assert_eq!(count_near(&old, rock), 0);
    // … and are not refuted: a second detection after a view confirms them
    old.start_frame();
    old.record_view(Pose2::new(0.5, 0.0, 0.0), half_fov, 0.5);
    old.start_frame();
    assert!(old.add_rock(rock, 0.1));
    assert_eq!(count_near(&old, rock), 1);
}

#[test]
fn small_sightings_keep_a_rock_and_its_size_is_a_quantile() {
    let config = ObstacleConfig {
        sighting_radius_fraction: 0.5,
        size_quantile: 0.75,
        ..ObstacleConfig::default()
    };
    let rock = Point2::new(2.0, 0.0);
    let camera = Pose2::new(0.5, 0.0, 0.0);
    // a 0.085 m rock measured large once, then small: the small sightings are detections,
    // not misses, and confirm it
    let mut m = ObstacleMemory::new(&config);
    m.start_frame();
    assert!(m.add_rock(rock, 0.104));
    for r in [0.066, 0.08, 0.09] {
        m.start_frame();
        assert!(m.add_rock(rock, r));
        m.record_view(camera, 0.6, 0.5);
    }
    let o = m.obstacles()[0];
    assert_eq!((o.hits, o.misses, o.sightings), (4, 0, 4));
    // nearest rank 0.75 of [0.066, 0.08, 0.09, 0.104]
    assert!((o.radius_m - 0.09).abs() < 1e-12);
    assert_eq!(count_near(&m, rock), 1);
    // a small detection starts nothing on its own
    m.start_frame();
    assert!(!m.add_rock(Point2::new(-3.0, 0.0), 0.06));
    assert!(!m.add_rock(Point2::new(2.05, 0.0), 0.03));
    assert_eq!(m.obstacles().len(), 1);
    // a small rock measured large once and small since stops counting
    let mut m = ObstacleMemory::new(&config);
    m.start_frame();
    assert!(m.add_rock(rock, 0.07));
    for r in [0.05, 0.055, 0.06] {
        m.start_frame();
        assert!(m.add_rock(rock, r));
    }
    assert_eq!(count_near(&m, rock), 0);
    // without sightings small detections are ignored, and they are misses
    let mut old = ObstacleMemory::new(&ObstacleConfig {
        sighting_radius_fraction: 0.0,
        size_quantile: 1.0,
        ..ObstacleConfig::default()
    });
    old.start_frame();
    assert!(old.add_rock(rock, 0.104));
    old.start_frame();
    assert!(!old.add_rock(rock, 0.06));
    old.record_view(camera, 0.6, 0.5);
    assert_eq!(count_near(&old, rock), 0);
}

#[test]
fn a_prompt_redetection_restores_the_detections() {
    let rock = Point2::new(2.0, 0.0);
    let camera = Pose2::new(0.5, 0.0, 0.0);
    let detect_miss_detect = |window: u64, gap: usize| {
        let mut m = ObstacleMemory::new(&ObstacleConfig {
            redetect_window_frames: window,
            ..ObstacleConfig::default()
        });
        m.start_frame();
        m.add_rock(rock, 0.1);
        for _ in 0..gap {
            m.start_frame();
            m.record_view(camera, 0.6, 0.5);
        }
        assert_eq!(count_near(&m, rock), 0, "refuted by the views");
        m.start_frame();
        m.add_rock(rock, 0.1);
        m.obstacles()[0].hits
    };
    // within the window the earlier detection comes back and confirms the rock
    assert_eq!(detect_miss_detect(5, 1), 2);
    // too late, or without the window: it starts afresh
    assert_eq!(detect_miss_detect(5, 8), 1);
    assert_eq!(detect_miss_detect(0, 1), 1);
}

#[test]
fn a_rock_below_the_image_is_not_missed() {
    let mut m = ObstacleMemory::new(&ObstacleConfig::default());
    m.start_frame();
    // a rock on the ground (centre 0.05 m up) detected once, 2 m ahead of a camera 0.3 m up
    let rock = Point3::new(2.0, 0.0, 0.05);
    assert!(m.add_rock_at(rock, 0.1));
    let camera_at = |x: f64| Isometry3::translation(x, 0.0, 0.3);
    let (half_fov, half_vertical_fov) = (0.61, 0.375);
    // 0.6 m away its centre lies 22° below the axis, below the image (21.5° half field of
    // view): no miss, it stays an obstacle
    m.start_frame();
    m.record_camera_view(&camera_at(1.4), half_fov, half_vertical_fov, 0.5);
    assert_eq!(m.obstacles()[0].misses, 0);
    assert_eq!(count_near(&m, rock.xy()), 1);
    // 1.5 m away it is well inside the image: a miss refutes it
    m.start_frame();
    m.record_camera_view(&camera_at(0.5), half_fov, half_vertical_fov, 0.5);
    assert_eq!(count_near(&m, rock.xy()), 0);
    // without the check, the first view had refuted it already
    let mut flat = ObstacleMemory::new(&ObstacleConfig {
        refute_within_image: false,
        ..ObstacleConfig::default()
    });
    flat.start_frame();
    assert!(flat.add_rock_at(rock, 0.1));
    flat.start_frame();
    flat.record_camera_view(&camera_at(1.4), half_fov, half_vertical_fov, 0.5);
    assert_eq!(count_near(&flat, rock.xy()), 0);
}

#[test]
fn near_detections_merge_only_when_close() {
    let mut m = ObstacleMemory::new(&ObstacleConfig::default());
    m.set_rover_position(Point2::new(0.0, 0.0));
    m.start_frame();
    // two rocks 0.25 m apart, 1 m from the rover: two obstacles that stay where they are
    assert!(m.add_rock(Point2::new(1.0, 0.0), 0.1));
    assert!(m.add_rock(Point2::new(1.0, 0.25), 0.1));
    m.start_frame();
    assert!(m.add_rock(Point2::new(1.0, 0.26), 0.1));
    assert_eq!(m.obstacles().len(), 2);
    assert_eq!(m.obstacles()[0].p, Point2::new(1.0, 0.0));
    // far from the rover the usual radius applies
    m.add_rock(Point2::new(5.0, 0.0), 0.1);
    m.add_rock(Point2::new(5.0, 0.25), 0.1);
    assert_eq!(m.obstacles().len(), 3);
    // without it, the near pair is one obstacle that wanders between the two
    let mut merged = ObstacleMemory::new(&ObstacleConfig {
        near_merge_radius_m: 0.0,
        ..ObstacleConfig::default()
    });
    merged.set_rover_position(Point2::new(0.0, 0.0));
    merged.add_rock(Point2::new(1.0, 0.0), 0.1);
    merged.add_rock(Point2::new(1.0, 0.25), 0.1);
    assert_eq!(merged.obstacles().len(), 1);
    assert!(merged.obstacles()[0].p.y > 0.1);
}

#[test]
fn a_rock_of_another_size_is_another_rock() {
    let mut m = ObstacleMemory::new(&ObstacleConfig::default());
    m.set_rover_position(Point2::new(0.0, 0.0));
    m.start_frame();
    // a small rock 5 m away, twice
    assert!(m.add_rock(Point2::new(5.0, 0.0), 0.07));
    assert!(m.add_rock(Point2::new(5.0, 0.0), 0.07));
    // a detection three times larger 0.2 m from it is a second rock ...
    m.start_frame();
    assert!(m.add_rock(Point2::new(5.0, 0.2), 0.21));
    assert_eq!(m.obstacles().len(), 2);
    assert_eq!(m.obstacles()[0].radius_m, 0.07);
    // ... and one of a similar size is the small rock again
    assert!(m.add_rock(Point2::new(5.0, 0.05), 0.1));
    assert_eq!(m.obstacles().len(), 2);
    assert_eq!(m.obstacles()[0].hits, 3);
    // any size merges when asked
    let mut any = ObstacleMemory::new(&ObstacleConfig {
        merge_size_ratio: 0.0,
        ..ObstacleConfig::default()
    });
    any.add_rock(Point2::new(5.0, 0.0), 0.07);
    any.add_rock(Point2::new(5.0, 0.2), 0.21);
    assert_eq!(any.obstacles().len(), 1);
}

#[test]
fn known_rocks_count_until_replaced_and_are_never_refuted() {
    let mut m = ObstacleMemory::new(&ObstacleConfig::default());
    let kept = m.set_known_rocks(&[
        (Point2::new(2.0, 0.0), 0.1),
        // too small to avoid, and not finite
        (Point2::new(3.0, 0.0), 0.03),
        (Point2::new(f64::NAN, 0.0), 0.2),
    ]);
    assert_eq!(kept, 1);
    assert!((m.max_radius_m() - 0.1).abs() < 1e-12);
    let near = |m: &ObstacleMemory| {
        let mut n = 0;
        m.for_each_near(Point2::new(1.5, 0.0), 1.0, |_| n += 1);
        n
    };
    assert_eq!(near(&m), 1);
    // a camera looking straight at it without detecting it, frame after frame
    for _ in 0..5 {
        m.start_frame();
        m.record_view(Pose2::new(0.5, 0.0, 0.0), 0.6, 0.3);
    }
    assert_eq!(near(&m), 1);
    assert!(m.obstacles().is_empty());
    // a new relocalization places them anew
    m.set_known_rocks(&[(Point2::new(2.0, 0.05), 0.1)]);
    assert_eq!(m.known_rocks().len(), 1);
    assert_eq!(m.known_rocks()[0].p, Point2::new(2.0, 0.05));
    assert_eq!(near(&m), 1);
}
