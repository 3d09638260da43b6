//! A rock raster seen from above (orbital imagery, a survey): a mask of rock cells on a
//! regular grid placed in the world by its top-left corner and cell size, with an optional
//! heights raster of the same shape.
//!
//! Orientation, as in a GIS raster: row 0 is the top (largest y), column 0 the left
//! (smallest x); the world position of the raster's top-left corner (the outer corner of
//! cell (0, 0)) and the cell size place every cell:
//! `centre(row, column) = (x₀ + (column + ½)·cell, y₀ − (row + ½)·cell)`.
//!
//! Files:
//! - a PNG mask (any bit depth or colour type; read as grey): a pixel is rock when its
//!   grey level is at least half of full scale;
//! - a CSV mask: one line per raster row, top row first, values `0` or `1` separated by
//!   commas or white space; blank lines and lines starting with `#` are skipped;
//! - a CSV heights raster (metres), the same shape and layout as the mask; `nan` or an
//!   empty field means unknown.

use std::path::Path;

use crate::atomic::read_text;
use crate::error::snippet;
use crate::MapError;

/// A rock mask (and optional heights) on a regular grid placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct RockRaster {
    /// Number of rows (along −y).
    pub rows: usize,
    /// Number of columns (along +x).
    pub columns: usize,
    /// Cell edge length, metres.
    pub cell_size_m: f64,
    /// World (x, y) of the raster's top-left corner, metres.
    pub top_left_m: (f64, f64),
    /// Rock flag per cell, row-major (`row * columns + column`).
    pub rock: Vec<bool>,
    /// Terrain height per cell, metres, row-major; NaN = unknown (all NaN without a
    /// heights raster).
    pub height_m: Vec<f64>,
}

impl RockRaster {
    /// Flat index of cell (row, column).
    pub fn index(&self, row: usize, column: usize) -> usize {
        row * self.columns + column
    }

    /// World (x, y) of the centre of cell (row, column), metres.
    pub fn cell_center(&self, row: usize, column: usize) -> (f64, f64) {
        let c = self.cell_size_m;
        (
            self.top_left_m.0 + (column as f64 + 0.5) * c,
            self.top_left_m.1 - (row as f64 + 0.5) * c,
        )
    }

    /// Whether any cell has a height.
    pub fn has_heights(&self) -> bool {
        self.height_m.iter().any(|h| !h.is_nan())
    }

    /// Number of rock cells.
    pub fn rock_count(&self) -> usize {
        self.rock.iter().filter(|&&r| r).count()
    }
}

/// Read a rock mask (PNG, or CSV for any other extension) placed by `cell_size_m` and
/// `top_left_m` (see the module docs); heights unknown.
pub fn read_rock_mask(
    path: &Path,
    cell_size_m: f64,
    top_left_m: (f64, f64),
) -> Result<RockRaster, MapError> {
    if !(cell_size_m.is_finite() && cell_size_m > 0.0) {
        return Err(MapError::parse(
            path,
            format!("the cell size must be a positive number of metres, got {cell_size_m}"),
        ));
    }
    if !(top_left_m.0.is_finite() && top_left_m.1.is_finite()) {
        return Err(MapError::parse(
            path,
            format!("the raster's corner must be finite, got {top_left_m:?}"),
        ));
    }
    let is_png = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let (rows, columns, rock) = if is_png {
        read_png_mask(path)?
    } else {
        read_csv_raster(path, parse_mask_value)?
    };
    let raster = RockRaster {
        rows,
        columns,
        cell_size_m,
        top_left_m,
        rock,
        height_m: vec![f64::NAN; rows * columns],
    };
    if raster.rock_count() == 0 {
        return Err(MapError::parse(path, "the mask has no rock cells"));
    }
    Ok(raster)
}

/// Read a heights raster (CSV, metres) into `raster`; its shape must be the mask's.
pub fn read_heights_into(raster: &mut RockRaster, path: &Path) -> Result<(), MapError> {
    let (rows, columns, heights) = read_csv_raster(path, parse_height_value)?;
    if (rows, columns) != (raster.rows, raster.columns) {
        return Err(MapError::Invalid {
            path: path.to_path_buf(),
            message: format!(
                "{rows} rows × {columns} columns, but the rock mask has {} × {}: the heights \
                 must cover the same cells",
                raster.rows, raster.columns
            ),
        });
    }
    raster.height_m = heights;
    Ok(())
}

/// A PNG as (rows, columns, rock flags): grey ≥ half of full scale is rock.
fn read_png_mask(path: &Path) -> Result<(usize, usize, Vec<bool>), MapError> {
    let bytes = std::fs::read(path).map_err(|e| MapError::read_io(path, e))?;
    let image = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
        .map_err(|e| MapError::parse(path, format!("not a readable PNG image: {e}")))?;
    let grey = image.to_luma16();
    let (columns, rows) = (grey.width() as usize, grey.height() as usize);
    if rows == 0 || columns == 0 {
        return Err(MapError::parse(path, "the image has no pixels"));
    }
    let rock = grey.pixels().map(|p| p.0[0] >= 0x8000).collect();
    Ok((rows, columns, rock))
}

fn parse_mask_value(field: &str) -> Result<bool, String> {
    match field {
        "0" => Ok(false),
        "1" => Ok(true),
        other => Err(format!("expected 0 or 1, got '{}'", snippet(other, 20))),
    }
}

fn parse_height_value(field: &str) -> Result<f64, String> {
    if field.is_empty() || field.eq_ignore_ascii_case("nan") {
        return Ok(f64::NAN);
    }
    match field.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!(
            "expected a height in metres (or nan), got '{}'",
            snippet(field, 20)
        )),
    }
}

/// A CSV raster as (rows, columns, values in row-major order); every row must have as
/// many values as the first.
fn read_csv_raster<T>(
    path: &Path,
    parse: fn(&str) -> Result<T, String>,
) -> Result<(usize, usize, Vec<T>), MapError> {
    let text = read_text(path)?;
    let mut values = Vec::new();
    let (mut rows, mut columns) = (0usize, None);
    for (index, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = if line.contains(',') {
            line.split(',').map(str::trim).collect()
        } else {
            line.split_whitespace().collect()
        };
        let expected = *columns.get_or_insert(fields.len());
        if fields.len() != expected {
            return Err(MapError::parse_at(
                path,
                index + 1,
                format!(
                    "{} values, but the first row has {expected}: every row of a raster must \
                     have the same number of cells",
                    fields.len()
                ),
            ));
        }
        for (column, field) in fields.iter().enumerate() {
            let value = parse(field).map_err(|m| {
                MapError::parse_at(path, index + 1, format!("column {}: {m}", column + 1))
            })?;
            values.push(value);
        }
        rows += 1;
    }
    match columns {
        Some(columns) if columns > 0 => Ok((rows, columns, values)),
        _ => Err(MapError::parse(path, "the raster has no cells")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_mask_and_heights_place_cells_from_the_top_left_corner() {
        let dir = tempfile::tempdir().unwrap();
        let mask = dir.path().join("mask.csv");
        std::fs::write(&mask, "# a 2 × 3 mask\n0,1,0\n\n1 0 0\n").unwrap();
        let mut r = read_rock_mask(&mask, 0.5, (10.0, 20.0)).unwrap();
        assert_eq!((r.rows, r.columns, r.rock_count()), (2, 3, 2));
        assert!(r.rock[r.index(0, 1)] && r.rock[r.index(1, 0)]);
        assert_eq!(r.cell_center(0, 1), (10.75, 19.75));
        assert_eq!(r.cell_center(1, 0), (10.25, 19.25));
        assert!(!r.has_heights());
        let heights = dir.path().join("h.csv");
        std::fs::write(&heights, "1.5,2,nan\n1,,3\n").unwrap();
        read_heights_into(&mut r, &heights).unwrap();
        assert_eq!(r.height_m[r.index(0, 1)], 2.0);
        assert!(r.height_m[r.index(1, 1)].is_nan() && r.has_heights());
    }

    #[test]
    fn png_mask_reads_bright_pixels_as_rock() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mask.png");
        let mut img = image::GrayImage::new(4, 2);
        img.put_pixel(3, 1, image::Luma([255]));
        img.put_pixel(0, 0, image::Luma([100]));
        img.save(&path).unwrap();
        let r = read_rock_mask(&path, 1.0, (0.0, 2.0)).unwrap();
        assert_eq!((r.rows, r.columns, r.rock_count()), (2, 4, 1));
        assert!(r.rock[r.index(1, 3)]);
        assert_eq!(r.cell_center(1, 3), (3.5, 0.5));
    }

    #[test]
    fn bad_rasters_name_the_file_line_and_problem() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, text: &str| {
            let p = dir.path().join(name);
            std::fs::write(&p, text).unwrap();
            p
        };
        let err = |p: &Path| read_rock_mask(p, 0.15, (0.0, 0.0)).unwrap_err().to_string();
        let ragged = write("ragged.csv", "0,1\n0,1,1\n");
        assert!(err(&ragged).contains("ragged.csv:2: 3 values, but the first row has 2"));
        let value = write("value.csv", "0,1\n0,7\n");
        assert!(err(&value).contains("value.csv:2: column 2: expected 0 or 1, got '7'"));
        let empty = write("empty.csv", "# nothing\n");
        assert!(err(&empty).contains("no cells"));
        let no_rock = write("none.csv", "0,0\n");
        assert!(err(&no_rock).contains("no rock cells"));
        let not_png = write("fake.png", "0,1\n");
        assert!(err(&not_png).contains("not a readable PNG"));
        let ok = write("ok.csv", "0,1\n1,0\n");
        let bad_size = read_rock_mask(&ok, 0.0, (0.0, 0.0))
            .unwrap_err()
            .to_string();
        assert!(
            bad_size.contains("cell size must be a positive"),
            "{bad_size}"
        );
        let mut r = read_rock_mask(&ok, 0.15, (0.0, 0.0)).unwrap();
        let short = write("h.csv", "1,2\n");
        let e = read_heights_into(&mut r, &short).unwrap_err().to_string();
        assert!(
            e.contains("1 rows × 2 columns, but the rock mask has 2 × 2"),
            "{e}"
        );
        let inf = write("hinf.csv", "1,2\n1,inf\n");
        let e = read_heights_into(&mut r, &inf).unwrap_err().to_string();
        assert!(e.contains("hinf.csv:2: column 2: expected a height"), "{e}");
    }
}
