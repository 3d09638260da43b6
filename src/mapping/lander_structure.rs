//! Detections on the lander's own structure, told apart from rocks.
//!
//! The LAC lander stands at the world origin, and its geometry is given to every team
//! (`ipex_geometry.json`): an octagonal body whose fiducial panels sit 0.69–1.03 m from
//! its axis at 0.4–0.9 m up, and the charging antenna at (0, 1.45) m, 0.5 m up. A boulder
//! segmenter finds some of that structure too: on the 17 LunarLoc traverses, eight cells
//! inside the lander's footprint gather tens to hundreds of detections 0.25–0.7 m above the
//! ground, and none of them is a rock in the ground truth. The rocks that *do* lie under
//! the lander (the ground truth marks some) show up within a few centimetres of the ground.
//!
//! So a detection inside the lander's footprint (a box of half-side
//! [`LanderStructureConfig::half_extent_m`] about the origin) that stands more than
//! [`LanderStructureConfig::max_rock_height_m`] above the ground there is taken for
//! lander structure and does not vote. The ground height at the lander comes from the
//! rover itself: the median of the rover's height minus its body height over every frame
//! driven within [`LanderStructureConfig::ground_margin_m`] of the footprint — no ground
//! truth enters it.

use super::check_numbers;
use crate::field_error::FieldError;
use crate::landmarks::estimate::median;
use segloc_maps::Traverse;
use serde::{Deserialize, Serialize};

/// Parameters of the lander-structure test.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LanderStructureConfig {
    /// Half-side (m) of the lander's footprint, a box about the world origin (0 turns the
    /// test off). The default is the planner's lander box.
    pub half_extent_m: f64,
    /// A detection in the footprint standing more than this (m) above the ground is
    /// lander structure (the lowest, the fiducial panels' lower edge, is about 0.25 m up
    /// as the segmenter sees it; rocks under the lander stay within 0.05 m).
    pub max_rock_height_m: f64,
    /// Height (m) of the rover's reported position above the ground under it (0.11 m for
    /// the IPEX rover in the LunarLoc traverses).
    pub rover_height_m: f64,
    /// Rover frames within this distance (m, per axis) outside the footprint give the
    /// ground height.
    pub ground_margin_m: f64,
    /// Ground height (m, world z) at the lander. Unset (omitted from the TOML),
    /// [`lander_ground_from`] estimates it from the traverses.
    pub ground_z_m: Option<f64>,
}

impl Default for LanderStructureConfig {
    fn default() -> Self {
        Self {
            half_extent_m: 1.5,
            max_rock_height_m: 0.15,
            rover_height_m: 0.11,
            ground_margin_m: 1.5,
            ground_z_m: None,
        }
    }
}

impl LanderStructureConfig {
    /// Check every field: a message naming the first bad one.
    pub fn validate(&self) -> Result<(), FieldError> {
        check_numbers(
            &[
                ("lander.half_extent_m", self.half_extent_m),
                ("lander.rover_height_m", self.rover_height_m),
                ("lander.ground_margin_m", self.ground_margin_m),
            ],
            false,
        )?;
        check_numbers(
            &[("lander.max_rock_height_m", self.max_rock_height_m)],
            true,
        )?;
        if let Some(z) = self.ground_z_m {
            if !z.is_finite() {
                return Err(FieldError::new(
                    "lander.ground_z_m",
                    format!("must be a number, got {z}"),
                ));
            }
        }
        Ok(())
    }

    /// Whether the test is on and has a ground height to work with.
    pub fn is_active(&self) -> bool {
        self.half_extent_m > 0.0 && self.ground_z_m.is_some()
    }

    /// Whether a detection at `p_world` is lander structure (always false while the test
    /// is off or the ground height unknown).
    pub fn is_structure(&self, p_world: &nalgebra::Point3<f64>) -> bool {
        let Some(ground_z) = self.ground_z_m else {
            return false;
        };
        self.half_extent_m > 0.0
            && p_world.x.abs() <= self.half_extent_m
            && p_world.y.abs() <= self.half_extent_m
            && p_world.z - ground_z > self.max_rock_height_m
    }
}

/// The ground height at the lander estimated from the rovers' own heights: the median of
/// the rover height minus `rover_height_m` over the frames within `ground_margin_m` of the
/// footprint, and how many frames that was (`None` when no traverse came that near).
pub fn lander_ground_from(
    traverses: &[Traverse],
    config: &LanderStructureConfig,
) -> Option<(f64, usize)> {
    let reach = config.half_extent_m + config.ground_margin_m;
    let mut z: Vec<f64> = traverses
        .iter()
        .flat_map(|t| &t.frames)
        .map(|f| f.rover_position)
        .filter(|p| p.x.abs() <= reach && p.y.abs() <= reach && p.z.is_finite())
        .map(|p| p.z - config.rover_height_m)
        .collect();
    if z.is_empty() {
        return None;
    }
    Some((median(&mut z), z.len()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;
    use segloc_maps::TraverseFrame;

    fn traverse(positions: &[[f64; 3]]) -> Traverse {
        Traverse {
            name: "t".into(),
            frames: positions
                .iter()
                .enumerate()
                .map(|(k, p)| TraverseFrame {
                    frame: k as u64,
                    rover_position: Point3::new(p[0], p[1], p[2]),
                    boulders: Vec::new(),
                })
                .collect(),
        }
    }

    #[test]
    fn ground_is_the_median_rover_height_near_the_lander() {
        let config = LanderStructureConfig::default();
        // three frames within 3 m of the origin (per axis), one far away
        let t = traverse(&[
            [2.5, 0.0, 1.51],
            [0.0, -2.9, 1.50],
            [-2.0, 2.0, 1.60],
            [9.0, 0.0, 3.0],
        ]);
        let (z, n) = lander_ground_from(&[t], &config).unwrap();
        assert_eq!(n, 3);
        assert!((z - 1.40).abs() < 1e-12, "{z}");
        let far = traverse(&[[9.0, 0.0, 3.0]]);
        assert!(lander_ground_from(&[far], &config).is_none());
    }

    #[test]
    fn tall_detections_in_the_footprint_are_structure() {
        let config = LanderStructureConfig {
            ground_z_m: Some(1.4),
            ..LanderStructureConfig::default()
        };
        assert!(config.is_active());
        // the charging antenna, 0.45 m up
        assert!(config.is_structure(&Point3::new(0.0, 1.45, 1.85)));
        // a rock under the lander, 4 cm up
        assert!(!config.is_structure(&Point3::new(0.07, -0.8, 1.44)));
        // a tall rock outside the footprint
        assert!(!config.is_structure(&Point3::new(3.4, 9.6, 2.0)));
        // off, or without a ground height
        let off = LanderStructureConfig {
            half_extent_m: 0.0,
            ..config.clone()
        };
        assert!(!off.is_structure(&Point3::new(0.0, 1.45, 1.85)));
        assert!(!LanderStructureConfig::default().is_structure(&Point3::new(0.0, 1.45, 1.85)));
    }

    #[test]
    fn validate_names_the_field() {
        let bad = LanderStructureConfig {
            max_rock_height_m: 0.0,
            ..LanderStructureConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("lander.max_rock_height_m"));
        let bad = LanderStructureConfig {
            ground_z_m: Some(f64::NAN),
            ..LanderStructureConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("lander.ground_z_m"));
        assert!(LanderStructureConfig::default().validate().is_ok());
    }
}
