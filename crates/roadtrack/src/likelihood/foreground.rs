//! The foreground detector's mask as a likelihood: the fraction of a window that is
//! moving, alone or multiplying another likelihood (the filters' `LikelihoodKind`).

use super::{Likelihood, Window};
use crate::error::{Error, Result};
use crate::geometry::Point;
use image::{GrayImage, RgbImage};
use serde::{Deserialize, Serialize};
use std::sync::{Arc, RwLock};

/// What the trackers' likelihood `h(y | x)` measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LikelihoodKind {
    /// The colour-histogram likelihood alone.
    #[default]
    Colour,
    /// The fraction of the window that the foreground detector marks as moving, divided
    /// by `foreground_full` (the filters' `TrackLikelihoodConfig`) and capped at 1: the detector's mask
    /// as a dense score map (an integral image, O(1) per particle).
    Foreground,
    /// The product of the two.
    ColourForeground,
}

/// The foreground mask of the current frame as an integral image: `sums[(y·(w+1)) + x]`
/// counts the foreground pixels above and left of `(x, y)`.
#[derive(Debug, Default)]
pub struct MaskIntegral {
    width: usize,
    height: usize,
    sums: Vec<u32>,
}

/// The current frame's mask, shared by the tracker (which sets it) and the likelihoods that
/// read it.
pub type SharedMask = Arc<RwLock<MaskIntegral>>;

impl MaskIntegral {
    /// Replaces the mask (255 or any non-zero value = foreground).
    pub fn set(&mut self, mask: &GrayImage) {
        let (w, h) = (mask.width() as usize, mask.height() as usize);
        self.width = w;
        self.height = h;
        self.sums.clear();
        self.sums.resize((w + 1) * (h + 1), 0);
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += u32::from(mask.as_raw()[y * w + x] > 0);
                self.sums[(y + 1) * (w + 1) + x + 1] = self.sums[y * (w + 1) + x + 1] + row;
            }
        }
    }

    /// Fraction of the `window` centred on `p` (clipped to the image) that is foreground.
    pub fn fraction(&self, p: Point, window: &Window) -> f64 {
        if self.width == 0 || !(p.x.is_finite() && p.y.is_finite()) {
            return 0.0;
        }
        let clip = |v: f64, max: usize| v.round().clamp(0.0, max as f64) as usize;
        let (hw, hh) = (
            f64::from(window.width_px) / 2.0,
            f64::from(window.height_px) / 2.0,
        );
        let (x0, x1) = (clip(p.x - hw, self.width), clip(p.x + hw, self.width));
        let (y0, y1) = (clip(p.y - hh, self.height), clip(p.y + hh, self.height));
        if x1 <= x0 || y1 <= y0 {
            return 0.0;
        }
        let s = |x: usize, y: usize| f64::from(self.sums[y * (self.width + 1) + x]);
        (s(x1, y1) - s(x0, y1) - s(x1, y0) + s(x0, y0)) / ((x1 - x0) * (y1 - y0)) as f64
    }
}

/// `inner` as `kind` says: alone, replaced by the foreground fraction of `window` in the
/// current `mask` divided by `full` (capped at 1), or multiplied by it.
pub fn with_foreground(
    kind: LikelihoodKind,
    full: f64,
    inner: Box<dyn Likelihood>,
    window: Window,
    mask: &SharedMask,
) -> Box<dyn Likelihood> {
    match kind {
        LikelihoodKind::Colour => inner,
        LikelihoodKind::Foreground => Box::new(ForegroundLikelihood {
            inner: None,
            mask: Arc::clone(mask),
            window,
            full,
        }),
        LikelihoodKind::ColourForeground => Box::new(ForegroundLikelihood {
            inner: Some(inner),
            mask: Arc::clone(mask),
            window,
            full,
        }),
    }
}

/// `h = inner · min(1, foreground fraction / full)` (`inner` = 1 when absent).
pub struct ForegroundLikelihood {
    inner: Option<Box<dyn Likelihood>>,
    mask: SharedMask,
    window: Window,
    full: f64,
}

impl Likelihood for ForegroundLikelihood {
    fn evaluate(&self, image: &RgbImage, positions_px: &[Point], out: &mut [f64]) -> Result<()> {
        match &self.inner {
            Some(inner) => inner.evaluate(image, positions_px, out)?,
            None => {
                crate::likelihood::check_lengths(positions_px, out)?;
                out.iter_mut().for_each(|o| *o = 1.0);
            }
        }
        let mask = self
            .mask
            .read()
            .map_err(|_| Error::Invalid("foreground mask lock poisoned".to_owned()))?;
        for (o, &p) in out.iter_mut().zip(positions_px) {
            *o *= (mask.fraction(p, &self.window) / self.full).min(1.0);
        }
        Ok(())
    }

    fn begin_frame(&mut self, image: &RgbImage) -> Result<()> {
        match &mut self.inner {
            Some(inner) => inner.begin_frame(image),
            None => Ok(()),
        }
    }
}
