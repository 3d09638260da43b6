//! The LAC geometric / rock grid: 180 × 180 cells of 0.15 m centred on the world origin,
//! and its CSV form `i,j,x,y,height,rock` (the ground-truth format).
//!
//! ```text
//! i,j,x,y,height,rock
//! 0,0,-13.425,-13.425,1.981639,1
//! 0,1,-13.425,-13.275,1.990703,1
//! ```
//!
//! `i` indexes x and `j` indexes y; `x,y` are the cell centre; `height` is the mean terrain
//! height in metres; `rock` is 1 if the cell holds a rock. Rows are written with `i` outer,
//! `j` inner, `x,y` with just enough decimals for the cell size (3 for 0.15 m), `height`
//! with 6 decimals. An unfilled cell (`NaN` height in memory) is written as `-inf`, LAC's
//! "uncompleted" value (`np.NINF`); on reading, `-inf`, `inf`, `NaN`/`nan` and an empty
//! field all mean unfilled, and a `rock` of `-inf` or empty means "no rock" (as LAC scores
//! an unfilled cell). Rows may come in any order but every cell must appear exactly once.

use std::fmt::Write as _;
use std::path::Path;

use crate::atomic::{read_text, write_atomic};
use crate::error::{snippet, LineError};
use crate::traverse::header_matches;
use crate::MapError;

/// Header of the grid CSV.
pub const GRID_HEADER: &str = "i,j,x,y,height,rock";

/// Cells per side of the LAC map.
pub const LAC_CELLS_PER_SIDE: usize = 180;

/// Cell size of the LAC map, metres.
pub const LAC_CELL_SIZE_M: f64 = 0.15;

/// A square height / rock grid centred on the origin.
///
/// ```
/// use segloc_maps::LacGrid;
/// let g = LacGrid::new_lac();
/// assert_eq!(g.cell_center(0, 0), (-13.425, -13.425));
/// assert_eq!(g.cell_of(0.01, -0.01), Some((90, 89)));
/// assert_eq!(g.cell_of(20.0, 0.0), None);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct LacGrid {
    /// Number of cells along x and along y (180 for LAC).
    pub cells_per_side: usize,
    /// Cell edge length, metres (0.15 for LAC).
    pub cell_size_m: f64,
    /// Terrain height per cell, metres, at [`LacGrid::index`]; NaN = unfilled.
    pub height: Vec<f64>,
    /// Rock flag per cell, at [`LacGrid::index`].
    pub rock: Vec<bool>,
}

impl LacGrid {
    /// An unfilled grid of `cells_per_side`² cells of `cell_size_m`.
    pub fn new(cells_per_side: usize, cell_size_m: f64) -> Self {
        let n = cells_per_side * cells_per_side;
        LacGrid {
            cells_per_side,
            cell_size_m,
            height: vec![f64::NAN; n],
            rock: vec![false; n],
        }
    }

    /// An unfilled LAC grid: 180 × 180 cells of 0.15 m.
    pub fn new_lac() -> Self {
        Self::new(LAC_CELLS_PER_SIDE, LAC_CELL_SIZE_M)
    }

    /// Total number of cells.
    pub fn num_cells(&self) -> usize {
        self.cells_per_side * self.cells_per_side
    }

    /// Flat index of cell (i, j): `i * cells_per_side + j` (the CSV row order).
    pub fn index(&self, i: usize, j: usize) -> usize {
        i * self.cells_per_side + j
    }

    /// Half the grid's side, metres (13.5 for LAC).
    pub fn half_extent_m(&self) -> f64 {
        self.cells_per_side as f64 * self.cell_size_m / 2.0
    }

    /// The cell containing world point (x, y), or `None` outside the grid (or non-finite).
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let h = self.half_extent_m();
        let fi = ((x + h) / self.cell_size_m).floor();
        let fj = ((y + h) / self.cell_size_m).floor();
        let n = self.cells_per_side as f64;
        if fi >= 0.0 && fi < n && fj >= 0.0 && fj < n {
            Some((fi as usize, fj as usize))
        } else {
            None
        }
    }

    /// Centre (x, y) of cell (i, j), metres.
    pub fn cell_center(&self, i: usize, j: usize) -> (f64, f64) {
        // (2k + 1 - n) half cells, snapped to 1e-9 m so that a decimal cell size gives the
        // double nearest the decimal centre (-13.425, not -13.424999999999999)
        let half = self.cell_size_m / 2.0;
        let n = self.cells_per_side as f64;
        let c = |k: usize| ((2.0 * k as f64 + 1.0 - n) * half * 1e9).round() / 1e9;
        (c(i), c(j))
    }

    /// Whether cell (i, j) has a height.
    pub fn is_filled(&self, i: usize, j: usize) -> bool {
        !self.height[self.index(i, j)].is_nan()
    }

    /// Number of cells with a height.
    pub fn filled_count(&self) -> usize {
        self.height.iter().filter(|h| !h.is_nan()).count()
    }

    /// Number of rock cells.
    pub fn rock_count(&self) -> usize {
        self.rock.iter().filter(|&&r| r).count()
    }

    /// Check sizes agree and every filled height is finite.
    pub fn validate(&self) -> Result<(), MapError> {
        let bad = |message: String| MapError::InvalidData {
            what: "grid",
            message,
        };
        if self.cells_per_side == 0 || !(self.cell_size_m.is_finite() && self.cell_size_m > 0.0) {
            return Err(bad(format!(
                "{} cells per side of {} m: need at least one cell of positive size",
                self.cells_per_side, self.cell_size_m
            )));
        }
        let n = self.num_cells();
        if self.height.len() != n || self.rock.len() != n {
            return Err(bad(format!(
                "{} heights and {} rock flags for {n} cells",
                self.height.len(),
                self.rock.len()
            )));
        }
        if let Some(k) = self.height.iter().position(|h| h.is_infinite()) {
            let (i, j) = (k / self.cells_per_side, k % self.cells_per_side);
            return Err(bad(format!(
                "cell ({i}, {j}) has an infinite height (use NaN for unfilled)"
            )));
        }
        Ok(())
    }
}

/// Decimals needed to write cell centres exactly (centres are multiples of half a cell).
fn center_decimals(cell_size_m: f64) -> usize {
    let half = cell_size_m / 2.0;
    (3..=9)
        .find(|&d| {
            let scaled = half * 10f64.powi(d as i32);
            (scaled - scaled.round()).abs() < 1e-6
        })
        .unwrap_or(9)
}

/// Write the grid as CSV atomically (see the module docs for the exact form).
pub fn write_grid_csv(grid: &LacGrid, path: &Path) -> Result<(), MapError> {
    grid.validate().map_err(|e| e.in_file(path))?;
    write_atomic(path, grid_to_string(grid).as_bytes())
}

/// The CSV text of a grid (no validation; see [`write_grid_csv`]).
pub fn grid_to_string(grid: &LacGrid) -> String {
    let n = grid.cells_per_side;
    let d = center_decimals(grid.cell_size_m);
    let mut s = String::with_capacity(40 * grid.num_cells() + 32);
    s.push_str(GRID_HEADER);
    s.push('\n');
    for i in 0..n {
        for j in 0..n {
            let k = grid.index(i, j);
            let (x, y) = grid.cell_center(i, j);
            let _ = write!(s, "{i},{j},{x:.d$},{y:.d$},");
            let h = grid.height.get(k).copied().unwrap_or(f64::NAN);
            if h.is_nan() {
                s.push_str("-inf");
            } else {
                let _ = write!(s, "{h:.6}");
            }
            let rock = grid.rock.get(k).copied().unwrap_or(false);
            s.push_str(if rock { ",1\n" } else { ",0\n" });
        }
    }
    s
}

/// Read a grid CSV. The grid size is taken from the largest `i`/`j` and the cell size from
/// the cell centres, which must be consistent with a grid centred on the origin.
pub fn read_grid_csv(path: &Path) -> Result<LacGrid, MapError> {
    let text = read_text(path)?;
    parse_grid_csv(&text, path)
}

struct Row {
    line: usize,
    i: usize,
    j: usize,
    x: f64,
    y: f64,
    height: f64,
    rock: bool,
}

/// Parse the text of a grid CSV; `source` names it in errors.
pub fn parse_grid_csv(text: &str, source: &Path) -> Result<LacGrid, MapError> {
    let mut lines = text.lines().enumerate();
    check_grid_header(lines.next().map(|(_, h)| h), source)?;
    let rows = parse_grid_rows(lines, text.len(), source)?;
    let n = grid_side(&rows, source)?;
    let cell_size_m = grid_cell_size(&rows, n, source)?;
    fill_grid(rows, n, cell_size_m, source)
}

/// Check the first line `header` (None: the text is empty) is the grid header.
fn check_grid_header(header: Option<&str>, source: &Path) -> Result<(), MapError> {
    match header {
        Some(h) if header_matches(h, GRID_HEADER) => Ok(()),
        Some(h) => Err(MapError::parse_at(
            source,
            1,
            format!(
                "expected the grid header '{GRID_HEADER}', got '{}'",
                snippet(h, 60)
            ),
        )),
        None => Err(MapError::parse(
            source,
            format!("the file is empty; expected the grid header '{GRID_HEADER}'"),
        )),
    }
}

/// Parse the rows after the header (`lines` numbered from 0, of a text `text_len` bytes
/// long), skipping blank lines.
fn parse_grid_rows<'t>(
    lines: impl Iterator<Item = (usize, &'t str)>,
    text_len: usize,
    source: &Path,
) -> Result<Vec<Row>, MapError> {
    // a row takes at least 12 bytes (`0,0,0,0,,0\n`): reserve for the rows the text can hold
    let mut rows = Vec::with_capacity((text_len / 12).min(LAC_CELLS_PER_SIDE * LAC_CELLS_PER_SIDE));
    for (index, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let row = parse_grid_row(line, index + 1)
            .map_err(|m| MapError::parse_at(source, index + 1, m))?;
        rows.push(row);
    }
    Ok(rows)
}

/// Cells per side of the grid `rows` describe (one more than the largest index); an error
/// unless there is exactly one row per cell.
fn grid_side(rows: &[Row], source: &Path) -> Result<usize, MapError> {
    let Some(max_ij) = rows.iter().map(|r| r.i.max(r.j)).max() else {
        return Err(MapError::parse(source, "the grid has no cells"));
    };
    let n = max_ij + 1;
    if rows.len() != n * n {
        return Err(MapError::Invalid {
            path: source.to_path_buf(),
            message: format!(
                "{} cells for a {n} × {n} grid (largest index {max_ij}); expected {}",
                rows.len(),
                n * n
            ),
        });
    }
    Ok(n)
}

/// Cell size of an `n` × `n` grid centred on the origin, from the centre of the row
/// furthest from the centre in i, snapped to a round size.
fn grid_cell_size(rows: &[Row], n: usize, source: &Path) -> Result<f64, MapError> {
    // cell size from the row furthest from the centre in i
    let far = rows
        .iter()
        .max_by(|a, b| {
            let da = (a.i as f64 + 0.5 - n as f64 / 2.0).abs();
            let db = (b.i as f64 + 0.5 - n as f64 / 2.0).abs();
            da.total_cmp(&db)
        })
        .map(|r| (r.i, r.x))
        .unwrap_or((0, 0.0));
    let offset = far.0 as f64 + 0.5 - n as f64 / 2.0;
    let cell_size_m = far.1 / offset;
    if !(cell_size_m.is_finite() && cell_size_m > 0.0) {
        return Err(MapError::Invalid {
            path: source.to_path_buf(),
            message: format!(
                "cell ({}, ...) is centred at x = {}, which does not fit a grid centred on the origin",
                far.0, far.1
            ),
        });
    }
    // snap to a round size (0.15 m is not exact in binary; the file has a few decimals)
    Ok((cell_size_m * 1e9).round() / 1e9)
}

/// The `n` × `n` grid of `cell_size_m` cells holding `rows`; an error for a row centred
/// off its cell or a cell appearing twice.
fn fill_grid(
    rows: Vec<Row>,
    n: usize,
    cell_size_m: f64,
    source: &Path,
) -> Result<LacGrid, MapError> {
    let mut grid = LacGrid::new(n, cell_size_m);
    let mut seen = vec![false; n * n];
    let tol = 1e-4 * cell_size_m.max(1e-3) + 1e-6;
    for r in rows {
        let (cx, cy) = grid.cell_center(r.i, r.j);
        if (cx - r.x).abs() > tol || (cy - r.y).abs() > tol {
            return Err(MapError::parse_at(
                source,
                r.line,
                format!(
                    "cell ({}, {}) is centred at ({}, {}), but a {n} × {n} grid of {cell_size_m} m \
                     centred on the origin puts it at ({cx}, {cy})",
                    r.i, r.j, r.x, r.y
                ),
            ));
        }
        let k = grid.index(r.i, r.j);
        if std::mem::replace(&mut seen[k], true) {
            return Err(MapError::parse_at(
                source,
                r.line,
                format!("cell ({}, {}) appears twice", r.i, r.j),
            ));
        }
        grid.height[k] = r.height;
        grid.rock[k] = r.rock;
    }
    Ok(grid)
}

fn parse_grid_row(line: &str, line_no: usize) -> Result<Row, LineError> {
    let mut f = [""; 6];
    let mut count = 0;
    for field in line.split(',') {
        if count == 6 {
            return Err(format!("expected 6 fields ({GRID_HEADER}), got more").into());
        }
        f[count] = field.trim();
        count += 1;
    }
    if count < 6 {
        return Err(format!("expected 6 fields ({GRID_HEADER}), got {count}").into());
    }
    let int = |k: usize, name: &str| -> Result<usize, LineError> {
        f[k].parse().map_err(|_| {
            LineError::from(format!(
                "{name}: expected a non-negative integer, got '{}'",
                snippet(f[k], 20)
            ))
        })
    };
    let num = |k: usize, name: &str| -> Result<f64, LineError> {
        let v: f64 = f[k]
            .parse()
            .map_err(|_| format!("{name}: expected a number, got '{}'", snippet(f[k], 20)))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{name}: '{}' is not a finite number", f[k]).into())
        }
    };
    let i = int(0, "i")?;
    let j = int(1, "j")?;
    if i.max(j) >= 100_000 {
        return Err(format!("cell ({i}, {j}): index too large for a grid").into());
    }
    let x = num(2, "x")?;
    let y = num(3, "y")?;
    let height = match f[4] {
        "" => f64::NAN,
        t => {
            let v: f64 = t.parse().map_err(|_| {
                format!(
                    "height: expected a number or -inf (unfilled), got '{}'",
                    snippet(t, 20)
                )
            })?;
            if v.is_finite() {
                v
            } else {
                f64::NAN
            }
        }
    };
    let rock = match f[5] {
        "1" | "1.0" | "True" | "true" => true,
        "0" | "0.0" | "False" | "false" | "" | "-inf" | "nan" | "NaN" => false,
        t => return Err(format!("rock: expected 0 or 1, got '{}'", snippet(t, 20)).into()),
    };
    Ok(Row {
        line: line_no,
        i,
        j,
        x,
        y,
        height,
        rock,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> LacGrid {
        let mut g = LacGrid::new(4, 0.15);
        for (k, h) in g.height.iter_mut().enumerate() {
            *h = if k == 5 {
                f64::NAN
            } else {
                1.0 + k as f64 * 0.001234
            };
        }
        g.rock[3] = true;
        g.rock[5] = true;
        g
    }

    fn parse(text: &str) -> Result<LacGrid, MapError> {
        parse_grid_csv(text, Path::new("g.csv"))
    }

    #[test]
    fn geometry() {
        let g = LacGrid::new_lac();
        assert_eq!(g.num_cells(), 32_400);
        assert_eq!(g.index(1, 2), 182);
        assert!((g.half_extent_m() - 13.5).abs() < 1e-12);
        assert_eq!(g.cell_center(179, 90), (13.425, 0.075));
        assert_eq!(g.cell_center(1, 89), (-13.275, -0.075));
        assert_eq!(g.cell_of(-13.5, -13.5), Some((0, 0)));
        assert_eq!(g.cell_of(13.4999, 13.4999), Some((179, 179)));
        assert_eq!(g.cell_of(13.5, 0.0), None);
        assert_eq!(g.cell_of(f64::NAN, 0.0), None);
        for i in [0, 17, 90, 179] {
            let (x, y) = g.cell_center(i, 179 - i);
            assert_eq!(g.cell_of(x, y), Some((i, 179 - i)));
        }
        assert_eq!(g.filled_count(), 0);
        assert!(!g.is_filled(0, 0));
    }

    #[test]
    fn round_trip_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("g.csv");
        let mut g = small();
        // heights with 6 decimals round-trip exactly
        for h in g.height.iter_mut().filter(|h| !h.is_nan()) {
            *h = format!("{h:.6}").parse().unwrap();
        }
        write_grid_csv(&g, &p).unwrap();
        let back = read_grid_csv(&p).unwrap();
        assert_eq!(back.cells_per_side, 4);
        assert_eq!(back.cell_size_m, 0.15);
        assert_eq!(back.rock, g.rock);
        for (a, b) in back.height.iter().zip(&g.height) {
            assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
        }
        // and the text is identical on the second write
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(grid_to_string(&back), text);
        assert!(text.contains("\n1,1,-0.075,-0.075,-inf,1\n"), "{text}");
        assert!(text.starts_with("i,j,x,y,height,rock\n0,0,-0.225,-0.225,1.000000,0\n"));
    }

    #[test]
    fn other_cell_sizes() {
        let g = LacGrid::new(3, 0.1);
        let text = grid_to_string(&g);
        let back = parse(&text).unwrap();
        assert_eq!(back.cells_per_side, 3);
        assert_eq!(back.cell_size_m, 0.1);
        assert_eq!(center_decimals(0.0375), 5);
    }

    #[test]
    fn unfilled_forms() {
        let text = "i,j,x,y,height,rock\n0,0,-0.075,-0.075,nan,0\n0,1,-0.075,0.075,,\n1,0,0.075,-0.075,-inf,-inf\n1,1,0.075,0.075,2.5,1\n";
        let g = parse(text).unwrap();
        assert_eq!(g.filled_count(), 1);
        assert_eq!(g.rock_count(), 1);
    }

    #[test]
    fn bad_inputs_name_line() {
        let h = "i,j,x,y,height,rock\n";
        let e = |body: &str| parse(&format!("{h}{body}")).unwrap_err().to_string();
        assert_eq!(
            e("0,0,-0.075\n"),
            "g.csv:2: expected 6 fields (i,j,x,y,height,rock), got 3"
        );
        assert_eq!(
            e("0,0,nan,0,1,0\n"),
            "g.csv:2: x: 'nan' is not a finite number"
        );
        assert!(e("0,0,0,0,abc,0\n").starts_with("g.csv:2: height: expected a number"));
        assert!(e("0,0,0,0,1,2\n").starts_with("g.csv:2: rock: expected 0 or 1"));
        assert!(e("0,-1,0,0,1,0\n").starts_with("g.csv:2: j: expected"));
        // a missing cell
        let three = "0,0,-0.075,-0.075,1,0\n0,1,-0.075,0.075,1,0\n1,0,0.075,-0.075,1,0\n";
        assert!(e(three).contains("3 cells for a 2 × 2 grid"));
        // a duplicated cell
        let dup = "0,0,-0.075,-0.075,1,0\n0,1,-0.075,0.075,1,0\n1,0,0.075,-0.075,1,0\n1,0,0.075,-0.075,1,0\n";
        assert_eq!(e(dup), "g.csv:5: cell (1, 0) appears twice");
        // a wrong centre
        let off = "0,0,-0.075,-0.075,1,0\n0,1,-0.075,0.075,1,0\n1,0,0.075,-0.075,1,0\n1,1,0.075,0.5,1,0\n";
        assert!(e(off).starts_with("g.csv:5: cell (1, 1) is centred at (0.075, 0.5)"));
        assert!(parse("").unwrap_err().to_string().contains("empty"));
        assert!(parse("i,j\n")
            .unwrap_err()
            .to_string()
            .starts_with("g.csv:1: expected the grid header"));
        assert!(parse(h).unwrap_err().to_string().contains("no cells"));
    }

    #[test]
    fn write_refuses_inconsistent_grid() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("g.csv");
        let mut g = small();
        g.rock.pop();
        assert!(write_grid_csv(&g, &p)
            .unwrap_err()
            .to_string()
            .contains("g.csv"));
        let mut g = small();
        g.height[2] = f64::INFINITY;
        assert!(write_grid_csv(&g, &p)
            .unwrap_err()
            .to_string()
            .contains("cell (0, 2)"));
        assert!(!p.exists());
        assert!(matches!(
            read_grid_csv(&p).unwrap_err(),
            MapError::Io { .. }
        ));
    }
}
