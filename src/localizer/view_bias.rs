//! The mission's self-calibration of the detections' viewpoint bias
//! ([`crate::landmarks::size_bias`]): a boulder's detected centroid sits in front of its
//! centre by a fraction of its size, and the fraction is estimated from the session's own
//! passes — stretches of `stretch_s` seconds, each placed with the poses of the time, as
//! the rover would do online — then used by every fusion that follows: submaps, loop
//! closures, the session's map, session 2 and the LAC rock map.

use super::frame_log::FrameLog;
use crate::landmarks::size_bias::SizeBiasEvidence;
use crate::landmarks::FusionConfig;
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

/// Parameters of the viewpoint-bias calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ViewBiasConfig {
    /// Estimate the size fraction of the bias from session 1's passes (otherwise the
    /// fusion's `view_bias_size_fraction` is used as given).
    pub calibrate: bool,
    /// Length of a stretch (one pass), seconds: short enough that the odometry within it is
    /// accurate to millimetres.
    pub stretch_s: f64,
    /// Fewest boulders seen from several directions before the estimate is used.
    pub min_boulders: usize,
    /// … and largest standard error of the estimated fraction (a session that passes few
    /// boulders close enough to see both sides keeps the fusion's fixed value instead).
    pub max_standard_error: f64,
    /// At the end of session 1, close every loop again with the final estimate (the
    /// closures made before there was an estimate kept the bias).
    pub reprocess: bool,
}

impl Default for ViewBiasConfig {
    fn default() -> Self {
        Self {
            calibrate: true,
            stretch_s: 30.0,
            min_boulders: 20,
            max_standard_error: 0.03,
            reprocess: true,
        }
    }
}

/// The estimate so far.
#[derive(Clone, Debug)]
pub struct ViewBiasCalibration {
    config: ViewBiasConfig,
    evidence: SizeBiasEvidence,
    /// The latest estimate (once there was enough evidence).
    fraction: Option<f64>,
    /// Updates leave the estimate as it is.
    fixed: bool,
}

impl ViewBiasCalibration {
    /// No evidence yet.
    pub fn new(config: &ViewBiasConfig) -> Self {
        Self {
            config: config.clone(),
            evidence: SizeBiasEvidence::default(),
            fraction: None,
            fixed: false,
        }
    }

    /// This calibration with its estimate held at `fraction` (updates change nothing).
    pub fn fixed_at(&self, fraction: f64) -> Self {
        Self {
            fraction: Some(fraction),
            fixed: true,
            ..self.clone()
        }
    }

    /// Estimates the fraction again from every stretch that ended by `now_s` (and began
    /// before the log's last frame), its detections placed with `poses` (one per frame of
    /// `log`), gated by `fusion` and clustered after a correction by the latest estimate:
    /// repeated calls iterate the estimate as the evidence grows.
    pub fn update(
        &mut self,
        log: &FrameLog,
        poses: &[Isometry3<f64>],
        now_s: f64,
        fusion: &FusionConfig,
    ) {
        let stretch_ok = self.config.stretch_s.is_finite() && self.config.stretch_s > 0.0;
        if !self.config.calibrate || !stretch_ok || self.fixed {
            return;
        }
        let stretch_s = self.config.stretch_s;
        let last_s = log.last_t();
        let guess = self.fraction.unwrap_or(0.0);
        let mut evidence = SizeBiasEvidence::default();
        let mut k = 0usize;
        while (k + 1) as f64 * stretch_s <= now_s + 1e-9 && k as f64 * stretch_s <= last_s {
            let first = log.frames.partition_point(|f| f.t < k as f64 * stretch_s);
            let end = log
                .frames
                .partition_point(|f| f.t < (k + 1) as f64 * stretch_s);
            let set = log.detections_with_poses(poses, first..end, "stretch", "session");
            evidence.add(&SizeBiasEvidence::from_detections(
                &set.detections,
                fusion,
                guess,
            ));
            k += 1;
        }
        self.evidence = evidence;
        let precise = evidence
            .fraction_standard_error()
            .is_some_and(|se| se <= self.config.max_standard_error);
        if let (Some(f), true) = (evidence.fraction(self.config.min_boulders), precise) {
            self.fraction = Some(f);
        }
    }

    /// The evidence of the last update.
    pub fn evidence(&self) -> SizeBiasEvidence {
        self.evidence
    }

    /// The estimated fraction, once there is enough evidence and calibration is on.
    pub fn fraction(&self) -> Option<f64> {
        self.fraction.filter(|_| self.config.calibrate)
    }

    /// `base` with the estimated fraction, if any.
    pub fn fusion(&self, base: &FusionConfig) -> FusionConfig {
        FusionConfig {
            view_bias_size_fraction: self.fraction().unwrap_or(base.view_bias_size_fraction),
            ..base.clone()
        }
    }
}
