//! The height layer of the LAC grid from ground points.
//!
//! Each ground point (world frame) falls in one cell; an observed cell's height is the
//! median of its points (robust to the stereo outliers at the edges of rocks). Cells
//! without points are filled by natural-neighbour interpolation (Sibson) over a Delaunay
//! triangulation of the observed cells' centres (crate `spade`): smooth, exact on planes,
//! and local. Cells outside the convex hull of the observed cells, where natural-neighbour
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
    samples: Vec<Vec<f64>>,
    outside: usize,
}

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
        let n = grid.num_cells();
        HeightMapBuilder {
            template: grid,
            samples: vec![Vec::new(); n],
            outside: 0,
        }
    }

    /// A builder for the LAC grid (180 × 180 cells of 0.15 m).
    pub fn new_lac() -> Self {
        Self::new(LacGrid::new_lac())
    }

    /// Add one ground point in the world frame; points outside the grid (or non-finite)
    /// are counted and ignored.
    pub fn add_point(&mut self, p_world: &Point3<f64>) {
        match self.template.cell_of(p_world.x, p_world.y) {
            Some((i, j)) if p_world.z.is_finite() => {
                let k = self.template.index(i, j);
                self.samples[k].push(p_world.z);
            }
            _ => self.outside += 1,
        }
    }

    /// Number of points ignored because they fell outside the grid.
    pub fn points_outside(&self) -> usize {
        self.outside
    }

    /// Number of cells with at least one point.
    pub fn observed_cells(&self) -> usize {
        self.samples.iter().filter(|s| !s.is_empty()).count()
    }

    /// The grid: medians in observed cells, natural-neighbour interpolation inside their
    /// convex hull, nearest observed cell outside it.
    pub fn build(&self) -> LacGrid {
        let mut grid = self.template.clone();
        let n = grid.cells_per_side;
        let mut observed = vec![false; grid.num_cells()];
        let mut triangulation: DelaunayTriangulation<Observed> = DelaunayTriangulation::new();
        for i in 0..n {
            for j in 0..n {
                let k = grid.index(i, j);
                if self.samples[k].is_empty() {
                    grid.height[k] = f64::NAN;
                    continue;
                }
                let mut values = self.samples[k].clone();
                let h = median(&mut values);
                grid.height[k] = h;
                observed[k] = true;
                let (x, y) = grid.cell_center(i, j);
                // centres are distinct and finite, so insertion cannot fail; skip if it does
                let _ = triangulation.insert(Observed {
                    position: Point2::new(x, y),
                    height: h,
                });
            }
        }
        if triangulation.num_vertices() == 0 {
            return grid;
        }
        let nn = triangulation.natural_neighbor();
        for i in 0..n {
            for j in 0..n {
                let k = grid.index(i, j);
                if observed[k] {
                    continue;
                }
                let (x, y) = grid.cell_center(i, j);
                let p = Point2::new(x, y);
                let h = nn
                    .interpolate(|v| v.data().height, p)
                    .or_else(|| triangulation.nearest_neighbor(p).map(|v| v.data().height));
                grid.height[k] = h.unwrap_or(f64::NAN);
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
        let mut b = HeightMapBuilder::new(LacGrid::new(6, 0.15));
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
    fn no_points_leave_the_grid_unfilled() {
        let g = HeightMapBuilder::new(LacGrid::new(3, 0.15)).build();
        assert_eq!(g.filled_count(), 0);
    }
}
