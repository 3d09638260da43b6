//! 8-bit grayscale images: PNG input/output with strict checks, and 2 × 2 box reduction.

use std::io::Cursor;
use std::path::Path;

use super::PerceptionError;

/// An 8-bit grayscale image, row-major, `data[y * width + x]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GrayImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixel values, row-major.
    pub data: Vec<u8>,
}

impl GrayImage {
    /// An image from its pixels; `None` if `data.len() != width * height`.
    pub fn new(width: usize, height: usize, data: Vec<u8>) -> Option<Self> {
        (data.len() == width * height).then_some(GrayImage {
            width,
            height,
            data,
        })
    }

    /// A black image.
    pub fn zeros(width: usize, height: usize) -> Self {
        GrayImage {
            width,
            height,
            data: vec![0; width * height],
        }
    }

    /// The pixel at column `x`, row `y` (panics out of range, like slice indexing).
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> u8 {
        self.data[y * self.width + x]
    }

    /// The image at half resolution: each output pixel is the rounded mean of a 2 × 2 block
    /// (an odd last row or column is dropped). Output pixel `(i, j)` is centred on input
    /// coordinates `(2i + 0.5, 2j + 0.5)`.
    pub fn downsample2(&self) -> GrayImage {
        let (w, h) = (self.width / 2, self.height / 2);
        let mut data = vec![0u8; w * h];
        for (y, row) in data.chunks_exact_mut(w.max(1)).enumerate().take(h) {
            let a = &self.data[2 * y * self.width..];
            let b = &self.data[(2 * y + 1) * self.width..];
            for (x, out) in row.iter_mut().enumerate() {
                let s =
                    a[2 * x] as u16 + a[2 * x + 1] as u16 + b[2 * x] as u16 + b[2 * x + 1] as u16;
                *out = ((s + 2) / 4) as u8;
            }
        }
        GrayImage {
            width: w,
            height: h,
            data,
        }
    }

    /// The image reduced by `2^levels` (see [`GrayImage::downsample2`]).
    pub fn reduced(&self, levels: u32) -> GrayImage {
        let mut image = self.clone();
        for _ in 0..levels {
            image = image.downsample2();
        }
        image
    }
}

/// Read an 8-bit grayscale PNG. Any other pixel type (16-bit, colour, alpha) is an error
/// naming the file and the type found, as is an empty image.
pub fn read_gray_png(path: &Path) -> Result<GrayImage, PerceptionError> {
    let bytes = std::fs::read(path).map_err(|e| PerceptionError::io(path, e))?;
    decode_gray_png(&bytes, path)
}

/// Decode an 8-bit grayscale PNG from memory; `path` names it in errors.
pub fn decode_gray_png(bytes: &[u8], path: &Path) -> Result<GrayImage, PerceptionError> {
    let format_error = |e: image::ImageError| PerceptionError::ImageFormat {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let decoded = image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
        .map_err(format_error)?;
    let image::DynamicImage::ImageLuma8(buffer) = decoded else {
        return Err(PerceptionError::PixelType {
            path: path.to_path_buf(),
            found: format!("{:?}", decoded.color()),
        });
    };
    let (width, height) = (buffer.width() as usize, buffer.height() as usize);
    if width == 0 || height == 0 {
        return Err(PerceptionError::ImageSize {
            path: path.to_path_buf(),
            message: "the image is empty".into(),
        });
    }
    Ok(GrayImage {
        width,
        height,
        data: buffer.into_raw(),
    })
}

/// Encode an 8-bit grayscale image as PNG bytes.
pub fn encode_gray_png(image: &GrayImage) -> Result<Vec<u8>, PerceptionError> {
    encode_png(
        &image.data,
        image.width,
        image.height,
        image::ExtendedColorType::L8,
    )
}

/// Encode 8-bit RGB pixels (`3 * width * height` bytes) as PNG bytes.
pub fn encode_rgb_png(rgb: &[u8], width: usize, height: usize) -> Result<Vec<u8>, PerceptionError> {
    encode_png(rgb, width, height, image::ExtendedColorType::Rgb8)
}

fn encode_png(
    pixels: &[u8],
    width: usize,
    height: usize,
    color: image::ExtendedColorType,
) -> Result<Vec<u8>, PerceptionError> {
    use image::ImageEncoder as _;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(Cursor::new(&mut out))
        .write_image(pixels, width as u32, height as u32, color)
        .map_err(|e| PerceptionError::ImageFormat {
            path: "<memory>".into(),
            message: e.to_string(),
        })?;
    Ok(out)
}

/// Write an 8-bit grayscale PNG.
pub fn write_gray_png(image: &GrayImage, path: &Path) -> Result<(), PerceptionError> {
    let bytes = encode_gray_png(image)?;
    std::fs::write(path, bytes).map_err(|e| PerceptionError::io(path, e))
}

/// The 4-connected neighbours of pixel `i` (row-major index) in a `w` × `h` image.
pub(crate) fn neighbours4(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (i % w, i / w);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < w).then(|| i + 1),
        (y > 0).then(|| i - w),
        (y + 1 < h).then(|| i + w),
    ]
    .into_iter()
    .flatten()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip_is_exact() {
        let data: Vec<u8> = (0..6 * 4).map(|i| (i * 11) as u8).collect();
        let image = GrayImage::new(6, 4, data).unwrap();
        let bytes = encode_gray_png(&image).unwrap();
        let back = decode_gray_png(&bytes, Path::new("x.png")).unwrap();
        assert_eq!(back, image);
    }

    #[test]
    fn colour_png_is_refused_with_its_type() {
        let bytes = encode_rgb_png(&[0u8; 3 * 4], 2, 2).unwrap();
        let err = decode_gray_png(&bytes, Path::new("c.png")).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("c.png") && text.contains("Rgb8"), "{text}");
    }

    #[test]
    fn garbage_is_a_format_error() {
        let err = decode_gray_png(b"not a png", Path::new("g.png")).unwrap_err();
        assert!(matches!(err, PerceptionError::ImageFormat { .. }));
    }

    #[test]
    fn downsample_averages_blocks() {
        let image = GrayImage::new(4, 2, vec![0, 2, 10, 10, 2, 4, 10, 11]).unwrap();
        let half = image.downsample2();
        assert_eq!((half.width, half.height), (2, 1));
        assert_eq!(half.data, vec![2, 10]);
    }
}
