//! Dense mode: score the frame once, look particles up.
//!
//! Scoring every particle's window costs `ρ × objects` classifier calls per frame. A dense
//! scorer instead produces a [`ScoreMap`] — scores on a regular grid of window centres —
//! once per frame (a fully convolutional pass of a classifier, a detector's heat map, or
//! any window scorer on a stride grid through [`GridScorer`]); [`DenseLikelihood`] then
//! answers each particle by bilinear interpolation. The cost no longer grows with the
//! number of particles.

use super::{Likelihood, check_lengths};
use crate::error::{Error, Result};
use crate::geometry::Point;
use image::RgbImage;

/// Scores on a regular grid: value `(c, r)` (column `c`, row `r`) belongs to the window
/// centred on `(origin.x + c·stride, origin.y + r·stride)` px.
///
/// The one score-map type of the crate: [`GridScorer`], the CNN classifier's fully
/// convolutional pass (`cnn::OnnxClassifier::score_map`) and the SSD detector's map
/// (`cnn::SsdPersonDetector::score_map`) all produce it; [`DenseLikelihood`] answers
/// particles from it by [`ScoreMap::sample`].
#[derive(Debug, Clone, PartialEq)]
pub struct ScoreMap {
    /// Centre of grid cell `(0, 0)`, px.
    pub origin_px: Point,
    /// Grid spacing, px (same along x and y).
    pub stride_px: f64,
    /// Number of columns.
    pub cols: usize,
    /// Number of rows.
    pub rows: usize,
    /// Row-major scores in `[0, 1]`, `cols × rows` of them.
    pub values: Vec<f64>,
}

impl ScoreMap {
    /// Checks the shape.
    pub fn validate(&self) -> Result<()> {
        if self.cols == 0
            || self.rows == 0
            || self.values.len() != self.cols * self.rows
            || !(self.stride_px.is_finite() && self.stride_px > 0.0)
        {
            return Err(Error::Invalid(format!(
                "score map: {} values for {} × {} cells, stride {} px",
                self.values.len(),
                self.cols,
                self.rows,
                self.stride_px
            )));
        }
        Ok(())
    }

    /// The value of cell `(row, col)`; 0 outside the grid.
    pub fn cell(&self, row: usize, col: usize) -> f64 {
        if row < self.rows && col < self.cols {
            self.values
                .get(row * self.cols + col)
                .copied()
                .unwrap_or(0.0)
        } else {
            0.0
        }
    }

    /// The image position of cell `(row, col)`, px.
    pub fn cell_centre_px(&self, row: usize, col: usize) -> Point {
        Point::new(
            self.origin_px.x + col as f64 * self.stride_px,
            self.origin_px.y + row as f64 * self.stride_px,
        )
    }

    /// The score at `p`, bilinear between the four nearest grid points; positions outside
    /// the grid take the nearest edge value. An empty map and NaN positions give 0.
    pub fn sample(&self, p: Point) -> f64 {
        if self.cols == 0 || self.rows == 0 {
            return 0.0;
        }
        let fx = ((p.x - self.origin_px.x) / self.stride_px).clamp(0.0, (self.cols - 1) as f64);
        let fy = ((p.y - self.origin_px.y) / self.stride_px).clamp(0.0, (self.rows - 1) as f64);
        if !(fx.is_finite() && fy.is_finite()) {
            return 0.0;
        }
        let (c0, r0) = (fx.floor() as usize, fy.floor() as usize);
        let (c1, r1) = ((c0 + 1).min(self.cols - 1), (r0 + 1).min(self.rows - 1));
        let (tx, ty) = (fx - c0 as f64, fy - r0 as f64);
        let top = self.cell(r0, c0) * (1.0 - tx) + self.cell(r0, c1) * tx;
        let bottom = self.cell(r1, c0) * (1.0 - tx) + self.cell(r1, c1) * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// [`ScoreMap::sample`] at every position, into `out`.
    ///
    /// # Errors
    /// When `out` and `positions_px` differ in length.
    pub fn lookup(&self, positions_px: &[Point], out: &mut [f64]) -> Result<()> {
        check_lengths(positions_px, out)?;
        for (o, &p) in out.iter_mut().zip(positions_px) {
            *o = self.sample(p);
        }
        Ok(())
    }
}

/// Anything that scores a whole frame at once: a fully convolutional classifier, a
/// detector's per-class heat map, or [`GridScorer`].
pub trait DenseScorer: Send + Sync {
    /// The score map of `image`.
    fn score_map(&self, image: &RgbImage) -> Result<ScoreMap>;
}

/// Any window likelihood evaluated on a grid of centres `k·stride_px` (`k = 0, 1, …`, up to
/// the first centre at or beyond the last pixel), in one batch.
#[derive(Debug, Clone)]
pub struct GridScorer<L> {
    /// The window scorer.
    pub inner: L,
    /// Grid spacing, px (≥ 1).
    pub stride_px: u32,
}

impl<L: Likelihood> DenseScorer for GridScorer<L> {
    fn score_map(&self, image: &RgbImage) -> Result<ScoreMap> {
        let (w, h) = image.dimensions();
        let s = self.stride_px.max(1);
        let cols = (w.saturating_sub(1)).div_ceil(s) as usize + 1;
        let rows = (h.saturating_sub(1)).div_ceil(s) as usize + 1;
        let mut centres = Vec::with_capacity(cols * rows);
        for r in 0..rows {
            for c in 0..cols {
                centres.push(Point::new(
                    (c as u32 * s) as f64 + 0.5,
                    (r as u32 * s) as f64 + 0.5,
                ));
            }
        }
        let mut values = vec![0.0; centres.len()];
        self.inner.evaluate(image, &centres, &mut values)?;
        Ok(ScoreMap {
            origin_px: Point::new(0.5, 0.5),
            stride_px: f64::from(s),
            cols,
            rows,
            values,
        })
    }
}

/// A cheap fingerprint of an image: its size and 64 sampled pixels.
fn fingerprint(image: &RgbImage) -> u64 {
    let (w, h) = image.dimensions();
    let mut f = (u64::from(w) << 32) ^ u64::from(h);
    let raw = image.as_raw();
    if !raw.is_empty() {
        for k in 0..64u64 {
            let i = (k.wrapping_mul(0x9E37_79B9_7F4A_7C15) % raw.len() as u64) as usize;
            f = f.rotate_left(5) ^ u64::from(raw[i]) ^ k;
            f = f.wrapping_mul(0x1000_0000_01B3);
        }
    }
    f
}

/// A likelihood answered from a score map computed once per frame in
/// [`Likelihood::begin_frame`].
pub struct DenseLikelihood {
    scorer: Box<dyn DenseScorer>,
    map: Option<(u64, ScoreMap)>,
}

impl std::fmt::Debug for DenseLikelihood {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DenseLikelihood")
            .field("map", &self.map.as_ref().map(|(_, m)| (m.cols, m.rows)))
            .finish_non_exhaustive()
    }
}

impl DenseLikelihood {
    /// Wraps a dense scorer.
    pub fn new(scorer: Box<dyn DenseScorer>) -> Self {
        Self { scorer, map: None }
    }

    /// The score map of the current frame, if [`Likelihood::begin_frame`] has run.
    pub fn map(&self) -> Option<&ScoreMap> {
        self.map.as_ref().map(|(_, m)| m)
    }
}

impl Likelihood for DenseLikelihood {
    fn evaluate(&self, image: &RgbImage, positions_px: &[Point], out: &mut [f64]) -> Result<()> {
        check_lengths(positions_px, out)?;
        let map = match &self.map {
            Some((f, m)) if *f == fingerprint(image) => m,
            _ => {
                return Err(Error::Invalid(
                    "dense likelihood: begin_frame was not called for this frame".into(),
                ));
            }
        };
        map.lookup(positions_px, out)
    }

    fn begin_frame(&mut self, image: &RgbImage) -> Result<()> {
        let map = self.scorer.score_map(image)?;
        map.validate()?;
        self.map = Some((fingerprint(image), map));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::colour::{ColourLikelihood, ColourLikelihoodConfig};
    use super::*;
    use crate::geometry::BBox;
    use image::Rgb;

    fn small_map() -> ScoreMap {
        ScoreMap {
            origin_px: Point::new(10.0, 20.0),
            stride_px: 4.0,
            cols: 3,
            rows: 2,
            values: vec![0.0, 0.4, 0.8, 0.2, 0.6, 1.0],
        }
    }

    #[test]
    fn lookup_at_cell_centres_returns_cells() {
        let m = small_map();
        for i in 0..2 {
            for j in 0..3 {
                assert!((m.sample(m.cell_centre_px(i, j)) - m.cell(i, j)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn lookup_between_cells_is_bilinear_and_clamped() -> Result<()> {
        let m = small_map();
        assert!((m.sample(Point::new(12.0, 22.0)) - 0.3).abs() < 1e-12);
        assert!((m.sample(Point::new(-100.0, -100.0)) - 0.0).abs() < 1e-12);
        assert!((m.sample(Point::new(1e6, 1e6)) - 1.0).abs() < 1e-12);
        assert_eq!(m.sample(Point::new(f64::NAN, 21.0)), 0.0);
        let mut out = [0.0; 2];
        m.lookup(&[Point::new(14.0, 20.0), Point::new(18.0, 24.0)], &mut out)?;
        assert!((out[0] - 0.4).abs() < 1e-12 && (out[1] - 1.0).abs() < 1e-12);
        assert!(m.lookup(&[Point::new(14.0, 20.0)], &mut out).is_err());
        let empty = ScoreMap {
            cols: 0,
            rows: 0,
            values: Vec::new(),
            ..small_map()
        };
        assert_eq!(empty.sample(Point::new(1.0, 1.0)), 0.0);
        assert!(empty.validate().is_err() && m.validate().is_ok());
        Ok(())
    }

    #[test]
    fn bilinear_lookup_is_exact_for_a_linear_scorer() -> Result<()> {
        let img = RgbImage::new(64, 48);
        let linear = |_: &RgbImage, p: Point| 0.001 * p.x + 0.002 * p.y + 0.1;
        let mut dense = DenseLikelihood::new(Box::new(GridScorer {
            inner: linear,
            stride_px: 8,
        }));
        dense.begin_frame(&img)?;
        let pos: Vec<Point> = (0..50)
            .map(|i| Point::new(1.0 + i as f64 * 1.17, 0.6 + i as f64 * 0.83))
            .collect();
        let mut a = vec![0.0; pos.len()];
        let mut b = vec![0.0; pos.len()];
        dense.evaluate(&img, &pos, &mut a)?;
        linear.evaluate(&img, &pos, &mut b)?;
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-12, "{x} vs {y}");
        }
        Ok(())
    }

    #[test]
    fn dense_colour_agrees_with_per_window_scoring() -> Result<()> {
        // A smooth colour gradient with a red object; the score map at stride 4 must equal
        // per-window scores at grid points and stay close between them.
        let img = RgbImage::from_fn(96, 64, |x, y| {
            let d = ((x as f64 - 48.0).powi(2) + (y as f64 - 32.0).powi(2)).sqrt();
            let red = (255.0 * (1.0 - d / 60.0).max(0.0)) as u8;
            Rgb([red, 60, 255 - red])
        });
        let cfg = ColourLikelihoodConfig {
            sharpness: 3.0,
            ..Default::default()
        };
        let colour = ColourLikelihood::from_boxes(cfg, &img, &[BBox::new(36.0, 20.0, 24.0, 24.0)])?;
        let mut dense = DenseLikelihood::new(Box::new(GridScorer {
            inner: colour.clone(),
            stride_px: 4,
        }));
        dense.begin_frame(&img)?;
        let grid: Vec<Point> = (0..10)
            .map(|i| Point::new(0.5 + 8.0 * i as f64, 0.5 + 4.0 * i as f64))
            .collect();
        let between: Vec<Point> = (0..10)
            .map(|i| Point::new(20.0 + 5.3 * i as f64, 12.0 + 3.7 * i as f64))
            .collect();
        for (points, tol) in [(&grid, 1e-12), (&between, 0.08)] {
            let mut a = vec![0.0; points.len()];
            let mut b = vec![0.0; points.len()];
            dense.evaluate(&img, points, &mut a)?;
            colour.evaluate(&img, points, &mut b)?;
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() <= tol, "dense {x} vs window {y} (tol {tol})");
            }
        }
        Ok(())
    }

    #[test]
    fn evaluating_before_begin_frame_is_an_error() {
        let img = RgbImage::new(8, 8);
        let mut dense = DenseLikelihood::new(Box::new(GridScorer {
            inner: |_: &RgbImage, _: Point| 0.5,
            stride_px: 4,
        }));
        let mut out = [0.0];
        assert!(
            dense
                .evaluate(&img, &[Point::new(1.0, 1.0)], &mut out)
                .is_err()
        );
        assert!(dense.begin_frame(&img).is_ok());
        assert!(
            dense
                .evaluate(&img, &[Point::new(1.0, 1.0)], &mut out)
                .is_ok()
        );
        let other = RgbImage::from_pixel(8, 8, Rgb([1, 2, 3]));
        assert!(
            dense
                .evaluate(&other, &[Point::new(1.0, 1.0)], &mut out)
                .is_err()
        );
    }
}
