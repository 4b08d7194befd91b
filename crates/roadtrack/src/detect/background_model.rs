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
//! Start-up ([`Startup`], module [`super::startup`]): from frames sampled evenly over the
//! sequence, either the per-pixel median (the earlier behaviour) or the most persistent
//! colour (the densest cluster of samples), which keeps vehicles that wait in a queue for
//! a large part of the sequence out of the background as long as no single one of them
//! covers the pixel longer than the empty road shows.
//!
//! Shadows (MOG2's test, Prati et al. 2003): a foreground pixel whose colour is the
//! background's darkened by a factor in `[shadow_min_ratio, 1)` with small chromaticity
//! distortion is a shadow, classified background but not learnt.
//!
//! Hold ([`BackgroundModel::update_held`]): the detector passes its cleaned mask; the model
//! does not learn under it until the pixel has been foreground for `hold_still_s`, so a
//! vehicle that stops stays an object, holes included.
//!
//! Choice: a single Gaussian rather than a Gaussian mixture. Our scenes (fixed cameras on
//! roads, simulated or real) have unimodal backgrounds; a mixture costs 3–5× the time and
//! its extra modes absorb slow vehicles in queues.

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
    /// Frames sampled evenly over the sequence for the start-up. Default 25.
    pub bootstrap_frames: u32,
    /// How the initial background is made from the sampled frames. Default
    /// [`Startup::Persistent`].
    pub startup: Startup,
    /// Shadow suppression: a darkened background colour with the same chromaticity is not
    /// foreground. Default true.
    pub shadows: bool,
    /// Smallest brightness ratio `I·μ / |μ|²` a shadow may have (MOG2's τ). Default 0.5.
    pub shadow_min_ratio: f64,
    /// A pixel under the detector's cleaned foreground mask is not learnt until it has been
    /// foreground this long, seconds (then the foreground rate applies). Default 60; 0
    /// disables the hold.
    pub hold_still_s: f64,
    /// Ghost suppression ([`super::ghosts`]): a region of the cleaned mask that has stood
    /// still for `ghost_still_s` and whose outline shows in the frame with less than this
    /// share of the edge strength it has in the background is a ghost (the background
    /// holds an object that has left); it is dropped and the background there set to the
    /// frame. Default 0.5; 0 disables it.
    pub ghost_edge_ratio: f64,
    /// How long (s) a region must have been under the cleaned mask before the ghost test
    /// looks at it. Default 0.5.
    pub ghost_still_s: f64,
}

/// How the initial background is made from the sampled frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Startup {
    /// Per-pixel median of each channel (the earlier behaviour; `--as-published`).
    Median,
    /// Per-pixel most persistent colour: the mean of the densest cluster of samples.
    Persistent,
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
            startup: Startup::Persistent,
            shadows: true,
            shadow_min_ratio: 0.5,
            hold_still_s: 60.0,
            ghost_edge_ratio: 0.5,
            ghost_still_s: 0.5,
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
        if !(self.shadow_min_ratio > 0.0 && self.shadow_min_ratio < 1.0) {
            return Err(Error::config(
                "BackgroundConfig",
                "shadow_min_ratio",
                format!("must be in (0, 1), found {}", self.shadow_min_ratio),
            ));
        }
        if !(self.hold_still_s >= 0.0 && self.hold_still_s.is_finite()) {
            return Err(Error::config(
                "BackgroundConfig",
                "hold_still_s",
                format!("must be finite and ≥ 0, found {}", self.hold_still_s),
            ));
        }
        unit(self.ghost_edge_ratio, "ghost_edge_ratio")?;
        if !(self.ghost_still_s >= 0.0 && self.ghost_still_s.is_finite()) {
            return Err(Error::config(
                "BackgroundConfig",
                "ghost_still_s",
                format!("must be finite and ≥ 0, found {}", self.ghost_still_s),
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

    /// The same config with the detector's later additions off: median start-up, no
    /// shadow suppression, no hold, no ghost suppression (the behaviour `--as-published`
    /// reproduces).
    pub fn as_published(mut self) -> Self {
        self.startup = Startup::Median;
        self.shadows = false;
        self.hold_still_s = 0.0;
        self.ghost_edge_ratio = 0.0;
        self
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
    /// The last classification of each pixel ([`CLASS_BG`], [`CLASS_FG`], [`CLASS_SHADOW`]),
    /// read by [`BackgroundModel::update_held`].
    class: Vec<u8>,
    /// Time (s) since which each pixel has been under the detector's cleaned mask without
    /// a break; NaN when it is not.
    held_since: Vec<f32>,
}

const CLASS_BG: u8 = 0;
const CLASS_FG: u8 = 1;
const CLASS_SHADOW: u8 = 2;

/// Per-frame constants of the classification and update.
#[derive(Clone, Copy)]
struct Params {
    k2x3: f32,
    min_var: f32,
    max_var: f32,
    a_bg: f32,
    a_fg: f32,
    shadows: bool,
    tau: f32,
}

impl Params {
    fn of(c: &BackgroundConfig) -> Self {
        Self {
            k2x3: (c.threshold_sigma * c.threshold_sigma * 3.0) as f32,
            min_var: (c.min_sigma * c.min_sigma) as f32,
            max_var: (c.max_sigma * c.max_sigma) as f32,
            a_bg: c.learning_rate as f32,
            a_fg: c.foreground_learning_rate as f32,
            shadows: c.shadows,
            tau: c.shadow_min_ratio as f32,
        }
    }

    /// The class of colour `rgb` against mean `mu` and variance `v`, and the colour
    /// difference with its squared norm.
    ///
    /// Branch-free (every test computed, the class chosen by selects) and always inlined:
    /// as a called function with early returns it cost a call and two unpredictable
    /// branches per pixel. The arithmetic and its order are those of the tests written
    /// out (the test `branch_free_classify_matches_the_written_out_tests` checks the
    /// class on random colours), so the masks are bit-identical.
    #[inline(always)]
    fn classify(&self, rgb: &[u8], mu: &[f32], v: f32) -> (u8, [f32; 3], f32) {
        let i = [f32::from(rgb[0]), f32::from(rgb[1]), f32::from(rgb[2])];
        let d = [i[0] - mu[0], i[1] - mu[1], i[2] - mu[2]];
        let dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let thr = self.k2x3 * v.max(self.min_var);
        // MOG2's shadow test (Prati et al. 2003; OpenCV's detectShadowGMM): the brightness
        // ratio β = I·μ/|μ|² in [τ, 1) and the chromaticity distortion |I − βμ|² below
        // the foreground threshold scaled by β². With |μ|² = 0, β is not finite and the
        // `mu2 > 0` term decides.
        let mu2 = mu[0] * mu[0] + mu[1] * mu[1] + mu[2] * mu[2];
        let beta = (i[0] * mu[0] + i[1] * mu[1] + i[2] * mu[2]) / mu2;
        let e0 = i[0] - beta * mu[0];
        let e1 = i[1] - beta * mu[1];
        let e2 = i[2] - beta * mu[2];
        let shadow = self.shadows
            & (mu2 > 0.0)
            & (beta >= self.tau)
            & (beta < 1.0)
            & (e0 * e0 + e1 * e1 + e2 * e2 <= thr * beta * beta);
        let not_bg = dist2 > thr;
        let class = u8::from(not_bg) * (CLASS_FG + u8::from(shadow) * (CLASS_SHADOW - CLASS_FG));
        (class, d, dist2)
    }

    /// Moves mean and variance towards the pixel by rate `a`.
    #[inline(always)]
    fn learn(&self, mu: &mut [f32], v: &mut f32, d: [f32; 3], dist2: f32, a: f32) {
        mu[0] += a * d[0];
        mu[1] += a * d[1];
        mu[2] += a * d[2];
        *v = (*v + a * (dist2 / 3.0 - *v)).clamp(self.min_var, self.max_var);
    }
}

impl BackgroundModel {
    /// A model initialised from sample frames (all of the same size; at least one) by the
    /// config's [`Startup`]: per-pixel median and median absolute deviation, or the most
    /// persistent colour (see [`super::startup`]).
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
        let spread = super::startup::Spread {
            threshold_sigma: config.threshold_sigma,
            min_sigma: config.min_sigma,
            max_sigma: config.max_sigma,
        };
        let (mean, var) = match config.startup {
            Startup::Median => super::startup::median(samples, &spread),
            Startup::Persistent => super::startup::persistent(samples, &spread),
        };
        let n_px = var.len();
        Ok(Self {
            config,
            width,
            height,
            mean,
            var,
            class: vec![CLASS_BG; n_px],
            held_since: vec![f32::NAN; n_px],
        })
    }

    /// Frame size the model was built for.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The model's parameters.
    pub fn config(&self) -> &BackgroundConfig {
        &self.config
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

    /// Per pixel, the time (s) since which it has been under the detector's cleaned mask
    /// without a break (NaN when it is not), as of the last [`BackgroundModel::update_held`].
    pub fn held_since(&self) -> &[f32] {
        &self.held_since
    }

    /// The mean colour, 3 values per pixel, row-major.
    pub fn mean(&self) -> &[f32] {
        &self.mean
    }

    /// Sets the background to `image` on the pixels of `runs` (`(y, x0, x1)`: pixels
    /// `x0..x1` of row `y`) and forgets that they were held: the repair of a ghost.
    pub fn absorb(&mut self, image: &RgbImage, runs: &[(u32, u32, u32)]) {
        let w = self.width as usize;
        let px = image.as_raw();
        for &(y, x0, x1) in runs {
            let (a, b) = (y as usize * w + x0 as usize, y as usize * w + x1 as usize);
            for (m, &p) in self.mean[3 * a..3 * b].iter_mut().zip(&px[3 * a..3 * b]) {
                *m = f32::from(p);
            }
            self.held_since[a..b].fill(f32::NAN);
        }
    }

    /// An error naming frame `frame_index` when `image` is not of the model's size.
    ///
    /// # Errors
    /// [`Error::FrameSize`].
    pub(crate) fn check_size(&self, frame_index: u32, image: &RgbImage) -> Result<()> {
        if image.dimensions() != (self.width, self.height) {
            return Err(Error::FrameSize {
                frame: frame_index,
                got: image.dimensions(),
                expected: (self.width, self.height),
            });
        }
        Ok(())
    }

    /// Classifies every pixel of `image` (255 = foreground, 0 = background or shadow), then
    /// updates the model with `image` (background at the background rate, foreground and
    /// shadow at the foreground rate). One pass; no hold (the MRF's use).
    ///
    /// # Errors
    /// The image does not have the model's size.
    pub fn apply(&mut self, frame_index: u32, image: &RgbImage) -> Result<GrayImage> {
        use rayon::prelude::*;
        self.check_size(frame_index, image)?;
        let p = Params::of(&self.config);
        let mut mask = vec![0u8; self.var.len()];
        // Each pixel alone, split as classify splits: one thread ran it, 18 % of `track
        // --method mrf`'s CPU (docs/PERFORMANCE.md "MRF").
        let n = pixels_per_task(self.var.len());
        mask.par_chunks_mut(n)
            .zip(self.mean.par_chunks_mut(3 * n))
            .zip(self.var.par_chunks_mut(n))
            .zip(image.as_raw().par_chunks(3 * n))
            .for_each(|(((mask, mean), var), px)| {
                for (((m, mu), v), rgb) in mask
                    .iter_mut()
                    .zip(mean.chunks_exact_mut(3))
                    .zip(var.iter_mut())
                    .zip(px.chunks_exact(3))
                {
                    let (class, d, dist2) = p.classify(rgb, mu, *v);
                    let a = if class == CLASS_BG { p.a_bg } else { p.a_fg };
                    *m = if class == CLASS_FG { 255 } else { 0 };
                    p.learn(mu, v, d, dist2, a);
                }
            });
        GrayImage::from_raw(self.width, self.height, mask)
            .ok_or_else(|| Error::Invalid("mask size mismatch".into()))
    }

    /// Classifies every pixel of `image` (255 = foreground, 0 = background or shadow)
    /// without learning; [`BackgroundModel::update_held`] learns afterwards.
    ///
    /// # Errors
    /// The image does not have the model's size.
    pub fn classify(&mut self, frame_index: u32, image: &RgbImage) -> Result<GrayImage> {
        use rayon::prelude::*;
        self.check_size(frame_index, image)?;
        let p = Params::of(&self.config);
        let mut mask = vec![0u8; self.var.len()];
        let n = pixels_per_task(self.var.len());
        mask.par_chunks_mut(n)
            .zip(self.class.par_chunks_mut(n))
            .zip(self.mean.par_chunks(3 * n))
            .zip(self.var.par_chunks(n))
            .zip(image.as_raw().par_chunks(3 * n))
            .for_each(|((((mask, class), mean), var), px)| {
                for ((((m, c), mu), v), rgb) in mask
                    .iter_mut()
                    .zip(class.iter_mut())
                    .zip(mean.chunks_exact(3))
                    .zip(var)
                    .zip(px.chunks_exact(3))
                {
                    let (class, _, _) = p.classify(rgb, mu, *v);
                    *c = class;
                    *m = if class == CLASS_FG { 255 } else { 0 };
                }
            });
        GrayImage::from_raw(self.width, self.height, mask)
            .ok_or_else(|| Error::Invalid("mask size mismatch".into()))
    }

    /// Learns `image` (the one just classified) after [`BackgroundModel::classify`]:
    /// pixels under `held` (the detector's cleaned foreground mask, non-zero = held) that
    /// have been held for less than `hold_still_s` up to `time_s` are not learnt; the
    /// others as in [`BackgroundModel::apply`].
    ///
    /// # Errors
    /// `image` or `held` does not have the model's size.
    pub fn update_held(
        &mut self,
        frame_index: u32,
        image: &RgbImage,
        held: &GrayImage,
        time_s: f64,
    ) -> Result<()> {
        self.check_size(frame_index, image)?;
        if held.dimensions() != (self.width, self.height) {
            return Err(Error::FrameSize {
                frame: frame_index,
                got: held.dimensions(),
                expected: (self.width, self.height),
            });
        }
        use rayon::prelude::*;
        let p = Params::of(&self.config);
        let hold = self.config.hold_still_s as f32;
        let t = time_s as f32;
        let n = pixels_per_task(self.var.len());
        self.mean
            .par_chunks_mut(3 * n)
            .zip(self.var.par_chunks_mut(n))
            .zip(self.class.par_chunks(n))
            .zip(self.held_since.par_chunks_mut(n))
            .zip(image.as_raw().par_chunks(3 * n))
            .zip(held.as_raw().par_chunks(n))
            .for_each(|(((((mean, var), class), held_since), px), held)| {
                for (((((mu, v), &c), since), rgb), &h) in mean
                    .chunks_exact_mut(3)
                    .zip(var.iter_mut())
                    .zip(class)
                    .zip(held_since.iter_mut())
                    .zip(px.chunks_exact(3))
                    .zip(held)
                {
                    if h != 0 {
                        if since.is_nan() {
                            *since = t;
                        }
                        if t - *since < hold {
                            continue;
                        }
                    } else {
                        *since = f32::NAN;
                    }
                    let d = [
                        f32::from(rgb[0]) - mu[0],
                        f32::from(rgb[1]) - mu[1],
                        f32::from(rgb[2]) - mu[2],
                    ];
                    let dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                    let a = if c == CLASS_BG { p.a_bg } else { p.a_fg };
                    p.learn(mu, v, d, dist2, a);
                }
            });
        Ok(())
    }
}

/// Pixels per rayon task of the per-pixel passes: the frame in one contiguous piece per
/// thread, and no split below 64 Ki pixels (a task costs more than it saves there). Each
/// pixel is computed alone, so the result does not depend on the split.
fn pixels_per_task(n_px: usize) -> usize {
    n_px.div_ceil(rayon::current_num_threads().max(1))
        .max(64 * 1024)
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

    /// `Params::classify` as the tests read, one after another with early returns.
    fn classify_written_out(p: &Params, rgb: &[u8], mu: &[f32], v: f32) -> u8 {
        let i = [f32::from(rgb[0]), f32::from(rgb[1]), f32::from(rgb[2])];
        let d = [i[0] - mu[0], i[1] - mu[1], i[2] - mu[2]];
        let thr = p.k2x3 * v.max(p.min_var);
        if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= thr {
            return CLASS_BG;
        }
        if p.shadows {
            let mu2 = mu[0] * mu[0] + mu[1] * mu[1] + mu[2] * mu[2];
            if mu2 > 0.0 {
                let beta = (i[0] * mu[0] + i[1] * mu[1] + i[2] * mu[2]) / mu2;
                if beta >= p.tau && beta < 1.0 {
                    let e = [
                        i[0] - beta * mu[0],
                        i[1] - beta * mu[1],
                        i[2] - beta * mu[2],
                    ];
                    if e[0] * e[0] + e[1] * e[1] + e[2] * e[2] <= thr * beta * beta {
                        return CLASS_SHADOW;
                    }
                }
            }
        }
        CLASS_FG
    }

    #[test]
    fn branch_free_classify_matches_the_written_out_tests() {
        use rand::RngExt;
        let mut rng = crate::rng::rng_for(7, crate::rng::Stream::Synthetic, 0);
        for shadows in [true, false] {
            let p = Params::of(&BackgroundConfig {
                shadows,
                ..BackgroundConfig::default()
            });
            let mut seen = [0usize; 3];
            for n in 0..200_000 {
                let rgb: [u8; 3] = rng.random();
                // A darker copy of the mean makes shadows common; every 50th mean is black.
                let mu: [f32; 3] = if n % 50 == 0 {
                    [0.0; 3]
                } else if n % 3 == 0 {
                    let k = rng.random_range(1.0..2.5f32);
                    [
                        f32::from(rgb[0]) * k,
                        f32::from(rgb[1]) * k,
                        f32::from(rgb[2]) * k,
                    ]
                } else {
                    [
                        rng.random_range(0.0..255.0),
                        rng.random_range(0.0..255.0),
                        rng.random_range(0.0..255.0),
                    ]
                };
                let v = rng.random_range(0.0..400.0f32);
                let want = classify_written_out(&p, &rgb, &mu, v);
                let (got, d, dist2) = p.classify(&rgb, &mu, v);
                assert_eq!(got, want, "rgb {rgb:?} mu {mu:?} v {v}");
                assert_eq!(dist2, d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                seen[usize::from(got)] += 1;
            }
            // All three classes occur (none with shadows off), so the test can fail.
            assert!(seen[0] > 1000 && seen[1] > 1000, "{seen:?}");
            assert_eq!(seen[2] > 1000, shadows, "{seen:?}");
        }
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

    /// `apply` splits the frame over the threads; masks and model are the same at 1 and 4
    /// threads (a frame large enough to be split).
    #[test]
    fn apply_gives_the_same_at_any_thread_count() -> Result<()> {
        use rand::RngExt;
        let mut rng = crate::rng::rng_for(3, crate::rng::Stream::Synthetic, 0);
        let frames: Vec<RgbImage> = (0..4)
            .map(|_| RgbImage::from_fn(640, 480, |_, _| Rgb(rng.random())))
            .collect();
        type Run = (Vec<Vec<u8>>, Vec<f32>, Vec<f32>);
        let run = |threads: usize| -> Result<Run> {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| Error::Invalid(e.to_string()))?;
            pool.install(|| {
                let mut model =
                    BackgroundModel::from_samples(&frames[..1], BackgroundConfig::default())?;
                let masks = frames[1..]
                    .iter()
                    .zip(1..)
                    .map(|(f, i)| model.apply(i, f).map(GrayImage::into_raw))
                    .collect::<Result<Vec<_>>>()?;
                Ok((masks, model.mean.clone(), model.var.clone()))
            })
        };
        let one = run(1)?;
        assert!(one.0.iter().flatten().any(|&m| m == 255));
        assert!(one == run(4)?);
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
