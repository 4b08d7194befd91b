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

/// The affine head of a classifier that dense mode turns into a 1×1 convolution.
#[derive(Debug, Clone)]
struct DenseHead {
    /// Nodes of the backbone (everything before the global average pool).
    backbone: Vec<pb::NodeProto>,
    /// Tensor feeding the global average pool.
    features: String,
    /// Gemm weights as `[classes][features]`.
    weight: Vec<f32>,
    /// Gemm bias, one per class.
    bias: Vec<f32>,
    classes: usize,
    n_features: usize,
    /// The activation the model applied after the Gemm, if any.
    activation: Option<OutputKind>,
    /// Feature-map size of one window, `(height, width)`.
    feature_size: (usize, usize),
    /// Input pixels per feature cell.
    net_stride: usize,
}

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

fn model_error(path: &Path, message: impl std::fmt::Display) -> Error {
    Error::format(path, format!("ONNX model: {message}"))
}

/// The metadata value for `key`, if the model has it.
fn metadata<'a>(proto: &'a pb::ModelProto, key: &str) -> Option<&'a str> {
    proto
        .metadata_props
        .iter()
        .find(|p| p.key == key)
        .map(|p| p.value.as_str())
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
fn float_values(t: &pb::TensorProto) -> Option<Vec<f32>> {
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

fn tract_load(proto: &pb::ModelProto, input: [usize; 4]) -> TractResult<Arc<TypedRunnableModel>> {
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
        let prep = config.preprocessing.unwrap_or_else(|| {
            let d = Preprocessing::default();
            Preprocessing {
                input_scale: metadata(&proto, "roadtrack.input_scale")
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(d.input_scale),
                mean: metadata(&proto, "roadtrack.mean")
                    .and_then(parse_triple)
                    .unwrap_or(d.mean),
                std: metadata(&proto, "roadtrack.std")
                    .and_then(parse_triple)
                    .unwrap_or(d.std),
            }
        });
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

    /// Finds (once) and returns the classifier's affine head for dense mode.
    fn dense_head(&self) -> Result<Arc<DenseHead>> {
        let mut guard = self
            .head
            .lock()
            .map_err(|_| Error::Invalid("dense head lock poisoned".into()))?;
        if guard.is_none() {
            *guard = Some(self.find_dense_head().map(Arc::new));
        }
        match guard.as_ref() {
            Some(Ok(h)) => Ok(h.clone()),
            Some(Err(msg)) => Err(model_error(&self.path, msg)),
            None => Err(Error::Invalid("dense head missing".into())),
        }
    }

    fn find_dense_head(&self) -> std::result::Result<DenseHead, String> {
        const NEEDS: &str = "dense mode needs a `GlobalAveragePool → Flatten → Gemm [→ Softmax|Sigmoid]` head; use per-window scoring";
        let graph = self.proto.graph.as_ref().ok_or("no graph")?;
        let nodes = &graph.node;
        let consumers = |name: &str| -> Vec<usize> {
            (0..nodes.len())
                .filter(|&i| nodes[i].input.iter().any(|x| x == name))
                .collect()
        };
        let gap = nodes
            .iter()
            .rposition(|n| n.op_type == "GlobalAveragePool")
            .ok_or(NEEDS)?;
        let single = |name: &str| -> std::result::Result<usize, String> {
            match consumers(name).as_slice() {
                [i] => Ok(*i),
                _ => Err(NEEDS.to_string()),
            }
        };
        let flat = single(&nodes[gap].output[0])?;
        if !matches!(nodes[flat].op_type.as_str(), "Flatten" | "Reshape") {
            return Err(NEEDS.into());
        }
        let gemm = single(&nodes[flat].output[0])?;
        let g = &nodes[gemm];
        if g.op_type != "Gemm" || g.input.len() < 2 || g.input[0] != nodes[flat].output[0] {
            return Err(NEEDS.into());
        }
        let int_attr = |n: &str, d: i64| attr(g, n).map_or(d, |a| a.i);
        let float_attr = |n: &str, d: f32| attr(g, n).map_or(d, |a| a.f);
        if int_attr("transA", 0) != 0 || float_attr("alpha", 1.0) != 1.0 {
            return Err(format!("{NEEDS} (Gemm with transA/alpha not supported)"));
        }
        let init = |name: &str| graph.initializer.iter().find(|t| t.name == name);
        let b = init(&g.input[1]).ok_or(NEEDS)?;
        let bv = float_values(b).ok_or("Gemm weights are not float initializers")?;
        let (classes, n_features, weight) = match (b.dims.as_slice(), int_attr("transB", 0)) {
            ([c, f], 1) => (*c as usize, *f as usize, bv),
            ([f, c], 0) => {
                let (f, c) = (*f as usize, *c as usize);
                let mut t = vec![0.0; f * c];
                for i in 0..f {
                    for j in 0..c {
                        t[j * f + i] = bv[i * c + j];
                    }
                }
                (c, f, t)
            }
            _ => return Err("Gemm weights are not a matrix".into()),
        };
        let beta = float_attr("beta", 1.0);
        let bias = match g.input.get(2).filter(|s| !s.is_empty()) {
            Some(name) => {
                let c = init(name).ok_or(NEEDS)?;
                let v = float_values(c).ok_or("Gemm bias is not a float initializer")?;
                match v.len() {
                    1 => vec![v[0] * beta; classes],
                    n if n == classes => v.iter().map(|x| x * beta).collect(),
                    _ => return Err("Gemm bias does not broadcast per class".into()),
                }
            }
            None => vec![0.0; classes],
        };
        let activation = match consumers(&g.output[0]).as_slice() {
            [] => None,
            [i] if nodes[*i].op_type == "Softmax" => Some(OutputKind::Softmax),
            [i] if nodes[*i].op_type == "Sigmoid" => Some(OutputKind::Sigmoid),
            _ => return Err(NEEDS.into()),
        };
        let features = nodes[gap].input[0].clone();
        let backbone: Vec<pb::NodeProto> = nodes[..gap].to_vec();
        // Feature-map size of one window, and the stride, from tract's shape inference on
        // the backbone at two input sizes.
        let feature_hw = |h: usize, w: usize| -> std::result::Result<(usize, usize), String> {
            let proto = self.backbone_proto(&backbone, &features, &[], [1, 3, h, w]);
            let typed = tract_onnx::onnx()
                .model_for_proto_model(&proto)
                .and_then(|m| m.with_input_fact(0, f32::fact([1, 3, h, w]).into()))
                .and_then(|m| m.into_typed())
                .map_err(|e| format!("shape inference of the backbone failed: {e:#}"))?;
            let shape = typed
                .output_fact(0)
                .ok()
                .and_then(|f| f.shape.as_concrete().map(|s| s.to_vec()))
                .ok_or("backbone output shape is not fixed")?;
            match shape.as_slice() {
                [1, c, fh, fw] if *c == n_features => Ok((*fh, *fw)),
                _ => Err(format!(
                    "backbone output {shape:?} is not 1×{n_features}×h×w"
                )),
            }
        };
        let (fh, fw) = feature_hw(self.input_height, self.input_width)?;
        const GROW: usize = 256;
        let (fh2, fw2) = feature_hw(self.input_height + GROW, self.input_width + GROW)?;
        let (dh, dw) = (fh2.saturating_sub(fh), fw2.saturating_sub(fw));
        if dh == 0 || dh != dw || !GROW.is_multiple_of(dh) || fh == 0 || fw == 0 {
            return Err("cannot determine a whole-pixel network stride".into());
        }
        Ok(DenseHead {
            backbone,
            features,
            weight,
            bias,
            classes,
            n_features,
            activation,
            feature_size: (fh, fw),
            net_stride: GROW / dh,
        })
    }

    /// A model holding `backbone` + `extra` nodes with output `output`, fixed input dims.
    fn backbone_proto(
        &self,
        backbone: &[pb::NodeProto],
        output: &str,
        extra: &[(pb::NodeProto, Vec<pb::TensorProto>)],
        input: [usize; 4],
    ) -> pb::ModelProto {
        use pb::tensor_shape_proto::{Dimension, dimension::Value};
        let mut proto = self.proto.clone();
        if let Some(g) = proto.graph.as_mut() {
            g.node = backbone.to_vec();
            for (n, inits) in extra {
                g.node.push(n.clone());
                g.initializer.extend(inits.iter().cloned());
            }
            let initializers: Vec<String> = g.initializer.iter().map(|t| t.name.clone()).collect();
            for i in g.input.iter_mut() {
                if initializers.contains(&i.name) {
                    continue;
                }
                if let Some(pb::type_proto::Value::TensorType(t)) =
                    i.r#type.as_mut().and_then(|t| t.value.as_mut())
                {
                    t.shape = Some(pb::TensorShapeProto {
                        dim: input
                            .iter()
                            .map(|&d| Dimension {
                                value: Some(Value::DimValue(d as i64)),
                                ..Default::default()
                            })
                            .collect(),
                    });
                }
            }
            g.output = vec![pb::ValueInfoProto {
                name: output.to_string(),
                ..Default::default()
            }];
            g.value_info.clear();
        }
        proto
    }

    /// The dense plan for a `height × width` input and pool stride `k` (cached).
    fn dense_plan(
        &self,
        head: &DenseHead,
        height: usize,
        width: usize,
        k: usize,
    ) -> Result<DensePlan> {
        let key = (height, width, k);
        if let Some(p) = self
            .dense_plans
            .lock()
            .map_err(|_| Error::Invalid("dense plan lock poisoned".into()))?
            .get(&key)
        {
            return Ok(p.clone());
        }
        let pool = pb::NodeProto {
            input: vec![head.features.clone()],
            output: vec!["roadtrack_dense_pool".into()],
            name: "roadtrack_dense_pool".into(),
            op_type: "AveragePool".into(),
            attribute: vec![
                ints_attr("kernel_shape", &[head.feature_size.0, head.feature_size.1]),
                ints_attr("strides", &[k, k]),
            ],
            ..Default::default()
        };
        let w = float_tensor(
            "roadtrack_dense_w",
            &[head.classes, head.n_features, 1, 1],
            &head.weight,
        );
        let b = float_tensor("roadtrack_dense_b", &[head.classes], &head.bias);
        let conv = pb::NodeProto {
            input: vec![
                "roadtrack_dense_pool".into(),
                "roadtrack_dense_w".into(),
                "roadtrack_dense_b".into(),
            ],
            output: vec!["roadtrack_dense_logits".into()],
            name: "roadtrack_dense_head".into(),
            op_type: "Conv".into(),
            attribute: vec![ints_attr("kernel_shape", &[1, 1])],
            ..Default::default()
        };
        let proto = self.backbone_proto(
            &head.backbone,
            "roadtrack_dense_logits",
            &[(pool, vec![]), (conv, vec![w, b])],
            [1, 3, height, width],
        );
        let plan = tract_load(&proto, [1, 3, height, width])
            .map_err(|e| model_error(&self.path, format!("dense rewrite failed: {e:#}")))?;
        self.dense_plans
            .lock()
            .map_err(|_| Error::Invalid("dense plan lock poisoned".into()))?
            .insert(key, plan.clone());
        Ok(plan)
    }

    /// Dense mode: runs the network once over the whole frame and returns the target-class
    /// probability for windows centred on a grid of image positions.
    ///
    /// The grid starts at `(0, 0)` and covers the image (one cell beyond its right and
    /// bottom edges). Its stride is `network stride × pool step × window scale`, with the
    /// pool step `k = max(1, round(stride_px / (network stride × window scale)))`; the map
    /// says the stride actually used. At every grid point the value equals
    /// [`OnnxClassifier::score_windows`] for a classifier without padding (same samples,
    /// same border policy); between grid points [`ScoreMap::sample`] interpolates.
    ///
    /// # Errors
    /// When the model's head is not `GlobalAveragePool → Flatten → Gemm [→ activation]`.
    pub fn score_map(&self, image: &RgbImage, stride_px: u32) -> Result<ScoreMap> {
        let head = self.dense_head()?;
        let t = head.net_stride;
        let k = ((f64::from(stride_px) / (t as f64 * self.window_scale)).round() as usize).max(1);
        // Bands of about DENSE_BAND_PX input rows, so the window-height overlap between
        // bands stays a small fraction of the work.
        let band_rows = DENSE_BAND_PX.div_ceil(t * k).max(4);
        self.score_map_in_bands(image, stride_px, band_rows)
    }

    /// [`OnnxClassifier::score_map`] computed in horizontal bands of `band_rows` grid rows,
    /// one network pass per band, bands in parallel.
    ///
    /// Choice: the band height depends on the stride only (not on the thread count), so the
    /// tensors, and hence the values, do not depend on the thread count; tract runs one pass on one core, so bands
    /// are what uses the second core.
    fn score_map_in_bands(
        &self,
        image: &RgbImage,
        stride_px: u32,
        band_rows: usize,
    ) -> Result<ScoreMap> {
        let head = self.dense_head()?;
        let s = self.window_scale;
        let t = head.net_stride;
        let k = ((f64::from(stride_px) / (t as f64 * s)).round() as usize).max(1);
        let step_px = (t * k) as f64 * s;
        let (iw, ih) = image.dimensions();
        let nx = (f64::from(iw) / step_px).ceil() as usize + 1;
        let ny = (f64::from(ih) / step_px).ceil() as usize + 1;
        let dw = (nx - 1) * t * k + self.input_width;
        // Dense pixel q samples image position (q − w/2 + 0.5)·s − 0.5 (see cut_window).
        let x0 = (0.5 - self.input_width as f64 / 2.0) * s - 0.5;
        let y0 = (0.5 - self.input_height as f64 / 2.0) * s - 0.5;
        let kind = head.activation.unwrap_or(self.output);
        let band_rows = band_rows.max(1);
        let bands: Vec<(usize, usize)> = (0..ny)
            .step_by(band_rows)
            .map(|r0| (r0, (r0 + band_rows).min(ny)))
            .collect();
        let band_values: Vec<Vec<f64>> = bands
            .par_iter()
            .map(|&(r0, r1)| -> Result<Vec<f64>> {
                let rows = r1 - r0;
                let dh = (rows - 1) * t * k + self.input_height;
                let plan = self.dense_plan(&head, dh, dw, k)?;
                let mut input = vec![0.0f32; 3 * dw * dh];
                let band_y0 = y0 + (r0 * t * k) as f64 * s;
                sample_grid(image, x0, band_y0, s, dw, dh, &self.prep, &mut input);
                let t_in =
                    Tensor::from_shape(&[1, 3, dh, dw], &input).map_err(|e| self.run_error(e))?;
                let out = plan
                    .run(tvec![t_in.into()])
                    .map_err(|e| self.run_error(e))?;
                let first = out.first().ok_or_else(|| self.run_error("no output"))?;
                let view = first
                    .to_plain_array_view::<f32>()
                    .map_err(|e| self.run_error(e))?;
                let shape = view.shape().to_vec();
                let [1, c, oh, ow] = shape.as_slice() else {
                    return Err(self.run_error(format!("dense output shape {shape:?}")));
                };
                let (c, oh, ow) = (*c, *oh, *ow);
                if oh < rows || ow < nx {
                    return Err(self.run_error(format!(
                        "dense output {oh}×{ow} is smaller than the grid {rows}×{nx}"
                    )));
                }
                let data: Vec<f32> = view.iter().copied().collect();
                let mut values = Vec::with_capacity(rows * nx);
                let mut logits = vec![0.0f32; c];
                for i in 0..rows {
                    for j in 0..nx {
                        for (ch, l) in logits.iter_mut().enumerate() {
                            *l = data[(ch * oh + i) * ow + j];
                        }
                        values.push(class_probability(&logits, self.target_class, kind));
                    }
                }
                Ok(values)
            })
            .collect::<Result<_>>()?;
        Ok(ScoreMap {
            origin_px: Point::new(0.0, 0.0),
            stride_px: step_px,
            cols: nx,
            rows: ny,
            values: band_values.concat(),
        })
    }
}

/// Dense-input rows per band, about (see `score_map_in_bands`). Choice: 256, two bands for
/// a 480-row frame, so both cores of the reference machine work on one frame.
const DENSE_BAND_PX: usize = 256;

fn ints_attr(name: &str, v: &[usize]) -> pb::AttributeProto {
    pb::AttributeProto {
        name: name.into(),
        r#type: pb::attribute_proto::AttributeType::Ints as i32,
        ints: v.iter().map(|&x| x as i64).collect(),
        ..Default::default()
    }
}

/// A float initializer.
pub(crate) fn float_tensor(name: &str, dims: &[usize], values: &[f32]) -> pb::TensorProto {
    pb::TensorProto {
        name: name.into(),
        dims: dims.iter().map(|&d| d as i64).collect(),
        data_type: pb::tensor_proto::DataType::Float as i32,
        raw_data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIXTURE: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/tiny_classifier.onnx"
    );
    const REFERENCE: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/tiny_classifier_ref.json"
    );

    fn tiny() -> OnnxClassifier {
        OnnxClassifier::load(Path::new(FIXTURE), &CnnConfig::default()).expect("fixture loads")
    }

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
    fn tract_matches_onnxruntime_on_the_tiny_model() -> Result<()> {
        let reference: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(REFERENCE).map_err(|e| Error::io(REFERENCE, e))?,
        )
        .map_err(|e| Error::Invalid(e.to_string()))?;
        let expected = reference["output"].as_array().expect("output array");
        let model = tiny();
        assert_eq!(model.input_size(), (32, 16));
        let per = 3 * 32 * 16;
        for (n, row) in expected.iter().enumerate() {
            let input: Vec<f32> = (0..per)
                .map(|k| {
                    let i = (n * per + k) as i64;
                    (((i * 37 + 11) % 101) as f64 / 50.0 - 1.0) as f32
                })
                .collect();
            let got = model.raw_outputs(&input)?;
            let want: Vec<f64> = row
                .as_array()
                .expect("row")
                .iter()
                .filter_map(|v| v.as_f64())
                .collect();
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert!(
                    (f64::from(*g) - w).abs() < 1e-5,
                    "tract {g} vs onnxruntime {w}"
                );
            }
        }
        Ok(())
    }

    #[test]
    fn dense_lookup_equals_window_scores_at_grid_points() -> Result<()> {
        let model = tiny();
        let img = textured(61, 47);
        for stride in [4, 8] {
            let map = model.score_map(&img, stride)?;
            assert_eq!(map.stride_px, f64::from(stride));
            assert!(map.cols as f64 * map.stride_px >= 61.0);
            let mut centres = Vec::new();
            for i in 0..map.rows {
                for j in 0..map.cols {
                    centres.push(map.cell_centre_px(i, j));
                }
            }
            let mut direct = vec![0.0; centres.len()];
            model.score_windows(&img, &centres, &mut direct)?;
            for (c, d) in centres.iter().zip(&direct) {
                let dense = map.sample(*c);
                assert!(
                    (dense - d).abs() < 1e-5,
                    "at {c:?}: dense {dense} vs window {d}"
                );
            }
            // The scores vary over the image, so the comparison is not vacuous.
            let (lo, hi) = direct
                .iter()
                .fold((1.0f64, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
            assert!(hi - lo > 1e-3, "scores are flat: {lo}..{hi}");
        }
        Ok(())
    }

    #[test]
    fn dense_bands_give_the_same_map_as_one_pass() -> Result<()> {
        let model = tiny();
        let img = textured(45, 70);
        let one = model.score_map_in_bands(&img, 4, 1000)?;
        for rows in [1, 3, 7] {
            let banded = model.score_map_in_bands(&img, 4, rows)?;
            assert_eq!((banded.cols, banded.rows), (one.cols, one.rows));
            for (a, b) in banded.values.iter().zip(&one.values) {
                assert!((a - b).abs() < 1e-6, "{rows} rows: {a} vs {b}");
            }
        }
        Ok(())
    }

    #[test]
    fn dense_mode_is_exact_with_a_window_scale_too() -> Result<()> {
        let cfg = CnnConfig {
            window_scale: Some(1.5),
            ..Default::default()
        };
        let model = OnnxClassifier::load(Path::new(FIXTURE), &cfg)?;
        let img = textured(50, 40);
        let map = model.score_map(&img, 6)?;
        assert_eq!(map.stride_px, 6.0);
        let centres: Vec<Point> = (0..map.cols).map(|j| map.cell_centre_px(2, j)).collect();
        let mut direct = vec![0.0; centres.len()];
        model.score_windows(&img, &centres, &mut direct)?;
        for (c, d) in centres.iter().zip(&direct) {
            assert!((map.sample(*c) - d).abs() < 1e-5);
        }
        Ok(())
    }

    #[test]
    fn window_scores_do_not_depend_on_the_thread_count() -> Result<()> {
        let model = tiny();
        let img = textured(40, 30);
        let centres: Vec<Point> = (0..40)
            .map(|i| Point::new(i as f64 * 1.3, 29.0 - i as f64 * 0.7))
            .collect();
        let mut a = vec![0.0; 40];
        model.score_windows(&img, &centres, &mut a)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool");
        let mut b = vec![0.0; 40];
        pool.install(|| model.score_windows(&img, &centres, &mut b))?;
        assert_eq!(a, b);
        Ok(())
    }

    #[test]
    fn wrong_files_are_rejected_with_the_file_named() {
        let dir = tempfile::tempdir().expect("tempdir");
        let text = dir.path().join("notes.onnx");
        std::fs::write(&text, "this is not a model\n").expect("write");
        let err = OnnxClassifier::load(&text, &CnnConfig::default()).expect_err("text");
        assert!(err.to_string().contains("notes.onnx"), "{err}");

        // Wrong input rank: the tiny model's graph with a rank-2 input.
        let mut proto = tiny().proto.clone();
        if let Some(pb::type_proto::Value::TensorType(t)) = proto
            .graph
            .as_mut()
            .and_then(|g| g.input[0].r#type.as_mut().and_then(|t| t.value.as_mut()))
            && let Some(s) = t.shape.as_mut()
        {
            s.dim.truncate(2);
        }
        let rank = dir.path().join("rank2.onnx");
        std::fs::write(&rank, prost::Message::encode_to_vec(&proto)).expect("write");
        let err = OnnxClassifier::load(&rank, &CnnConfig::default()).expect_err("rank");
        let msg = err.to_string();
        assert!(
            msg.contains("rank2.onnx") && msg.contains("rank 2"),
            "{msg}"
        );

        // Missing output.
        let mut proto = tiny().proto.clone();
        if let Some(g) = proto.graph.as_mut() {
            g.output.clear();
        }
        let noout = dir.path().join("noout.onnx");
        std::fs::write(&noout, prost::Message::encode_to_vec(&proto)).expect("write");
        let err = OnnxClassifier::load(&noout, &CnnConfig::default()).expect_err("no output");
        let msg = err.to_string();
        assert!(
            msg.contains("noout.onnx") && msg.contains("no output"),
            "{msg}"
        );

        // Target class beyond the outputs.
        let cfg = CnnConfig {
            target_class: Some(5),
            ..Default::default()
        };
        let err = OnnxClassifier::load(Path::new(FIXTURE), &cfg).expect_err("class");
        assert!(err.to_string().contains("tiny_classifier.onnx"));

        let missing = dir.path().join("absent.onnx");
        let err = OnnxClassifier::load(&missing, &CnnConfig::default()).expect_err("absent");
        assert!(err.to_string().contains("absent.onnx"));
    }

    #[test]
    fn output_kinds_turn_outputs_into_probabilities() {
        assert_eq!(
            class_probability(&[0.2, 0.8], 1, OutputKind::Probabilities),
            0.8f32 as f64
        );
        let p = class_probability(&[0.0, 2.0_f32.ln()], 1, OutputKind::Softmax);
        assert!((p - 2.0 / 3.0).abs() < 1e-6);
        let s = class_probability(&[0.0], 0, OutputKind::Sigmoid);
        assert!((s - 0.5).abs() < 1e-12);
        assert_eq!(class_probability(&[0.5], 3, OutputKind::Probabilities), 0.0);
    }
}
