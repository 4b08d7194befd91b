//! Loading a network as the filters' class likelihood (`roadtrack track --likelihood
//! cnn|ssd`): an ONNX classifier or the SSDLite pedestrian detector, per particle window or
//! dense.

use crate::{
    CnnConfig, OnnxClassifier, OnnxDense, SsdConfig, SsdDense, SsdPersonDetector, dense_likelihood,
};
use image::RgbImage;
use roadtrack::error::{Error, Result};
use roadtrack::likelihood::Likelihood;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::Arc;

/// Which network replaces the colour histogram as the class likelihood (`roadtrack track
/// --likelihood`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// No network: the colour-histogram likelihood ([`TrackLikelihoodConfig`]).
    #[default]
    Colour,
    /// Any ONNX classifier (`cnn::OnnxClassifier`), e.g. one written by `roadtrack train`.
    Cnn,
    /// The SSDLite pedestrian detector (`cnn::SsdPersonDetector`).
    Ssd,
}

impl std::str::FromStr for ModelKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "colour" | "color" => Ok(Self::Colour),
            "cnn" => Ok(Self::Cnn),
            "ssd" => Ok(Self::Ssd),
            _ => Err(Error::Invalid(format!(
                "unknown likelihood {s:?}: expected colour, cnn or ssd"
            ))),
        }
    }
}

/// A network likelihood to load ([`load_model_likelihood`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelSpec {
    /// Which network.
    pub kind: ModelKind,
    /// The model file: required for `cnn`; for `ssd`, `None` = `cnn::ssd::default_model_path`.
    pub path: Option<PathBuf>,
    /// Dense mode grid spacing, px; 0 = score every particle's window. `None` = the
    /// default: [`SSD_DEFAULT_DENSE_STRIDE_PX`] for `ssd`, per window for `cnn`.
    pub dense_stride_px: Option<u32>,
    /// Image px per model px (`cnn`: overrides the model's `roadtrack.window_scale`;
    /// `ssd`: multiplies the per-window mode's window).
    pub window_scale: Option<f64>,
}

/// Default dense stride of the SSD likelihood, px. Choice: 4 px, a tenth of a vtest
/// pedestrian's width; the map costs far less than the network pass at any stride.
pub const SSD_DEFAULT_DENSE_STRIDE_PX: u32 = 4;

/// Loads the network of `spec` as a likelihood (dense when its stride is > 0); `None` for
/// [`ModelKind::Colour`].
///
/// # Errors
/// A missing model path for `cnn`; a model file that is absent or not the expected model
/// (the error names the file; for the SSD it says to run `scripts/setup.sh --models`);
/// a classifier without a dense-convertible head in dense mode; `cnn`/`ssd` in a build
/// without the `cnn` feature.
pub fn load_model_likelihood(spec: &ModelSpec) -> Result<Option<Box<dyn Likelihood>>> {
    if let Some(s) = spec.window_scale
        && !(s.is_finite() && s > 0.0)
    {
        return Err(Error::Invalid(format!("window scale must be > 0, got {s}")));
    }
    match spec.kind {
        ModelKind::Colour => Ok(None),
        ModelKind::Cnn => {
            let path = spec.path.as_deref().ok_or_else(|| {
                Error::Invalid("the cnn likelihood needs a model file (--model F.onnx)".into())
            })?;
            if crate::centernet::is_centernet_file(path) {
                return load_centernet_likelihood(path, spec);
            }
            let cfg = CnnConfig {
                window_scale: spec.window_scale,
                ..CnnConfig::default()
            };
            let model = OnnxClassifier::load(path, &cfg)?;
            match spec.dense_stride_px.unwrap_or(0) {
                0 => Ok(Some(Box::new(model))),
                stride => {
                    let model = Arc::new(model);
                    // Fail now, not on the first frame, when the head is not convertible.
                    model.score_map(&RgbImage::new(8, 8), stride)?;
                    Ok(Some(Box::new(dense_likelihood(OnnxDense {
                        model,
                        stride_px: stride,
                    }))))
                }
            }
        }
        ModelKind::Ssd => {
            let path = match &spec.path {
                Some(p) => p.clone(),
                None => crate::ssd::default_model_path()
                    .ok_or_else(|| Error::Invalid("no HOME to find the SSD model in".into()))?,
            };
            if !path.is_file() {
                return Err(Error::Invalid(format!(
                    "SSD model {} not found: run scripts/setup.sh --models (or give --model)",
                    path.display()
                )));
            }
            let mut cfg = SsdConfig::default();
            if let Some(s) = spec.window_scale {
                cfg.window_px = cfg.window_px.map(|v| v * s);
            }
            let det = SsdPersonDetector::load(&path, &cfg)?;
            match spec.dense_stride_px.unwrap_or(SSD_DEFAULT_DENSE_STRIDE_PX) {
                0 => Ok(Some(Box::new(det))),
                stride => Ok(Some(Box::new(dense_likelihood(SsdDense {
                    detector: Arc::new(det),
                    stride_px: stride,
                })))),
            }
        }
    }
}

/// The learned detector's heat map as a dense likelihood (seed 004's score map): one
/// network pass per frame, particles looked up at stride 4. Choice: the maximum over the
/// four class channels (the filters track every class; the trackers have no target class
/// to pick one channel).
fn load_centernet_likelihood(
    path: &std::path::Path,
    spec: &ModelSpec,
) -> Result<Option<Box<dyn Likelihood>>> {
    use crate::centernet::{CLASSES, CenterNetConfig, CenterNetDense, CenterNetDetector};
    if spec.window_scale.is_some() {
        return Err(Error::Invalid(format!(
            "{}: the learned detector's likelihood is its heat map; it takes no window scale",
            path.display()
        )));
    }
    let det = CenterNetDetector::load(path, &CenterNetConfig::default())?;
    Ok(Some(Box::new(dense_likelihood(CenterNetDense {
        detector: Arc::new(det),
        channels: (0..CLASSES).collect(),
    }))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use roadtrack::detect::background::BackgroundDetector;
    use roadtrack::io::SourceOptions;
    use roadtrack::track::filter::{FilterMethod, FilterTrackConfig, FilterTracker, FrameCount};
    use roadtrack::track::pipeline::run_frames;
    use roadtrack::track_point::TrackPoint;
    use roadtrack_sim::testkit::three_cars;
    use std::path::Path;

    #[test]
    fn model_specs_are_checked_before_loading() -> Result<()> {
        assert!(load_model_likelihood(&ModelSpec::default())?.is_none());
        assert_eq!("ssd".parse::<ModelKind>().ok(), Some(ModelKind::Ssd));
        assert!("yolo".parse::<ModelKind>().is_err());
        let no_path = ModelSpec {
            kind: ModelKind::Cnn,
            ..Default::default()
        };
        let err = load_model_likelihood(&no_path).err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains("--model")));
        let bad_scale = ModelSpec {
            window_scale: Some(0.0),
            ..no_path.clone()
        };
        assert!(load_model_likelihood(&bad_scale).is_err());
        Ok(())
    }

    #[test]
    fn a_cnn_likelihood_tracks_deterministically_at_any_thread_count() -> Result<()> {
        let frames = three_cars(8)?.0;
        let model = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/fixtures/tiny_classifier.onnx"
        );
        let cfg = FilterTrackConfig::default();
        let run_with = |threads: usize,
                        stride: u32|
         -> Result<(Vec<TrackPoint>, Vec<FrameCount>)> {
            let spec = ModelSpec {
                kind: ModelKind::Cnn,
                path: Some(PathBuf::from(model)),
                dense_stride_px: Some(stride),
                window_scale: None,
            };
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| Error::Invalid(e.to_string()))?;
            pool.install(|| {
                let detector = BackgroundDetector::bootstrap(
                    cfg.detector.clone(),
                    frames.iter().cloned().map(Ok),
                    Some(frames.len() as u32),
                )?;
                let mut tracker =
                    FilterTracker::new(FilterMethod::Phd, &cfg, 3, load_model_likelihood(&spec)?)?;
                tracker.record_counts();
                let points = run_frames(
                    Some(Box::new(detector)),
                    Box::new(&mut tracker),
                    frames.iter().cloned().map(Ok),
                )?;
                Ok((points, tracker.counts().to_vec()))
            })
        };
        for stride in [0, 8] {
            let one = run_with(1, stride)?;
            let two = run_with(2, stride)?;
            assert_eq!(one.0, two.0, "stride {stride}");
            assert_eq!(one.1.len(), frames.len());
            assert!(one.1.iter().all(|c| c.expected.is_finite()));
        }
        Ok(())
    }

    #[test]
    #[ignore = "needs the SSDLite model (scripts/setup.sh --models) and ../shared/data/vtest.avi"]
    fn phd_with_the_ssd_likelihood_counts_pedestrians_in_vtest() -> Result<()> {
        let Some(model) = crate::ssd::default_model_path().filter(|p| p.is_file()) else {
            eprintln!("note: SSD model absent; run scripts/setup.sh --models");
            return Ok(());
        };
        let video = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/data/vtest.avi"
        ));
        if !video.is_file() {
            eprintln!("note: {} absent; skipped", video.display());
            return Ok(());
        }
        let spec = ModelSpec {
            kind: ModelKind::Ssd,
            path: Some(model),
            ..Default::default()
        };
        let options = SourceOptions {
            end: Some(40),
            ..Default::default()
        };
        let built = roadtrack::track::MethodConfig::Filter {
            method: FilterMethod::Phd,
            config: Box::default(),
            model: None,
            seed: 0,
        }
        .build(
            video,
            &options,
            &roadtrack::io::source::open(video, &options)?.info,
            None,
        )?;
        let mut tracker = FilterTracker::new(
            FilterMethod::Phd,
            &FilterTrackConfig::default(),
            0,
            load_model_likelihood(&spec)?,
        )?;
        tracker.record_counts();
        let points = run_frames(
            built.detector,
            Box::new(&mut tracker),
            roadtrack::io::source::open(video, &options)?,
        )?;
        let counts = tracker.counts();
        assert_eq!(counts.len(), 40);
        // vtest shows several pedestrians from the first frame on.
        let late: Vec<f64> = counts[20..].iter().map(|c| c.expected).collect();
        let mean = late.iter().sum::<f64>() / late.len() as f64;
        assert!(
            mean > 1.0,
            "mean expected count {mean:.2} over frames 21–40"
        );
        assert!(!points.is_empty());
        Ok(())
    }
}
