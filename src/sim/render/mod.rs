//! Pixels of the synthetic moon: a software renderer of the IPEX front stereo cameras.
//!
//! [`Renderer::render_stereo`] draws the terrain mesh, the rocks, pebbles and the lander of a
//! [`crate::sim::moon::Moon`] with a z-buffer rasterizer ([`raster`]) and a shadow map from a
//! low sun ([`shadow`]), shades them with McEwen's phase-dependent lunar-Lambert reflectance
//! (see [`RenderConfig::phase_dependent_weight`]) and multi-scale albedo textures
//! ([`scene`]), and exposes 8-bit images with shot and read noise ([`sensor`]). Each frame
//! carries its ground truth ([`truth`]): the left camera's pose, per-pixel depth and rock
//! instance, and the visible rocks.
//!
//! Rocks are the moon's angular shapes ([`crate::sim::rock_shape`], the shapes the ray casts
//! of [`crate::sim::world_rays`] and the LAC ground truth use), drawn as geodesic polyhedra
//! pushed onto their surfaces.

pub mod config;
pub mod hash_noise;
pub mod icosphere;
pub mod raster;
pub mod renderer;
pub mod scene;
pub mod scoring;
pub mod sensor;
pub mod shadow;
pub mod terrain_light;
pub mod truth;

pub use config::{RenderConfig, RenderError};
pub use renderer::{
    rover_from_front_left_optical, rover_from_left_optical, RenderedView, Renderer,
};
pub use truth::{StereoFrame, VisibleRock, LANDER_INSTANCE};

#[cfg(test)]
mod renderer_tests;
