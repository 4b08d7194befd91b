//! Colour-histogram likelihood with the Bhattacharyya coefficient: the classic hand-made
//! observation model the paper sets against its CNN (seed 004 §1; Pérez et al. 2002).
//!
//! ```text
//! BC(p, q) = Σ_b √(p_b · q_b)            (Bhattacharyya coefficient, in [0, 1])
//! h(y | x) = exp(−λ · (1 − BC(p(x), q)))  (p(x): histogram of the window at x; q: reference)
//! ```
//!
//! It needs no model file: the reference histogram comes from the initial detection.

use super::roi::Window;
use super::{Likelihood, check_lengths};
use crate::error::{Error, Result};
use crate::geometry::{BBox, Point};
use image::RgbImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Parameters of the colour-histogram likelihood.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ColourLikelihoodConfig {
    /// Histogram bins per RGB channel (the histogram has `bins³` cells). Default 8.
    pub bins_per_channel: u32,
    /// The window scored at each particle.
    pub window: Window,
    /// Sample every `pixel_step`-th row and column of the window. Default 2.
    // Choice: a 2-pixel stride quarters the cost with no visible change of the histogram
    // for windows of 32 px and more.
    pub pixel_step: u32,
    /// `λ` in `h = exp(−λ·(1 − BC))`. Default 20 (Pérez et al. 2002).
    pub sharpness: f64,
}

impl Default for ColourLikelihoodConfig {
    fn default() -> Self {
        Self {
            bins_per_channel: 8,
            window: Window::default(),
            pixel_step: 2,
            sharpness: 20.0,
        }
    }
}

impl ColourLikelihoodConfig {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<()> {
        let c = "ColourLikelihoodConfig";
        if !(1..=64).contains(&self.bins_per_channel) {
            return Err(Error::config(c, "bins_per_channel", "must be in 1..=64"));
        }
        if self.window.width_px == 0 || self.window.height_px == 0 {
            return Err(Error::config(
                c,
                "window",
                "width and height must be ≥ 1 px",
            ));
        }
        let side = self.window.width_px.max(self.window.height_px);
        crate::limits::at_most(
            side,
            crate::limits::MAX_IMAGE_SIDE,
            "longest image side, px",
        )
        .map_err(|m| Error::config(c, "window", m))?;
        if self.pixel_step == 0 {
            return Err(Error::config(c, "pixel_step", "must be ≥ 1"));
        }
        if !(self.sharpness.is_finite() && self.sharpness > 0.0) {
            return Err(Error::config(c, "sharpness", "must be finite and > 0"));
        }
        Ok(())
    }
}

/// A normalised RGB histogram with `bins³` cells.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourHistogram {
    bins: u32,
    values: Vec<f64>,
}

impl ColourHistogram {
    /// An empty (all-zero) histogram.
    pub fn zeros(bins: u32) -> Self {
        Self {
            bins,
            values: vec![0.0; (bins * bins * bins) as usize],
        }
    }

    /// The normalised values, in cell order `(r·bins + g)·bins + b`.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Fills `self` with the histogram of the window at `centre_px`; returns the pixel count.
    fn fill(&mut self, image: &RgbImage, window: &Window, step: u32, centre_px: Point) -> usize {
        self.values.iter_mut().for_each(|v| *v = 0.0);
        let bins = self.bins;
        let n = window.for_each_pixel(image, centre_px, step, |p| {
            let q = |c: u8| u32::from(c) * bins / 256;
            let cell = (q(p[0]) * bins + q(p[1])) * bins + q(p[2]);
            self.values[cell as usize] += 1.0;
        });
        if n > 0 {
            let inv = 1.0 / n as f64;
            self.values.iter_mut().for_each(|v| *v *= inv);
        }
        n
    }

    /// The histogram of the window of `cfg` centred on `centre_px`.
    pub fn of_window(image: &RgbImage, cfg: &ColourLikelihoodConfig, centre_px: Point) -> Self {
        let mut h = Self::zeros(cfg.bins_per_channel);
        h.fill(image, &cfg.window, cfg.pixel_step, centre_px);
        h
    }

    /// The histogram of every pixel inside `bbox` (clipped to the image).
    pub fn of_box(image: &RgbImage, bins: u32, bbox: &BBox) -> Self {
        let window = Window::new(
            bbox.width.round().max(1.0) as u32,
            bbox.height.round().max(1.0) as u32,
            super::BorderPolicy::Skip,
        );
        let mut h = Self::zeros(bins);
        h.fill(image, &window, 1, bbox.centre());
        h
    }

    /// Bhattacharyya coefficient `Σ √(p_b q_b)` with `other` (1 for identical histograms).
    pub fn bhattacharyya(&self, other: &ColourHistogram) -> f64 {
        self.values
            .iter()
            .zip(&other.values)
            .map(|(a, b)| (a * b).sqrt())
            .sum::<f64>()
            .min(1.0)
    }

    /// The average of `hists` (all with the same bins), normalised; `None` if empty.
    pub fn mean(hists: &[ColourHistogram]) -> Option<Self> {
        let first = hists.first()?;
        let mut out = Self::zeros(first.bins);
        for h in hists {
            for (o, v) in out.values.iter_mut().zip(&h.values) {
                *o += v / hists.len() as f64;
            }
        }
        Some(out)
    }
}

/// `h(y | x) = exp(−λ(1 − BC))` against one reference histogram.
#[derive(Debug, Clone)]
pub struct ColourLikelihood {
    config: ColourLikelihoodConfig,
    reference: ColourHistogram,
}

impl ColourLikelihood {
    /// A likelihood with the given reference histogram.
    ///
    /// # Errors
    /// When the config is invalid or the reference has another number of bins.
    pub fn new(config: ColourLikelihoodConfig, reference: ColourHistogram) -> Result<Self> {
        config.validate()?;
        if reference.bins != config.bins_per_channel {
            return Err(Error::config(
                "ColourLikelihoodConfig",
                "bins_per_channel",
                format!(
                    "reference histogram has {} bins per channel, config {}",
                    reference.bins, config.bins_per_channel
                ),
            ));
        }
        Ok(Self { config, reference })
    }

    /// A likelihood whose reference is the mean histogram of the given boxes (e.g. the
    /// initial detections).
    ///
    /// # Errors
    /// When `boxes` is empty or the config is invalid.
    pub fn from_boxes(
        config: ColourLikelihoodConfig,
        image: &RgbImage,
        boxes: &[BBox],
    ) -> Result<Self> {
        let hists: Vec<_> = boxes
            .iter()
            .map(|b| ColourHistogram::of_box(image, config.bins_per_channel, b))
            .collect();
        let reference = ColourHistogram::mean(&hists).ok_or_else(|| {
            Error::Invalid("colour likelihood: no box to take the reference from".into())
        })?;
        Self::new(config, reference)
    }

    /// The configuration.
    pub fn config(&self) -> &ColourLikelihoodConfig {
        &self.config
    }

    /// The likelihood of the window at one position.
    pub fn score(&self, image: &RgbImage, centre_px: Point) -> f64 {
        let mut h = ColourHistogram::zeros(self.config.bins_per_channel);
        self.score_with(&mut h, image, centre_px)
    }

    fn score_with(&self, scratch: &mut ColourHistogram, image: &RgbImage, p: Point) -> f64 {
        if scratch.fill(image, &self.config.window, self.config.pixel_step, p) == 0 {
            return 0.0;
        }
        let bc = scratch.bhattacharyya(&self.reference);
        (-self.config.sharpness * (1.0 - bc)).exp()
    }
}

impl Likelihood for ColourLikelihood {
    fn evaluate(&self, image: &RgbImage, positions_px: &[Point], out: &mut [f64]) -> Result<()> {
        check_lengths(positions_px, out)?;
        let bins = self.config.bins_per_channel;
        out.par_iter_mut()
            .zip(positions_px.par_iter())
            .for_each_init(
                || ColourHistogram::zeros(bins),
                |scratch, (o, &p)| *o = self.score_with(scratch, image, p),
            );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    /// Grey background with a red 32 × 32 square centred on (50, 40).
    fn scene() -> RgbImage {
        RgbImage::from_fn(100, 80, |x, y| {
            if (34..66).contains(&x) && (24..56).contains(&y) {
                Rgb([200, 30, 30])
            } else {
                Rgb([90, 90, 90])
            }
        })
    }

    #[test]
    fn likelihood_peaks_on_the_reference_object() -> Result<()> {
        let img = scene();
        let cfg = ColourLikelihoodConfig::default();
        let l = ColourLikelihood::from_boxes(cfg, &img, &[BBox::new(34.0, 24.0, 32.0, 32.0)])?;
        let pos = [
            Point::new(50.0, 40.0),
            Point::new(58.0, 40.0),
            Point::new(15.0, 15.0),
        ];
        let mut out = [0.0; 3];
        l.evaluate(&img, &pos, &mut out)?;
        assert!((out[0] - 1.0).abs() < 1e-9, "on target {}", out[0]);
        assert!(out[0] > out[1] && out[1] > out[2], "{out:?}");
        assert!(out[2] < 1e-6, "background {}", out[2]);
        Ok(())
    }

    #[test]
    fn bhattacharyya_of_identical_histograms_is_one() {
        let img = scene();
        let h = ColourHistogram::of_box(&img, 8, &BBox::new(30.0, 20.0, 40.0, 40.0));
        assert!((h.bhattacharyya(&h) - 1.0).abs() < 1e-12);
        assert!((h.values().iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn mismatched_bins_are_rejected() {
        let cfg = ColourLikelihoodConfig::default();
        assert!(ColourLikelihood::new(cfg, ColourHistogram::zeros(4)).is_err());
        assert!(ColourLikelihood::from_boxes(cfg, &scene(), &[]).is_err());
    }
}
