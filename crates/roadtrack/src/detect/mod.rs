//! Finding objects in frames.
//!
//! A [`Detector`] turns one frame into [`FrameDetections`]: the objects found (centre, box,
//! class, score, mean colour when known) and, for detectors that have one, the foreground
//! mask. [`background::BackgroundDetector`] is the background-subtraction detector (per-pixel
//! model of [`background_model`] started by [`startup`], clean-up of [`morphology`] and connected regions of
//! [`regions`], ghosts dropped by [`ghosts`], cut into vehicles by [`split`] and into people by [`columns`]).

pub mod age_cut;
pub mod background;
pub mod background_model;
pub mod centernet;
pub mod columns;
pub mod dots;
pub mod file;
pub mod ghosts;
pub mod morphology;
pub mod motion_gate;
pub mod nested;
pub mod refine;
pub mod regions;
pub mod split;
pub mod startup;

#[cfg(test)]
mod scenario_tests;

use crate::detection::Detection;
use crate::error::Result;
use crate::frame::Frame;
use image::GrayImage;
use std::path::PathBuf;

/// What a detector found in one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameDetections {
    /// The objects, numbered `1..` within the frame.
    pub detections: Vec<Detection>,
    /// The cleaned foreground mask (255 = moving), when the detector computes one; the
    /// filters' foreground likelihood reads it.
    pub foreground: Option<GrayImage>,
}

/// Frame → detections. Implemented by [`background::BackgroundDetector`]; a closure
/// `FnMut(&Frame) -> Result<FrameDetections>` is one too (tests, adapters).
pub trait Detector {
    /// Finds the objects of `frame`. Frames come in order; a detector may learn from them
    /// (a background model updates itself).
    ///
    /// # Errors
    /// A frame the detector cannot process (e.g. of another size than the first).
    fn detect(&mut self, frame: &Frame) -> Result<FrameDetections>;

    /// How many consecutive frames [`Detector::detect_batch`] should be given at once: more
    /// than one for a detector that looks at each frame alone and spreads a batch over the
    /// threads. The results never depend on it.
    fn batch_len(&self) -> usize {
        1
    }

    /// Finds the objects of consecutive `frames`, one result per frame in order. The default
    /// calls [`Detector::detect`] on each.
    ///
    /// # Errors
    /// As [`Detector::detect`], for the first frame that fails.
    fn detect_batch(&mut self, frames: &[Frame]) -> Result<Vec<FrameDetections>> {
        frames.iter().map(|f| self.detect(f)).collect()
    }
}

/// Refills `batch` with up to `len` next frames of `frames`; false when none is left.
///
/// # Errors
/// The first frame that cannot be read.
pub fn next_batch(
    frames: &mut impl Iterator<Item = Result<Frame>>,
    len: usize,
    batch: &mut Vec<Frame>,
) -> Result<bool> {
    batch.clear();
    for frame in frames.by_ref().take(len.max(1)) {
        batch.push(frame?);
    }
    Ok(!batch.is_empty())
}

/// [`Detector`] for a wrapper of another detector (`inner: Box<dyn Detector>`) whose method
/// `$step(&mut self, &Frame, FrameDetections) -> Result<FrameDetections>` runs on each of
/// the inner detector's results, frame by frame in order, so that a background model beside
/// it learns every frame in order ([`motion_gate::MotionGated`], [`dots::WithDots`],
/// [`refine::RefinedBoxes`]).
macro_rules! detector_after_inner {
    ($wrapper:ty, $step:ident) => {
        impl super::Detector for $wrapper {
            fn detect(&mut self, frame: &Frame) -> Result<FrameDetections> {
                let found = self.inner.detect(frame)?;
                self.$step(frame, found)
            }

            fn batch_len(&self) -> usize {
                self.inner.batch_len()
            }

            fn detect_batch(&mut self, frames: &[Frame]) -> Result<Vec<FrameDetections>> {
                let found = super::detect_checked(self.inner.as_mut(), frames)?;
                frames
                    .iter()
                    .zip(found)
                    .map(|(frame, f)| self.$step(frame, f))
                    .collect()
            }
        }
    };
}
pub(crate) use detector_after_inner;

/// A wrapper of another detector (`inner`) with a background model beside it and a config
/// checked when built: the struct, its `Debug` (the config) and `new`
/// ([`motion_gate::MotionGated`], [`refine::RefinedBoxes`]). The attributes given (the
/// struct's documentation) go on the struct.
macro_rules! background_wrapper {
    ($(#[$attr:meta])* $name:ident, $config:ty) => {
        $(#[$attr])*
        pub struct $name {
            inner: Box<dyn super::Detector>,
            background: super::background::BackgroundDetector,
            config: $config,
        }

        impl std::fmt::Debug for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.debug_struct(stringify!($name))
                    .field("config", &self.config)
                    .finish_non_exhaustive()
            }
        }

        impl $name {
            /// `inner` with `background`'s model (already started on the input) beside it.
            ///
            /// # Errors
            /// An invalid configuration.
            pub fn new(
                inner: Box<dyn super::Detector>,
                background: super::background::BackgroundDetector,
                config: $config,
            ) -> crate::error::Result<Self> {
                config.validate()?;
                Ok(Self {
                    inner,
                    background,
                    config,
                })
            }
        }
    };
}
pub(crate) use background_wrapper;

/// `detector`'s [`Detector::detect_batch`] on `frames`, checked to give one result per frame.
///
/// # Errors
/// The detector's; an internal error when the count of results is wrong.
pub fn detect_checked(
    detector: &mut (impl Detector + ?Sized),
    frames: &[Frame],
) -> Result<Vec<FrameDetections>> {
    let found = detector.detect_batch(frames)?;
    if found.len() != frames.len() {
        return Err(crate::error::Error::Invalid(format!(
            "internal error: the detector returned {} results for {} frames",
            found.len(),
            frames.len()
        )));
    }
    Ok(found)
}

/// [`Detector::detect_batch`] for a detector whose result depends on each frame alone:
/// `detect` runs on the frames in parallel (rayon), so the output is the same as one frame
/// at a time, whatever the thread count.
///
/// # Errors
/// The first failing frame's error, in frame order.
pub fn detect_stateless_batch(
    frames: &[Frame],
    detect: impl Fn(&Frame) -> Result<FrameDetections> + Sync + Send,
) -> Result<Vec<FrameDetections>> {
    use rayon::prelude::*;
    // Collected whole first, so the error reported is the first frame's, not the first
    // thread's.
    let all: Vec<Result<FrameDetections>> = frames.par_iter().map(detect).collect();
    all.into_iter().collect()
}

impl<F: FnMut(&Frame) -> Result<FrameDetections>> Detector for F {
    fn detect(&mut self, frame: &Frame) -> Result<FrameDetections> {
        self(frame)
    }
}

/// A background detector with `cfg`, its model learnt by a first, read-only pass over
/// `input`.
fn background_on(
    cfg: background::BackgroundDetectorConfig,
    input: &std::path::Path,
    options: &crate::io::SourceOptions,
) -> Result<background::BackgroundDetector> {
    cfg.validate()?;
    let model = background_model::bootstrap_from_source(input, options, cfg.background.clone())?;
    background::BackgroundDetector::with_model(cfg, model)
}

/// Which detector a run uses (`--detector`).
pub enum DetectorSpec {
    /// Background subtraction with this config, its model learnt by a first pass over the
    /// input.
    Background(background::BackgroundDetectorConfig),
    /// Public detections from a file ([`file::FileDetector`]).
    File(PathBuf),
    /// A detector made elsewhere (the networks of `roadtrack-cnn`).
    Given(Box<dyn Detector>),
    /// Another detector's boxes kept only where a background detector with this config
    /// sees motion ([`motion_gate::MotionGated`]).
    MotionGated(
        Box<DetectorSpec>,
        background::BackgroundDetectorConfig,
        motion_gate::MotionGateConfig,
    ),
    /// Another detector's boxes plus the pedestrians too small for it, found as dots of
    /// the difference from a background model with this config ([`dots::WithDots`]); the
    /// calibration sizes their boxes and limits where they are looked for.
    WithDots(
        Box<DetectorSpec>,
        background::BackgroundDetectorConfig,
        dots::DotConfig,
        Option<Box<crate::calibration::Calibration>>,
    ),
    /// Another detector's boxes fitted to the pixels that differ from a background model
    /// with this config ([`refine::RefinedBoxes`]).
    Refined(
        Box<DetectorSpec>,
        background::BackgroundDetectorConfig,
        refine::RefineConfig,
    ),
}

impl std::fmt::Debug for DetectorSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DetectorSpec::Background(c) => f.debug_tuple("Background").field(c).finish(),
            DetectorSpec::File(p) => f.debug_tuple("File").field(p).finish(),
            DetectorSpec::Given(_) => f.write_str("Given(..)"),
            DetectorSpec::MotionGated(inner, c, g) => f
                .debug_tuple("MotionGated")
                .field(inner)
                .field(c)
                .field(g)
                .finish(),
            DetectorSpec::WithDots(inner, c, d, _) => f
                .debug_tuple("WithDots")
                .field(inner)
                .field(c)
                .field(d)
                .finish_non_exhaustive(),
            DetectorSpec::Refined(inner, c, r) => f
                .debug_tuple("Refined")
                .field(inner)
                .field(c)
                .field(r)
                .finish(),
        }
    }
}

impl DetectorSpec {
    /// Makes the detector for `input`: a background detector learns its model by a first,
    /// read-only pass over the input (as `roadtrack detect`); a detections file is read and
    /// checked against the input's length.
    ///
    /// # Errors
    /// An invalid config, an unreadable input or detections file.
    pub fn build(
        self,
        input: &std::path::Path,
        options: &crate::io::SourceOptions,
        info: &crate::io::SourceInfo,
    ) -> Result<Box<dyn Detector>> {
        Ok(match self {
            DetectorSpec::Background(cfg) => Box::new(background_on(cfg, input, options)?),
            DetectorSpec::File(path) => {
                Box::new(file::FileDetector::open(&path, info.total_frames)?)
            }
            DetectorSpec::Given(d) => d,
            DetectorSpec::MotionGated(inner, cfg, gate) => {
                gate.validate()?;
                let inner = inner.build(input, options, info)?;
                let bg = background_on(cfg, input, options)?;
                Box::new(motion_gate::MotionGated::new(inner, bg, gate)?)
            }
            DetectorSpec::WithDots(inner, cfg, dots, calibration) => {
                dots.validate()?;
                let inner = inner.build(input, options, info)?;
                let bg = background_on(cfg, input, options)?;
                Box::new(dots::WithDots::new(
                    inner,
                    bg,
                    dots,
                    calibration.map(|c| *c),
                )?)
            }
            DetectorSpec::Refined(inner, cfg, refine) => {
                refine.validate()?;
                let inner = inner.build(input, options, info)?;
                let bg = background_on(cfg, input, options)?;
                Box::new(refine::RefinedBoxes::new(inner, bg, refine)?)
            }
        })
    }
}
