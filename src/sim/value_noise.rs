//! Fractal value noise: a few octaves of smoothly interpolated random lattice values, for
//! the synthetic terrain's rolling relief. Seeded and deterministic.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Lattice size per octave (values wrap around; the terrain is far smaller than one period
/// at the wavelengths used).
const LATTICE: usize = 64;

/// One octave: random values on a square lattice of spacing `wavelength_m`.
#[derive(Clone, Debug)]
struct Octave {
    wavelength_m: f64,
    amplitude_m: f64,
    values: Vec<f64>,
}

/// Sum of octaves of value noise.
///
/// ```
/// use segloc::sim::value_noise::FractalNoise;
/// let n = FractalNoise::new(7, 16.0, 0.5, 4);
/// assert_eq!(n.at(1.0, 2.0), FractalNoise::new(7, 16.0, 0.5, 4).at(1.0, 2.0));
/// assert!(n.at(1.0, 2.0).abs() <= 1.0);
/// ```
#[derive(Clone, Debug)]
pub struct FractalNoise {
    octaves: Vec<Octave>,
}

impl FractalNoise {
    /// `octaves` octaves, the first of `base_wavelength_m` and amplitude `base_amplitude_m`
    /// (values within ±amplitude), each next one half the wavelength and half the amplitude.
    pub fn new(seed: u64, base_wavelength_m: f64, base_amplitude_m: f64, octaves: usize) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let octaves = (0..octaves)
            .map(|k| Octave {
                wavelength_m: base_wavelength_m / (1u64 << k) as f64,
                amplitude_m: base_amplitude_m / (1u64 << k) as f64,
                values: (0..LATTICE * LATTICE)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect(),
            })
            .collect();
        Self { octaves }
    }

    /// Noise value at (x, y), metres.
    pub fn at(&self, x: f64, y: f64) -> f64 {
        self.octaves.iter().map(|o| o.at(x, y)).sum()
    }
}

impl Octave {
    fn at(&self, x: f64, y: f64) -> f64 {
        let (u, v) = (x / self.wavelength_m, y / self.wavelength_m);
        let (fu, fv) = (u.floor(), v.floor());
        let (tu, tv) = (smooth(u - fu), smooth(v - fv));
        let wrap = |k: f64| (k as i64).rem_euclid(LATTICE as i64) as usize;
        let (i0, j0) = (wrap(fu), wrap(fv));
        let (i1, j1) = ((i0 + 1) % LATTICE, (j0 + 1) % LATTICE);
        let val = |i: usize, j: usize| self.values[j * LATTICE + i];
        let a = val(i0, j0) + tu * (val(i1, j0) - val(i0, j0));
        let b = val(i0, j1) + tu * (val(i1, j1) - val(i0, j1));
        self.amplitude_m * (a + tv * (b - a))
    }
}

/// Quintic fade: zero first and second derivatives at 0 and 1.
fn smooth(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn continuous_and_bounded() {
        let n = FractalNoise::new(3, 10.0, 0.4, 4);
        let bound = 0.4 * (1.0 + 0.5 + 0.25 + 0.125);
        let mut prev = n.at(-20.0, 3.0);
        let mut x = -20.0;
        while x < 20.0 {
            x += 0.01;
            let h = n.at(x, 3.0);
            assert!(h.abs() <= bound);
            assert!((h - prev).abs() < 0.01, "jump at {x}");
            prev = h;
        }
    }

    #[test]
    fn seeds_differ() {
        let a = FractalNoise::new(1, 10.0, 0.4, 3);
        let b = FractalNoise::new(2, 10.0, 0.4, 3);
        assert_ne!(a.at(1.3, 2.7), b.at(1.3, 2.7));
    }
}
