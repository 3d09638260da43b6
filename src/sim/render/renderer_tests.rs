//! The renderer against exact geometry: depth against the ray casts of
//! [`crate::sim::world_rays`], a rock's instance mask against its shape's ray-cast silhouette, and
//! shadows against shadow rays.

use super::config::RenderConfig;
use super::renderer::{rover_from_front_left_optical, Renderer};
use crate::sim::moon::{Moon, MoonConfig, Rock};
use crate::sim::rock_shape::{RockShape, ShapeRanges};
use crate::sim::rover::terrain_pose;
use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn flat_moon_with_rock(rock: Option<Rock>) -> Moon {
    let config = MoonConfig {
        relief_amplitude_m: 0.0,
        craters: 0,
        rocks: 0,
        ..MoonConfig::default()
    };
    let mut moon = Moon::generate(&config, 4).unwrap();
    moon.set_rocks(rock.into_iter().collect());
    moon
}

fn half_resolution() -> RenderConfig {
    RenderConfig {
        resolution_scale: 0.5,
        pebbles_per_m2: 0.0,
        ..RenderConfig::default()
    }
}

/// World ray (unit) through pixel (x, y) of a camera at `world_from_camera`.
fn pixel_ray(
    r: &Renderer,
    world_from_camera: &nalgebra::Isometry3<f64>,
    x: usize,
    y: usize,
) -> (Vector3<f64>, f64) {
    let p = r.camera().back_project(x as f64, y as f64, 1.0);
    let norm = p.coords.norm();
    (world_from_camera.rotation * (p.coords / norm), 1.0 / norm)
}

#[test]
fn pixel_depth_equals_ray_cast_depth() {
    let moon = Moon::generate(
        &MoonConfig {
            rocks: 0,
            ..MoonConfig::default()
        },
        7,
    )
    .unwrap();
    let r = Renderer::new(&moon, &half_resolution(), 7).unwrap();
    let world_from_rover = terrain_pose(&moon, -9.0, 6.0, -0.4);
    let world_from_camera = world_from_rover * rover_from_front_left_optical();
    let view = r.render_view(&world_from_camera, 0);
    let eye = Point3::from(world_from_camera.translation.vector);
    let (w, h) = (r.camera().width, r.camera().height);
    let mut compared = 0;
    for y in (0..h).step_by(3) {
        for x in (0..w).step_by(3) {
            let depth = view.depth_m[y * w + x] as f64;
            if !(4.0..6.0).contains(&depth) {
                continue;
            }
            let (dir, depth_per_m) = pixel_ray(&r, &world_from_camera, x, y);
            let hit = moon.cast_ray(&eye, &dir, 50.0, None).unwrap();
            let expected = hit.distance_m * depth_per_m;
            assert!(
                (depth - expected).abs() < 1e-3,
                "pixel ({x}, {y}): drawn {depth} m, ray cast {expected} m"
            );
            compared += 1;
        }
    }
    assert!(compared > 200, "{compared} pixels near 5 m");
}

#[test]
fn instance_mask_matches_the_rock_shapes_ray_cast() {
    let center = Point3::new(-8.0, 0.1, 0.12);
    let radius = 0.3;
    let shape = RockShape::draw(&mut ChaCha8Rng::seed_from_u64(3), &ShapeRanges::default());
    let rock = Rock {
        center,
        radius_m: radius,
        shape,
    };
    let moon = flat_moon_with_rock(Some(rock));
    let r = Renderer::new(&moon, &half_resolution(), 1).unwrap();
    let world_from_rover = terrain_pose(&moon, -10.5, 0.0, 0.0);
    let frame = r.render_stereo(&world_from_rover, 0);
    let eye = Point3::from(frame.world_from_left.translation.vector);
    let (w, h) = (r.camera().width, r.camera().height);
    let ground = moon.height_at(center.x, center.y);
    // the exact shape's first hit along each pixel's ray, above the ground
    let mut hit_z = vec![None; w * h];
    for y in 0..h {
        for x in 0..w {
            let (dir, _) = pixel_ray(&r, &frame.world_from_left, x, y);
            hit_z[y * w + x] = rock.cast_ray(&eye, &dir, 100.0).map(|t| (eye + dir * t).z);
        }
    }
    let inside = |x: usize, y: usize| hit_z[y * w + x].is_some_and(|z| z > ground);
    let (mut both, mut either, mut far_off, mut drawn_count, mut silhouette) = (0, 0, 0, 0, 0);
    for y in 2..h - 2 {
        for x in 2..w - 2 {
            let drawn = frame.instance[y * w + x] == 1;
            let exact = inside(x, y);
            drawn_count += usize::from(drawn);
            silhouette += usize::from(hit_z[y * w + x].is_some());
            both += usize::from(exact && drawn);
            either += usize::from(exact || drawn);
            // the polyhedron rounds the shape's edges, and where it meets the ground its
            // facets cut it a little differently: slack of 2 px at an edge, 2 cm at contact
            let at_edge = (y - 2..=y + 2).any(|v| (x - 2..=x + 2).any(|u| inside(u, v) != exact));
            let at_contact = hit_z[y * w + x].is_some_and(|z| (z - ground).abs() < 0.02);
            far_off += usize::from(exact != drawn && !at_edge && !at_contact);
        }
    }
    let iou = both as f64 / either as f64;
    assert!(iou > 0.95, "IoU {iou}");
    assert_eq!(
        far_off, 0,
        "pixels wrong more than 2 px from the silhouette"
    );
    let seen = &frame.rocks[0];
    assert_eq!(seen.pixels, drawn_count);
    // the part below the ground is hidden: visible over the whole shape's silhouette
    let expected = both as f64 / silhouette as f64;
    assert!(
        (seen.visible_fraction - expected).abs() < 0.04,
        "visible fraction {} (exact: {expected})",
        seen.visible_fraction
    );
    // the visible surface centre lies on the camera's side of the rock
    let c = Point3::from(seen.visible_center_world);
    assert!((c - center).norm() < radius && c.x < center.x);
}

#[test]
fn shadows_fall_where_the_shadow_ray_is_blocked() {
    let center = Point3::new(-8.0, 0.4, 0.2);
    let radius = 0.4;
    let moon = flat_moon_with_rock(Some(Rock::sphere(center, radius)));
    let config = RenderConfig {
        sun_elevation_deg: 10.0,
        sun_azimuth_deg: 150.0,
        ..half_resolution()
    };
    let r = Renderer::new(&moon, &config, 1).unwrap();
    let sun = config.sun_direction();
    let world_from_rover = terrain_pose(&moon, -11.0, 0.0, 0.0);
    let world_from_camera = world_from_rover * rover_from_front_left_optical();
    let view = r.render_view(&world_from_camera, 0);
    let (w, h) = (r.camera().width, r.camera().height);
    let (mut agree, mut compared, mut shadowed) = (0, 0, 0);
    for y in 0..h {
        for x in 0..w {
            let idx = y * w + x;
            if view.object[idx] != super::scene::TERRAIN_OBJECT {
                continue;
            }
            let p_cam = r
                .camera()
                .back_project(x as f64, y as f64, view.depth_m[idx] as f64);
            let p = world_from_camera * p_cam;
            let blocked =
                |q: Point3<f64>| moon.cast_rock(0, &(q + sun * 1e-3), &sun, 100.0).is_some();
            // skip the penumbra of the discretisation: points whose neighbours 2 cm away
            // disagree
            let across = Vector3::new(-sun.y, sun.x, 0.0).normalize() * 0.02;
            let b = blocked(p);
            if blocked(p + across) != b || blocked(p - across) != b {
                continue;
            }
            let lit = r.shadow_map().lit(&p, &Vector3::z());
            compared += 1;
            shadowed += usize::from(b);
            agree += usize::from(lit != b);
        }
    }
    assert!(shadowed > 300, "{shadowed} shadowed pixels");
    let fraction = agree as f64 / compared as f64;
    assert!(
        fraction > 0.995,
        "agreement {fraction} over {compared} pixels"
    );
}
