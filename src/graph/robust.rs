//! Robust kernels applied to the squared Mahalanobis distance `s = rᵀ Ω r` of a factor.
//!
//! A factor's cost is `½ ρ(s)`; with no kernel `ρ(s) = s`. The definitions match GTSAM's
//! `noiseModel::mEstimator` losses evaluated at `e = √s`, so robust costs can be compared
//! with GTSAM number for number. The solver uses iteratively reweighted least squares: the
//! factor's contribution to the normal equations is scaled by the weight `ρ'(s)`.

use serde::{Deserialize, Serialize};

/// Robust kernel of one factor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum RobustKernel {
    /// Plain least squares, `ρ(s) = s`.
    #[default]
    None,
    /// Huber: quadratic up to a Mahalanobis distance `k`, linear beyond.
    Huber {
        /// Threshold on the Mahalanobis distance `√s`.
        k: f64,
    },
    /// Cauchy: `ρ(s) = c² ln(1 + s / c²)`.
    Cauchy {
        /// Scale on the Mahalanobis distance.
        c: f64,
    },
    /// Geman–McClure: `ρ(s) = c² s / (c² + s)`, bounded, so a wrong factor's pull vanishes.
    GemanMcClure {
        /// Scale on the Mahalanobis distance.
        c: f64,
    },
    /// Graduated non-convexity towards truncated least squares: the solver starts from the
    /// Geman–McClure surrogate with scale `μ c²` and a large `μ` (almost convex), shrinks `μ`
    /// to 1 stage by stage, then finishes on the truncated quadratic `ρ(s) = min(s, c²)`,
    /// so factors whose Mahalanobis distance ends beyond `c` are ignored and the others
    /// count fully. This rejects wrong loop closures without a good initial guess.
    Gnc {
        /// Final scale on the Mahalanobis distance.
        c: f64,
    },
}

impl RobustKernel {
    /// Robust loss `ρ(s)` at the squared Mahalanobis distance `s`, with the GNC control
    /// parameter `mu` (ignored by every kernel except [`RobustKernel::Gnc`], for which
    /// `mu ≥ 1` selects the Geman–McClure surrogate of scale `μ c²` and `mu = 0` the final
    /// truncated quadratic).
    pub fn rho(&self, s: f64, mu: f64) -> f64 {
        match *self {
            RobustKernel::None => s,
            RobustKernel::Huber { k } => {
                if s <= k * k {
                    s
                } else {
                    2.0 * k * s.sqrt() - k * k
                }
            }
            RobustKernel::Cauchy { c } => c * c * (s / (c * c)).ln_1p(),
            RobustKernel::GemanMcClure { c } => c * c * s / (c * c + s),
            RobustKernel::Gnc { c } => {
                if mu == 0.0 {
                    s.min(c * c)
                } else {
                    let c2 = mu * c * c;
                    c2 * s / (c2 + s)
                }
            }
        }
    }

    /// IRLS weight `ρ'(s)`.
    pub fn weight(&self, s: f64, mu: f64) -> f64 {
        match *self {
            RobustKernel::None => 1.0,
            RobustKernel::Huber { k } => {
                if s <= k * k {
                    1.0
                } else {
                    k / s.sqrt()
                }
            }
            RobustKernel::Cauchy { c } => 1.0 / (1.0 + s / (c * c)),
            RobustKernel::GemanMcClure { c } => {
                let d = c * c + s;
                c.powi(4) / (d * d)
            }
            RobustKernel::Gnc { c } => {
                if mu == 0.0 {
                    if s <= c * c {
                        1.0
                    } else {
                        0.0
                    }
                } else {
                    let c2 = mu * c * c;
                    let d = c2 + s;
                    c2 * c2 / (d * d)
                }
            }
        }
    }

    /// True for kernels whose parameter must be positive and finite, and it is not.
    pub fn is_invalid(&self) -> bool {
        let p = match *self {
            RobustKernel::None => return false,
            RobustKernel::Huber { k } => k,
            RobustKernel::Cauchy { c }
            | RobustKernel::GemanMcClure { c }
            | RobustKernel::Gnc { c } => c,
        };
        !(p.is_finite() && p > 0.0)
    }

    /// True for [`RobustKernel::Gnc`].
    pub fn is_gnc(&self) -> bool {
        matches!(self, RobustKernel::Gnc { .. })
    }

    /// Scale parameter of the kernel (`k` or `c`), `None` for plain least squares.
    pub fn scale(&self) -> Option<f64> {
        match *self {
            RobustKernel::None => None,
            RobustKernel::Huber { k } => Some(k),
            RobustKernel::Cauchy { c }
            | RobustKernel::GemanMcClure { c }
            | RobustKernel::Gnc { c } => Some(c),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weight_is_derivative_of_rho() {
        let kernels = [
            RobustKernel::None,
            RobustKernel::Huber { k: 1.5 },
            RobustKernel::Cauchy { c: 2.0 },
            RobustKernel::GemanMcClure { c: 3.0 },
            RobustKernel::Gnc { c: 3.0 },
        ];
        for kernel in kernels {
            for &s in &[0.1, 1.0, 2.0, 9.5, 100.0] {
                for &mu in &[1.0, 7.0] {
                    // (μ = 0, the truncated quadratic, is not differentiable at c².)
                    let h = 1e-6 * s;
                    let fd = (kernel.rho(s + h, mu) - kernel.rho(s - h, mu)) / (2.0 * h);
                    let w = kernel.weight(s, mu);
                    assert!((fd - w).abs() < 1e-6, "{kernel:?} s={s}: {fd} vs {w}");
                }
            }
        }
    }

    #[test]
    fn kernels_are_quadratic_near_zero() {
        let s = 1e-8;
        for kernel in [
            RobustKernel::Huber { k: 1.0 },
            RobustKernel::Cauchy { c: 1.0 },
            RobustKernel::GemanMcClure { c: 1.0 },
        ] {
            assert!((kernel.rho(s, 1.0) - s).abs() < 1e-14);
        }
    }

    #[test]
    fn invalid_parameters_are_detected() {
        assert!(RobustKernel::Huber { k: 0.0 }.is_invalid());
        assert!(RobustKernel::Cauchy { c: f64::NAN }.is_invalid());
        assert!(!RobustKernel::None.is_invalid());
    }
}
