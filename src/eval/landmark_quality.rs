//! How well fused landmarks match the ground-truth rock cells of the LAC map.
//!
//! The LAC ground truth marks a 0.15 m cell as rock when any of its 4 × 4 ray casts hit a
//! rock, so a boulder centroid should fall on a rock cell or right beside one (a centroid
//! on the visible face can sit a few centimetres into the next cell).

use segloc_maps::{LacGrid, ObjectMap};
use serde::Serialize;

/// Precision-like figures of points against the rock cells.
#[derive(Clone, Debug, Serialize)]
pub struct RockMatch {
    /// Points inside the grid.
    pub points: usize,
    /// Fraction of those on a rock cell.
    pub on_rock: f64,
    /// Fraction on a rock cell or one of its 8 neighbours.
    pub near_rock: f64,
    /// Rock cells with a point on them or beside them, over all rock cells.
    pub rock_cells_covered: f64,
}

/// Match points against the rock cells of `grid`.
pub fn match_rocks(points: &[nalgebra::Point3<f64>], grid: &LacGrid) -> RockMatch {
    let n = grid.cells_per_side;
    let is_rock = |i: i64, j: i64| -> bool {
        i >= 0
            && j >= 0
            && (i as usize) < n
            && (j as usize) < n
            && grid.rock[grid.index(i as usize, j as usize)]
    };
    let mut covered = vec![false; grid.rock.len()];
    let (mut inside, mut on, mut near) = (0usize, 0usize, 0usize);
    for p in points {
        let Some((i, j)) = grid.cell_of(p.x, p.y) else {
            continue;
        };
        inside += 1;
        let (i, j) = (i as i64, j as i64);
        if is_rock(i, j) {
            on += 1;
        }
        let mut any = false;
        for di in -1..=1 {
            for dj in -1..=1 {
                if is_rock(i + di, j + dj) {
                    any = true;
                    covered[grid.index((i + di) as usize, (j + dj) as usize)] = true;
                }
            }
        }
        near += any as usize;
    }
    let rock_total = grid.rock.iter().filter(|&&r| r).count().max(1);
    let frac = |k: usize| {
        if inside == 0 {
            0.0
        } else {
            k as f64 / inside as f64
        }
    };
    RockMatch {
        points: inside,
        on_rock: frac(on),
        near_rock: frac(near),
        rock_cells_covered: covered.iter().filter(|&&c| c).count() as f64 / rock_total as f64,
    }
}

/// Match a map's landmarks against the rock cells.
pub fn match_map(map: &ObjectMap, grid: &LacGrid) -> RockMatch {
    match_rocks(&map.positions(), grid)
}
