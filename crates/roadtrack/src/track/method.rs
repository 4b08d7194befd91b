//! The one dispatch point: a [`Method`] with its config → the detector and tracker that run
//! it ([`MethodConfig::build`]), and [`track_source`], the source-to-tracks run used by
//! `roadtrack track`, `demo` and `bench`.

use super::Tracker;
use super::filter::config::LikelihoodKind;
use super::filter::{FilterMethod, FilterTrackConfig, FilterTracker};
use super::mrf::{MrfConfig, MrfTracker};
use super::pipeline::{Pipeline, PointSink, PointStage, RunSummary};
use super::relaxation::tracker::{RelaxationTracker, RelaxationTrackerConfig};
use crate::detect::background::{BackgroundDetector, BackgroundDetectorConfig};
use crate::detect::background_model::{BackgroundConfig, bootstrap_from_source};
use crate::detect::file::FileDetector;
use crate::detect::{Detector, DetectorSpec};
use crate::error::{Error, Result};
use crate::io::source::{self, SourceInfo, SourceOptions};
use crate::likelihood::Likelihood;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The tracking methods (METHODS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Method {
    /// Bidirectional probabilistic relaxation between consecutive frames' detections (seed 000).
    Relaxation,
    /// Spatio-temporal MRF model on 8×8 blocks (seed 002).
    Mrf,
    /// Basic particle filter, ρ particles per object, colour or CNN likelihood (seed 004).
    Pf,
    /// Labelled SMC-PHD filter, colour or CNN likelihood (seed 004).
    Phd,
}

impl Method {
    /// Every method, in the order of the papers.
    pub const ALL: [Method; 4] = [Method::Relaxation, Method::Mrf, Method::Pf, Method::Phd];

    /// The method's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Method::Relaxation => "relaxation",
            Method::Mrf => "mrf",
            Method::Pf => "pf",
            Method::Phd => "phd",
        }
    }
}

/// A method with everything it needs besides the frames.
pub enum MethodConfig {
    /// Relaxation over the background detector's detections.
    Relaxation {
        /// The tracker (`--config`).
        tracker: Box<RelaxationTrackerConfig>,
        /// The detector (`--detector-config`).
        detector: Box<BackgroundDetectorConfig>,
    },
    /// The MRF tracker, which reads the pixels itself (and the detector's boxes with
    /// `use_detections`).
    Mrf {
        /// The model (`--config`).
        config: Box<MrfConfig>,
        /// Gibbs sampler seed.
        seed: u64,
    },
    /// The particle or PHD filter over the background detector's detections.
    Filter {
        /// PF or PHD.
        method: FilterMethod,
        /// Detector, filters, likelihood, births (`--config`).
        config: Box<FilterTrackConfig>,
        /// A network likelihood replacing the colour histogram (`roadtrack-cnn`).
        model: Option<Box<dyn Likelihood>>,
        /// Seed of the particles.
        seed: u64,
    },
}

impl std::fmt::Debug for MethodConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("MethodConfig").field(&self.method()).finish()
    }
}

/// The detector and tracker of a method, ready to run.
pub struct Built {
    /// The detector (`None` for the MRF as published, which reads pixels itself).
    pub detector: Option<Box<dyn Detector>>,
    /// The tracker, concrete so a caller can reach method-specific state (the MRF's object
    /// map) before boxing it.
    pub tracker: BuiltTracker,
}

impl std::fmt::Debug for Built {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Built").finish_non_exhaustive()
    }
}

/// One of the methods' trackers.
#[derive(Debug)]
pub enum BuiltTracker {
    /// Seed 000.
    Relaxation(RelaxationTracker),
    /// Seed 002.
    Mrf(Box<MrfTracker>),
    /// Seed 004.
    Filter(Box<FilterTracker>),
}

impl BuiltTracker {
    /// As a trait object.
    pub fn boxed(self) -> Box<dyn Tracker> {
        match self {
            BuiltTracker::Relaxation(t) => Box::new(t),
            BuiltTracker::Mrf(t) => t,
            BuiltTracker::Filter(t) => t,
        }
    }
}

impl MethodConfig {
    /// The paper's defaults of `method` (colour likelihood for the filters).
    pub fn defaults(method: Method, seed: u64) -> Self {
        match method {
            Method::Relaxation => MethodConfig::Relaxation {
                tracker: Box::default(),
                detector: Box::default(),
            },
            Method::Mrf => MethodConfig::Mrf {
                config: Box::default(),
                seed,
            },
            Method::Pf | Method::Phd => MethodConfig::Filter {
                method: if method == Method::Pf {
                    FilterMethod::Pf
                } else {
                    FilterMethod::Phd
                },
                config: Box::default(),
                model: None,
                seed,
            },
        }
    }

    /// Which method this is.
    pub fn method(&self) -> Method {
        match self {
            MethodConfig::Relaxation { .. } => Method::Relaxation,
            MethodConfig::Mrf { .. } => Method::Mrf,
            MethodConfig::Filter {
                method: FilterMethod::Pf,
                ..
            } => Method::Pf,
            MethodConfig::Filter { .. } => Method::Phd,
        }
    }

    /// The background detector the method uses when none is given: relaxation's
    /// `--detector-config`, the filters' `[detector]`, the default for the MRF.
    pub fn background_detector(&self) -> BackgroundDetectorConfig {
        match self {
            MethodConfig::Relaxation { detector, .. } => (**detector).clone(),
            MethodConfig::Mrf { .. } => BackgroundDetectorConfig::default(),
            MethodConfig::Filter { config, .. } => config.detector.clone(),
        }
    }

    /// The method with its background detector and model as published: median start-up,
    /// no shadow suppression, hold, ghost suppression or splitting (see
    /// [`BackgroundDetectorConfig::as_published`]); the filters weigh particles by the
    /// image likelihood only.
    pub fn as_published(mut self) -> Self {
        match &mut self {
            MethodConfig::Relaxation { detector, .. } => {
                **detector = (**detector).clone().as_published();
            }
            MethodConfig::Mrf { config, .. } => {
                **config = (**config).clone().as_published();
            }
            MethodConfig::Filter { config, .. } => {
                config.detector = config.detector.clone().as_published();
                // The paper weighs particles by the image likelihood alone.
                config.measurements = super::filter::Measurements::Image;
            }
        }
        self
    }

    /// Gives the method's background detector the camera calibration (its expected vehicle
    /// size splits regions holding several vehicles).
    pub fn with_calibration(mut self, calibration: &crate::calibration::Calibration) -> Self {
        match &mut self {
            MethodConfig::Relaxation { detector, .. } => {
                detector.calibration = Some(Box::new(calibration.clone()));
            }
            MethodConfig::Mrf { .. } => {}
            MethodConfig::Filter { config, .. } => {
                config.detector.calibration = Some(Box::new(calibration.clone()));
            }
        }
        self
    }

    /// The background model the method learns before tracking.
    pub fn background(&self) -> &BackgroundConfig {
        match self {
            MethodConfig::Relaxation { detector, .. } => &detector.background,
            MethodConfig::Mrf { config, .. } => &config.background,
            MethodConfig::Filter { config, .. } => &config.detector.background,
        }
    }

    /// Checks the configs.
    ///
    /// # Errors
    /// The first invalid field.
    pub fn validate(&self) -> Result<()> {
        match self {
            MethodConfig::Relaxation { tracker, detector } => {
                tracker.validate()?;
                detector.validate()
            }
            MethodConfig::Mrf { config, .. } => config.validate(),
            MethodConfig::Filter { config, .. } => config.validate(),
        }
    }

    /// Builds the method's detector and tracker for frames like those of `info`.
    ///
    /// The detector is `detector` when given (`--detector`), else the method's own
    /// background detector (relaxation's `--detector-config`, the filters' `[detector]`,
    /// the default one for the MRF with `use_detections`; none for the MRF as published,
    /// which reads pixels). A background model, where one is needed (the
    /// background detector, the MRF, a filter likelihood that reads the foreground mask),
    /// is learnt by a first, read-only pass over `input` (the median of `bootstrap_frames`
    /// frames spread over the selection, as `roadtrack detect`).
    ///
    /// # Errors
    /// An invalid config, an unreadable source or detections file, a foreground likelihood
    /// without the background detector.
    pub fn build(
        self,
        input: &Path,
        options: &SourceOptions,
        info: &SourceInfo,
        detector: Option<DetectorSpec>,
    ) -> Result<Built> {
        self.validate()?;
        let own = match &self {
            MethodConfig::Relaxation { detector, .. } => Some((**detector).clone()),
            // The MRF reads boxes only with `use_detections`; then the background detector's.
            MethodConfig::Mrf { config, .. } => config
                .use_detections
                .then(BackgroundDetectorConfig::default),
            MethodConfig::Filter { config, .. } => Some(config.detector.clone()),
        };
        if let (MethodConfig::Filter { config, .. }, Some(spec)) = (&self, &detector)
            && config.measurements.uses_image()
            && config.likelihood.kind != LikelihoodKind::Colour
            && !matches!(
                spec,
                DetectorSpec::Background(_) | DetectorSpec::MotionGated(..)
            )
        {
            return Err(Error::Invalid(format!(
                "the {:?} likelihood reads the background detector's foreground mask; \
                 use --detector background or [likelihood] kind = \"colour\"",
                config.likelihood.kind
            )));
        }
        let spec = match (detector, own) {
            (Some(spec), _) => Some(spec),
            (None, Some(cfg)) => Some(DetectorSpec::Background(cfg)),
            (None, None) => None,
        };
        // The MRF's own model, and the background detector's (one pass when they agree).
        let mrf_model = match &self {
            MethodConfig::Mrf { config, .. } => Some(bootstrap_from_source(
                input,
                options,
                config.background.clone(),
            )?),
            _ => None,
        };
        let detector: Option<Box<dyn Detector>> = match spec {
            None => None,
            Some(DetectorSpec::Background(cfg)) => {
                let m = match &mrf_model {
                    Some(m) if *self.background() == cfg.background => m.clone(),
                    _ => bootstrap_from_source(input, options, cfg.background.clone())?,
                };
                Some(Box::new(BackgroundDetector::with_model(cfg, m)?))
            }
            Some(DetectorSpec::File(path)) => {
                Some(Box::new(FileDetector::open(&path, info.total_frames)?))
            }
            Some(DetectorSpec::Given(d)) => Some(d),
            Some(
                wrapped @ (DetectorSpec::MotionGated(..)
                | DetectorSpec::WithDots(..)
                | DetectorSpec::Refined(..)),
            ) => Some(wrapped.build(input, options, info)?),
        };
        Ok(match self {
            MethodConfig::Relaxation { tracker, .. } => Built {
                detector,
                tracker: BuiltTracker::Relaxation(RelaxationTracker::new(*tracker)?),
            },
            MethodConfig::Mrf { config, seed } => {
                let mut t = MrfTracker::new(*config, info.width, info.height, seed)?;
                t.set_background(
                    mrf_model.ok_or_else(|| {
                        Error::Invalid("internal error: no MRF background".into())
                    })?,
                )?;
                Built {
                    detector,
                    tracker: BuiltTracker::Mrf(Box::new(t)),
                }
            }
            MethodConfig::Filter {
                method,
                config,
                model: network,
                seed,
            } => Built {
                detector,
                tracker: BuiltTracker::Filter(Box::new(FilterTracker::new(
                    method, &config, seed, network,
                )?)),
            },
        })
    }
}

/// Tracks `input` (video, image folder, MOTChallenge sequence) with `method`: builds the
/// method ([`MethodConfig::build`]), then runs the [`Pipeline`] over a second pass with
/// `stages` and `sinks`. `progress(done, total)` after each frame (`total` 0 when unknown).
///
/// # Errors
/// An invalid config, an unreadable source, a frame of another size, a stage or sink that
/// fails.
pub fn track_source<'a>(
    input: &Path,
    options: &SourceOptions,
    method: MethodConfig,
    detector: Option<DetectorSpec>,
    stages: Vec<Box<dyn PointStage + 'a>>,
    sinks: Vec<Box<dyn PointSink + 'a>>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<RunSummary> {
    let frames = source::open(input, options)?;
    track_frames(
        input, options, method, detector, frames, stages, sinks, progress,
    )
}

/// [`track_source`] over `frames`, given, in place of its second pass over `input`: `input`
/// still gives the size and frame count and feeds the method's start-up passes (a
/// background model). `frames` must be `input`'s frames under `options`; the demo decodes
/// them once for all the methods it runs side by side.
///
/// # Errors
/// As [`track_source`].
#[allow(clippy::too_many_arguments)]
pub fn track_frames<'a>(
    input: &Path,
    options: &SourceOptions,
    method: MethodConfig,
    detector: Option<DetectorSpec>,
    frames: impl IntoIterator<Item = Result<crate::frame::Frame>>,
    stages: Vec<Box<dyn PointStage + 'a>>,
    sinks: Vec<Box<dyn PointSink + 'a>>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<RunSummary> {
    let info = source::open(input, options)?.info.clone();
    let built = method.build(input, options, &info, detector)?;
    let mut pipeline = Pipeline {
        detector: built.detector,
        tracker: built.tracker.boxed(),
        stages,
        sinks,
    };
    pipeline.run(frames, info.selected_frames.map(u64::from), progress)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;
    use crate::frame::Frame;
    use crate::track::pipeline::run_frames;
    use crate::track_point::TrackPoint;
    use roadtrack_sim::{SceneKind, SimConfig, Simulation, ViewKind};

    /// Every method gives the same points from an image folder (two passes, as `roadtrack
    /// track`) as from the same frames in memory with a background learnt from them.
    #[test]
    fn every_method_tracks_a_folder_as_it_tracks_the_frames_in_memory() -> Result<()> {
        let cfg = SimConfig {
            scene: SceneKind::Crossing,
            view: ViewKind::Oblique,
            frames: 20,
            ..Default::default()
        };
        let frames: Vec<Frame> = Simulation::new(&cfg, 4)?
            .map(|s| s.map(|s| s.frame))
            .collect::<Result<_>>()?;
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        for f in &frames {
            let path = dir.path().join(format!("{:06}.png", f.index));
            f.image
                .save(&path)
                .map_err(|e| Error::Invalid(e.to_string()))?;
        }
        let opts = SourceOptions {
            fps: Some(10.0),
            ..Default::default()
        };
        let info = source::open(dir.path(), &opts)?.info.clone();
        let mut seen = 0;
        for method in Method::ALL {
            let mut from_dir: Vec<TrackPoint> = Vec::new();
            let s = track_source(
                dir.path(),
                &opts,
                MethodConfig::defaults(method, 7),
                None,
                Vec::new(),
                vec![Box::new(&mut from_dir)],
                &mut |_, _| {},
            )?;
            assert_eq!(s.frames, 20);
            let built = MethodConfig::defaults(method, 7).build(dir.path(), &opts, &info, None)?;
            let in_memory = run_frames(
                built.detector,
                built.tracker.boxed(),
                frames.iter().cloned().map(Ok),
            )?;
            assert_eq!(from_dir, in_memory, "{}", method.name());
            seen += usize::from(!from_dir.is_empty());
        }
        assert!(seen >= 3, "only {seen} methods tracked anything");
        Ok(())
    }
}
