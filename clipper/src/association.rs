//! Putative associations and the pairwise rigid-motion invariants that test them.

use nalgebra::Point3;

use crate::ClipperError;

/// A putative association: prior point `prior` is the same landmark as query point `query`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Association {
    /// Index into the prior point list.
    pub prior: u32,
    /// Index into the query point list.
    pub query: u32,
}

impl Association {
    /// Association of prior point `prior` with query point `query`.
    pub fn new(prior: u32, query: u32) -> Self {
        Self { prior, query }
    }
}

/// The invariant that two associations must preserve to be consistent.
///
/// Two associations `(a_i, b_j)` and `(a_k, b_l)` are never consistent when they share a
/// prior point (`i == k`) or a query point (`j == l`): matching is one-to-one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Invariant {
    /// 6-DOF: | |a_i-a_k| - |b_j-b_l| | < epsilon; weight exp(-c^2/(2 sigma^2))
    Distance {
        /// Consistency threshold on the distance residual (same unit as the points).
        epsilon: f64,
        /// Width of the Gaussian edge weight.
        sigma: f64,
    },
    /// 4-DOF gravity aligned (z up): horizontal distance and height difference each preserved
    /// (|rho_a - rho_b| < epsilon, |dz_a - dz_b| < epsilon_z); weight = product of the two Gaussians.
    ///
    /// The height difference is signed: for the pair `(a_i, b_j)`, `(a_k, b_l)` it compares
    /// `z(a_i) - z(a_k)` with `z(b_j) - z(b_l)`.
    GravityAligned {
        /// Threshold on the horizontal-distance residual.
        epsilon: f64,
        /// Gaussian width for the horizontal-distance residual.
        sigma: f64,
        /// Threshold on the height-difference residual.
        epsilon_z: f64,
        /// Gaussian width for the height-difference residual.
        sigma_z: f64,
    },
}

impl Invariant {
    /// Checks that every threshold and width is positive and finite.
    pub fn validate(&self) -> Result<(), ClipperError> {
        let check = |name: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(ClipperError::InvalidParameter { name, value })
            }
        };
        match *self {
            Invariant::Distance { epsilon, sigma } => {
                check("epsilon", epsilon)?;
                check("sigma", sigma)
            }
            Invariant::GravityAligned {
                epsilon,
                sigma,
                epsilon_z,
                sigma_z,
            } => {
                check("epsilon", epsilon)?;
                check("sigma", sigma)?;
                check("epsilon_z", epsilon_z)?;
                check("sigma_z", sigma_z)
            }
        }
    }

    /// True for the 4-DOF gravity-aligned invariant.
    pub fn is_gravity_aligned(&self) -> bool {
        matches!(self, Invariant::GravityAligned { .. })
    }
}

/// The invariant reduced to the numbers the graph builders use.
///
/// Both builders (pair join and pairwise scan) decide edges with exactly these functions on
/// exactly the same `f64` inputs, so they produce bit-identical graphs.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PairTest {
    pub gravity: bool,
    pub epsilon: f64,
    pub epsilon_z: f64,
    pub inv_two_sigma_sq: f64,
    pub inv_two_sigma_z_sq: f64,
}

/// What the invariant measures on one ordered pair of points of the same map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PairMeasure {
    /// Distance (6-DOF) or horizontal distance (4-DOF).
    pub dist: f64,
    /// Signed height difference `z(first) - z(second)` (4-DOF only; 0 otherwise).
    pub dz: f64,
}

impl PairTest {
    pub fn new(invariant: &Invariant) -> Result<Self, ClipperError> {
        invariant.validate()?;
        Ok(match *invariant {
            Invariant::Distance { epsilon, sigma } => Self {
                gravity: false,
                epsilon,
                epsilon_z: f64::INFINITY,
                inv_two_sigma_sq: 1.0 / (2.0 * sigma * sigma),
                inv_two_sigma_z_sq: 0.0,
            },
            Invariant::GravityAligned {
                epsilon,
                sigma,
                epsilon_z,
                sigma_z,
            } => Self {
                gravity: true,
                epsilon,
                epsilon_z,
                inv_two_sigma_sq: 1.0 / (2.0 * sigma * sigma),
                inv_two_sigma_z_sq: 1.0 / (2.0 * sigma_z * sigma_z),
            },
        })
    }

    /// Measures the ordered pair `(p, q)`. Negating the pair (swapping p and q) negates every
    /// difference exactly, so `dist` is bitwise the same and `dz` flips sign exactly.
    #[inline]
    pub fn measure(&self, p: &Point3<f64>, q: &Point3<f64>) -> PairMeasure {
        let dx = p.x - q.x;
        let dy = p.y - q.y;
        let dz = p.z - q.z;
        if self.gravity {
            PairMeasure {
                dist: (dx * dx + dy * dy).sqrt(),
                dz,
            }
        } else {
            PairMeasure {
                dist: (dx * dx + dy * dy + dz * dz).sqrt(),
                dz: 0.0,
            }
        }
    }

    /// Gaussian exponent `x` of the edge weight `exp(-x)` if the two measures are
    /// consistent, else `None`.
    #[inline]
    pub fn exponent(&self, a: PairMeasure, b: PairMeasure) -> Option<f32> {
        let c = (a.dist - b.dist).abs();
        if self.gravity {
            let cz = (a.dz - b.dz).abs();
            (c < self.epsilon && cz < self.epsilon_z).then_some(
                (c * c * self.inv_two_sigma_sq + cz * cz * self.inv_two_sigma_z_sq) as f32,
            )
        } else {
            (c < self.epsilon).then_some((c * c * self.inv_two_sigma_sq) as f32)
        }
    }

    /// Full test of the association pair `(i, j)`, `(k, l)`, canonicalised so that the prior
    /// pair is ordered `i < k` (the orientation the join uses). Returns the weight exponent
    /// (see [`Self::exponent`]); `None` when inconsistent or when the two associations share a
    /// point.
    #[inline]
    pub fn test_associations(
        &self,
        prior: &[Point3<f64>],
        query: &[Point3<f64>],
        u: Association,
        v: Association,
    ) -> Option<f32> {
        if u.prior == v.prior || u.query == v.query {
            return None;
        }
        let (u, v) = if u.prior < v.prior { (u, v) } else { (v, u) };
        let a = self.measure(&prior[u.prior as usize], &prior[v.prior as usize]);
        let b = self.measure(&query[u.query as usize], &query[v.query as usize]);
        self.exponent(a, b)
    }
}

/// `exp(-x)` in single precision for `x >= 0`: exact-enough (relative error ~2e-7), branch
/// free so loops over it vectorise, and strictly positive (x is clamped to 80).
#[inline(always)]
pub(crate) fn exp_neg(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const ROUND: f32 = 12_582_912.0; // 1.5 * 2^23: adding and subtracting rounds to integer
    let t = -(x.clamp(0.0, 80.0)) * LOG2E;
    let k = (t + ROUND) - ROUND;
    let f = t - k; // in [-0.5, 0.5]
                   // 2^f = e^(f ln 2), Taylor to degree 6
    let p = 1.540_353_1e-4_f32;
    let p = p * f + 1.333_355_8e-3;
    let p = p * f + 9.618_129e-3;
    let p = p * f + 5.550_411e-2;
    let p = p * f + 2.402_265e-1;
    let p = p * f + 6.931_472e-1;
    let p = p * f + 1.0;
    let scale = f32::from_bits((((k as i32) + 127) as u32) << 23);
    p * scale
}

/// Replaces every exponent `x` by the weight `exp(-x)`.
pub(crate) fn exponents_to_weights(xs: &mut [f32]) {
    for x in xs.iter_mut() {
        *x = exp_neg(*x);
    }
}

/// Checks points for finiteness and associations for range and duplicates.
pub(crate) fn validate_input(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    associations: &[Association],
) -> Result<(), ClipperError> {
    for (map, points) in [("prior", prior), ("query", query)] {
        if let Some(index) = points
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
        {
            return Err(ClipperError::NonFinitePoint { map, index });
        }
    }
    if associations.len() >= u32::MAX as usize {
        return Err(ClipperError::TooLarge {
            what: "association count",
            size: associations.len(),
            limit: u32::MAX as usize - 1,
        });
    }
    for (index, a) in associations.iter().enumerate() {
        if a.prior as usize >= prior.len() {
            return Err(ClipperError::IndexOutOfRange {
                index,
                map: "prior",
                point: a.prior,
                len: prior.len(),
            });
        }
        if a.query as usize >= query.len() {
            return Err(ClipperError::IndexOutOfRange {
                index,
                map: "query",
                point: a.query,
                len: query.len(),
            });
        }
    }
    // Duplicates: sort indices by (prior, query) and compare neighbours.
    let mut order: Vec<u32> = (0..associations.len() as u32).collect();
    order.sort_unstable_by_key(|&k| (associations[k as usize], k));
    for w in order.windows(2) {
        if associations[w[0] as usize] == associations[w[1] as usize] {
            return Err(ClipperError::DuplicateAssociation {
                index: w[1] as usize,
                first: w[0] as usize,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new(x, y, z)
    }

    #[test]
    fn invalid_parameters_are_rejected() {
        for inv in [
            Invariant::Distance {
                epsilon: 0.0,
                sigma: 1.0,
            },
            Invariant::Distance {
                epsilon: 0.1,
                sigma: f64::NAN,
            },
            Invariant::GravityAligned {
                epsilon: 0.1,
                sigma: 0.1,
                epsilon_z: -1.0,
                sigma_z: 0.1,
            },
        ] {
            assert!(matches!(
                PairTest::new(&inv),
                Err(ClipperError::InvalidParameter { .. })
            ));
        }
    }

    #[test]
    fn distance_weight_is_gaussian() {
        let t = PairTest::new(&Invariant::Distance {
            epsilon: 0.3,
            sigma: 0.1,
        })
        .unwrap();
        let prior = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0)];
        let query = [p(5.0, 5.0, 5.0), p(5.0, 6.1, 5.0)];
        let w = t
            .test_associations(
                &prior,
                &query,
                Association::new(0, 0),
                Association::new(1, 1),
            )
            .unwrap();
        assert!((exp_neg(w) as f64 - (-0.01f64 / 0.02).exp()).abs() < 1e-6);
        // shared prior point: never consistent
        assert!(t
            .test_associations(
                &prior,
                &query,
                Association::new(0, 0),
                Association::new(0, 1)
            )
            .is_none());
    }

    #[test]
    fn gravity_sign_is_respected() {
        let t = PairTest::new(&Invariant::GravityAligned {
            epsilon: 0.1,
            sigma: 0.05,
            epsilon_z: 0.1,
            sigma_z: 0.05,
        })
        .unwrap();
        // prior: point 1 is 1 m above point 0; query: point 0 is 1 m above point 1.
        let prior = [p(0.0, 0.0, 0.0), p(3.0, 0.0, 1.0)];
        let query = [p(0.0, 0.0, 1.0), p(0.0, 3.0, 0.0)];
        // (0->0, 1->1): dz_a = -1, dz_b = +1: inconsistent.
        assert!(t
            .test_associations(
                &prior,
                &query,
                Association::new(0, 0),
                Association::new(1, 1)
            )
            .is_none());
        // (0->1, 1->0): dz_a = -1, dz_b = -1: consistent, in either argument order.
        let w1 = t.test_associations(
            &prior,
            &query,
            Association::new(0, 1),
            Association::new(1, 0),
        );
        let w2 = t.test_associations(
            &prior,
            &query,
            Association::new(1, 0),
            Association::new(0, 1),
        );
        assert_eq!(w1, Some(0.0));
        assert_eq!(w1, w2);
    }

    #[test]
    fn fast_exp_is_accurate_and_positive() {
        for k in 0..2000 {
            let x = k as f32 * 0.05;
            let e = (-(x as f64)).exp();
            let got = exp_neg(x) as f64;
            if x <= 80.0 {
                assert!(
                    (got - e).abs() <= (1e-6 + 1e-7 * x as f64) * e,
                    "x {x}: {got} vs {e}"
                );
            }
            assert!(got > 0.0);
        }
        assert_eq!(exp_neg(0.0), 1.0);
        assert!(exp_neg(f32::INFINITY) > 0.0);
    }

    #[test]
    fn input_validation() {
        let pts = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0)];
        let bad = [p(0.0, f64::NAN, 0.0)];
        let a = [Association::new(0, 1)];
        assert!(validate_input(&pts, &pts, &a).is_ok());
        assert!(matches!(
            validate_input(&bad, &pts, &[]),
            Err(ClipperError::NonFinitePoint {
                map: "prior",
                index: 0
            })
        ));
        assert!(matches!(
            validate_input(&pts, &pts, &[Association::new(0, 2)]),
            Err(ClipperError::IndexOutOfRange { map: "query", .. })
        ));
        assert!(matches!(
            validate_input(
                &pts,
                &pts,
                &[
                    Association::new(1, 1),
                    Association::new(0, 0),
                    Association::new(1, 1)
                ]
            ),
            Err(ClipperError::DuplicateAssociation { index: 2, first: 0 })
        ));
    }
}
