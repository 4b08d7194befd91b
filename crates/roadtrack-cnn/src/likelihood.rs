//! The networks as the trackers' likelihood `h(y | x)` (METHODS.md §3, "Observation
//! model"): per particle window ([`Likelihood`] on [`OnnxClassifier`] and
//! [`SsdPersonDetector`]) or dense, one network pass per frame ([`OnnxDense`],
//! [`SsdDense`], wrapped in [`DenseLikelihood`] by [`dense_likelihood`]).

use std::sync::Arc;

use image::RgbImage;

use super::onnx::OnnxClassifier;
use super::ssd::SsdPersonDetector;
use roadtrack::error::Result;
use roadtrack::geometry::Point;
use roadtrack::likelihood::{DenseLikelihood, DenseScorer, Likelihood, ScoreMap, check_lengths};

/// Per-window scoring: the classifier's target-class probability for the window centred on
/// each particle ([`OnnxClassifier::score_windows`]), the paper's likelihood.
impl Likelihood for OnnxClassifier {
    fn evaluate(&self, image: &RgbImage, positions_px: &[Point], out: &mut [f64]) -> Result<()> {
        check_lengths(positions_px, out)?;
        self.score_windows(image, positions_px, out)
    }
}

/// Per-window scoring with the SSD: one network pass per particle's window
/// ([`SsdPersonDetector::score_windows`]); slow, dense mode ([`SsdDense`]) is the fast path.
impl Likelihood for SsdPersonDetector {
    fn evaluate(&self, image: &RgbImage, positions_px: &[Point], out: &mut [f64]) -> Result<()> {
        check_lengths(positions_px, out)?;
        self.score_windows(image, positions_px, out)
    }
}

/// Dense mode of a classifier: the fully convolutional pass
/// ([`OnnxClassifier::score_map`]) at about `stride_px`.
#[derive(Debug, Clone)]
pub struct OnnxDense {
    /// The classifier.
    pub model: Arc<OnnxClassifier>,
    /// Requested grid spacing, px (the map says the one used).
    pub stride_px: u32,
}

impl DenseScorer for OnnxDense {
    fn score_map(&self, image: &RgbImage) -> Result<ScoreMap> {
        self.model.score_map(image, self.stride_px)
    }
}

/// Dense mode of the SSD: one whole-frame detection pass, the detections' bumps sampled on
/// a grid of `stride_px` ([`SsdPersonDetector::score_map`]).
#[derive(Debug, Clone)]
pub struct SsdDense {
    /// The detector.
    pub detector: Arc<SsdPersonDetector>,
    /// Grid spacing, px.
    pub stride_px: u32,
}

impl DenseScorer for SsdDense {
    fn score_map(&self, image: &RgbImage) -> Result<ScoreMap> {
        self.detector.score_map(image, self.stride_px)
    }
}

/// `scorer` as a likelihood answered from one score map per frame.
pub fn dense_likelihood(scorer: impl DenseScorer + 'static) -> DenseLikelihood {
    DenseLikelihood::new(Box::new(scorer))
}

#[cfg(test)]
mod tests {
    use super::super::onnx::CnnConfig;
    use super::*;
    use std::path::Path;

    const FIXTURE: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/tiny_classifier.onnx"
    );

    fn textured(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let v = (x * 37 + y * 91 + (x * y) % 53) % 256;
            image::Rgb([
                v as u8,
                ((v * 3 + y) % 256) as u8,
                ((x * 7 + 11) % 256) as u8,
            ])
        })
    }

    #[test]
    fn dense_classifier_likelihood_agrees_with_per_window_scoring() -> Result<()> {
        // Through the trackers' interface: begin_frame + evaluate on the folded ScoreMap
        // equals the per-window Likelihood at grid points and stays close between them.
        let model = Arc::new(OnnxClassifier::load(
            Path::new(FIXTURE),
            &CnnConfig::default(),
        )?);
        let img = textured(64, 48);
        let mut dense = dense_likelihood(OnnxDense {
            model: Arc::clone(&model),
            stride_px: 4,
        });
        dense.begin_frame(&img)?;
        let map = dense
            .map()
            .cloned()
            .ok_or_else(|| roadtrack::error::Error::Invalid("no map".into()))?;
        map.validate()?;
        let grid: Vec<Point> = (0..map.rows.min(8))
            .map(|i| map.cell_centre_px(i, (3 * i) % map.cols))
            .collect();
        let mut a = vec![0.0; grid.len()];
        let mut b = vec![0.0; grid.len()];
        dense.evaluate(&img, &grid, &mut a)?;
        model.evaluate(&img, &grid, &mut b)?;
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-5, "dense {x} vs window {y}");
        }
        // Between grid points: the lookup is a convex combination of the four neighbours.
        let p = Point::new(
            map.origin_px.x + 2.5 * map.stride_px,
            map.origin_px.y + 1.5 * map.stride_px,
        );
        let mut v = [0.0];
        dense.evaluate(&img, &[p], &mut v)?;
        let n = [
            map.cell(1, 2),
            map.cell(1, 3),
            map.cell(2, 2),
            map.cell(2, 3),
        ];
        let mean = n.iter().sum::<f64>() / 4.0;
        assert!((v[0] - mean).abs() < 1e-12);
        assert!(model.evaluate(&img, &[p], &mut [0.0; 2]).is_err());
        Ok(())
    }
}
