//! Any ONNX object detector as a roadtrack [`Detector`] (`--detector onnx --model F.onnx`):
//! YOLO-style (`[1, N, 4+C]`, `[1, 4+C, N]`), YOLOX (`[1, N, 5+C]`) and DETR-style
//! (boxes `[1, Q, 4]` + logits `[1, Q, C]`) outputs, loaded with tract (pure Rust).
//!
//! Per frame: letterbox (resize keeping the aspect, pad with grey 114, RGB planes, NCHW,
//! [`Preprocessing`] applied: `[0, 1]` by default), run, decode the layout, keep scores ≥
//! `min_score`, class-wise NMS, undo the letterbox to image px and clip to the frame, map
//! the model's classes (COCO by default) to roadtrack classes, and fill each detection's
//! mean colour from the frame. See docs/DETECTION.md "ONNX detectors".

pub mod decode;
#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use image::RgbImage;
use serde::{Deserialize, Serialize};
use tract_onnx::prelude::*;

use decode::{COCO80, Candidate, Placement, RawOutput};
pub use decode::{DetrScores, Layout};

use super::onnx::{model_error, read_image_model, tract_load};
use super::window::{Preprocessing, sample_grid_xy};
use roadtrack::class::ObjectClass;
use roadtrack::detect::FrameDetections;
use roadtrack::detection::Detection;
use roadtrack::error::{Error, Result};
use roadtrack::frame::Frame;
use roadtrack::geometry::BBox;

/// The channel order the model takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Channels {
    /// R, G, B planes (ultralytics, RT-DETR, D-FINE).
    #[default]
    Rgb,
    /// B, G, R planes (YOLOX, trained on OpenCV images).
    Bgr,
}

/// How the frame is fitted into the model input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Resize {
    /// Keep the aspect, pad the rest with `pad_value` grey, centred.
    #[default]
    Letterbox,
    /// Keep the aspect, pad right and bottom (YOLOX's `preproc`).
    LetterboxTopLeft,
    /// Scale each axis to fill the input (DETR-style exports that resize to a square).
    Stretch,
}

/// How to run an ONNX detector (TOML: `--onnx-config F.toml`; flags override fields).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OnnxDetectorConfig {
    /// Output layout. Default `auto` (see [`Layout::Auto`]).
    pub layout: Layout,
    /// Model input `[height, width]`. Default: the model's own when fixed, else 640×640.
    pub input_size: Option<[u32; 2]>,
    /// Pixel scaling after the letterbox: `(pixel · input_scale − mean) / std` per model
    /// channel. Default `[0, 1]` (input_scale 1/255, mean 0, std 1); YOLOX wants
    /// input_scale 1 (0..255).
    pub preprocessing: Preprocessing,
    /// Channel order. Default RGB.
    pub channels: Channels,
    /// Fitting the frame in. Default letterbox, centred.
    pub resize: Resize,
    /// Grey level of the letterbox padding, 0–255. Default 114 (YOLOX/ultralytics).
    pub pad_value: u8,
    /// Detections with a lower score are dropped. Default 0.25.
    pub min_score: f64,
    /// Class-wise NMS: a box overlapping a better one of its class by more than this IoU
    /// is dropped. Default 0.45.
    pub iou_threshold: f64,
    /// DETR logits: sigmoid (default; RT-DETR, D-FINE) or softmax with a last "no object"
    /// column (DETR).
    pub detr_scores: DetrScores,
    /// The model's class names by index. Default: the 80 COCO classes.
    pub class_names: Option<Vec<String>>,
    /// Explicit mapping `INDEX=CLASS,…` (e.g. `"0=pedestrian,2=car"`); only the listed
    /// indices are kept. Overrides `class_names`.
    pub classes: Option<String>,
    /// Keep classes that map to no roadtrack class (under their own name). Default false:
    /// dropped.
    pub keep_other_classes: bool,
    /// At most this many detections per frame (highest scores). Default 300.
    pub max_detections: usize,
}

impl Default for OnnxDetectorConfig {
    fn default() -> Self {
        Self {
            layout: Layout::Auto,
            input_size: None,
            preprocessing: Preprocessing::default(),
            channels: Channels::Rgb,
            resize: Resize::Letterbox,
            // Choice: the YOLOX/ultralytics defaults: grey 114, score 0.25, IoU 0.45.
            pad_value: 114,
            min_score: 0.25,
            iou_threshold: 0.45,
            detr_scores: DetrScores::Sigmoid,
            class_names: None,
            classes: None,
            keep_other_classes: false,
            max_detections: 300,
        }
    }
}

impl roadtrack::config::Validate for OnnxDetectorConfig {
    fn validate(&self) -> Result<()> {
        let bad =
            |field: &str, reason: String| Err(Error::config("OnnxDetectorConfig", field, reason));
        if let Some([h, w]) = self.input_size
            && (h == 0 || w == 0 || h > 8192 || w > 8192)
        {
            return bad("input_size", format!("must be 1–8192 px, got [{h}, {w}]"));
        }
        if !(0.0..=1.0).contains(&self.min_score) {
            return bad(
                "min_score",
                format!("must be in [0, 1], got {}", self.min_score),
            );
        }
        if !(0.0..=1.0).contains(&self.iou_threshold) {
            return bad(
                "iou_threshold",
                format!("must be in [0, 1], got {}", self.iou_threshold),
            );
        }
        if self.max_detections == 0 {
            return bad("max_detections", "must be at least 1".into());
        }
        if let Some(c) = &self.classes
            && let Err(e) = decode::parse_class_map(c)
        {
            return bad("classes", e);
        }
        if self.class_names.as_ref().is_some_and(Vec::is_empty) {
            return bad("class_names", "must name at least one class".into());
        }
        self.preprocessing
            .validate()
            .map_err(|e| Error::config("OnnxDetectorConfig", "preprocessing", e.to_string()))
    }
}

/// One detected object in image px.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedBox {
    /// Box in image px, clipped to the frame.
    pub bbox: BBox,
    /// roadtrack class.
    pub class: ObjectClass,
    /// Model class index.
    pub model_class: usize,
    /// Confidence in `[0, 1]`.
    pub score: f64,
}

/// An ONNX detector ready to run (see the module docs).
pub struct OnnxDetector {
    path: PathBuf,
    plan: Arc<TypedRunnableModel>,
    input_h: usize,
    input_w: usize,
    layout: Layout,
    config: OnnxDetectorConfig,
    /// roadtrack class by model class index (`None`: dropped).
    class_map: Vec<Option<ObjectClass>>,
}

impl std::fmt::Debug for OnnxDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxDetector")
            .field("path", &self.path)
            .field("input_hw", &(self.input_h, self.input_w))
            .field("layout", &self.layout)
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

/// The class table of `config`: explicit `classes`, else `class_names` (COCO 80 by
/// default) through [`decode::road_class`].
fn class_map(config: &OnnxDetectorConfig) -> Result<Vec<Option<ObjectClass>>> {
    if let Some(text) = &config.classes {
        let pairs = decode::parse_class_map(text)
            .map_err(|e| Error::config("OnnxDetectorConfig", "classes", e))?;
        let n = pairs.iter().map(|(i, _)| i + 1).max().unwrap_or(0);
        let mut map = vec![None; n];
        for (i, c) in pairs {
            map[i] = Some(c);
        }
        return Ok(map);
    }
    let names: Vec<String> = match &config.class_names {
        Some(n) => n.clone(),
        None => COCO80.iter().map(|s| (*s).to_owned()).collect(),
    };
    Ok(names
        .iter()
        .map(|n| {
            decode::road_class(n).or_else(|| {
                config
                    .keep_other_classes
                    .then(|| ObjectClass::Other(n.trim().to_ascii_lowercase()))
            })
        })
        .collect())
}

impl OnnxDetector {
    /// Loads the detector at `path` with `config`. The model is run once on a blank input
    /// to learn its output shapes, which fix (or check) the layout.
    ///
    /// # Errors
    /// [`Error::Io`] when unreadable; [`Error::Format`] naming the file when it is not
    /// ONNX, has no single `N×3×H×W` input, ops tract cannot run, or outputs that fit no
    /// detector layout (the message lists the shapes found); [`Error::InvalidConfig`] for a
    /// bad config.
    pub fn load(path: &Path, config: &OnnxDetectorConfig) -> Result<Self> {
        roadtrack::config::Validate::validate(config)?;
        let (proto, dims) = read_image_model(path)?;
        // Choice: 640×640 when the model leaves its input size symbolic and the config
        // gives none (the size YOLOX-s/m/l, YOLOv8, RT-DETR and D-FINE are trained at).
        let (h, w) = match (config.input_size, dims[2], dims[3]) {
            (Some([h, w]), _, _) => (h as usize, w as usize),
            (None, Some(h), Some(w)) => (h as usize, w as usize),
            _ => (640, 640),
        };
        let plan = tract_load(&proto, [1, 3, h, w])
            .map_err(|e| model_error(path, format!("tract cannot load it: {e:#}")))?;
        let class_map = class_map(config)?;
        let mut det = Self {
            path: path.to_path_buf(),
            plan,
            input_h: h,
            input_w: w,
            layout: config.layout,
            config: config.clone(),
            class_map,
        };
        let outputs = det.run(vec![0.0; 3 * h * w])?;
        let shapes: Vec<Vec<usize>> = outputs.iter().map(|o| o.shape.clone()).collect();
        let names = match (&config.classes, &config.class_names) {
            (None, Some(n)) => n.len(),
            _ => COCO80.len(),
        };
        det.layout = decode::resolve_layout(config.layout, &shapes, names)
            .map_err(|m| model_error(path, m))?;
        Ok(det)
    }

    /// The model file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The layout in use (resolved from `auto`).
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Model input `(height, width)`, px.
    pub fn input_size(&self) -> (usize, usize) {
        (self.input_h, self.input_w)
    }

    fn run_error(&self, e: impl std::fmt::Display) -> Error {
        Error::Invalid(format!("{}: running the model: {e:#}", self.path.display()))
    }

    /// Runs the network on one preprocessed `3 × H × W` input.
    fn run(&self, input_chw: Vec<f32>) -> Result<Vec<RawOutput>> {
        let t = Tensor::from_shape(&[1, 3, self.input_h, self.input_w], &input_chw)
            .map_err(|e| self.run_error(e))?;
        let out = self
            .plan
            .run(tvec![t.into()])
            .map_err(|e| self.run_error(e))?;
        out.iter()
            .map(|v| {
                let view = v
                    .cast_to::<f32>()
                    .map_err(|e| self.run_error(e))?
                    .into_owned();
                let view = view
                    .to_plain_array_view::<f32>()
                    .map_err(|e| self.run_error(e))?;
                Ok(RawOutput {
                    shape: view.shape().to_vec(),
                    values: view.iter().copied().collect(),
                })
            })
            .collect()
    }

    /// The model input for `image` and where the frame sits in it.
    pub fn letterbox(&self, image: &RgbImage) -> (Vec<f32>, Placement) {
        letterbox(image, (self.input_w, self.input_h), &self.config)
    }

    /// The objects in `image`, best first.
    ///
    /// # Errors
    /// The model fails to run.
    pub fn detect_boxes(&self, image: &RgbImage) -> Result<Vec<DetectedBox>> {
        let (input, placement) = self.letterbox(image);
        let outputs = self.run(input)?;
        let candidates = decode::decode(
            self.layout,
            &outputs,
            (self.input_w, self.input_h),
            self.config.detr_scores,
            self.config.min_score,
        );
        // Classes roadtrack drops go before NMS, so they cannot suppress kept ones.
        let candidates: Vec<Candidate> = candidates
            .into_iter()
            .filter(|c| self.class_of(c.class).is_some())
            .collect();
        let kept = decode::nms(
            candidates,
            self.config.iou_threshold,
            self.config.max_detections,
        );
        Ok(kept
            .iter()
            .filter_map(|c| {
                Some(DetectedBox {
                    bbox: placement.to_image(c, image.dimensions())?,
                    class: self.class_of(c.class)?,
                    model_class: c.class,
                    score: c.score,
                })
            })
            .collect())
    }

    fn class_of(&self, index: usize) -> Option<ObjectClass> {
        match self.class_map.get(index) {
            Some(c) => c.clone(),
            // Choice: an index beyond the names is kept as `class<i>` only with
            // keep_other_classes (and never with an explicit `classes` map).
            None => (self.config.keep_other_classes && self.config.classes.is_none())
                .then(|| ObjectClass::Other(format!("class{index}"))),
        }
    }
}

/// The letterboxed, preprocessed `3 × H × W` input of `image` for an input of `input_wh`,
/// and where the frame sits in it. Bilinear resampling with pixel centres aligned
/// (as OpenCV's `INTER_LINEAR`).
pub fn letterbox(
    image: &RgbImage,
    input_wh: (usize, usize),
    config: &OnnxDetectorConfig,
) -> (Vec<f32>, Placement) {
    let (iw, ih) = input_wh;
    let placement = Placement::new(
        image.dimensions(),
        input_wh,
        config.resize == Resize::Stretch,
        config.resize == Resize::LetterboxTopLeft,
    );
    let (nw, nh) = placement.size;
    let (sx, sy) = placement.scale;
    let raw = Preprocessing {
        input_scale: 1.0,
        mean: [0.0; 3],
        std: [1.0; 3],
    };
    let mut content = vec![0.0f32; 3 * nw * nh];
    sample_grid_xy(
        image,
        (0.5 / sx - 0.5, 0.5 / sy - 0.5),
        (1.0 / sx, 1.0 / sy),
        (nw, nh),
        &raw,
        &mut content,
    );
    let plane = iw * ih;
    let mut out = vec![f32::from(config.pad_value); 3 * plane];
    let (ox, oy) = (placement.offset.0 as usize, placement.offset.1 as usize);
    for c in 0..3 {
        let src_c = match config.channels {
            Channels::Rgb => c,
            Channels::Bgr => 2 - c,
        };
        for y in 0..nh {
            let src = &content[src_c * nw * nh + y * nw..][..nw];
            out[c * plane + (oy + y) * iw + ox..][..nw].copy_from_slice(src);
        }
    }
    let p = &config.preprocessing;
    for c in 0..3 {
        let (gain, offset) = (p.input_scale / p.std[c], -p.mean[c] / p.std[c]);
        for v in &mut out[c * plane..(c + 1) * plane] {
            *v = gain * *v + offset;
        }
    }
    (out, placement)
}

impl OnnxDetector {
    /// [`Detector::detect`] on `&self`: the result depends on `frame` alone.
    fn frame_detections(&self, frame: &Frame) -> Result<FrameDetections> {
        let boxes = self.detect_boxes(&frame.image)?;
        let detections = boxes
            .into_iter()
            .enumerate()
            .map(|(i, b)| Detection {
                frame: frame.index,
                id: i as u64 + 1,
                pos_px: b.bbox.centre(),
                size_px: Some((b.bbox.width, b.bbox.height)),
                colour_rgb: roadtrack::detect::file::mean_colour(&frame.image, &b.bbox),
                class: Some(b.class),
                score: Some(b.score),
                area_px: None,
            })
            .collect();
        Ok(FrameDetections {
            detections,
            foreground: None,
        })
    }
}

crate::stateless_detector!(OnnxDetector);
