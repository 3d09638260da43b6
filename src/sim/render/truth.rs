//! Ground truth of a rendered frame: the stereo pair with the left camera's pose, depth and
//! rock-instance image, and each visible rock's centre, size and visible fraction.

use super::raster::{coverage, ScreenTriangle};
use super::renderer::{rover_from_front_left_optical, RenderedView, Renderer};
use super::scene::{ObjectKind, FIRST_ROCK_OBJECT, LANDER_OBJECT};
use crate::perception::GrayImage;
use nalgebra::{Isometry3, Point3, Translation3};
use serde::Serialize;
use std::collections::HashMap;

/// A rock seen in the left image.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VisibleRock {
    /// Index in the moon's rocks.
    pub id: usize,
    /// Rock centre, world frame, metres.
    pub center_world: [f64; 3],
    /// Rock radius, metres: the mean radius of its footprint (size: the diameter, twice
    /// this).
    pub radius_m: f64,
    /// Pixels of the rock in the left image.
    pub pixels: usize,
    /// Visible pixels over the pixels of its whole silhouette within the image.
    pub visible_fraction: f64,
    /// Mean of the visible surface points, world frame, metres.
    pub visible_center_world: [f64; 3],
}

/// A rendered stereo frame with its ground truth.
#[derive(Clone, Debug)]
pub struct StereoFrame {
    /// Left (reference) image.
    pub left: GrayImage,
    /// Right image.
    pub right: GrayImage,
    /// Pose of the left camera, optical frame (x right, y down, z forward).
    pub world_from_left: Isometry3<f64>,
    /// Depth along the left camera's axis per pixel, metres (0: sky).
    pub depth_m: Vec<f32>,
    /// Rock instance per pixel: 0 nothing, `i + 1` the moon's rock `i`, `u32::MAX` the
    /// lander.
    pub instance: Vec<u32>,
    /// The rocks seen in the left image.
    pub rocks: Vec<VisibleRock>,
    /// Milliseconds to render both views (without the ground truth).
    pub render_ms: f64,
}

/// Instance value of the lander in [`StereoFrame::instance`].
pub const LANDER_INSTANCE: u32 = u32::MAX;

impl Renderer {
    /// Render the front stereo pair of a rover at `world_from_rover`, with the ground truth;
    /// `frame` draws the images' noise.
    pub fn render_stereo(&self, world_from_rover: &Isometry3<f64>, frame: u64) -> StereoFrame {
        self.render_stereo_from(&(world_from_rover * rover_from_front_left_optical()), frame)
    }

    /// Render the stereo pair whose left camera (optical frame) is at `world_from_left`, with
    /// the ground truth; `frame` draws the images' noise.
    pub fn render_stereo_from(&self, world_from_left: &Isometry3<f64>, frame: u64) -> StereoFrame {
        let world_from_left = *world_from_left;
        let (left, right, render_ms) = self.render_stereo_views(&world_from_left, frame);
        let instance = left.object.iter().map(|&o| self.instance_of(o)).collect();
        let rocks = self.visible_rocks(&left, &world_from_left);
        StereoFrame {
            left: left.image,
            right: right.image,
            world_from_left,
            depth_m: left.depth_m,
            instance,
            rocks,
            render_ms,
        }
    }

    /// The two views of the stereo pair whose left camera (optical frame) is at
    /// `world_from_left`, rendered in parallel, without the ground truth; `frame` draws the
    /// images' noise (keys `2·frame` and `2·frame + 1`). Also the milliseconds both took.
    pub fn render_stereo_views(
        &self,
        world_from_left: &Isometry3<f64>,
        frame: u64,
    ) -> (RenderedView, RenderedView, f64) {
        let baseline = self.camera().baseline_m;
        let world_from_right = world_from_left * Translation3::new(baseline, 0.0, 0.0);
        let start = std::time::Instant::now();
        let (left, right) = rayon::join(
            || self.render_view(world_from_left, 2 * frame),
            || self.render_view(&world_from_right, 2 * frame + 1),
        );
        (left, right, start.elapsed().as_secs_f64() * 1e3)
    }

    /// Instance value of a scene object (see [`StereoFrame::instance`]).
    pub fn instance_of(&self, object: u32) -> u32 {
        match self.scene().objects.get(object as usize).map(|o| o.kind) {
            Some(ObjectKind::Rock(i)) => i as u32 + 1,
            Some(ObjectKind::Lander) if object == LANDER_OBJECT => LANDER_INSTANCE,
            _ => 0,
        }
    }

    /// The rocks of a view: pixels, visible surface centre and visible fraction.
    pub fn visible_rocks(
        &self,
        view: &RenderedView,
        world_from_camera: &Isometry3<f64>,
    ) -> Vec<VisibleRock> {
        let (w, h) = (self.camera().width, self.camera().height);
        let mut seen: HashMap<u32, (usize, nalgebra::Vector3<f64>)> = HashMap::new();
        for (idx, &o) in view.object.iter().enumerate() {
            if o == u32::MAX || o < FIRST_ROCK_OBJECT {
                continue;
            }
            if !matches!(self.scene().objects[o as usize].kind, ObjectKind::Rock(_)) {
                continue;
            }
            let (x, y) = ((idx % w) as f64, (idx / w) as f64);
            let p = self.camera().back_project(x, y, view.depth_m[idx] as f64);
            let entry = seen.entry(o).or_insert((0, nalgebra::Vector3::zeros()));
            entry.0 += 1;
            entry.1 += (world_from_camera * p).coords;
        }
        let mut silhouettes: HashMap<u32, Vec<&ScreenTriangle>> = HashMap::new();
        for t in &view.triangles {
            let o = self.scene().triangle_object[t.triangle as usize];
            if seen.contains_key(&o) {
                silhouettes.entry(o).or_default().push(t);
            }
        }
        let mut rocks: Vec<VisibleRock> = seen
            .into_iter()
            .filter_map(|(o, (pixels, sum))| {
                let obj = &self.scene().objects[o as usize];
                let ObjectKind::Rock(id) = obj.kind else {
                    return None;
                };
                let tris = silhouettes.get(&o).map_or(&[][..], |v| &v[..]);
                let whole = coverage(tris, w, h).max(pixels);
                let c = Point3::from(sum / pixels as f64);
                Some(VisibleRock {
                    id,
                    center_world: obj.center,
                    radius_m: obj.size_radius_m,
                    pixels,
                    visible_fraction: pixels as f64 / whole as f64,
                    visible_center_world: [c.x, c.y, c.z],
                })
            })
            .collect();
        rocks.sort_by_key(|r| r.id);
        rocks
    }
}
