//! The height layer of the LAC grid from ground points.
//!
//! Each ground point (world frame) falls in one cell; an observed cell's height is the
//! median of its points (robust to the stereo outliers at the edges of rocks). Cells
//! without points are filled by natural-neighbour interpolation (Sibson) over a Delaunay
//! triangulation of the observed cells' centres (crate `spade`): smooth, exact on planes,
//! and local. Ground seen just beyond the grid's edge (a margin of cells around it, 3 m by
//! default) joins the triangulation, so that the grid's outer cells are interpolated
//! between what was seen on both sides of the edge instead of extrapolated from inside.
//! Cells outside the convex hull of the observed cells, where natural-neighbour
//! interpolation is undefined, take the height of the nearest observed cell. With no
//! observed cell at all, the grid stays unfilled.

use nalgebra::Point3;
use segloc_maps::LacGrid;
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation as _};

use crate::landmarks::estimate::median;

/// Accumulates ground points and builds the height layer of a [`LacGrid`].
///
/// ```
/// use nalgebra::Point3;
/// use segloc::mapping::HeightMapBuilder;
/// use segloc_maps::LacGrid;
/// let mut b = HeightMapBuilder::new(LacGrid::new(10, 0.15));
/// // four corner cells, points at their centres, on the plane z = 0.5 + 0.1 x
/// for (x, y) in [(-0.675, -0.675), (0.675, -0.675), (-0.675, 0.675), (0.675, 0.675)] {
///     b.add_point(&Point3::new(x, y, 0.5 + 0.1 * x));
/// }
/// let grid = b.build();
/// assert_eq!(grid.filled_count(), 100);
/// let (x, _) = grid.cell_center(5, 5);
/// assert!((grid.height[grid.index(5, 5)] - (0.5 + 0.1 * x)).abs() < 1e-9);
/// ```
#[derive(Clone, Debug)]
pub struct HeightMapBuilder {
    template: LacGrid,
    /// The template widened by `margin_cells` on every side: where samples are kept.
    extended: LacGrid,
    margin_cells: usize,
    samples: Vec<Vec<f64>>,
    outside: usize,
}

/// Width of the band around the grid whose ground points help fill the grid, metres.
pub const DEFAULT_MARGIN_M: f64 = 3.0;

/// A vertex of the interpolation triangulation: an observed cell centre and its height.
struct Observed {
    position: Point2<f64>,
    height: f64,
}

impl HasPosition for Observed {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.position
    }
}

impl HeightMapBuilder {
    /// A builder for the geometry of `grid` (its heights are ignored, its rock flags kept).
    pub fn new(grid: LacGrid) -> Self {
        Self::with_margin(grid, DEFAULT_MARGIN_M)
    }

    /// A builder that also keeps the ground points within `margin_m` beyond the grid's edge
    /// (rounded up to whole cells; 0: only the grid's own cells) for the interpolation.
    pub fn with_margin(grid: LacGrid, margin_m: f64) -> Self {
        let margin_cells = if margin_m > 0.0 && grid.cell_size_m > 0.0 {
            (margin_m / grid.cell_size_m).ceil().min(1e4) as usize
        } else {
            0
        };
        let extended = LacGrid::new(grid.cells_per_side + 2 * margin_cells, grid.cell_size_m);
        HeightMapBuilder {
            samples: vec![Vec::new(); extended.num_cells()],
            template: grid,
            extended,
            margin_cells,
            outside: 0,
        }
    }

    /// A builder for the LAC grid (180 × 180 cells of 0.15 m).
    pub fn new_lac() -> Self {
        Self::new(LacGrid::new_lac())
    }

    /// Add one ground point in the world frame; points outside the grid and its margin (or
    /// non-finite) are counted and ignored.
    pub fn add_point(&mut self, p_world: &Point3<f64>) {
        match self.extended.cell_of(p_world.x, p_world.y) {
            Some((i, j)) if p_world.z.is_finite() => {
                let k = self.extended.index(i, j);
                self.samples[k].push(p_world.z);
            }
            _ => self.outside += 1,
        }
    }

    /// Number of points ignored because they fell outside the grid and its margin.
    pub fn points_outside(&self) -> usize {
        self.outside
    }

    /// Number of the grid's own cells with at least one point.
    pub fn observed_cells(&self) -> usize {
        let n = self.template.cells_per_side;
        (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .filter(|&(i, j)| !self.samples[self.extended_index(i, j)].is_empty())
            .count()
    }

    /// Index in the extended grid of the grid's cell (i, j).
    fn extended_index(&self, i: usize, j: usize) -> usize {
        let m = self.margin_cells;
        self.extended.index(i + m, j + m)
    }

    /// The grid: medians in observed cells, natural-neighbour interpolation inside their
    /// convex hull, nearest observed cell outside it.
    pub fn build(&self) -> LacGrid {
        let mut grid = self.template.clone();
        let n = grid.cells_per_side;
        let mut triangulation: DelaunayTriangulation<Observed> = DelaunayTriangulation::new();
        let mut medians = vec![f64::NAN; self.samples.len()];
        let side = self.extended.cells_per_side;
        for i in 0..side {
            for j in 0..side {
                let k = self.extended.index(i, j);
                if self.samples[k].is_empty() {
                    continue;
                }
                let mut values = self.samples[k].clone();
                let h = median(&mut values);
                medians[k] = h;
                let (x, y) = self.extended.cell_center(i, j);
                // centres are distinct and finite, so insertion cannot fail; skip if it does
                let _ = triangulation.insert(Observed {
                    position: Point2::new(x, y),
                    height: h,
                });
            }
        }
        let nn = triangulation.natural_neighbor();
        for i in 0..n {
            for j in 0..n {
                let k = grid.index(i, j);
                let observed = medians[self.extended_index(i, j)];
                grid.height[k] = if observed.is_finite() || triangulation.num_vertices() == 0 {
                    observed
                } else {
                    let (x, y) = grid.cell_center(i, j);
                    let p = Point2::new(x, y);
                    nn.interpolate(|v| v.data().height, p)
                        .or_else(|| triangulation.nearest_neighbor(p).map(|v| v.data().height))
                        .unwrap_or(f64::NAN)
                };
            }
        }
        grid
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(x: f64, y: f64) -> f64 {
        1.5 + 0.03 * x - 0.07 * y
    }

    #[test]
    fn natural_neighbour_fill_reproduces_a_plane() {
        let mut b = HeightMapBuilder::new(LacGrid::new(40, 0.15));
        let g0 = LacGrid::new(40, 0.15);
        // scattered observed cells, several points each (median of equal values)
        let mut state = 12345u64;
        for _ in 0..120 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let i = (state >> 33) as usize % 40;
            let j = (state >> 13) as usize % 40;
            let (x, y) = g0.cell_center(i, j);
            for _ in 0..3 {
                b.add_point(&Point3::new(x, y, plane(x, y)));
            }
        }
        // corners so that the hull covers the grid
        for (i, j) in [(0, 0), (0, 39), (39, 0), (39, 39)] {
            let (x, y) = g0.cell_center(i, j);
            b.add_point(&Point3::new(x, y, plane(x, y)));
        }
        let g = b.build();
        assert_eq!(g.filled_count(), 1600);
        for i in 0..40 {
            for j in 0..40 {
                let (x, y) = g.cell_center(i, j);
                let h = g.height[g.index(i, j)];
                assert!((h - plane(x, y)).abs() < 1e-9, "cell ({i},{j}): {h}");
            }
        }
    }

    #[test]
    fn median_per_cell_and_nearest_outside_the_hull() {
        let mut b = HeightMapBuilder::with_margin(LacGrid::new(6, 0.15), 0.0);
        let g0 = LacGrid::new(6, 0.15);
        let (x, y) = g0.cell_center(2, 2);
        for z in [1.0, 1.1, 5.0] {
            b.add_point(&Point3::new(x, y, z));
        }
        b.add_point(&Point3::new(100.0, 0.0, 1.0));
        b.add_point(&Point3::new(0.0, 0.0, f64::NAN));
        assert_eq!(b.points_outside(), 2);
        assert_eq!(b.observed_cells(), 1);
        let g = b.build();
        // one observed cell: its median everywhere (nearest neighbour)
        for h in &g.height {
            assert!((h - 1.1).abs() < 1e-6, "{h}");
        }
        // two observed cells in a row (no triangle): nearest neighbour
        let (x2, y2) = g0.cell_center(2, 5);
        b.add_point(&Point3::new(x2, y2, 2.0));
        let g = b.build();
        assert!((g.height[g.index(0, 0)] - 1.1).abs() < 1e-6);
        assert!((g.height[g.index(5, 5)] - 2.0).abs() < 1e-6);
    }

    #[test]
    fn ground_beyond_the_edge_is_interpolated_toward() {
        // observed: the middle column inside a 10-cell grid, and one column of cell centres
        // 0.6 m beyond each edge; on a plane, the edge cells are then interpolated exactly
        let g0 = LacGrid::new(10, 0.15);
        let mut b = HeightMapBuilder::with_margin(g0.clone(), 1.0);
        let mut b0 = HeightMapBuilder::with_margin(g0.clone(), 0.0);
        for j in 0..10 {
            let (x, y) = g0.cell_center(5, j);
            for x in [x, -1.275, 1.275] {
                b.add_point(&Point3::new(x, y, plane(x, y)));
                b0.add_point(&Point3::new(x, y, plane(x, y)));
            }
        }
        assert_eq!(b.observed_cells(), 10);
        assert_eq!(b.points_outside(), 0);
        assert_eq!(b0.points_outside(), 20);
        let (g, g_inside) = (b.build(), b0.build());
        let (x, y) = g.cell_center(0, 4);
        let edge = g.index(0, 4);
        assert!((g.height[edge] - plane(x, y)).abs() < 1e-9);
        // without the margin the edge takes the nearest observed column's height
        assert!((g_inside.height[edge] - plane(x, y)).abs() > 0.01);
    }

    #[test]
    fn no_points_leave_the_grid_unfilled() {
        let g = HeightMapBuilder::new(LacGrid::new(3, 0.15)).build();
        assert_eq!(g.filled_count(), 0);
    }
}
