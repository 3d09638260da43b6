//! Counter-based randomness for the renderer: a 64-bit hash, value noise on an unbounded
//! (or periodic) lattice, and per-pixel Gaussian noise, all free of state so that rows can be
//! drawn in parallel and the same inputs give the same values.

/// SplitMix64's finaliser: a well-mixed 64-bit hash of `x`.
#[inline]
pub fn hash64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// A uniform value in [−1, 1) from a lattice point and a seed.
#[inline]
fn lattice_value(seed: u64, i: i64, j: i64) -> f64 {
    let h = hash64(seed ^ hash64((i as u64).wrapping_mul(0x1_0000_01B3) ^ (j as u64) << 32));
    (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

#[inline]
fn smooth(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

/// Value noise at (x, y) on a lattice of spacing `wavelength`, in [−1, 1]; with
/// `period = Some(p)` the lattice wraps every `p` cells (a tileable texture).
pub fn value_noise(seed: u64, x: f64, y: f64, wavelength: f64, period: Option<i64>) -> f64 {
    let (u, v) = (x / wavelength, y / wavelength);
    let (fu, fv) = (u.floor(), v.floor());
    let (tu, tv) = (smooth(u - fu), smooth(v - fv));
    let wrap = |k: i64| period.map_or(k, |p| k.rem_euclid(p));
    let (i0, j0) = (fu as i64, fv as i64);
    let at = |di: i64, dj: i64| lattice_value(seed, wrap(i0 + di), wrap(j0 + dj));
    let a = at(0, 0) + tu * (at(1, 0) - at(0, 0));
    let b = at(0, 1) + tu * (at(1, 1) - at(0, 1));
    a + tv * (b - a)
}

/// A standard normal draw (approximately: the sum of four 16-bit uniforms, rescaled) for
/// counter `key`.
#[inline]
pub fn gaussian(key: u64) -> f64 {
    let h = hash64(key);
    let s: u64 = (0..4).map(|k| (h >> (16 * k)) & 0xFFFF).sum();
    // mean 2·65535, variance 4·65536²/12
    (s as f64 - 2.0 * 65535.0) / (65536.0 * (4.0f64 / 12.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaussian_has_unit_variance_and_noise_tiles() {
        let n = 100_000;
        let xs: Vec<f64> = (0..n).map(|k| gaussian(k as u64)).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.02 && (var - 1.0).abs() < 0.03,
            "{mean} {var}"
        );
        let a = value_noise(3, 0.3, 0.7, 0.1, Some(10));
        let b = value_noise(3, 1.3, 1.7, 0.1, Some(10));
        assert!((a - b).abs() < 1e-9);
        assert!(a.abs() <= 1.0);
    }
}
