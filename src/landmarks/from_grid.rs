//! A prior map from a rock grid (the LAC ground-truth grid, an orbital rock raster): rock
//! cells clustered into rocks, one landmark per rock.
//!
//! Rock cells that touch (8-connected) are one rock; its landmark sits at the mean of its
//! cells' centres, at the mean of their heights. The covariance says honestly what the
//! grid knows: the rock's true centroid lies somewhere within half a cell of that mean in
//! x and y (uniform, so a variance of `cell²/12` per axis), and its height is the cells'
//! mean terrain height, which a detected boulder centroid matches only to
//! [`GridRocksConfig::height_sigma_m`] (plus the spread of the cells' heights). The size is
//! the cluster's largest horizontal extent (cells × cell size). No detection went into it,
//! so its `observations` is 0: the relocalizer treats such a map as a survey prior.
//!
//! Coarse cells (at least [`GridRocksConfig::split_from_cell_m`]) are each their own rock:
//! a rock rarely spans two of them, so touching rock cells are mostly neighbouring rocks
//! OR-ed together, whose common centre is no rock's (docs/design/grid-coarse-cells.md).

use nalgebra::{Matrix3, Point3};
use segloc_maps::{LacGrid, Landmark, MapError, ObjectMap, RockRaster};
use serde::{Deserialize, Serialize};

/// Parameters of the grid-to-landmarks stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GridRocksConfig {
    /// Rocks of fewer cells are left out.
    pub min_cells: usize,
    /// Standard deviation (m) of a detected boulder centroid's height about its cells'
    /// mean terrain height (measured on four LunarLoc traverses: median +2 cm, IQR 1.4 cm).
    pub height_sigma_m: f64,
    /// Grids whose cells are at least this large (m) give one landmark per rock cell
    /// instead of one per 8-connected cluster (see the module docs).
    pub split_from_cell_m: f64,
}

impl Default for GridRocksConfig {
    fn default() -> Self {
        Self {
            min_cells: 1,
            height_sigma_m: 0.03,
            split_from_cell_m: 0.3,
        }
    }
}

impl GridRocksConfig {
    /// Check the fields; errors name the TOML path (`grid_rocks.<field>`).
    pub fn validate(&self) -> Result<(), MapError> {
        if self.min_cells == 0 {
            return Err(invalid("grid_rocks.min_cells must be at least 1".into()));
        }
        if !(self.height_sigma_m.is_finite() && self.height_sigma_m > 0.0) {
            return Err(invalid(format!(
                "grid_rocks.height_sigma_m must be positive, got {}",
                self.height_sigma_m
            )));
        }
        if !(self.split_from_cell_m.is_finite() && self.split_from_cell_m > 0.0) {
            return Err(invalid(format!(
                "grid_rocks.split_from_cell_m must be positive, got {}",
                self.split_from_cell_m
            )));
        }
        Ok(())
    }
}

fn invalid(message: String) -> MapError {
    MapError::InvalidData {
        what: "grid",
        message,
    }
}

/// A regular grid of cells seen from above, some of them rock: the LAC grid
/// ([`LacGrid`], cells `(i, j)` along x and y) or a rock raster ([`RockRaster`], cells
/// `(row, column)`). Cells are addressed `(a, b)` with `a < shape().0`, `b < shape().1`.
pub trait RockCells {
    /// Number of cells along the first and the second index.
    fn shape(&self) -> (usize, usize);
    /// Cell edge length, metres.
    fn cell_size_m(&self) -> f64;
    /// Whether cell `(a, b)` holds rock.
    fn is_rock(&self, a: usize, b: usize) -> bool;
    /// Terrain height of cell `(a, b)`, metres; NaN when unknown.
    fn height_m(&self, a: usize, b: usize) -> f64;
    /// World (x, y) of the centre of cell `(a, b)`, metres.
    fn center(&self, a: usize, b: usize) -> (f64, f64);
}

impl RockCells for LacGrid {
    fn shape(&self) -> (usize, usize) {
        (self.cells_per_side, self.cells_per_side)
    }
    fn cell_size_m(&self) -> f64 {
        self.cell_size_m
    }
    fn is_rock(&self, a: usize, b: usize) -> bool {
        self.rock[self.index(a, b)]
    }
    fn height_m(&self, a: usize, b: usize) -> f64 {
        self.height[self.index(a, b)]
    }
    fn center(&self, a: usize, b: usize) -> (f64, f64) {
        self.cell_center(a, b)
    }
}

impl RockCells for RockRaster {
    fn shape(&self) -> (usize, usize) {
        (self.rows, self.columns)
    }
    fn cell_size_m(&self) -> f64 {
        self.cell_size_m
    }
    fn is_rock(&self, a: usize, b: usize) -> bool {
        self.rock[self.index(a, b)]
    }
    fn height_m(&self, a: usize, b: usize) -> f64 {
        self.height_m[self.index(a, b)]
    }
    fn center(&self, a: usize, b: usize) -> (f64, f64) {
        self.cell_center(a, b)
    }
}

/// The rocks of `grid` as a gravity-aligned map (frame "world", session `session`), ids in
/// the order of each rock's first cell (i outer, j inner). A grid without rock cells, or
/// whose rocks all fall below `min_cells`, is an error; so is a rock cell without a height.
pub fn map_from_grid(
    grid: &LacGrid,
    config: &GridRocksConfig,
    session: &str,
) -> Result<ObjectMap, MapError> {
    grid.validate()?;
    map_from_rock_cells(grid, config, session)
}

/// The rocks of a rock raster as a gravity-aligned map, as [`map_from_grid`] (ids in the
/// order of each rock's first cell, rows outer). Without a heights raster every landmark
/// sits at height 0 (the relocalizer's 4-DOF alignment finds the offset; the terrain's
/// relief within the query's extent then adds to the residuals), and a rock cell without
/// a height in a raster that has heights is an error.
pub fn map_from_raster(
    raster: &RockRaster,
    config: &GridRocksConfig,
    session: &str,
) -> Result<ObjectMap, MapError> {
    if raster.has_heights() {
        return map_from_rock_cells(raster, config, session);
    }
    let flat = RockRaster {
        height_m: vec![0.0; raster.height_m.len()],
        ..raster.clone()
    };
    let mut map = map_from_rock_cells(&flat, config, session)?;
    map.notes
        .insert("heights".into(), "none: every rock at height 0".into());
    Ok(map)
}

/// The rocks of any [`RockCells`] grid (see [`map_from_grid`]).
pub fn map_from_rock_cells<G: RockCells>(
    grid: &G,
    config: &GridRocksConfig,
    session: &str,
) -> Result<ObjectMap, MapError> {
    config.validate()?;
    let clusters = rock_clusters(grid);
    if clusters.is_empty() {
        return Err(invalid("the grid has no rock cells".into()));
    }
    let rock_cells: usize = clusters.iter().map(Vec::len).sum();
    let split = grid.cell_size_m() >= config.split_from_cell_m - 1e-9;
    let mut map = ObjectMap::new("world", session, true);
    for cells in clusters {
        if cells.len() < config.min_cells {
            continue;
        }
        let rocks = if split {
            cells.iter().map(|&c| vec![c]).collect()
        } else {
            vec![cells]
        };
        for rock in rocks {
            let landmark = rock_landmark(grid, &rock, config, map.landmarks.len() as u32)?;
            map.landmarks.push(landmark);
        }
    }
    if map.landmarks.is_empty() {
        return Err(invalid(format!(
            "the grid's {rock_cells} rock cells make no rock of at least {} cells",
            config.min_cells
        )));
    }
    map.notes.insert(
        "source".into(),
        format!("rock grid, {} m cells", grid.cell_size_m()),
    );
    Ok(map)
}

/// The 8-connected clusters of rock cells, each a list of `(a, b)` in discovery order.
pub fn rock_clusters<G: RockCells>(grid: &G) -> Vec<Vec<(usize, usize)>> {
    let (na, nb) = grid.shape();
    let mut seen = vec![false; na * nb];
    let mut clusters = Vec::new();
    for start in 0..na * nb {
        let (a0, b0) = (start / nb, start % nb);
        if !grid.is_rock(a0, b0) || seen[start] {
            continue;
        }
        seen[start] = true;
        let mut stack = vec![(a0, b0)];
        let mut cells = Vec::new();
        while let Some((a, b)) = stack.pop() {
            cells.push((a, b));
            for na_ in a.saturating_sub(1)..=(a + 1).min(na - 1) {
                for nb_ in b.saturating_sub(1)..=(b + 1).min(nb - 1) {
                    let k = na_ * nb + nb_;
                    if grid.is_rock(na_, nb_) && !seen[k] {
                        seen[k] = true;
                        stack.push((na_, nb_));
                    }
                }
            }
        }
        clusters.push(cells);
    }
    clusters
}

/// One rock's landmark (see the module docs for the covariance).
fn rock_landmark<G: RockCells>(
    grid: &G,
    cells: &[(usize, usize)],
    config: &GridRocksConfig,
    id: u32,
) -> Result<Landmark, MapError> {
    let count = cells.len() as f64;
    let (mut x, mut y, mut z, mut zz) = (0.0, 0.0, 0.0, 0.0);
    for &(a, b) in cells {
        let h = grid.height_m(a, b);
        if h.is_nan() {
            return Err(invalid(format!(
                "rock cell ({a}, {b}) has no height; a rock map needs the height layer"
            )));
        }
        let (cx, cy) = grid.center(a, b);
        x += cx / count;
        y += cy / count;
        z += h / count;
        zz += h * h / count;
    }
    let cell = grid.cell_size_m();
    let var_xy = cell * cell / 12.0;
    let var_z = config.height_sigma_m.powi(2) + (zz - z * z).max(0.0);
    let extent = |axis: fn(&(usize, usize)) -> usize| {
        let lo = cells.iter().map(axis).min().unwrap_or(0);
        let hi = cells.iter().map(axis).max().unwrap_or(0);
        (hi - lo + 1) as f64 * cell
    };
    let size = extent(|c| c.0).max(extent(|c| c.1));
    let mut landmark = Landmark::new(
        id,
        Point3::new(x, y, z),
        Matrix3::from_diagonal(&nalgebra::Vector3::new(var_xy, var_xy, var_z)),
    );
    landmark.size_m = Some(size);
    // no detection was fused: a survey landmark (see `AssociationConfig::max_associations`)
    landmark.observations = 0;
    Ok(landmark)
}

/// `grid` coarsened by `factor`: each coarse cell is a rock if any of its fine cells is
/// (OR), and its height is the mean of its filled fine cells' heights. A side that does not
/// divide by `factor` is padded with unfilled, rock-free cells, keeping the grid centred.
pub fn coarsened(grid: &LacGrid, factor: usize) -> LacGrid {
    let factor = factor.max(1);
    let n = grid.cells_per_side;
    let coarse_n = n.div_ceil(factor);
    let pad = (coarse_n * factor - n) / 2;
    let mut out = LacGrid::new(coarse_n, grid.cell_size_m * factor as f64);
    let mut sums = vec![(0.0f64, 0usize); out.num_cells()];
    for i in 0..n {
        for j in 0..n {
            let (ci, cj) = ((i + pad) / factor, (j + pad) / factor);
            let k = out.index(ci, cj);
            let fine = grid.index(i, j);
            out.rock[k] |= grid.rock[fine];
            if !grid.height[fine].is_nan() {
                sums[k].0 += grid.height[fine];
                sums[k].1 += 1;
            }
        }
    }
    for (h, (sum, count)) in out.height.iter_mut().zip(sums) {
        if count > 0 {
            *h = sum / count as f64;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_with_rocks(n: usize, rocks: &[(usize, usize)]) -> LacGrid {
        let mut g = LacGrid::new(n, 0.15);
        g.height = vec![1.0; n * n];
        for &(i, j) in rocks {
            let k = g.index(i, j);
            g.rock[k] = true;
        }
        g
    }

    #[test]
    fn clusters_are_eight_connected() {
        // a diagonal pair, an L of three, and a lone cell
        let g = grid_with_rocks(6, &[(0, 0), (1, 1), (4, 0), (4, 1), (5, 1), (3, 4)]);
        let map = map_from_grid(&g, &GridRocksConfig::default(), "site").unwrap();
        assert_eq!(map.len(), 3);
        let sizes: Vec<f64> = map.landmarks.iter().filter_map(|l| l.size_m).collect();
        assert_eq!(sizes.len(), 3);
        assert!((sizes[1] - 0.15).abs() < 1e-12 && (sizes[2] - 0.3).abs() < 1e-12);
        assert!(map.landmarks.iter().all(|l| l.observations == 0));
        // the diagonal pair's centre: between cells (0,0) and (1,1)
        let (c0, c1) = (g.cell_center(0, 0), g.cell_center(1, 1));
        let p = map.landmarks[0].position;
        assert!((p.x - 0.5 * (c0.0 + c1.0)).abs() < 1e-12);
        assert!((p.y - 0.5 * (c0.1 + c1.1)).abs() < 1e-12);
        assert!((map.landmarks[0].size_m.unwrap() - 0.3).abs() < 1e-12);
        assert!(map.gravity_aligned);
    }

    #[test]
    fn covariance_is_the_cell_quantisation() {
        let mut g = grid_with_rocks(4, &[(1, 1), (1, 2)]);
        let k = g.index(1, 2);
        g.height[k] = 1.2;
        let map = map_from_grid(&g, &GridRocksConfig::default(), "site").unwrap();
        let cov = map.landmarks[0].covariance;
        assert!((cov[(0, 0)] - 0.15f64.powi(2) / 12.0).abs() < 1e-15);
        assert!((cov[(1, 1)] - cov[(0, 0)]).abs() < 1e-15);
        // height: 3 cm plus the cells' spread (0.1 m about the mean 1.1)
        assert!((cov[(2, 2)] - (0.03f64.powi(2) + 0.01)).abs() < 1e-12);
        assert!((map.landmarks[0].position.z - 1.1).abs() < 1e-12);
    }

    #[test]
    fn coarse_cells_are_each_a_rock() {
        // an L of three touching cells: one rock at 0.15 m, three at 0.45 m
        let cells = [(1, 1), (1, 2), (2, 2)];
        let fine = grid_with_rocks(4, &cells);
        let fine_map = map_from_grid(&fine, &GridRocksConfig::default(), "s").unwrap();
        assert_eq!(fine_map.len(), 1);
        let mut coarse = grid_with_rocks(4, &cells);
        coarse.cell_size_m = 0.45;
        let map = map_from_grid(&coarse, &GridRocksConfig::default(), "s").unwrap();
        assert_eq!(map.len(), 3);
        // one landmark at each cell's centre (in the cluster's discovery order)
        for &(a, b) in &cells {
            let (x, y) = coarse.cell_center(a, b);
            let at = |l: &&Landmark| (l.position.x - x).abs() + (l.position.y - y).abs() < 1e-9;
            assert_eq!(
                map.landmarks.iter().filter(at).count(),
                1,
                "cell ({a}, {b})"
            );
        }
        for landmark in &map.landmarks {
            assert!((landmark.covariance[(0, 0)] - 0.45f64.powi(2) / 12.0).abs() < 1e-15);
            assert_eq!(landmark.size_m, Some(0.45));
        }
        let bad = GridRocksConfig {
            split_from_cell_m: 0.0,
            ..GridRocksConfig::default()
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(err.contains("grid_rocks.split_from_cell_m"), "{err}");
    }

    #[test]
    fn min_cells_and_empty_grids() {
        let g = grid_with_rocks(4, &[(0, 0), (3, 3), (3, 2)]);
        let cfg = GridRocksConfig {
            min_cells: 2,
            ..GridRocksConfig::default()
        };
        assert_eq!(map_from_grid(&g, &cfg, "s").unwrap().len(), 1);
        let none = grid_with_rocks(4, &[]);
        let err = map_from_grid(&none, &cfg, "s").unwrap_err().to_string();
        assert!(err.contains("no rock cells"), "{err}");
        let cfg3 = GridRocksConfig {
            min_cells: 3,
            ..GridRocksConfig::default()
        };
        assert!(map_from_grid(&g, &cfg3, "s").is_err());
    }

    #[test]
    fn coarsening_ors_rocks_and_keeps_the_centre() {
        let g = grid_with_rocks(6, &[(0, 0), (5, 5)]);
        let c = coarsened(&g, 3);
        assert_eq!(c.cells_per_side, 2);
        assert!((c.cell_size_m - 0.45).abs() < 1e-12);
        assert!(c.rock[c.index(0, 0)] && c.rock[c.index(1, 1)]);
        assert!(!c.rock[c.index(0, 1)]);
        assert_eq!(c.height[0], 1.0);
        // 180 cells by 2: 90 cells of 0.3 m, same centre
        let lac = LacGrid::new_lac();
        let c2 = coarsened(&lac, 2);
        assert_eq!(c2.cells_per_side, 90);
        assert!((c2.half_extent_m() - lac.half_extent_m()).abs() < 1e-9);
    }
}
