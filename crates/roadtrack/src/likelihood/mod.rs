//! Observation likelihoods `h(y | x)` for the particle filters (METHODS.md §3 "Observation
//! model", seed 004).
//!
//! A [`Likelihood`] scores a batch of particle positions on one image: for each position,
//! the probability in `[0, 1]` that a window centred there shows the target. The batch
//! shape lets a CNN score every particle of a frame in one forward pass; the provided
//! [`Likelihood::begin_frame`] lets a dense scorer compute a whole-frame score map once per
//! frame ([`dense`]) and answer particles by lookup.
//!
//! Implementations: [`colour::ColourLikelihood`] (colour-histogram Bhattacharyya, the classic
//! model-free baseline), [`dense::DenseLikelihood`] (score map + bilinear lookup), and any
//! closure `Fn(&RgbImage, Point) -> f64`. A CNN classifier (ONNX through tract) implements
//! `Likelihood` on windows cut by [`roi::Window`], and [`dense::DenseScorer`] for its
//! fully convolutional or heat-map form.

pub mod colour;
pub mod dense;
pub mod foreground;
pub mod roi;

pub use colour::{ColourHistogram, ColourLikelihood, ColourLikelihoodConfig};
pub use dense::{DenseLikelihood, DenseScorer, GridScorer, ScoreMap};
pub use roi::{BorderPolicy, Window};

use crate::error::{Error, Result};
use crate::geometry::Point;
use image::RgbImage;
use rayon::prelude::*;

/// The observation likelihood `h(y | x)` of METHODS.md §3.
///
/// For each position, the probability that a window of `image` centred there shows the
/// target class. Values are in `[0, 1]`. Implementations must be deterministic: the same
/// image and positions give the same values whatever the thread count.
pub trait Likelihood: Send + Sync {
    /// Writes `h(y | x_i)` into `out[i]` for every `positions_px[i]`.
    ///
    /// # Errors
    /// When `out` and `positions_px` differ in length, or the scorer fails.
    fn evaluate(&self, image: &RgbImage, positions_px: &[Point], out: &mut [f64]) -> Result<()>;

    /// Called by the trackers once per frame, before any [`Likelihood::evaluate`] on it.
    /// Dense likelihoods compute their score map here; the default does nothing.
    fn begin_frame(&mut self, image: &RgbImage) -> Result<()> {
        let _ = image;
        Ok(())
    }
}

/// Any closure `|image, pos_px| -> probability` is a likelihood (evaluated in parallel).
impl<F> Likelihood for F
where
    F: Fn(&RgbImage, Point) -> f64 + Send + Sync,
{
    fn evaluate(&self, image: &RgbImage, positions_px: &[Point], out: &mut [f64]) -> Result<()> {
        check_lengths(positions_px, out)?;
        out.par_iter_mut()
            .zip(positions_px.par_iter())
            .for_each(|(o, &p)| *o = self(image, p));
        Ok(())
    }
}

/// Returns an error unless `positions` and `out` have the same length.
pub fn check_lengths(positions: &[Point], out: &[f64]) -> Result<()> {
    if positions.len() == out.len() {
        Ok(())
    } else {
        Err(Error::Invalid(format!(
            "likelihood: {} positions but {} output slots",
            positions.len(),
            out.len()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_closure_is_a_likelihood() -> Result<()> {
        let img = RgbImage::new(4, 4);
        let l = |_: &RgbImage, p: Point| if p.x > 1.0 { 0.9 } else { 0.1 };
        let mut out = [0.0; 2];
        l.evaluate(
            &img,
            &[Point::new(0.0, 0.0), Point::new(2.0, 0.0)],
            &mut out,
        )?;
        assert_eq!(out, [0.1, 0.9]);
        assert!(l.evaluate(&img, &[Point::new(0.0, 0.0)], &mut out).is_err());
        Ok(())
    }
}
