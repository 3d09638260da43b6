//! Ray casts into the synthetic moon with parry3d: the terrain as a `HeightField`, rocks as
//! balls, the lander as a box. nalgebra at the interface, parry's glam types inside.

use crate::sim::ipex::LANDER_HALF_EXTENT_M;
use crate::sim::moon::Moon;
use nalgebra::{Point3, Vector3};
use parry3d_f64::math::{Pose, Vector};
use parry3d_f64::query::{Ray, RayCast};
use parry3d_f64::shape::Cuboid;

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayTarget {
    /// The terrain.
    Terrain,
    /// The rock at this index in [`Moon::rocks`].
    Rock(usize),
    /// The lander.
    Lander,
}

/// The first hit along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance from the origin along the (unit) direction, metres.
    pub distance_m: f64,
    /// What was hit.
    pub target: RayTarget,
    /// The hit point, world frame.
    pub point: Point3<f64>,
}

fn v(p: &Vector3<f64>) -> Vector {
    Vector::new(p.x, p.y, p.z)
}

impl Moon {
    /// Distance along the unit direction `dir` from `origin` to the terrain, if hit within
    /// `max_m`.
    pub fn cast_terrain(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        max_m: f64,
    ) -> Option<f64> {
        // height-field local frame: (x, height, y)
        let ray = Ray::new(
            Vector::new(origin.x, origin.z, origin.y),
            Vector::new(dir.x, dir.z, dir.y),
        );
        self.heightfield.cast_local_ray(&ray, max_m, true)
    }

    /// Distance to the lander box along the unit direction, if hit within `max_m`.
    pub fn cast_lander(&self, origin: &Point3<f64>, dir: &Vector3<f64>, max_m: f64) -> Option<f64> {
        let (base, top) = (self.lander_base_m(), self.lander_top_m());
        let cuboid = Cuboid::new(Vector::new(
            LANDER_HALF_EXTENT_M,
            LANDER_HALF_EXTENT_M,
            (top - base) / 2.0,
        ));
        let pose = Pose::from_translation(Vector::new(0.0, 0.0, (top + base) / 2.0));
        cuboid.cast_ray(&pose, &Ray::new(v(&origin.coords), v(dir)), max_m, true)
    }

    /// Distance to rock `index` along the unit direction, if hit within `max_m`.
    pub fn cast_rock(
        &self,
        index: usize,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        max_m: f64,
    ) -> Option<f64> {
        self.rocks().get(index)?.cast_ray(origin, dir, max_m)
    }

    /// The first hit along the unit direction `dir` from `origin` within `max_m`, testing the
    /// terrain, the lander and the rocks listed in `rocks` (indices into [`Moon::rocks`]; pass
    /// the rocks that can lie on the ray, e.g. those culled for a camera's view). With
    /// `rocks = None` every rock near the segment is tested.
    pub fn cast_ray(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        max_m: f64,
        rocks: Option<&[usize]>,
    ) -> Option<RayHit> {
        let mut best: Option<(f64, RayTarget)> = None;
        let consider = |d: Option<f64>, t: RayTarget, best: &mut Option<(f64, RayTarget)>| {
            if let Some(d) = d {
                if best.is_none_or(|(bd, _)| d < bd) {
                    *best = Some((d, t));
                }
            }
        };
        let terrain = self.cast_terrain(origin, dir, max_m);
        consider(terrain, RayTarget::Terrain, &mut best);
        let reach = best.map_or(max_m, |(d, _)| d);
        consider(
            self.cast_lander(origin, dir, reach),
            RayTarget::Lander,
            &mut best,
        );
        let test_rock = |i: usize, best: &mut Option<(f64, RayTarget)>| {
            let reach = best.map_or(max_m, |(d, _)| d);
            consider(
                self.cast_rock(i, origin, dir, reach),
                RayTarget::Rock(i),
                best,
            );
        };
        match rocks {
            Some(list) => list.iter().for_each(|&i| test_rock(i, &mut best)),
            None => {
                let reach = best.map_or(max_m, |(d, _)| d);
                let mid = origin + dir * (reach / 2.0);
                let mut near = Vec::new();
                self.for_each_rock_near(
                    mid.x,
                    mid.y,
                    reach / 2.0 + self.max_rock_radius_m(),
                    |i, _| near.push(i),
                );
                near.into_iter().for_each(|i| test_rock(i, &mut best));
            }
        }
        best.map(|(distance_m, target)| RayHit {
            distance_m,
            target,
            point: origin + dir * distance_m,
        })
    }
}

#[cfg(test)]
mod tests {
    use crate::sim::moon::{Moon, MoonConfig};
    use crate::sim::world_rays::RayTarget;
    use nalgebra::{Point3, Vector3};

    #[test]
    fn vertical_ray_hits_terrain_at_its_height() {
        let m = Moon::generate(
            &MoonConfig {
                rocks: 0,
                ..MoonConfig::default()
            },
            5,
        )
        .unwrap();
        for &(x, y) in &[(3.0, 4.0), (-12.34, 7.77), (15.01, -15.02)] {
            let o = Point3::new(x, y, 5.0);
            let d = m.cast_terrain(&o, &-Vector3::z(), 20.0).unwrap();
            assert!((5.0 - d - m.height_at(x, y)).abs() < 2e-3, "{x},{y}");
        }
        // an oblique ray lands on the surface
        let o = Point3::new(-5.0, -5.0, m.height_at(-5.0, -5.0) + 0.3);
        let dir = Vector3::new(1.0, 0.3, -0.1).normalize();
        let hit = m.cast_ray(&o, &dir, 20.0, None).unwrap();
        assert!((hit.point.z - m.height_at(hit.point.x, hit.point.y)).abs() < 5e-3);
    }

    #[test]
    fn rays_hit_rocks_and_lander() {
        let m = Moon::generate(&MoonConfig::default(), 5).unwrap();
        let (i, rock) = m
            .rocks()
            .iter()
            .enumerate()
            .find(|(_, r)| r.radius_m > 0.15)
            .unwrap();
        let o = rock.center + Vector3::new(0.0, 0.0, 3.0);
        let hit = m.cast_ray(&o, &-Vector3::z(), 10.0, None).unwrap();
        assert_eq!(hit.target, RayTarget::Rock(i));
        let top = rock.center + Vector3::new(0.0, 0.0, 3.0 - hit.distance_m);
        // the hit is on the rock's surface: a little further down is inside it
        let below = rock.cast_ray(&(top - Vector3::z() * 1e-6), &Vector3::z(), 1.0);
        assert_eq!(below, Some(0.0));
        assert!(hit.distance_m >= 3.0 - rock.radius_m - 1e-9);
        let o = Point3::new(-6.0, 0.0, m.lander_base_m() + 1.0);
        let hit = m.cast_ray(&o, &Vector3::x(), 10.0, None).unwrap();
        assert_eq!(hit.target, RayTarget::Lander);
        assert!((hit.distance_m - 4.5).abs() < 1e-9);
    }
}
