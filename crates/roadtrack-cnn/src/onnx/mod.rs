//! Any ONNX image classifier as the likelihood `h(y | x)` (METHODS.md §3), loaded with
//! tract (pure Rust), scored per window or densely once per frame.
//!
//! The model takes `N × 3 × H × W` float input (RGB planes, preprocessed as
//! [`Preprocessing`] says) and returns class probabilities or logits; [`CnnConfig`] says
//! which index is the target class and whether to apply a softmax or sigmoid.
//!
//! Dense mode rewrites a `… → GlobalAveragePool → Flatten → Gemm [→ Softmax|Sigmoid]` head
//! into `AveragePool(k = window's feature size) → 1×1 Conv`, so one pass over the whole
//! frame gives the classifier's output for every window on a grid (the classic fully
//! convolutional conversion). It is exact when the backbone has no padding (as the tiny
//! fixture and the models `roadtrack train` writes) and the grid is aligned to the
//! network's stride; with padded convolutions it is close away from window borders.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use image::RgbImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tract_onnx::pb;
use tract_onnx::prelude::*;

use super::window::{Preprocessing, cut_window, sample_grid};
use roadtrack::error::{Error, Result};
use roadtrack::geometry::Point;
use roadtrack::likelihood::ScoreMap;

/// What the model's (first) output holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OutputKind {
    /// Class probabilities: the target index is the likelihood as is.
    Probabilities,
    /// Logits over classes: apply a softmax, then take the target index.
    Softmax,
    /// Independent logits: apply a sigmoid to the target index.
    Sigmoid,
}

/// How to use an ONNX classifier as a likelihood.
///
/// Fields left `None` take the model's own defaults, written by `roadtrack train` into the
/// ONNX metadata (`roadtrack.target_class`, `roadtrack.output`, `roadtrack.input_scale`,
/// `roadtrack.mean`, `roadtrack.std`), and otherwise: target class 1, probabilities,
/// [`Preprocessing::default`].
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CnnConfig {
    /// Index of the target class (person or vehicle) in the output.
    pub target_class: Option<usize>,
    /// What the output holds.
    pub output: Option<OutputKind>,
    /// Pixel preprocessing.
    pub preprocessing: Option<Preprocessing>,
    /// Input `[height, width]` in model pixels, needed only when the model leaves them
    /// symbolic.
    pub input_size: Option<[u32; 2]>,
    /// Image pixels per model pixel: the window is `input_size × window_scale` image px.
    /// `None` = the model's `roadtrack.window_scale` metadata, else 1.
    pub window_scale: Option<f64>,
}

mod dense;
#[cfg(test)]
mod tests;

use dense::DenseHead;
pub(crate) use dense::float_tensor;

/// A loaded dense plan, for one input size and pool stride.
type DensePlan = Arc<TypedRunnableModel>;

/// An ONNX classifier ready to score windows (see the module docs).
pub struct OnnxClassifier {
    path: PathBuf,
    proto: pb::ModelProto,
    plan: Arc<TypedRunnableModel>,
    input_height: usize,
    input_width: usize,
    classes: usize,
    target_class: usize,
    output: OutputKind,
    prep: Preprocessing,
    window_scale: f64,
    head: Mutex<Option<std::result::Result<Arc<DenseHead>, String>>>,
    dense_plans: Mutex<HashMap<(usize, usize, usize), DensePlan>>,
}

impl std::fmt::Debug for OnnxClassifier {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxClassifier")
            .field("path", &self.path)
            .field("input_hw", &(self.input_height, self.input_width))
            .field("classes", &self.classes)
            .field("target_class", &self.target_class)
            .field("output", &self.output)
            .field("prep", &self.prep)
            .field("window_scale", &self.window_scale)
            .finish()
    }
}

pub(crate) fn model_error(path: &Path, message: impl std::fmt::Display) -> Error {
    Error::format(path, format!("ONNX model: {message}"))
}

/// The metadata value for `key`, if the model has it.
pub(crate) fn metadata<'a>(proto: &'a pb::ModelProto, key: &str) -> Option<&'a str> {
    proto
        .metadata_props
        .iter()
        .find(|p| p.key == key)
        .map(|p| p.value.as_str())
}

/// The preprocessing a model's metadata gives (`roadtrack.input_scale`, `roadtrack.mean`,
/// `roadtrack.std`, as `roadtrack train` writes them); the default for each key missing or
/// unreadable.
pub(crate) fn preprocessing_from_metadata(proto: &pb::ModelProto) -> Preprocessing {
    let d = Preprocessing::default();
    Preprocessing {
        input_scale: metadata(proto, "roadtrack.input_scale")
            .and_then(|s| s.parse().ok())
            .unwrap_or(d.input_scale),
        mean: metadata(proto, "roadtrack.mean")
            .and_then(parse_triple)
            .unwrap_or(d.mean),
        std: metadata(proto, "roadtrack.std")
            .and_then(parse_triple)
            .unwrap_or(d.std),
    }
}

fn parse_triple(s: &str) -> Option<[f32; 3]> {
    let v: Vec<f32> = s
        .split(',')
        .map(|t| t.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .ok()?;
    <[f32; 3]>::try_from(v).ok()
}

/// The dims of a value's tensor type: `Some(n)` known, `None` symbolic.
fn value_dims(v: &pb::ValueInfoProto) -> Option<Vec<Option<i64>>> {
    use pb::tensor_shape_proto::dimension::Value;
    let ty = v.r#type.as_ref()?;
    let pb::type_proto::Value::TensorType(t) = ty.value.as_ref()?;
    let shape = t.shape.as_ref()?;
    Some(
        shape
            .dim
            .iter()
            .map(|d| match d.value {
                Some(Value::DimValue(n)) if n > 0 => Some(n),
                _ => None,
            })
            .collect(),
    )
}

/// The values of a float initializer.
pub(crate) fn float_values(t: &pb::TensorProto) -> Option<Vec<f32>> {
    if t.data_type != pb::tensor_proto::DataType::Float as i32 {
        return None;
    }
    if !t.float_data.is_empty() {
        return Some(t.float_data.clone());
    }
    if !t.raw_data.len().is_multiple_of(4) {
        return None;
    }
    Some(
        t.raw_data
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
    )
}

fn attr<'a>(node: &'a pb::NodeProto, name: &str) -> Option<&'a pb::AttributeProto> {
    node.attribute.iter().find(|a| a.name == name)
}

/// The class probability from one output vector (`values` = one sample's outputs).
pub fn class_probability(values: &[f32], target: usize, kind: OutputKind) -> f64 {
    let Some(&v) = values.get(target) else {
        return 0.0;
    };
    let p = match kind {
        OutputKind::Probabilities => f64::from(v),
        OutputKind::Sigmoid => 1.0 / (1.0 + (-f64::from(v)).exp()),
        OutputKind::Softmax => {
            let max = values.iter().fold(f32::NEG_INFINITY, |m, &x| m.max(x));
            let sum: f64 = values.iter().map(|&x| f64::from(x - max).exp()).sum();
            f64::from(v - max).exp() / sum
        }
    };
    if p.is_finite() {
        p.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Reads the ONNX model at `path` and checks it has one image input `N×3×H×W`; returns the
/// model and the input's dims (`None` where symbolic). Shared by the classifier and the
/// detector.
///
/// # Errors
/// [`Error::Io`] when the file cannot be read; [`Error::Format`] naming the file when it is
/// not ONNX or has no single rank-4, 3-channel input.
pub(crate) fn read_image_model(path: &Path) -> Result<(pb::ModelProto, Vec<Option<i64>>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let proto = <pb::ModelProto as prost::Message>::decode(bytes.as_slice())
        .map_err(|e| model_error(path, format!("not an ONNX file ({e})")))?;
    let graph = proto
        .graph
        .as_ref()
        .filter(|g| !g.node.is_empty())
        .ok_or_else(|| model_error(path, "not an ONNX model (no graph nodes)"))?;
    let initializers: Vec<&str> = graph.initializer.iter().map(|t| t.name.as_str()).collect();
    let inputs: Vec<&pb::ValueInfoProto> = graph
        .input
        .iter()
        .filter(|i| !initializers.contains(&i.name.as_str()))
        .collect();
    let [input] = inputs.as_slice() else {
        return Err(model_error(
            path,
            format!("expected one image input, found {}", inputs.len()),
        ));
    };
    let dims = value_dims(input).unwrap_or_default();
    if dims.len() != 4 {
        return Err(model_error(
            path,
            format!(
                "input `{}` has rank {}, expected 4 (N×3×H×W)",
                input.name,
                dims.len()
            ),
        ));
    }
    if let Some(c) = dims[1]
        && c != 3
    {
        return Err(model_error(
            path,
            format!(
                "input `{}` has {c} channels, expected 3 (N×3×H×W, RGB)",
                input.name
            ),
        ));
    }
    Ok((proto, dims))
}

pub(crate) fn tract_load(
    proto: &pb::ModelProto,
    input: [usize; 4],
) -> TractResult<Arc<TypedRunnableModel>> {
    tract_onnx::onnx()
        .model_for_proto_model(proto)?
        .with_input_fact(0, f32::fact(input).into())?
        .into_optimized()?
        .into_runnable()
}

impl OnnxClassifier {
    /// Loads `path` with `config` (see [`CnnConfig`] for defaults).
    ///
    /// # Errors
    /// [`Error::Io`] when the file cannot be read; [`Error::Format`] naming the file when
    /// it is not ONNX, has no single rank-4 `N×3×H×W` input, no output, a target class
    /// beyond its outputs, or ops tract cannot run.
    pub fn load(path: &Path, config: &CnnConfig) -> Result<Self> {
        let (proto, dims) = read_image_model(path)?;
        let graph = proto
            .graph
            .as_ref()
            .ok_or_else(|| model_error(path, "no graph"))?;
        let (h, w) = match (config.input_size, dims[2], dims[3]) {
            (Some([h, w]), _, _) => (h as usize, w as usize),
            (None, Some(h), Some(w)) => (h as usize, w as usize),
            _ => {
                return Err(model_error(
                    path,
                    "input height/width are symbolic; set input_size = [height, width]",
                ));
            }
        };
        if h == 0 || w == 0 {
            return Err(model_error(path, "input size must be positive"));
        }
        if graph.output.is_empty() {
            return Err(model_error(path, "the graph has no output"));
        }

        let target_class = config
            .target_class
            .or_else(|| metadata(&proto, "roadtrack.target_class")?.parse().ok())
            .unwrap_or(1);
        let output = config
            .output
            .or_else(|| {
                serde_json::from_str(&format!("\"{}\"", metadata(&proto, "roadtrack.output")?)).ok()
            })
            .unwrap_or(OutputKind::Probabilities);
        let prep = config
            .preprocessing
            .unwrap_or_else(|| preprocessing_from_metadata(&proto));
        prep.validate()?;
        let window_scale = config
            .window_scale
            .or_else(|| metadata(&proto, "roadtrack.window_scale")?.parse().ok())
            .unwrap_or(1.0);
        if !(window_scale.is_finite() && window_scale > 0.0) {
            return Err(Error::config(
                "CnnConfig",
                "window_scale",
                format!("must be positive, got {window_scale}"),
            ));
        }

        let plan = tract_load(&proto, [1, 3, h, w])
            .map_err(|e| model_error(path, format!("tract cannot load it: {e:#}")))?;
        let out_fact = plan
            .model()
            .output_fact(0)
            .map_err(|e| model_error(path, format!("missing output: {e:#}")))?;
        let classes = out_fact
            .shape
            .as_concrete()
            .map(|s| s.iter().product::<usize>())
            .ok_or_else(|| model_error(path, "output shape is not fixed for one window"))?;
        if target_class >= classes {
            return Err(model_error(
                path,
                format!("target class {target_class} but the output has {classes} values"),
            ));
        }
        if output == OutputKind::Softmax && classes < 2 {
            return Err(model_error(path, "softmax needs at least 2 outputs"));
        }
        Ok(Self {
            path: path.to_path_buf(),
            proto,
            plan,
            input_height: h,
            input_width: w,
            classes,
            target_class,
            output,
            prep,
            window_scale,
            head: Mutex::new(None),
            dense_plans: Mutex::new(HashMap::new()),
        })
    }

    /// The model file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Model input `(height, width)`, model px.
    pub fn input_size(&self) -> (usize, usize) {
        (self.input_height, self.input_width)
    }

    /// Window size in image px, `(width, height)` = input size × window scale.
    pub fn window_size_px(&self) -> (f64, f64) {
        (
            self.input_width as f64 * self.window_scale,
            self.input_height as f64 * self.window_scale,
        )
    }

    /// The preprocessing in use.
    pub fn preprocessing(&self) -> &Preprocessing {
        &self.prep
    }

    /// Runs the network on one preprocessed `3 × H × W` input and returns its raw outputs.
    pub fn raw_outputs(&self, input_chw: &[f32]) -> Result<Vec<f32>> {
        let t = Tensor::from_shape(&[1, 3, self.input_height, self.input_width], input_chw)
            .map_err(|e| self.run_error(e))?;
        let out = self
            .plan
            .run(tvec![t.into()])
            .map_err(|e| self.run_error(e))?;
        let first = out.first().ok_or_else(|| self.run_error("no output"))?;
        let view = first
            .to_plain_array_view::<f32>()
            .map_err(|e| self.run_error(e))?;
        Ok(view.iter().copied().collect())
    }

    fn run_error(&self, e: impl std::fmt::Display) -> Error {
        Error::Invalid(format!("{}: running the model: {e:#}", self.path.display()))
    }

    /// Probability of the target class for the window of the model's input size × window
    /// scale centred on each point, written to `out` (METHODS.md §3, `h(y | x)`).
    ///
    /// Border policy: window pixels outside the image replicate the nearest edge pixel.
    /// Windows run in parallel (one per task); results do not depend on the thread count.
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
        let n = 3 * self.input_height * self.input_width;
        let scores: Vec<f64> = centres_px
            .par_iter()
            .map_init(
                || vec![0.0f32; n],
                |buf, c| {
                    cut_window(
                        image,
                        *c,
                        self.input_width,
                        self.input_height,
                        self.window_scale,
                        &self.prep,
                        buf,
                    );
                    let raw = self.raw_outputs(buf)?;
                    Ok(class_probability(&raw, self.target_class, self.output))
                },
            )
            .collect::<Result<_>>()?;
        out.copy_from_slice(&scores);
        Ok(())
    }
}
