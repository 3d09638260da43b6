//! Self-calibration of the visual odometry's systematic errors from the pose graph.
//!
//! Most of the odometry's drift is not random: a per-session scale error (distances come
//! back a percent or so long or short), a yaw drift per metre driven and a yaw-rate scale
//! error (every turn comes back a fraction of a percent too large or too small). Left in the
//! odometry factors these biases bend every submap the same way and pull every stretch
//! between two fixes the same way, which a graph of independent per-step noise cannot
//! explain. Once relocalizations or loop closures tie the trajectory down, the optimised
//! relative motions reveal the biases: this module estimates them by weighted least
//! squares over every odometry step (with a Gaussian prior on each bias, so a session
//! without fixes keeps them at zero), and corrects the measurements with them.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix2, Matrix6, UnitQuaternion, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// The odometry measured between two consecutive frames, with what its biases scale with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdometryStep {
    /// Measured `prev_from_cur`.
    pub measured: Isometry3<f64>,
    /// Distance driven (sum of the measured per-tick translations), metres.
    pub distance_m: f64,
    /// Signed yaw turned (sum of the measured per-tick yaw increments), radians.
    pub turned_rad: f64,
    /// Absolute yaw turned (sum of the absolute per-tick yaw increments), radians.
    pub turned_abs_rad: f64,
    /// The odometry's own covariance of `measured` (right perturbation, rotation then
    /// translation), when the frame reported one.
    pub reported_cov: Option<Matrix6<f64>>,
}

/// The systematic errors of the odometry: measured distance = true × (1 + `scale_error`);
/// measured yaw increment = true + `yaw_drift_rad_per_m` × distance + `yaw_scale_error` ×
/// turned.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OdometryBias {
    /// Fractional scale error of the measured distances.
    pub scale_error: f64,
    /// Yaw error per metre driven, radians per metre.
    pub yaw_drift_rad_per_m: f64,
    /// Fractional error of the measured yaw increments.
    pub yaw_scale_error: f64,
}

/// Gaussian prior of each bias: its mean (zero, or a calibration carried over from an
/// earlier session of the same odometry) and its one σ (the sensor's specification, or the
/// uncertainty of that calibration), bias by bias.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BiasPrior {
    /// The prior's mean.
    pub mean: OdometryBias,
    /// The prior's one σ of each bias.
    pub sigma: OdometryBias,
}

impl OdometryBias {
    /// The biases as a vector (scale error, yaw drift, yaw-rate scale error).
    pub fn to_vector(&self) -> Vector3<f64> {
        Vector3::new(
            self.scale_error,
            self.yaw_drift_rad_per_m,
            self.yaw_scale_error,
        )
    }

    /// The biases of a vector in [`OdometryBias::to_vector`]'s order.
    pub fn from_vector(v: &Vector3<f64>) -> Self {
        Self {
            scale_error: v[0],
            yaw_drift_rad_per_m: v[1],
            yaw_scale_error: v[2],
        }
    }

    /// The step with the biases taken out.
    pub fn correct(&self, step: &OdometryStep) -> Isometry3<f64> {
        let yaw_error =
            self.yaw_drift_rad_per_m * step.distance_m + self.yaw_scale_error * step.turned_rad;
        let rotation = step.measured.rotation
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -yaw_error);
        let translation = step.measured.translation.vector / (1.0 + self.scale_error);
        Isometry3::from_parts(translation.into(), rotation)
    }
}

/// Weights of one step in the estimate: inverse variances of its yaw and of each
/// translation axis (the odometry factor's information).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepWeight {
    /// 1/σ² of the yaw, 1/rad².
    pub yaw: f64,
    /// 1/σ² of each translation axis, 1/m².
    pub translation: f64,
}

/// The maximum-a-posteriori biases given the estimated poses: `steps[i]` is the odometry
/// from `poses[i]` to `poses[i + 1]` (`x_from_rover`), weighted by `weights[i]`; the
/// residual of each step is the difference between the estimated relative motion and the
/// corrected measurement, linear in the biases for small errors. Extra entries of the
/// longer slices are ignored.
pub fn estimate_bias(
    steps: &[OdometryStep],
    poses: &[Isometry3<f64>],
    weights: &[StepWeight],
    prior: &BiasPrior,
) -> OdometryBias {
    let prior_weight = |sigma: f64| {
        if sigma > 0.0 && sigma.is_finite() {
            1.0 / (sigma * sigma)
        } else {
            1e12
        }
    };
    // yaw: −e = b_d·d + b_s·θ, with e the estimated minus the measured yaw increment
    let mut normal = Matrix2::new(
        prior_weight(prior.sigma.yaw_drift_rad_per_m),
        0.0,
        0.0,
        prior_weight(prior.sigma.yaw_scale_error),
    );
    let mut rhs = Vector2::new(
        prior_weight(prior.sigma.yaw_drift_rad_per_m) * prior.mean.yaw_drift_rad_per_m,
        prior_weight(prior.sigma.yaw_scale_error) * prior.mean.yaw_scale_error,
    );
    // translation: estimated ≈ u · measured, u = 1 / (1 + scale error), prior
    // u ~ N(1 / (1 + mean scale error), σ²)
    let u_prior = prior_weight(prior.sigma.scale_error);
    let (mut num, mut den) = (u_prior / (1.0 + prior.mean.scale_error), u_prior);
    for ((step, pair), w) in steps.iter().zip(poses.windows(2)).zip(weights) {
        let estimated = pair[0].inverse() * pair[1];
        let e = (step.measured.rotation.inverse() * estimated.rotation)
            .euler_angles()
            .2;
        let a = Vector2::new(step.distance_m, step.turned_rad);
        normal += w.yaw * a * a.transpose();
        rhs -= w.yaw * e * a;
        let z = step.measured.translation.vector;
        num += w.translation * estimated.translation.vector.dot(&z);
        den += w.translation * z.norm_squared();
    }
    let yaw = normal.try_inverse().map_or_else(
        || Vector2::new(prior.mean.yaw_drift_rad_per_m, prior.mean.yaw_scale_error),
        |n| n * rhs,
    );
    let u = num / den;
    let scale_error = if u > 0.5 && u < 2.0 {
        1.0 / u - 1.0
    } else {
        0.0
    };
    OdometryBias {
        scale_error,
        yaw_drift_rad_per_m: yaw[0],
        yaw_scale_error: yaw[1],
    }
}

/// The next bias of the calibration's alternation (bias estimate, then graph solve) by
/// Anderson's acceleration: `applied[i]` is the bias the trajectory of round `i` was solved
/// with, `estimated[i]` the bias estimated from that trajectory.
///
/// Each round of the plain alternation moves the estimate only part of the way: the odometry
/// factors, corrected with the bias being tried, pull the solved trajectory towards it, so
/// the next estimate recovers only the fixes' share of what is left (on a stream with fixes
/// 10 m apart, a thousandth a round). The map from the applied bias to the estimated one is
/// nearly affine, so the combination of the last `depth` + 1 rounds whose residuals
/// (estimated − applied, in σ of `prior`) cancel best points at its fixed point; with one
/// round it is the plain alternation's next step.
pub fn anderson_step(
    applied: &[OdometryBias],
    estimated: &[OdometryBias],
    prior: &BiasPrior,
    depth: usize,
) -> OdometryBias {
    let n = applied.len().min(estimated.len());
    let Some(last) = n.checked_sub(1) else {
        return OdometryBias::default();
    };
    let m = depth.min(last);
    if m == 0 {
        return estimated[last];
    }
    let sigma = prior
        .sigma
        .to_vector()
        .map(|s| if s > 0.0 && s.is_finite() { s } else { 1.0 });
    let vector = |b: &OdometryBias| b.to_vector().component_div(&sigma);
    let g: Vec<Vector3<f64>> = estimated[..n].iter().map(vector).collect();
    let f: Vec<Vector3<f64>> = applied[..n]
        .iter()
        .zip(&g)
        .map(|(x, g)| g - vector(x))
        .collect();
    let columns =
        |v: &[Vector3<f64>]| DMatrix::from_fn(3, m, |r, c| v[last - c][r] - v[last - c - 1][r]);
    let (delta_f, delta_g) = (columns(&f), columns(&g));
    let rhs = DVector::from_column_slice(f[last].as_slice());
    let mut next = g[last];
    if let Ok(gamma) = delta_f.svd(true, true).solve(&rhs, 1e-12) {
        next -= delta_g * gamma;
    }
    OdometryBias::from_vector(&next.component_mul(&sigma))
}

/// How far the corrections the odometry factors carry (`applied[i]` on `steps[i]`) are from
/// the bias `estimate`, in σ of what the fixes can absorb: a stale correction is
/// systematic, so over a stretch of L steps between two fixes its change adds up to L·δ
/// while the factors' noise adds up to √L·σ. The trajectory is cut into stretches at the
/// frames in `fix_frames` (frame k sits between `steps[k − 1]` and `steps[k]`); on each
/// stretch the summed yaw change and the summed translation change are divided by the root
/// of their summed variances (`weights[i]` are the inverse variances), and the result is the
/// largest root-sum-square of the two over the stretches; 0 when there are no steps.
pub fn stale_correction_sigma(
    steps: &[OdometryStep],
    applied: &[OdometryBias],
    weights: &[StepWeight],
    estimate: &OdometryBias,
    fix_frames: &[usize],
) -> f64 {
    let mut cuts: Vec<usize> = fix_frames
        .iter()
        .copied()
        .filter(|&k| k > 0 && k < steps.len())
        .collect();
    cuts.sort_unstable();
    cuts.dedup();
    cuts.push(steps.len());
    let mut worst: f64 = 0.0;
    let mut start = 0;
    for end in cuts {
        let stretch = start..end;
        start = end;
        let (mut yaw, mut yaw_var, mut translation, mut translation_var) = (0.0, 0.0, 0.0, 0.0);
        for ((step, a), w) in steps[stretch.clone()]
            .iter()
            .zip(&applied[stretch.clone()])
            .zip(&weights[stretch])
        {
            yaw += (estimate.yaw_drift_rad_per_m - a.yaw_drift_rad_per_m) * step.distance_m
                + (estimate.yaw_scale_error - a.yaw_scale_error) * step.turned_rad;
            let scale = 1.0 / (1.0 + estimate.scale_error) - 1.0 / (1.0 + a.scale_error);
            translation += scale * step.measured.translation.vector.norm();
            yaw_var += 1.0 / w.yaw;
            translation_var += 1.0 / w.translation;
        }
        if yaw_var > 0.0 && translation_var > 0.0 {
            let z2 = yaw * yaw / yaw_var + translation * translation / translation_var;
            worst = worst.max(z2.sqrt());
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One σ of each bias.
    fn sigma(scale_error: f64, yaw_drift_rad_per_m: f64, yaw_scale_error: f64) -> OdometryBias {
        OdometryBias {
            scale_error,
            yaw_drift_rad_per_m,
            yaw_scale_error,
        }
    }

    /// Steps of a drive that goes straight, turns on the spot and drives on, measured with
    /// known biases.
    fn drive(bias: &OdometryBias) -> (Vec<OdometryStep>, Vec<Isometry3<f64>>) {
        let mut truth = vec![Isometry3::identity()];
        let mut steps = Vec::new();
        for k in 0..60 {
            let (forward, turn) = match k % 20 {
                0..=9 => (0.3, 0.02),
                10..=14 => (0.0, 0.5),
                _ => (0.25, -0.1),
            };
            let motion = Isometry3::from_parts(
                Vector3::new(forward, 0.0, 0.0).into(),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn),
            );
            let yaw_error = bias.yaw_drift_rad_per_m * forward + bias.yaw_scale_error * turn;
            let measured = Isometry3::from_parts(
                (motion.translation.vector * (1.0 + bias.scale_error)).into(),
                motion.rotation * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_error),
            );
            steps.push(OdometryStep {
                measured,
                distance_m: measured.translation.vector.norm(),
                turned_rad: measured.rotation.euler_angles().2,
                turned_abs_rad: measured.rotation.euler_angles().2.abs(),
                reported_cov: None,
            });
            let last = *truth.last().unwrap();
            truth.push(last * motion);
        }
        (steps, truth)
    }

    #[test]
    fn recovers_the_biases_from_the_true_trajectory() {
        let bias = OdometryBias {
            scale_error: 0.012,
            yaw_drift_rad_per_m: 0.0007,
            yaw_scale_error: -0.004,
        };
        let (steps, truth) = drive(&bias);
        let weights = vec![
            StepWeight {
                yaw: 1e10,
                translation: 1e9,
            };
            steps.len()
        ];
        let prior = BiasPrior {
            mean: OdometryBias::default(),
            sigma: sigma(0.01, 0.0005, 0.003),
        };
        let got = estimate_bias(&steps, &truth, &weights, &prior);
        assert!((got.scale_error - bias.scale_error).abs() < 1e-4, "{got:?}");
        assert!((got.yaw_drift_rad_per_m - bias.yaw_drift_rad_per_m).abs() < 2e-5);
        assert!((got.yaw_scale_error - bias.yaw_scale_error).abs() < 1e-4);
        // corrected steps compose to the truth
        let mut pose = Isometry3::identity();
        for s in &steps {
            pose *= got.correct(s);
        }
        let end = truth.last().unwrap();
        assert!((pose.translation.vector - end.translation.vector).norm() < 0.01);
    }

    #[test]
    fn a_stale_correction_is_measured_over_the_stretches_between_fixes() {
        let (steps, _) = drive(&OdometryBias::default());
        let weights = vec![
            StepWeight {
                yaw: 1e6,
                translation: 1e4,
            };
            steps.len()
        ];
        let applied = vec![OdometryBias::default(); steps.len()];
        let same =
            stale_correction_sigma(&steps, &applied, &weights, &OdometryBias::default(), &[]);
        assert_eq!(same, 0.0);
        // 1 % of scale on steps of 0.25-0.3 m against σ = 1 cm: about a quarter σ a step,
        // systematic, so it grows with the root of the stretch's length
        let scaled = OdometryBias {
            scale_error: 0.01,
            ..OdometryBias::default()
        };
        let whole = stale_correction_sigma(&steps, &applied, &weights, &scaled, &[]);
        let halves = stale_correction_sigma(&steps, &applied, &weights, &scaled, &[30]);
        let step_rms = 0.2; // ≈ the per-step change, in σ
        assert!(
            whole > step_rms * (steps.len() as f64).sqrt() * 0.7,
            "{whole}"
        );
        assert!(
            (halves / whole - 0.5f64.sqrt()).abs() < 0.1,
            "{halves} {whole}"
        );
        // fixes at every frame: back to the per-step change
        let every: Vec<usize> = (0..=steps.len()).collect();
        let single = stale_correction_sigma(&steps, &applied, &weights, &scaled, &every);
        assert!((0.1..0.35).contains(&single), "{single}");
    }

    #[test]
    fn without_evidence_the_prior_keeps_the_biases_at_zero() {
        let (steps, _) = drive(&OdometryBias::default());
        // poses exactly as measured: nothing to explain
        let mut poses = vec![Isometry3::identity()];
        for s in &steps {
            let last = *poses.last().unwrap();
            poses.push(last * s.measured);
        }
        let weights = vec![
            StepWeight {
                yaw: 1e4,
                translation: 1e4,
            };
            steps.len()
        ];
        let prior = BiasPrior {
            mean: OdometryBias::default(),
            sigma: sigma(0.01, 0.0005, 0.003),
        };
        let got = estimate_bias(&steps, &poses, &weights, &prior);
        assert!(got.scale_error.abs() < 1e-9);
        assert!(got.yaw_drift_rad_per_m.abs() < 1e-9);
        assert!(got.yaw_scale_error.abs() < 1e-9);
    }

    #[test]
    fn the_default_priors_let_a_few_noisy_fixes_learn_the_stream_drift() {
        // the drift of `segloc eval stream` (1° per 10 m, 1 %), seen through the noisy
        // relative motions of a graph tied down by a few fixes: weak per-step evidence
        let bias = OdometryBias {
            scale_error: 0.01,
            yaw_drift_rad_per_m: 1f64.to_radians() / 10.0,
            yaw_scale_error: 0.0,
        };
        let (steps, truth) = drive(&bias);
        let weights = vec![
            StepWeight {
                yaw: 1e5,
                translation: 1e4,
            };
            steps.len()
        ];
        let defaults = crate::localizer::config::CalibrationConfig::default();
        let got = estimate_bias(&steps, &truth, &weights, &defaults.prior());
        let old = crate::localizer::config::CalibrationConfig {
            prior_scale: 0.01,
            prior_yaw_drift_rad_per_m: 0.0005,
            ..defaults
        };
        let shrunk = estimate_bias(&steps, &truth, &weights, &old.prior());
        let learnt = got.yaw_drift_rad_per_m / bias.yaw_drift_rad_per_m;
        let learnt_old = shrunk.yaw_drift_rad_per_m / bias.yaw_drift_rad_per_m;
        // the former priors (0.0005 rad/m, 1 %) shrank the same evidence to a tenth
        assert!(learnt > 0.8 && learnt_old < 0.2, "{learnt} {learnt_old}");
        assert!(
            (got.scale_error - bias.scale_error).abs() < 0.002,
            "{got:?}"
        );
    }

    #[test]
    fn a_known_bias_is_the_prior_mean_the_evidence_refines() {
        let bias = OdometryBias {
            scale_error: 0.01,
            yaw_drift_rad_per_m: 0.0017,
            yaw_scale_error: 0.0,
        };
        let (steps, truth) = drive(&bias);
        let none = vec![
            StepWeight {
                yaw: 0.0,
                translation: 0.0,
            };
            steps.len()
        ];
        let carried = BiasPrior {
            mean: OdometryBias {
                yaw_drift_rad_per_m: 0.0015,
                ..bias
            },
            sigma: sigma(0.0002, 0.00003, 0.00002),
        };
        // no evidence: the carried calibration itself
        let got = estimate_bias(&steps, &truth, &none, &carried);
        assert!((got.yaw_drift_rad_per_m - 0.0015).abs() < 1e-12, "{got:?}");
        assert!((got.scale_error - 0.01).abs() < 1e-9, "{got:?}");
        // strong evidence moves it to the truth
        let strong = vec![
            StepWeight {
                yaw: 1e12,
                translation: 1e12,
            };
            steps.len()
        ];
        let got = estimate_bias(&steps, &truth, &strong, &carried);
        // per measured metre, 1 % longer than the true one
        assert!(
            (got.yaw_drift_rad_per_m - 0.0017 / 1.01).abs() < 1e-6,
            "{got:?}"
        );
    }

    #[test]
    fn anderson_finds_the_fixed_point_the_plain_alternation_creeps_towards() {
        // an alternation that recovers 1 % of the bias left a round, the components coupled
        let target = Vector3::new(0.01, 0.0017, -0.0003);
        let prior = BiasPrior {
            mean: OdometryBias::default(),
            sigma: sigma(0.02, 0.005, 0.003),
        };
        let round = |b: &OdometryBias| {
            let x = b.to_vector();
            let step = nalgebra::Matrix3::new(0.01, 0.0, 0.0, 0.001, 0.01, 0.0, 0.0, 0.002, 0.02)
                * (target - x);
            OdometryBias::from_vector(&(x + step))
        };
        let error = |b: &OdometryBias| (b.to_vector() - target).norm();
        let (mut applied, mut estimated) = (Vec::new(), Vec::new());
        let mut plain = OdometryBias::default();
        let mut accelerated = OdometryBias::default();
        for _ in 0..4 {
            plain = round(&plain);
            applied.push(accelerated);
            estimated.push(round(&accelerated));
            accelerated = anderson_step(&applied, &estimated, &prior, 3);
        }
        assert!(error(&plain) > 0.9 * target.norm(), "{plain:?}");
        assert!(
            error(&accelerated) < 1e-9 * target.norm(),
            "{accelerated:?}"
        );
        // depth 0 is the plain alternation
        let one = anderson_step(&applied, &estimated, &prior, 0);
        assert_eq!(one, estimated[3]);
    }
}
