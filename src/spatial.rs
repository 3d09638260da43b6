//! A uniform grid over the horizontal plane for radius queries on points.
//!
//! Boulder maps are a few hundred to a few thousand points spread over tens of metres, and
//! every query here has a fixed small radius (a clustering radius, an association gate):
//! a hash of square cells the size of that radius answers each query by visiting the
//! 3 × 3 cells around it.

use nalgebra::Point3;
use rustc_hash::FxHashMap as HashMap;

/// Points bucketed by their horizontal (x, y) cell.
#[derive(Clone, Debug)]
pub struct GridIndex {
    cell_m: f64,
    cells: HashMap<(i64, i64), Vec<u32>>,
}

impl GridIndex {
    /// An empty index with square cells of `cell_m` metres (use the query radius).
    pub fn new(cell_m: f64) -> Self {
        Self {
            cell_m: if cell_m > 0.0 && cell_m.is_finite() {
                cell_m
            } else {
                1.0
            },
            cells: HashMap::default(),
        }
    }

    /// An index holding `points` under their positions in the slice.
    pub fn from_points(points: &[Point3<f64>], cell_m: f64) -> Self {
        let mut index = Self::new(cell_m);
        for (i, p) in points.iter().enumerate() {
            index.insert(i as u32, p);
        }
        index
    }

    fn key(&self, p: &Point3<f64>) -> (i64, i64) {
        (
            (p.x / self.cell_m).floor() as i64,
            (p.y / self.cell_m).floor() as i64,
        )
    }

    /// Add point `id` at `p`.
    pub fn insert(&mut self, id: u32, p: &Point3<f64>) {
        let key = self.key(p);
        self.cells.entry(key).or_default().push(id);
    }

    /// Move point `id` from `old` to `new` (no-op when both fall in the same cell).
    pub fn relocate(&mut self, id: u32, old: &Point3<f64>, new: &Point3<f64>) {
        let (k_old, k_new) = (self.key(old), self.key(new));
        if k_old == k_new {
            return;
        }
        if let Some(ids) = self.cells.get_mut(&k_old) {
            ids.retain(|&x| x != id);
        }
        self.cells.entry(k_new).or_default().push(id);
    }

    /// Calls `visit(id)` for every point in the cells within `radius_m` of `p` (a superset
    /// of the points within the radius; the caller checks the distance).
    pub fn for_each_near(&self, p: &Point3<f64>, radius_m: f64, mut visit: impl FnMut(u32)) {
        let reach = (radius_m / self.cell_m).ceil().max(1.0) as i64;
        let (cx, cy) = self.key(p);
        for dx in -reach..=reach {
            for dy in -reach..=reach {
                if let Some(ids) = self.cells.get(&(cx + dx, cy + dy)) {
                    ids.iter().for_each(|&id| visit(id));
                }
            }
        }
    }

    /// The nearest point to `p` among `points` (the slice this index was built from) within
    /// `radius_m` in 3D, with its distance.
    pub fn nearest(
        &self,
        points: &[Point3<f64>],
        p: &Point3<f64>,
        radius_m: f64,
    ) -> Option<(u32, f64)> {
        let mut best: Option<(u32, f64)> = None;
        self.for_each_near(p, radius_m, |id| {
            let d = (points[id as usize] - p).norm();
            if d <= radius_m && best.is_none_or(|(_, bd)| d < bd) {
                best = Some((id, d));
            }
        });
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_matches_brute_force() {
        let pts: Vec<_> = (0..200)
            .map(|i| {
                let f = i as f64;
                Point3::new((f * 0.37).sin() * 5.0, (f * 0.73).cos() * 5.0, 0.0)
            })
            .collect();
        let index = GridIndex::from_points(&pts, 0.5);
        for q in &pts {
            let probe = q + nalgebra::Vector3::new(0.05, -0.03, 0.0);
            let brute = pts
                .iter()
                .enumerate()
                .map(|(i, p)| (i as u32, (p - probe).norm()))
                .filter(|(_, d)| *d <= 0.5)
                .min_by(|a, b| a.1.partial_cmp(&b.1).unwrap());
            assert_eq!(index.nearest(&pts, &probe, 0.5), brute);
        }
    }

    #[test]
    fn relocate_moves_between_cells() {
        let mut index = GridIndex::new(1.0);
        let a = Point3::new(0.5, 0.5, 0.0);
        let b = Point3::new(3.5, 0.5, 0.0);
        index.insert(7, &a);
        index.relocate(7, &a, &b);
        let mut seen = vec![];
        index.for_each_near(&b, 0.1, |id| seen.push(id));
        assert_eq!(seen, vec![7]);
        seen.clear();
        index.for_each_near(&a, 0.1, |id| seen.push(id));
        assert!(seen.is_empty());
    }
}
