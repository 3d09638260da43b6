//! The localizer's configuration: one section per stage, each with its defaults and its
//! check; printed and loaded as TOML (`segloc localize --print-config`).

use super::boulder_adjustment::BoulderAdjustmentConfig;
use super::lander_factor::LanderFitConfig;
use super::odometry_bias::OdometryBias;
use super::view_bias::ViewBiasConfig;
use crate::field_error::FieldError;
use crate::landmarks::{CentroidEstimator, FusionConfig};
use crate::relocalize::RelocalizeConfig;
use serde::{Deserialize, Serialize};

/// `Ok` when every value is finite and positive, else the first offender.
fn positive(fields: &[(&str, f64)]) -> Result<(), FieldError> {
    match fields.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
        Some((name, v)) => Err(FieldError::new(*name, format!("must be positive, not {v}"))),
        None => Ok(()),
    }
}

/// `Ok` when every value is finite and non-negative, else the first offender.
fn non_negative(fields: &[(&str, f64)]) -> Result<(), FieldError> {
    match fields.iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
        Some((name, v)) => Err(FieldError::new(
            *name,
            format!("must be non-negative, not {v}"),
        )),
        None => Ok(()),
    }
}

/// When the localizer relocalizes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScheduleConfig {
    /// Seconds between relocalization attempts (and loop-closure periods).
    pub relocalize_period_s: f64,
}

impl Default for ScheduleConfig {
    fn default() -> Self {
        Self {
            relocalize_period_s: 10.0,
        }
    }
}

impl ScheduleConfig {
    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), FieldError> {
        if !(self.relocalize_period_s.is_finite() && self.relocalize_period_s >= 1.0) {
            return Err(FieldError::new("relocalize_period_s", "must be at least 1"));
        }
        Ok(())
    }
}

/// The submap of recent detections that is relocalized.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SubmapConfig {
    /// Seconds of recent detections in a submap.
    pub window_s: f64,
    /// A submap stops (going back in time) once the rover turned this much in it, degrees
    /// (the odometry's yaw error grows with the angle turned and bends the submap).
    pub max_turn_deg: f64,
    /// … but spans at least this many seconds.
    pub min_window_s: f64,
    /// The fusion's `pose_sigma_m` (m) of a submap placed by a not yet calibrated odometry
    /// (against a prior map); see `docs/design/fix-gate.md`.
    pub pose_sigma_m: f64,
}

impl Default for SubmapConfig {
    fn default() -> Self {
        Self {
            window_s: 25.0,
            max_turn_deg: 180.0,
            min_window_s: 10.0,
            pose_sigma_m: 0.1,
        }
    }
}

impl SubmapConfig {
    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), FieldError> {
        positive(&[
            ("window_s", self.window_s),
            ("max_turn_deg", self.max_turn_deg),
        ])?;
        non_negative(&[
            ("min_window_s", self.min_window_s),
            ("pose_sigma_m", self.pose_sigma_m),
        ])
    }
}

/// The consistency gate ([`super::fix_gate`]): a relocalization enters the graph only when
/// an independent estimate of the same pose confirms it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GateConfig {
    /// Gate relocalizations and loop closures (`false`: every accepted result enters).
    pub enabled: bool,
    /// Largest horizontal disagreement of two estimates (m), before the odometry's
    /// uncertainty between them is added.
    pub position_m: f64,
    /// Largest yaw disagreement (degrees), before the odometry's uncertainty.
    pub yaw_deg: f64,
    /// The odometry's uncertainty (in σ) added to the tolerance when the first two results
    /// confirm each other (no fix in the graph yet); 3 σ afterwards.
    pub bootstrap_sigmas: f64,
    /// The graph's prediction confirms a result alone only while its tolerance, widened by
    /// the odometry since the last fix, stays within this yaw (degrees); beyond, results
    /// confirm each other pairwise as at the start. See docs/design/fix-gate.md.
    pub max_prediction_yaw_deg: f64,
    /// A relocalization whose information implies a yaw σ above this (degrees) is refused:
    /// its submap cannot tell the yaw to the degree. See docs/design/fix-gate.md.
    pub max_yaw_sigma_deg: f64,
}

impl Default for GateConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            position_m: 0.08,
            yaw_deg: 0.5,
            bootstrap_sigmas: 0.0,
            max_prediction_yaw_deg: 3.0,
            max_yaw_sigma_deg: 0.6,
        }
    }
}

impl GateConfig {
    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), FieldError> {
        positive(&[
            ("position_m", self.position_m),
            ("yaw_deg", self.yaw_deg),
            ("max_prediction_yaw_deg", self.max_prediction_yaw_deg),
            ("max_yaw_sigma_deg", self.max_yaw_sigma_deg),
        ])?;
        non_negative(&[("bootstrap_sigmas", self.bootstrap_sigmas)])
    }
}

/// The odometry's noise model: the weights of its factors in the pose graph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OdometryNoiseConfig {
    /// Translation noise per metre driven, 1 σ.
    pub translation_sigma_m_per_m: f64,
    /// Yaw noise per metre driven, 1 σ, radians.
    pub yaw_sigma_rad_per_m: f64,
    /// Yaw noise per radian turned, 1 σ.
    pub yaw_sigma_per_rad_turned: f64,
    /// A frame's own odometry covariance (`step_cov` in the frames file: the stereo VO's)
    /// is used, times this, in place of the noise model above; 0 ignores it. Default 1.
    pub reported_covariance_scale: f64,
}

impl Default for OdometryNoiseConfig {
    fn default() -> Self {
        Self {
            translation_sigma_m_per_m: 0.008,
            yaw_sigma_rad_per_m: 0.0015,
            yaw_sigma_per_rad_turned: 0.003,
            reported_covariance_scale: 1.0,
        }
    }
}

impl OdometryNoiseConfig {
    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), FieldError> {
        positive(&[
            ("translation_sigma_m_per_m", self.translation_sigma_m_per_m),
            ("yaw_sigma_rad_per_m", self.yaw_sigma_rad_per_m),
            ("yaw_sigma_per_rad_turned", self.yaw_sigma_per_rad_turned),
        ])?;
        non_negative(&[("reported_covariance_scale", self.reported_covariance_scale)])
    }
}

/// Self-calibration of the odometry's biases ([`super::odometry_bias`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CalibrationConfig {
    /// Estimate the odometry's biases (scale, yaw drift per metre, yaw-rate scale) from the
    /// fixes and correct the odometry factors and submaps with them.
    pub enabled: bool,
    /// Alternations of bias estimate and graph solve per calibration.
    pub rounds: usize,
    /// Rounds before the latest that Anderson's acceleration combines to choose the next
    /// bias (0: the plain alternation, each round solving with the latest estimate). Each
    /// plain round recovers only part of the bias left, a small part when fixes are far
    /// apart, so a few rounds stop short of it; see `docs/design/odometry-bias-prior.md`.
    /// Batch solves only: the fast online mode's updates (`online_graph.incremental`) are
    /// steps towards a solution, which Anderson's step cannot take for one.
    pub anderson_depth: usize,
    /// Prior (1 σ) of the scale error, fraction.
    pub prior_scale: f64,
    /// Prior (1 σ) of the yaw drift, radians per metre.
    pub prior_yaw_drift_rad_per_m: f64,
    /// Prior (1 σ) of the yaw-rate scale error, fraction.
    pub prior_yaw_scale: f64,
    /// The biases known before the session (their priors' mean, and the correction the
    /// odometry carries until the fixes say otherwise): zero, or a calibration carried over
    /// from an earlier session of the same odometry (`segloc localize --json` reports each
    /// session's `odometry_bias`); the `prior_*` σ are then that calibration's uncertainty.
    pub known: OdometryBias,
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            rounds: 3,
            anderson_depth: 2,
            // loose enough for the drift of the real-stream benchmark (1 % scale, 1° per
            // 10 m = 0.0017 rad/m) to be learnt from a few fixes
            // (docs/design/odometry-bias-prior.md)
            prior_scale: 0.02,
            prior_yaw_drift_rad_per_m: 0.005,
            prior_yaw_scale: 0.003,
            known: OdometryBias::default(),
        }
    }
}

impl CalibrationConfig {
    /// The priors as [`estimate_bias`](super::odometry_bias::estimate_bias) takes them.
    pub fn prior(&self) -> super::odometry_bias::BiasPrior {
        super::odometry_bias::BiasPrior {
            mean: self.known,
            sigma: OdometryBias {
                scale_error: self.prior_scale,
                yaw_drift_rad_per_m: self.prior_yaw_drift_rad_per_m,
                yaw_scale_error: self.prior_yaw_scale,
            },
        }
    }

    /// Start from a calibration carried over: `known` as the biases' mean and the
    /// odometry's correction from the first frame, `sigma` as the priors' σ.
    pub fn carry(&mut self, known: OdometryBias, sigma: OdometryBias) {
        self.known = known;
        self.prior_scale = sigma.scale_error;
        self.prior_yaw_drift_rad_per_m = sigma.yaw_drift_rad_per_m;
        self.prior_yaw_scale = sigma.yaw_scale_error;
    }

    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), FieldError> {
        if self.anderson_depth > 5 {
            return Err(FieldError::new("anderson_depth", "must be at most 5"));
        }
        positive(&[
            ("prior_scale", self.prior_scale),
            ("prior_yaw_drift_rad_per_m", self.prior_yaw_drift_rad_per_m),
            ("prior_yaw_scale", self.prior_yaw_scale),
        ])?;
        known_bias_in_range(&self.known).map_err(|e| e.within("known"))
    }
}

/// `Ok` when every bias is finite and within its plausible range (±0.5 for the scale errors,
/// ±0.1 rad/m for the yaw drift), else the first offender.
fn known_bias_in_range(bias: &OdometryBias) -> Result<(), FieldError> {
    let fields = [
        ("scale_error", bias.scale_error, 0.5),
        ("yaw_drift_rad_per_m", bias.yaw_drift_rad_per_m, 0.1),
        ("yaw_scale_error", bias.yaw_scale_error, 0.5),
    ];
    match fields
        .iter()
        .find(|(_, v, max)| !(v.is_finite() && v.abs() < *max))
    {
        Some((name, v, max)) => Err(FieldError::new(
            *name,
            format!("must be finite and within ±{max}, not {v}"),
        )),
        None => Ok(()),
    }
}

/// How the trajectory graph is solved while driving ([`super::trajectory`]); the smoothed
/// solve at the end of a session is a batch solve either way.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OnlineGraphConfig {
    /// Bring the estimate to the optimum incrementally (`graph::IncrementalGraph`) after a
    /// fix, a loop closure or a lander factor (milliseconds a fix instead of a batch
    /// re-solve that grows with the drive); false (the default): re-solve in batch, which
    /// keeps the online estimate more accurate on the real streams and in the mission (see
    /// docs/design/incremental-localizer.md).
    pub incremental: bool,
    /// Re-correct every odometry factor with the re-estimated bias (a batch re-solve) only
    /// when the corrections the factors carry differ from the new estimate by more than this:
    /// the change summed over each stretch between two fixes, in units of the σ of that
    /// stretch's summed odometry noise, the worst stretch
    /// (`odometry_bias::stale_correction_sigma`). Below it the new estimate corrects the
    /// steps added from then on. 0 (the default): every time. See
    /// docs/design/incremental-localizer.md.
    pub recalibrate_sigma: f64,
}

impl Default for OnlineGraphConfig {
    fn default() -> Self {
        Self {
            incremental: false,
            recalibrate_sigma: 0.0,
        }
    }
}

impl OnlineGraphConfig {
    /// The fast online mode: incremental updates, the odometry re-corrected only past 0.1 σ.
    pub fn fast() -> Self {
        Self {
            incremental: true,
            recalibrate_sigma: 0.1,
        }
    }
}

impl OnlineGraphConfig {
    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), FieldError> {
        non_negative(&[("recalibrate_sigma", self.recalibrate_sigma)])
    }
}

/// The factors besides odometry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FactorConfig {
    /// Multiplies the relocalizer's information before it enters the graph (< 1: trust the
    /// submap less, since its odometry drifted within the window).
    pub relocalization_information_scale: f64,
    /// Scale (Mahalanobis distance) of the Cauchy kernel on loop-closure, relocalization
    /// and lander factors.
    pub robust_scale: f64,
    /// Gravity factor on every frame's roll and pitch, 1 σ, radians; 0 leaves the tilt to
    /// the odometry alone (it then drifts).
    pub gravity_sigma_rad: f64,
    /// Add an absolute pose factor for every frame whose points measured on the lander fit
    /// its known sides ([`super::lander_factor`]).
    pub lander: bool,
}

impl Default for FactorConfig {
    fn default() -> Self {
        Self {
            relocalization_information_scale: 1.0,
            robust_scale: 3.0,
            gravity_sigma_rad: 0.002,
            lander: true,
        }
    }
}

impl FactorConfig {
    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), FieldError> {
        positive(&[
            (
                "relocalization_information_scale",
                self.relocalization_information_scale,
            ),
            ("robust_scale", self.robust_scale),
        ])?;
        non_negative(&[("gravity_sigma_rad", self.gravity_sigma_rad)])
    }
}

/// Loop closures of a mapping session against its own map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoopClosureConfig {
    /// Relocalize recent submaps against the session's own earlier map.
    pub enabled: bool,
    /// Also close loops while driving (each period), not only at the end of the session.
    pub online: bool,
    /// The earlier map ends this many seconds before the submap starts.
    pub gap_s: f64,
    /// The start map holds the frames before the rover moved this far (m) …
    pub start_map_max_motion_m: f64,
    /// … or turned this much (degrees) from its start.
    pub start_map_max_turn_deg: f64,
}

impl Default for LoopClosureConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            online: false,
            gap_s: 30.0,
            start_map_max_motion_m: 2.0,
            start_map_max_turn_deg: 90.0,
        }
    }
}

impl LoopClosureConfig {
    /// Check the values are in range.
    pub fn validate(&self) -> Result<(), FieldError> {
        non_negative(&[("gap_s", self.gap_s)])?;
        positive(&[
            ("start_map_max_motion_m", self.start_map_max_motion_m),
            ("start_map_max_turn_deg", self.start_map_max_turn_deg),
        ])
    }
}

/// Every parameter of the [`super::Localizer`], one section per stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalizerConfig {
    /// When relocalizations are attempted.
    pub schedule: ScheduleConfig,
    /// The submaps that are relocalized.
    pub submap: SubmapConfig,
    /// The consistency gate of relocalizations and loop closures.
    pub gate: GateConfig,
    /// The odometry's noise model.
    pub odometry: OdometryNoiseConfig,
    /// The odometry's bias calibration.
    pub calibration: CalibrationConfig,
    /// How the trajectory graph is solved while driving.
    pub online_graph: OnlineGraphConfig,
    /// Relocalization, gravity and lander factors.
    pub factors: FactorConfig,
    /// Loop closures of a mapping session.
    pub loop_closures: LoopClosureConfig,
    /// The lander fit.
    pub lander: LanderFitConfig,
    /// Boulder fusion (maps and submaps).
    pub fusion: FusionConfig,
    /// Self-calibration of the detections' viewpoint bias (mapping sessions).
    pub view_bias: ViewBiasConfig,
    /// Relocalization.
    pub relocalize: RelocalizeConfig,
    /// Bundle adjustment of the session's poses and boulders at its end.
    pub boulder_adjustment: BoulderAdjustmentConfig,
}

impl Default for LocalizerConfig {
    fn default() -> Self {
        Self {
            schedule: ScheduleConfig::default(),
            submap: SubmapConfig::default(),
            gate: GateConfig::default(),
            odometry: OdometryNoiseConfig::default(),
            calibration: CalibrationConfig::default(),
            online_graph: OnlineGraphConfig::default(),
            factors: FactorConfig::default(),
            loop_closures: LoopClosureConfig::default(),
            lander: LanderFitConfig::default(),
            // detections carry the rover's position: weight the views by the stereo noise
            fusion: FusionConfig {
                centroid: CentroidEstimator::StereoWeighted,
                ..FusionConfig::default()
            },
            view_bias: ViewBiasConfig::default(),
            // 4-DOF: see `RelocalizeConfig::gravity_aligned_dof`. Fixed tolerances (no
            // covariance-driven widening): with them the mission on seeds 1-20 accepted 1,856
            // loop closures and relocalizations instead of 1,956, 2 of them wrong (seed 13),
            // see docs/design/covariance-tolerances.md
            relocalize: RelocalizeConfig {
                gravity_aligned_dof: crate::align::Dof::Four,
                consistency: crate::relocalize::ConsistencyConfig {
                    sigma_multiplier: 0.0,
                    ..Default::default()
                },
                verification: crate::relocalize::VerificationConfig {
                    rmse_multiplier: 0.0,
                    ..Default::default()
                },
                ..RelocalizeConfig::default()
            },
            boulder_adjustment: BoulderAdjustmentConfig::default(),
        }
    }
}

impl LocalizerConfig {
    /// This configuration for a session against `prior`: a map a localizer made records the
    /// viewpoint-bias size fraction its boulders were fused with (the note
    /// [`super::VIEW_BIAS_NOTE`], which a mapping session calibrates), and the
    /// query's detections must be corrected alike, or every landmark of the two maps sits
    /// a sixth of its size apart along the lines of sight. Without the note, unchanged.
    pub fn calibrated_for(&self, prior: &segloc_maps::ObjectMap) -> Self {
        let fraction = prior
            .notes
            .get(super::session::VIEW_BIAS_NOTE)
            .and_then(|v| v.parse::<f64>().ok())
            .filter(|f| f.is_finite() && (0.0..=0.5).contains(f));
        let mut config = self.clone();
        if let Some(f) = fraction {
            config.fusion.view_bias_size_fraction = f;
        }
        config
    }

    /// Check every section; the error names the TOML path of the field.
    pub fn validate(&self) -> Result<(), FieldError> {
        self.schedule.validate().map_err(|e| e.within("schedule"))?;
        self.submap.validate().map_err(|e| e.within("submap"))?;
        self.gate.validate().map_err(|e| e.within("gate"))?;
        self.odometry.validate().map_err(|e| e.within("odometry"))?;
        self.calibration
            .validate()
            .map_err(|e| e.within("calibration"))?;
        self.online_graph
            .validate()
            .map_err(|e| e.within("online_graph"))?;
        self.factors.validate().map_err(|e| e.within("factors"))?;
        self.loop_closures
            .validate()
            .map_err(|e| e.within("loop_closures"))?;
        self.lander.validate().map_err(|e| e.within("lander"))?;
        self.fusion
            .validate()
            .map_err(|m| FieldError::new("fusion", m.to_string()))?;
        self.boulder_adjustment
            .validate()
            .map_err(|m| FieldError::new("boulder_adjustment", m.to_string()))?;
        let stretch_s = self.view_bias.stretch_s;
        if !(stretch_s.is_finite() && stretch_s >= 1.0) {
            return Err(FieldError::new("view_bias.stretch_s", "must be at least 1"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_round_trips_through_toml_and_is_valid() {
        let c = LocalizerConfig::default();
        c.validate().unwrap();
        let text = toml::to_string(&c).unwrap();
        let back: LocalizerConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn errors_name_the_toml_path() {
        let mut c = LocalizerConfig::default();
        c.gate.yaw_deg = -1.0;
        let e = c.validate().unwrap_err();
        assert_eq!(e.field, "gate.yaw_deg");
        let mut c = LocalizerConfig::default();
        c.schedule.relocalize_period_s = 0.0;
        assert_eq!(
            c.validate().unwrap_err().field,
            "schedule.relocalize_period_s"
        );
    }

    #[test]
    fn a_carried_calibration_loads_from_toml_and_is_checked() {
        let text = "[calibration]\nprior_yaw_drift_rad_per_m = 0.00003\n\
                    [calibration.known]\nscale_error = 0.0099\nyaw_drift_rad_per_m = 0.00174\n";
        let c: LocalizerConfig = toml::from_str(text).unwrap();
        c.validate().unwrap();
        assert_eq!(c.calibration.known.yaw_drift_rad_per_m, 0.00174);
        assert_eq!(c.calibration.known.yaw_scale_error, 0.0);
        assert_eq!(c.calibration.prior().mean, c.calibration.known);
        let mut bad = c.clone();
        bad.calibration.known.scale_error = f64::NAN;
        assert_eq!(
            bad.validate().unwrap_err().field,
            "calibration.known.scale_error"
        );
        let mut bad = c;
        bad.calibration.anderson_depth = 9;
        assert_eq!(
            bad.validate().unwrap_err().field,
            "calibration.anderson_depth"
        );
    }
}
