//! Per-pixel background model for fixed cameras, and the foreground mask it gives.
//!
//! The model is a running Gaussian per pixel (Wren et al. 1997, "Pfinder"; the "running
//! Gaussian average" of Piccardi 2004): a mean colour `μ` (RGB) and one variance `σ²` per
//! pixel. A pixel is foreground when its squared colour distance to the mean exceeds
//! `k² · 3 · max(σ², σ_min²)`. After each frame the mean and variance move towards the
//! frame by a learning rate, a slow one where the pixel is foreground (selective update), so
//! that slow lighting change is absorbed while moving objects do not burn into the
//! background, and a stopped object fades in after roughly `1 / foreground_learning_rate`
//! frames.
//!
//! Start-up: the initial mean is the per-pixel median of a handful of frames sampled evenly
//! over the sequence (a moving object covers a pixel in only a few of them), and the initial
//! variance is the squared median absolute deviation of those samples, scaled to a standard
//! deviation (× 1.4826).
//!
//! Choice: a single Gaussian rather than a Gaussian mixture. Our scenes (fixed cameras on
//! roads, simulated or real) have unimodal backgrounds; a mixture costs 3–5× the time and
//! its extra modes absorb slow vehicles in queues. Shadows are not modelled: a strong
//! shadow is foreground (documented limitation in docs/DETECTION.md).

use crate::error::{Error, Result};
use image::{GrayImage, RgbImage};
use serde::{Deserialize, Serialize};

/// Parameters of the background model (not from a paper: the spine's own defaults, tuned
/// on `vtest.avi` and on simulated scenes; see docs/DETECTION.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BackgroundConfig {
    /// Learning rate of background pixels per frame (α). Default 0.02 (time constant 50 frames).
    pub learning_rate: f64,
    /// Learning rate of foreground pixels per frame. Default 0.001 (a stopped object fades
    /// into the background after about 1 000 frames).
    pub foreground_learning_rate: f64,
    /// Threshold `k` in standard deviations. Default 3.
    pub threshold_sigma: f64,
    /// Floor on the per-pixel standard deviation, grey levels. Default 8 (compression noise).
    pub min_sigma: f64,
    /// Ceiling on the per-pixel standard deviation, grey levels. Default 40 (keeps flicker
    /// from disabling a pixel).
    pub max_sigma: f64,
    /// Frames sampled evenly over the sequence for the initial median. Default 25.
    pub bootstrap_frames: u32,
}

impl Default for BackgroundConfig {
    fn default() -> Self {
        Self {
            learning_rate: 0.02,
            foreground_learning_rate: 0.001,
            threshold_sigma: 3.0,
            min_sigma: 8.0,
            max_sigma: 40.0,
            bootstrap_frames: 25,
        }
    }
}

impl BackgroundConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        let unit = |v: f64, f: &'static str| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(Error::config(
                    "BackgroundConfig",
                    f,
                    format!("must be in [0, 1], found {v}"),
                ))
            }
        };
        unit(self.learning_rate, "learning_rate")?;
        unit(self.foreground_learning_rate, "foreground_learning_rate")?;
        if !(self.threshold_sigma.is_finite() && self.threshold_sigma > 0.0) {
            return Err(Error::config(
                "BackgroundConfig",
                "threshold_sigma",
                "must be positive",
            ));
        }
        if !(self.min_sigma.is_finite() && self.min_sigma > 0.0) {
            return Err(Error::config(
                "BackgroundConfig",
                "min_sigma",
                format!("must be finite and > 0, found {}", self.min_sigma),
            ));
        }
        if !(self.max_sigma.is_finite() && self.max_sigma >= self.min_sigma) {
            return Err(Error::config(
                "BackgroundConfig",
                "max_sigma",
                format!(
                    "must be finite and ≥ min_sigma {}, found {}",
                    self.min_sigma, self.max_sigma
                ),
            ));
        }
        if self.bootstrap_frames == 0 {
            return Err(Error::config(
                "BackgroundConfig",
                "bootstrap_frames",
                "must be at least 1",
            ));
        }
        crate::limits::at_most(
            self.bootstrap_frames,
            crate::limits::MAX_BOOTSTRAP_FRAMES,
            "frames held for the median",
        )
        .map_err(|m| Error::config("BackgroundConfig", "bootstrap_frames", m))?;
        Ok(())
    }
}

/// The running per-pixel Gaussian background.
#[derive(Debug, Clone)]
pub struct BackgroundModel {
    config: BackgroundConfig,
    width: u32,
    height: u32,
    /// Mean colour, 3 values per pixel, row-major.
    mean: Vec<f32>,
    /// Variance of one channel, 1 value per pixel.
    var: Vec<f32>,
}

impl BackgroundModel {
    /// A model initialised from sample frames: per-pixel median and median absolute
    /// deviation over `samples` (all of the same size; at least one).
    pub fn from_samples(samples: &[RgbImage], config: BackgroundConfig) -> Result<Self> {
        config.validate()?;
        let first = samples.first().ok_or_else(|| {
            Error::Invalid("background model needs at least one sample frame".into())
        })?;
        let (width, height) = first.dimensions();
        for (i, s) in samples.iter().enumerate() {
            if s.dimensions() != (width, height) {
                return Err(Error::FrameSize {
                    frame: i as u32 + 1,
                    got: s.dimensions(),
                    expected: (width, height),
                });
            }
        }
        let n_px = width as usize * height as usize;
        let mut mean = vec![0f32; n_px * 3];
        let mut var = vec![0f32; n_px];
        let mut column = Vec::with_capacity(samples.len());
        let mut dev = Vec::with_capacity(samples.len() * 3);
        let min_var = (config.min_sigma * config.min_sigma) as f32;
        let max_var = (config.max_sigma * config.max_sigma) as f32;
        for p in 0..n_px {
            dev.clear();
            for c in 0..3 {
                column.clear();
                column.extend(samples.iter().map(|s| s.as_raw()[p * 3 + c]));
                column.sort_unstable();
                let med = median_u8(&column);
                mean[p * 3 + c] = med;
                dev.extend(column.iter().map(|&v| (f32::from(v) - med).abs()));
            }
            dev.sort_unstable_by(f32::total_cmp);
            let mad = if dev.is_empty() {
                0.0
            } else {
                dev[dev.len() / 2]
            };
            let sigma = 1.4826 * mad;
            var[p] = (sigma * sigma).clamp(min_var, max_var);
        }
        Ok(Self {
            config,
            width,
            height,
            mean,
            var,
        })
    }

    /// Frame size the model was built for.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The current background estimate as an image.
    pub fn background(&self) -> RgbImage {
        let raw = self
            .mean
            .iter()
            .map(|&m| m.round().clamp(0.0, 255.0) as u8)
            .collect();
        RgbImage::from_raw(self.width, self.height, raw)
            .unwrap_or_else(|| RgbImage::new(self.width, self.height))
    }

    /// Classifies every pixel of `image` (255 = foreground, 0 = background), then updates
    /// the model with `image`.
    ///
    /// # Errors
    /// The image does not have the model's size.
    pub fn apply(&mut self, frame_index: u32, image: &RgbImage) -> Result<GrayImage> {
        if image.dimensions() != (self.width, self.height) {
            return Err(Error::FrameSize {
                frame: frame_index,
                got: image.dimensions(),
                expected: (self.width, self.height),
            });
        }
        let k2x3 = (self.config.threshold_sigma * self.config.threshold_sigma * 3.0) as f32;
        let min_var = (self.config.min_sigma * self.config.min_sigma) as f32;
        let max_var = (self.config.max_sigma * self.config.max_sigma) as f32;
        let a_bg = self.config.learning_rate as f32;
        let a_fg = self.config.foreground_learning_rate as f32;
        let mut mask = vec![0u8; self.var.len()];
        let px = image.as_raw();
        for (((m, mu), v), rgb) in mask
            .iter_mut()
            .zip(self.mean.chunks_exact_mut(3))
            .zip(self.var.iter_mut())
            .zip(px.chunks_exact(3))
        {
            let d0 = f32::from(rgb[0]) - mu[0];
            let d1 = f32::from(rgb[1]) - mu[1];
            let d2 = f32::from(rgb[2]) - mu[2];
            let dist2 = d0 * d0 + d1 * d1 + d2 * d2;
            let fg = dist2 > k2x3 * v.max(min_var);
            let a = if fg { a_fg } else { a_bg };
            *m = if fg { 255 } else { 0 };
            mu[0] += a * d0;
            mu[1] += a * d1;
            mu[2] += a * d2;
            *v = (*v + a * (dist2 / 3.0 - *v)).clamp(min_var, max_var);
        }
        GrayImage::from_raw(self.width, self.height, mask)
            .ok_or_else(|| Error::Invalid("mask size mismatch".into()))
    }
}

fn median_u8(sorted: &[u8]) -> f32 {
    let n = sorted.len();
    if n % 2 == 1 {
        f32::from(sorted[n / 2])
    } else {
        (f32::from(sorted[n / 2 - 1]) + f32::from(sorted[n / 2])) / 2.0
    }
}

/// Indices of `bootstrap` frames spread evenly over `total` frames (0-based positions in the
/// selected sequence), or the first `bootstrap` when `total` is unknown.
pub fn bootstrap_positions(total: Option<u32>, bootstrap: u32) -> Vec<u32> {
    match total {
        Some(t) if t > bootstrap => (0..bootstrap)
            .map(|i| ((u64::from(i) * u64::from(t)) / u64::from(bootstrap)) as u32)
            .collect(),
        Some(t) => (0..t).collect(),
        None => (0..bootstrap).collect(),
    }
}

/// Keeps `bootstrap` frames spread evenly over `frames` (whose count is `total` when known;
/// see [`bootstrap_positions`]) and stops reading once it has them.
pub fn sample_frames(
    frames: impl Iterator<Item = Result<crate::frame::Frame>>,
    total: Option<u32>,
    bootstrap: u32,
) -> Result<Vec<RgbImage>> {
    let wanted = bootstrap_positions(total, bootstrap);
    let mut samples = Vec::with_capacity(wanted.len());
    let mut next = wanted.iter().peekable();
    for (pos, frame) in frames.enumerate() {
        let Some(&&want) = next.peek() else { break };
        if pos as u32 == want {
            samples.push(frame?.image);
            next.next();
        }
    }
    Ok(samples)
}

/// A background model bootstrapped from a frame source: a first, read-only pass over
/// `input` with `options` collects the sample frames.
pub fn bootstrap_from_source(
    input: &std::path::Path,
    options: &crate::io::SourceOptions,
    config: BackgroundConfig,
) -> Result<BackgroundModel> {
    let first = crate::io::source::open(input, options)?;
    let total = first.info.selected_frames;
    let samples = sample_frames(first, total, config.bootstrap_frames)?;
    BackgroundModel::from_samples(&samples, config)
}

/// A background model bootstrapped from frames already in memory: `bootstrap_frames`
/// of them spread evenly over the slice (see [`bootstrap_positions`]).
///
/// # Errors
/// No frames, or frames of different sizes (see [`BackgroundModel::from_samples`]).
pub fn bootstrap_from_frames(
    frames: &[crate::frame::Frame],
    config: BackgroundConfig,
) -> Result<BackgroundModel> {
    let samples: Vec<RgbImage> =
        bootstrap_positions(Some(frames.len() as u32), config.bootstrap_frames)
            .iter()
            .map(|&p| frames[p as usize].image.clone())
            .collect();
    BackgroundModel::from_samples(&samples, config)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    fn plain(v: u8) -> RgbImage {
        RgbImage::from_pixel(16, 12, Rgb([v, v, v]))
    }

    #[test]
    fn bootstrap_from_frames_uses_the_evenly_spread_frames() -> Result<()> {
        // 8 frames of grey levels 0, 10, …, 70; 4 bootstrap frames → positions 0, 2, 4, 6
        // (levels 0, 20, 40, 60): the per-pixel median is the same as from those samples.
        let frames: Vec<crate::frame::Frame> = (0..8u8)
            .map(|i| crate::frame::Frame {
                index: u32::from(i) + 1,
                time_s: f64::from(i) / 10.0,
                image: plain(10 * i),
            })
            .collect();
        let config = BackgroundConfig {
            bootstrap_frames: 4,
            ..BackgroundConfig::default()
        };
        let direct = BackgroundModel::from_samples(
            &[plain(0), plain(20), plain(40), plain(60)],
            config.clone(),
        )?;
        let model = bootstrap_from_frames(&frames, config)?;
        assert_eq!(model.background(), direct.background());
        assert!(bootstrap_from_frames(&[], BackgroundConfig::default()).is_err());
        Ok(())
    }

    #[test]
    fn median_ignores_an_object_seen_in_a_minority_of_samples() -> Result<()> {
        let mut with_object = plain(100);
        with_object.put_pixel(3, 3, Rgb([250, 0, 0]));
        let model = BackgroundModel::from_samples(
            &[plain(100), with_object, plain(100)],
            BackgroundConfig::default(),
        )?;
        assert_eq!(model.background().get_pixel(3, 3), &Rgb([100, 100, 100]));
        Ok(())
    }

    #[test]
    fn object_is_foreground_and_background_is_not() -> Result<()> {
        let mut model = BackgroundModel::from_samples(&[plain(100)], BackgroundConfig::default())?;
        let mut img = plain(100);
        for x in 4..8 {
            img.put_pixel(x, 5, Rgb([30, 200, 30]));
        }
        let mask = model.apply(1, &img)?;
        let fg: Vec<(u32, u32)> = mask
            .enumerate_pixels()
            .filter(|p| p.2[0] == 255)
            .map(|p| (p.0, p.1))
            .collect();
        assert_eq!(fg, vec![(4, 5), (5, 5), (6, 5), (7, 5)]);
        Ok(())
    }

    #[test]
    fn slow_lighting_drift_is_absorbed() -> Result<()> {
        let mut model = BackgroundModel::from_samples(&[plain(100)], BackgroundConfig::default())?;
        // +1 grey level per frame for 100 frames: never foreground.
        for i in 1..=100u8 {
            let mask = model.apply(u32::from(i), &plain(100 + i))?;
            assert!(mask.pixels().all(|p| p[0] == 0), "frame {i} has foreground");
        }
        Ok(())
    }

    #[test]
    fn sudden_change_is_foreground_and_wrong_size_is_an_error() -> Result<()> {
        let mut model = BackgroundModel::from_samples(&[plain(100)], BackgroundConfig::default())?;
        assert!(model.apply(1, &plain(160))?.pixels().all(|p| p[0] == 255));
        let e = model
            .apply(2, &RgbImage::new(3, 3))
            .expect_err("size")
            .to_string();
        assert!(e.contains("frame 2"), "{e}");
        Ok(())
    }

    #[test]
    fn bootstrap_positions_are_spread() {
        assert_eq!(bootstrap_positions(Some(100), 4), vec![0, 25, 50, 75]);
        assert_eq!(bootstrap_positions(Some(3), 4), vec![0, 1, 2]);
        assert_eq!(bootstrap_positions(None, 2), vec![0, 1]);
    }
}
