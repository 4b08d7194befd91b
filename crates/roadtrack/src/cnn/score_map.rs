//! A per-location class-probability grid over a frame (dense mode), with bilinear lookup.

use crate::geometry::Point;

/// Class probabilities on a regular grid of image positions: cell `(i, j)` (row `i`,
/// column `j`) holds the probability for the window centred at
/// `(origin_px.x + j · stride_px, origin_px.y + i · stride_px)`.
///
/// Built once per frame by a dense pass of the network; particles then look their
/// likelihood up with [`ScoreMap::at`] instead of running the network per particle.
#[derive(Debug, Clone, PartialEq)]
pub struct ScoreMap {
    /// Image position of cell `(0, 0)`, px.
    pub origin_px: Point,
    /// Distance between neighbouring cells, px (same along x and y).
    pub stride_px: f64,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Row-major probabilities, `height · width` values in `[0, 1]`.
    pub values: Vec<f32>,
}

impl ScoreMap {
    /// The value of cell `(row, col)`.
    ///
    /// # Panics
    /// If the cell is outside the grid.
    pub fn cell(&self, row: usize, col: usize) -> f64 {
        f64::from(self.values[row * self.width + col])
    }

    /// The image position of cell `(row, col)`, px.
    pub fn cell_centre_px(&self, row: usize, col: usize) -> Point {
        Point::new(
            self.origin_px.x + col as f64 * self.stride_px,
            self.origin_px.y + row as f64 * self.stride_px,
        )
    }

    /// Bilinear interpolation of the grid at image position `p`; positions beyond the grid
    /// take the nearest edge cell's value. An empty map gives 0.
    pub fn at(&self, p: Point) -> f64 {
        if self.width == 0 || self.height == 0 {
            return 0.0;
        }
        let gx = ((p.x - self.origin_px.x) / self.stride_px).clamp(0.0, (self.width - 1) as f64);
        let gy = ((p.y - self.origin_px.y) / self.stride_px).clamp(0.0, (self.height - 1) as f64);
        if !gx.is_finite() || !gy.is_finite() {
            return 0.0;
        }
        let (j0, i0) = (gx.floor() as usize, gy.floor() as usize);
        let (j1, i1) = ((j0 + 1).min(self.width - 1), (i0 + 1).min(self.height - 1));
        let (fx, fy) = (gx - j0 as f64, gy - i0 as f64);
        let top = self.cell(i0, j0) * (1.0 - fx) + self.cell(i0, j1) * fx;
        let bottom = self.cell(i1, j0) * (1.0 - fx) + self.cell(i1, j1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Looks every position up ([`ScoreMap::at`]) into `out`.
    ///
    /// # Panics
    /// If `out` and `positions_px` differ in length.
    pub fn lookup(&self, positions_px: &[Point], out: &mut [f64]) {
        assert_eq!(positions_px.len(), out.len(), "one output per position");
        for (o, p) in out.iter_mut().zip(positions_px) {
            *o = self.at(*p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map() -> ScoreMap {
        ScoreMap {
            origin_px: Point::new(10.0, 20.0),
            stride_px: 4.0,
            width: 3,
            height: 2,
            values: vec![0.0, 0.4, 0.8, 0.2, 0.6, 1.0],
        }
    }

    #[test]
    fn lookup_at_cell_centres_returns_cells() {
        let m = map();
        for i in 0..2 {
            for j in 0..3 {
                assert!((m.at(m.cell_centre_px(i, j)) - m.cell(i, j)).abs() < 1e-7);
            }
        }
    }

    #[test]
    fn lookup_between_cells_is_bilinear_and_clamped() {
        let m = map();
        assert!((m.at(Point::new(12.0, 22.0)) - 0.3).abs() < 1e-7);
        assert!((m.at(Point::new(-100.0, -100.0)) - 0.0).abs() < 1e-12);
        assert!((m.at(Point::new(1e6, 1e6)) - 1.0).abs() < 1e-7);
        let mut out = [0.0; 2];
        m.lookup(&[Point::new(14.0, 20.0), Point::new(18.0, 24.0)], &mut out);
        assert!((out[0] - 0.4).abs() < 1e-7 && (out[1] - 1.0).abs() < 1e-7);
    }
}
