//! roadtrack's learned detector (`--detector cnn`): a small fully convolutional
//! centre-point network (CenterNet, Zhou et al. 2019, "Objects as Points") trained by
//! `roadtrack train --detector` on simulator renders (crate `roadtrack-learn`), stored as
//! ONNX and run here through tract.
//!
//! The network ([`CenterNetShape::layers`]) takes `N × 3 × H × W` (H, W multiples of
//! [`INPUT_MULTIPLE`]) and returns, at stride [`STRIDE`]:
//! - `heatmap` `N × 4 × H/4 × W/4`: the sigmoid probability that an object of class
//!   [`CLASS_NAMES`]`[k]` has its box centre in the cell;
//! - `boxes` `N × 4 × H/4 × W/4`: `ln(w / 4)`, `ln(h / 4)` (box size, px) and the centre's
//!   sub-cell offset `dx`, `dy` in cells.
//!
//! This module holds the architecture (shared with the trainer), the ONNX writer
//! ([`onnx_model`]) and the detector ([`CenterNetDetector`], in `detector.rs`).

mod detector;
#[cfg(test)]
mod tests;

pub use detector::{
    CenterNetConfig, CenterNetDense, CenterNetDetector, HeatMaps, decode_peaks, default_model_path,
    score_map_of,
};

use std::path::Path;

use prost::Message as _;
use tract_onnx::pb;

use super::onnx::float_tensor;
use super::window::Preprocessing;
use roadtrack::class::ObjectClass;
use roadtrack::error::{Error, Result};

/// Output stride of the heat map, input px per cell.
pub const STRIDE: usize = 4;
/// Input sides must be multiples of this (four stride-2 stages); frames are padded.
pub const INPUT_MULTIPLE: usize = 16;
/// Heat-map classes.
pub const CLASSES: usize = 4;
/// The heat-map channels' names (ONNX metadata `roadtrack.class_names`).
pub const CLASS_NAMES: [&str; CLASSES] = ["car", "bus/truck", "bicycle/motorcycle", "pedestrian"];
/// ONNX metadata value of `roadtrack.kind` that marks a model as this detector.
pub const KIND: &str = "centernet";

/// The heat-map channel of a roadtrack class (`None`: not detected).
pub fn class_channel(class: &ObjectClass) -> Option<usize> {
    match class {
        ObjectClass::Car => Some(0),
        ObjectClass::Bus | ObjectClass::Truck => Some(1),
        ObjectClass::Bicycle | ObjectClass::Motorcycle => Some(2),
        ObjectClass::Pedestrian => Some(3),
        _ => None,
    }
}

/// The roadtrack class a heat-map channel reports. Choice: bus/truck → truck and
/// bicycle/motorcycle → motorcycle (the simulator renders lorries, buses and motorcycles;
/// the evaluation groups them as lorry/bus and motorcycle).
pub fn channel_class(channel: usize) -> ObjectClass {
    match channel {
        0 => ObjectClass::Car,
        1 => ObjectClass::Truck,
        2 => ObjectClass::Motorcycle,
        _ => ObjectClass::Pedestrian,
    }
}

/// Whether the ONNX file at `path` is a learned detector (`roadtrack.kind = centernet` in
/// its metadata); `false` for anything unreadable.
pub fn is_centernet_file(path: &Path) -> bool {
    std::fs::read(path)
        .ok()
        .and_then(|b| <pb::ModelProto as prost::Message>::decode(b.as_slice()).ok())
        .is_some_and(|m| super::onnx::metadata(&m, "roadtrack.kind") == Some(KIND))
}

/// Channel widths of the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CenterNetShape {
    /// Stride-2 stem.
    pub c1: usize,
    /// Stride 4 (the output's resolution).
    pub c2: usize,
    /// Stride 8.
    pub c3: usize,
    /// Stride 16.
    pub c4: usize,
    /// The 1 × 1 head before the outputs.
    pub head: usize,
}

impl Default for CenterNetShape {
    /// Choice: 16/24/48/64, head 32: about 0.48 GMAC per 640 × 480 frame, 120 k weights.
    fn default() -> Self {
        Self {
            c1: 16,
            c2: 24,
            c3: 48,
            c4: 64,
            head: 32,
        }
    }
}

/// Kind of one layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LayerKind {
    /// Convolution, weight `[out, in, k, k]`, symmetric zero padding `pad`.
    Conv,
    /// Transposed convolution, weight `[in, out, k, k]`, no padding.
    Deconv,
}

/// One layer of the network (see [`CenterNetShape::layers`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LayerSpec {
    /// Name (ONNX initialisers `NAME.w`, `NAME.b`).
    pub name: &'static str,
    /// Convolution or transposed convolution.
    pub kind: LayerKind,
    /// Input channels.
    pub cin: usize,
    /// Output channels.
    pub cout: usize,
    /// Kernel side.
    pub k: usize,
    /// Stride.
    pub stride: usize,
    /// Zero padding on every side.
    pub pad: usize,
}

impl LayerSpec {
    /// The weight tensor's dims.
    pub fn weight_dims(&self) -> [usize; 4] {
        match self.kind {
            LayerKind::Conv => [self.cout, self.cin, self.k, self.k],
            LayerKind::Deconv => [self.cin, self.cout, self.k, self.k],
        }
    }

    /// Number of weights (without the bias).
    pub fn weight_len(&self) -> usize {
        self.weight_dims().iter().product()
    }
}

impl CenterNetShape {
    /// The layers in order. The graph: `conv1..conv7` each followed by ReLU (`conv1`,
    /// `conv2`, `conv4`, `conv6` with stride 2); `up1(r7) + r5 → ReLU`, `up2(·) + r3 →
    /// ReLU` (2 × 2 stride-2 transposed convolutions back to stride 4); `head` (1 × 1) →
    /// ReLU; then `heat` (1 × 1) → Sigmoid = `heatmap` and `box` (1 × 1) = `boxes`.
    pub fn layers(&self) -> Vec<LayerSpec> {
        let conv = |name, cin, cout, k, stride| LayerSpec {
            name,
            kind: LayerKind::Conv,
            cin,
            cout,
            k,
            stride,
            pad: k / 2,
        };
        let up = |name, cin, cout| LayerSpec {
            name,
            kind: LayerKind::Deconv,
            cin,
            cout,
            k: 2,
            stride: 2,
            pad: 0,
        };
        let s = self;
        vec![
            conv("conv1", 3, s.c1, 3, 2),
            conv("conv2", s.c1, s.c2, 3, 2),
            conv("conv3", s.c2, s.c2, 3, 1),
            conv("conv4", s.c2, s.c3, 3, 2),
            conv("conv5", s.c3, s.c3, 3, 1),
            conv("conv6", s.c3, s.c4, 3, 2),
            conv("conv7", s.c4, s.c4, 3, 1),
            up("up1", s.c4, s.c3),
            up("up2", s.c3, s.c2),
            conv("head", s.c2, s.head, 1, 1),
            conv("heat", s.head, CLASSES, 1, 1),
            conv("box", s.head, 4, 1, 1),
        ]
    }

    /// Multiply-accumulates of one forward pass on an `h × w` input.
    pub fn macs(&self, h: usize, w: usize) -> u64 {
        let mut total = 0u64;
        let (mut ch, mut cw) = (h, w);
        for l in self.layers() {
            match l.kind {
                LayerKind::Conv => {
                    ch = (ch + 2 * l.pad - l.k) / l.stride + 1;
                    cw = (cw + 2 * l.pad - l.k) / l.stride + 1;
                    total += (ch * cw * l.weight_len()) as u64;
                }
                LayerKind::Deconv => {
                    total += (ch * cw * l.weight_len()) as u64;
                    ch *= 2;
                    cw *= 2;
                }
            }
        }
        total
    }
}

/// Trained weights of one layer.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LayerWeights {
    /// Weight values, row-major in [`LayerSpec::weight_dims`] order.
    pub weight: Vec<f32>,
    /// Bias, one per output channel.
    pub bias: Vec<f32>,
}

/// A trained network: its shape, weights by layer (in [`CenterNetShape::layers`] order)
/// and its input preprocessing.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CenterNetWeights {
    /// Channel widths.
    pub shape: CenterNetShape,
    /// One entry per layer.
    pub layers: Vec<LayerWeights>,
    /// `(pixel · input_scale − mean) / std`, RGB.
    pub preprocessing: Preprocessing,
}

impl CenterNetWeights {
    /// Weights from the JSON `roadtrack-learn` writes (`arch::CenterNetWeights::to_json`).
    ///
    /// # Errors
    /// Malformed JSON or weights that do not match the shape.
    pub fn from_json(text: &str) -> Result<Self> {
        let w: Self = serde_json::from_str(text)
            .map_err(|e| Error::Invalid(format!("detector weights JSON: {e}")))?;
        w.validate()?;
        Ok(w)
    }

    /// Checks the weight counts against the shape.
    ///
    /// # Errors
    /// A layer count or size that does not match.
    pub fn validate(&self) -> Result<()> {
        let specs = self.shape.layers();
        if specs.len() != self.layers.len() {
            return Err(Error::Invalid(format!(
                "centre-point network: {} layers of weights for {} layers",
                self.layers.len(),
                specs.len()
            )));
        }
        for (s, l) in specs.iter().zip(&self.layers) {
            if l.weight.len() != s.weight_len() || l.bias.len() != s.cout {
                return Err(Error::Invalid(format!(
                    "centre-point network: layer {} has {} weights and {} biases, expected {} and {}",
                    s.name,
                    l.weight.len(),
                    l.bias.len(),
                    s.weight_len(),
                    s.cout
                )));
            }
        }
        Ok(())
    }
}

fn ints(name: &str, v: &[i64]) -> pb::AttributeProto {
    pb::AttributeProto {
        name: name.into(),
        r#type: pb::attribute_proto::AttributeType::Ints as i32,
        ints: v.to_vec(),
        ..Default::default()
    }
}

fn node(
    op: &str,
    inputs: &[&str],
    output: &str,
    attribute: Vec<pb::AttributeProto>,
) -> pb::NodeProto {
    pb::NodeProto {
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![output.into()],
        name: output.into(),
        op_type: op.into(),
        attribute,
        ..Default::default()
    }
}

fn value_info(name: &str, dims: &[Option<i64>], params: &[&str]) -> pb::ValueInfoProto {
    use pb::tensor_shape_proto::{Dimension, dimension::Value};
    let mut symbolic = params.iter();
    pb::ValueInfoProto {
        name: name.into(),
        r#type: Some(pb::TypeProto {
            value: Some(pb::type_proto::Value::TensorType(pb::type_proto::Tensor {
                elem_type: pb::tensor_proto::DataType::Float as i32,
                shape: Some(pb::TensorShapeProto {
                    dim: dims
                        .iter()
                        .map(|d| Dimension {
                            value: Some(match d {
                                Some(n) => Value::DimValue(*n),
                                None => {
                                    Value::DimParam(symbolic.next().copied().unwrap_or("N").into())
                                }
                            }),
                            ..Default::default()
                        })
                        .collect(),
                }),
            })),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// The ONNX model (opset 13) of `net`: input `input` `N × 3 × H × W` (symbolic), outputs
/// `heatmap` and `boxes`; metadata `roadtrack.kind = centernet`, `roadtrack.stride`,
/// `roadtrack.class_names`, and the preprocessing keys of `roadtrack train`'s classifiers.
///
/// # Errors
/// Weights that do not match the shape.
pub fn onnx_model(net: &CenterNetWeights) -> Result<pb::ModelProto> {
    net.validate()?;
    let specs = net.shape.layers();
    let mut initializer = Vec::new();
    for (s, l) in specs.iter().zip(&net.layers) {
        initializer.push(float_tensor(
            &format!("{}.w", s.name),
            &s.weight_dims(),
            &l.weight,
        ));
        initializer.push(float_tensor(&format!("{}.b", s.name), &[s.cout], &l.bias));
    }
    let layer = |name: &str, input: &str, output: &str| -> pb::NodeProto {
        let s = specs
            .iter()
            .find(|s| s.name == name)
            .copied()
            .unwrap_or(specs[0]);
        let w = format!("{name}.w");
        let b = format!("{name}.b");
        match s.kind {
            LayerKind::Conv => node(
                "Conv",
                &[input, &w, &b],
                output,
                vec![
                    ints("kernel_shape", &[s.k as i64, s.k as i64]),
                    ints("strides", &[s.stride as i64, s.stride as i64]),
                    ints("pads", &[s.pad as i64; 4]),
                ],
            ),
            LayerKind::Deconv => node(
                "ConvTranspose",
                &[input, &w, &b],
                output,
                vec![
                    ints("kernel_shape", &[s.k as i64, s.k as i64]),
                    ints("strides", &[s.stride as i64, s.stride as i64]),
                ],
            ),
        }
    };
    let relu = |input: &str, output: &str| node("Relu", &[input], output, vec![]);
    let mut nodes = Vec::new();
    let mut prev = "input".to_string();
    for i in 1..=7 {
        let name = format!("conv{i}");
        nodes.push(layer(&name, &prev, &format!("c{i}")));
        nodes.push(relu(&format!("c{i}"), &format!("r{i}")));
        prev = format!("r{i}");
    }
    nodes.push(layer("up1", "r7", "u1"));
    nodes.push(node("Add", &["u1", "r5"], "s1", vec![]));
    nodes.push(relu("s1", "m1"));
    nodes.push(layer("up2", "m1", "u2"));
    nodes.push(node("Add", &["u2", "r3"], "s2", vec![]));
    nodes.push(relu("s2", "m2"));
    nodes.push(layer("head", "m2", "h"));
    nodes.push(relu("h", "rh"));
    nodes.push(layer("heat", "rh", "heat_logits"));
    nodes.push(node("Sigmoid", &["heat_logits"], "heatmap", vec![]));
    nodes.push(layer("box", "rh", "boxes"));

    let p = &net.preprocessing;
    let triple = |t: [f32; 3]| format!("{},{},{}", t[0], t[1], t[2]);
    let meta = vec![
        ("roadtrack.kind", KIND.to_string()),
        ("roadtrack.stride", STRIDE.to_string()),
        ("roadtrack.class_names", CLASS_NAMES.join(",")),
        ("roadtrack.input_scale", p.input_scale.to_string()),
        ("roadtrack.mean", triple(p.mean)),
        ("roadtrack.std", triple(p.std)),
    ];
    let out_dims = |c: i64| [None, Some(c), None, None];
    Ok(pb::ModelProto {
        ir_version: 8,
        opset_import: vec![pb::OperatorSetIdProto {
            domain: String::new(),
            version: 13,
        }],
        producer_name: "roadtrack train --detector".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        graph: Some(pb::GraphProto {
            node: nodes,
            name: "roadtrack_centernet".into(),
            initializer,
            input: vec![value_info(
                "input",
                &[None, Some(3), None, None],
                &["N", "H", "W"],
            )],
            output: vec![
                value_info("heatmap", &out_dims(CLASSES as i64), &["N", "H4", "W4"]),
                value_info("boxes", &out_dims(4), &["N", "H4", "W4"]),
            ],
            ..Default::default()
        }),
        metadata_props: meta
            .into_iter()
            .map(|(k, v)| pb::StringStringEntryProto {
                key: k.into(),
                value: v,
            })
            .collect(),
        ..Default::default()
    })
}

/// The ONNX bytes of `net` ([`onnx_model`]).
///
/// # Errors
/// Weights that do not match the shape.
pub fn onnx_bytes(net: &CenterNetWeights) -> Result<Vec<u8>> {
    Ok(onnx_model(net)?.encode_to_vec())
}

/// Writes `net` as ONNX to `path` (atomically).
///
/// # Errors
/// Weights that do not match the shape; the file cannot be written.
pub fn write_onnx(path: &Path, net: &CenterNetWeights) -> Result<()> {
    roadtrack::io::atomic::write_bytes_atomic(path, &onnx_bytes(net)?)
}
