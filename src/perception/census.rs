//! Census transform: each pixel becomes a bit string saying which of its neighbours are
//! brighter than it. Matching census strings by Hamming distance is robust to the gain and
//! offset differences between two cameras and to the hard lunar lighting.

use rayon::prelude::*;

use super::GrayImage;

/// The census transform with a `(2r + 1) × (2r + 1)` window (`r ≤ 3`, at most 48 bits).
/// Bit k is set when the k-th neighbour (row-major, centre skipped) is strictly brighter
/// than the centre. Outside the image, coordinates are clamped to the border.
pub fn census_transform(image: &GrayImage, radius: usize) -> Vec<u64> {
    let (w, h) = (image.width, image.height);
    let mut out = vec![0u64; w * h];
    let shifted = vec![0u8; w];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each_with(shifted, |shifted, (y, row)| {
            census_row(image, radius, y, row, shifted)
        });
    out
}

/// The census strings of row `y` into `row` (zeroed); `shifted` is scratch of one row.
/// Neighbour by neighbour over the whole row, so the inner loop vectorises.
fn census_row(image: &GrayImage, radius: usize, y: usize, row: &mut [u64], shifted: &mut [u8]) {
    let r = radius.min(3) as isize;
    let (w, h) = (image.width, image.height);
    let centre = &image.data[y * w..(y + 1) * w];
    for dy in -r..=r {
        let yy = (y as isize + dy).clamp(0, h as isize - 1) as usize;
        let src = &image.data[yy * w..(yy + 1) * w];
        for dx in -r..=r {
            if dy == 0 && dx == 0 {
                continue;
            }
            shift_row(src, dx, shifted);
            for ((o, &n), &c) in row.iter_mut().zip(shifted.iter()).zip(centre) {
                *o = (*o << 1) | u64::from(n > c);
            }
        }
    }
}

/// The census transform as three 16-bit planes per row, the layout the SGM sweeps read:
/// `out[(3 y + k) w + x]` holds neighbours 16k .. 16k + 15 (row-major, centre skipped) of
/// pixel (x, y), neighbour 16k + b at bit b. The same comparisons as [`census_transform`],
/// in another bit order (so Hamming distances are the same); 16 pixels per AVX2 register.
pub fn census_planes_into(image: &GrayImage, radius: usize, out: &mut Vec<u16>) {
    let (w, h) = (image.width, image.height);
    out.clear();
    out.resize(3 * w * h, 0);
    let shifted = vec![0u8; w];
    out.par_chunks_mut((3 * w).max(1))
        .enumerate()
        .for_each_with(shifted, |shifted, (y, rows)| {
            census_planes_row(image, radius, y, rows, shifted)
        });
}

/// The planes of row `y` into `rows` (`3 w`, zeroed); `shifted` is scratch of one row.
fn census_planes_row(
    image: &GrayImage,
    radius: usize,
    y: usize,
    rows: &mut [u16],
    shifted: &mut [u8],
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { census_planes_row_avx2(image, radius, y, rows, shifted) };
    }
    census_planes_row_generic(image, radius, y, rows, shifted)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn census_planes_row_avx2(
    image: &GrayImage,
    radius: usize,
    y: usize,
    rows: &mut [u16],
    shifted: &mut [u8],
) {
    census_planes_row_generic(image, radius, y, rows, shifted)
}

#[inline(always)]
fn census_planes_row_generic(
    image: &GrayImage,
    radius: usize,
    y: usize,
    rows: &mut [u16],
    shifted: &mut [u8],
) {
    let r = radius.min(3) as isize;
    let (w, h) = (image.width, image.height);
    let centre = &image.data[y * w..(y + 1) * w];
    let mut k = 0usize;
    for dy in -r..=r {
        let yy = (y as isize + dy).clamp(0, h as isize - 1) as usize;
        let src = &image.data[yy * w..(yy + 1) * w];
        for dx in -r..=r {
            if dy == 0 && dx == 0 {
                continue;
            }
            shift_row(src, dx, shifted);
            let plane = &mut rows[(k / 16) * w..(k / 16 + 1) * w];
            let bit = (k % 16) as u32;
            for ((o, &n), &c) in plane.iter_mut().zip(shifted.iter()).zip(centre) {
                *o |= u16::from(n > c) << bit;
            }
            k += 1;
        }
    }
}

/// `shifted[x] = src[clamp(x + dx)]`.
#[inline(always)]
fn shift_row(src: &[u8], dx: isize, shifted: &mut [u8]) {
    let w = src.len();
    let k = (dx.unsigned_abs()).min(w);
    if dx >= 0 {
        shifted[..w - k].copy_from_slice(&src[k..]);
        shifted[w - k..].fill(src[w - 1]);
    } else {
        shifted[k..].copy_from_slice(&src[..w - k]);
        shifted[..k].fill(src[0]);
    }
}

/// Number of bits in a census string of the given radius (`(2r + 1)² − 1`).
pub fn census_bits(radius: usize) -> u32 {
    let side = 2 * radius.min(3) as u32 + 1;
    side * side - 1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn census_is_invariant_to_gain_and_offset() {
        let data: Vec<u8> = (0..100).map(|i| ((i * 37) % 101) as u8).collect();
        let a = GrayImage::new(10, 10, data.clone()).unwrap();
        let b = GrayImage::new(10, 10, data.iter().map(|&v| v * 2 + 10).collect()).unwrap();
        assert_eq!(census_transform(&a, 3), census_transform(&b, 3));
    }

    #[test]
    fn bright_right_neighbour_sets_its_bit() {
        let mut image = GrayImage::zeros(3, 3);
        image.data[5] = 9; // (2, 1): right of the centre
        let c = census_transform(&image, 1);
        // row-major without the centre: index 4 of 8 -> bit 3 from the least significant end
        assert_eq!(c[4], 1 << 3);
        assert_eq!(census_bits(1), 8);
        assert_eq!(census_bits(3), 48);
    }

    #[test]
    fn planes_hold_the_same_comparisons() {
        let data: Vec<u8> = (0..35 * 9).map(|i| ((i * 7919) % 251) as u8).collect();
        let image = GrayImage::new(35, 9, data).unwrap();
        for radius in 1..=3 {
            let strings = census_transform(&image, radius);
            let mut planes = Vec::new();
            census_planes_into(&image, radius, &mut planes);
            let bits = census_bits(radius) as usize;
            for (i, &s) in strings.iter().enumerate() {
                let (y, x) = (i / 35, i % 35);
                for k in 0..bits {
                    let from_string = (s >> (bits - 1 - k)) & 1;
                    let from_planes = (planes[(3 * y + k / 16) * 35 + x] >> (k % 16)) & 1;
                    assert_eq!(
                        from_string as u16, from_planes,
                        "radius {radius} pixel {i} bit {k}"
                    );
                }
            }
        }
    }
}
