//! A uniform grid over points for rectangle queries, stored as points sorted by cell.
//!
//! Memory is one `(cell key, index)` pair per point whatever the extent of the scene (no
//! dense cell array), and a query costs one binary search per grid row it touches.

use crate::geometry::Point;

/// Points bucketed into square cells of side `cell`, sorted by `(row, column, index)`.
#[derive(Debug, Clone)]
pub(crate) struct PointGrid {
    cell: f64,
    /// `(key, point index)`, sorted; the key packs `(row, column)`.
    entries: Vec<(u64, u32)>,
}

/// Row and column of `(x, y)` in cells of side `cell`, clamped to ±2³⁰.
pub(crate) fn cell_of(x: f64, y: f64, cell: f64) -> (i64, i64) {
    const LIM: f64 = (1u64 << 30) as f64;
    let c = (x / cell).floor().clamp(-LIM, LIM) as i64;
    let r = (y / cell).floor().clamp(-LIM, LIM) as i64;
    (r, c)
}

/// Packs `(row, column)` so that keys sort by row, then column.
pub(crate) fn key(r: i64, c: i64) -> u64 {
    const OFF: i64 = 1 << 31;
    (((r + OFF) as u64) << 32) | ((c + OFF) as u64)
}

impl PointGrid {
    /// A grid of side `cell` px (values ≤ 0 or non-finite become 1 px) over `points`.
    pub fn new(points: impl Iterator<Item = Point>, cell: f64) -> Self {
        let cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            1.0
        };
        let mut entries: Vec<(u64, u32)> = points
            .enumerate()
            .map(|(i, p)| {
                let (r, c) = cell_of(p.x, p.y, cell);
                (key(r, c), i as u32)
            })
            .collect();
        entries.sort_unstable();
        Self { cell, entries }
    }

    /// The point indices in grid order: by cell row, cell column, then index.
    pub fn order(&self) -> Vec<u32> {
        self.entries.iter().map(|e| e.1).collect()
    }

    /// Calls `f` with the index of every point whose cell meets the rectangle
    /// `[x0, x1] × [y0, y1]` (a superset of the points inside it; callers test exactly).
    /// Order: by row, column, then index.
    pub fn for_each_candidate(&self, x0: f64, y0: f64, x1: f64, y1: f64, mut f: impl FnMut(u32)) {
        let (r0, c0) = cell_of(x0, y0, self.cell);
        let (r1, c1) = cell_of(x1, y1, self.cell);
        for r in r0..=r1 {
            let lo = key(r, c0);
            let hi = key(r, c1);
            let start = self.entries.partition_point(|e| e.0 < lo);
            for e in &self.entries[start..] {
                if e.0 > hi {
                    break;
                }
                f(e.1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rectangle_query_finds_every_point_inside() {
        let pts: Vec<Point> = (0..200)
            .map(|i| Point::new((i * 37 % 101) as f64 - 50.0, (i * 53 % 97) as f64 - 40.0))
            .collect();
        let grid = PointGrid::new(pts.iter().copied(), 7.0);
        let (x0, y0, x1, y1) = (-13.5, -3.0, 22.0, 30.5);
        let mut found = Vec::new();
        grid.for_each_candidate(x0, y0, x1, y1, |i| found.push(i));
        let inside: Vec<u32> = (0..pts.len() as u32)
            .filter(|&i| {
                let p = pts[i as usize];
                (x0..=x1).contains(&p.x) && (y0..=y1).contains(&p.y)
            })
            .collect();
        for i in &inside {
            assert!(found.contains(i), "point {i} missed");
        }
        assert!(found.len() < pts.len(), "the grid should prune");
    }
}
