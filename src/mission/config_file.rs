//! Reading a mission configuration from TOML, with a clear refusal of the flat layout that
//! mission files had before the localizer's settings became nested sections.

use super::{MissionConfig, MissionError};

/// The keys of the flat mission layout and where each one lives now (TOML paths).
const MOVED_KEYS: &[(&str, &str)] = &[
    (
        "relocalize_period_s",
        "localizer.schedule.relocalize_period_s",
    ),
    ("submap_window_s", "localizer.submap.window_s"),
    ("submap_max_turn_deg", "localizer.submap.max_turn_deg"),
    ("submap_min_window_s", "localizer.submap.min_window_s"),
    ("lost_submap_pose_sigma_m", "localizer.submap.pose_sigma_m"),
    ("loop_closures", "localizer.loop_closures.enabled"),
    ("online_loop_closures", "localizer.loop_closures.online"),
    ("loop_closure_gap_s", "localizer.loop_closures.gap_s"),
    (
        "start_map_max_motion_m",
        "localizer.loop_closures.start_map_max_motion_m",
    ),
    (
        "start_map_max_turn_deg",
        "localizer.loop_closures.start_map_max_turn_deg",
    ),
    (
        "relocalization_information_scale",
        "localizer.factors.relocalization_information_scale",
    ),
    ("robust_scale", "localizer.factors.robust_scale"),
    ("gravity_sigma_rad", "localizer.factors.gravity_sigma_rad"),
    ("lander_factors", "localizer.factors.lander"),
    (
        "vo_translation_sigma_m_per_m",
        "localizer.odometry.translation_sigma_m_per_m",
    ),
    (
        "vo_yaw_sigma_rad_per_m",
        "localizer.odometry.yaw_sigma_rad_per_m",
    ),
    (
        "vo_yaw_sigma_per_rad_turned",
        "localizer.odometry.yaw_sigma_per_rad_turned",
    ),
    ("calibrate_odometry", "localizer.calibration.enabled"),
    ("calibration_rounds", "localizer.calibration.rounds"),
    ("vo_bias_prior_scale", "localizer.calibration.prior_scale"),
    (
        "vo_bias_prior_yaw_drift_rad_per_m",
        "localizer.calibration.prior_yaw_drift_rad_per_m",
    ),
    (
        "vo_bias_prior_yaw_scale",
        "localizer.calibration.prior_yaw_scale",
    ),
    ("gate_relocalizations", "localizer.gate.enabled"),
    ("gate_position_m", "localizer.gate.position_m"),
    ("gate_yaw_deg", "localizer.gate.yaw_deg"),
    ("gate_bootstrap_sigmas", "localizer.gate.bootstrap_sigmas"),
    ("lander", "localizer.lander"),
    ("fusion", "localizer.fusion"),
    ("view_bias", "localizer.view_bias"),
    ("relocalize", "localizer.relocalize"),
    ("boulder_adjustment", "localizer.boulder_adjustment"),
];

impl MissionConfig {
    /// Parse and validate a mission configuration (the TOML that `segloc config print
    /// --mission` prints; missing fields take their defaults). A file in the flat layout of
    /// earlier versions is refused with the new TOML path of each old key it uses.
    pub fn from_toml(text: &str) -> Result<MissionConfig, MissionError> {
        let table: toml::Table =
            toml::from_str(text).map_err(|e| MissionError::InvalidConfig(e.to_string()))?;
        let moved: Vec<String> = MOVED_KEYS
            .iter()
            .filter(|(old, _)| table.contains_key(*old))
            .map(|(old, new)| format!("`{old}` is now `{new}`"))
            .collect();
        if !moved.is_empty() {
            return Err(MissionError::InvalidConfig(format!(
                "this file uses the flat layout of earlier versions: {} (`segloc config print \
                 --mission` prints the current layout)",
                moved.join(", ")
            )));
        }
        let config: MissionConfig =
            toml::from_str(text).map_err(|e| MissionError::InvalidConfig(e.to_string()))?;
        config.validate()?;
        Ok(config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_printed_defaults_read_back() {
        let text = toml::to_string(&MissionConfig::default()).unwrap();
        assert_eq!(
            MissionConfig::from_toml(&text).unwrap(),
            MissionConfig::default()
        );
    }

    #[test]
    fn a_flat_file_is_refused_naming_the_new_keys() {
        let err = MissionConfig::from_toml("gate_yaw_deg = 0.5\nsubmap_window_s = 20.0\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("`gate_yaw_deg` is now `localizer.gate.yaw_deg`"),
            "{err}"
        );
        assert!(
            err.contains("`submap_window_s` is now `localizer.submap.window_s`"),
            "{err}"
        );
    }

    #[test]
    fn a_bad_value_names_its_toml_path() {
        let err = MissionConfig::from_toml("[localizer.gate]\nmax_yaw_sigma_deg = -1.0\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("localizer.gate.max_yaw_sigma_deg"), "{err}");
    }
}
