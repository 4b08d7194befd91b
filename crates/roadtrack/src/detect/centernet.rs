//! The learned detector's architecture (issue 13): layer list, class channels, and the
//! trained weights in JSON. Shared by the trainer (`roadtrack-learn`, burn) and the
//! inference (`roadtrack_cnn::centernet`, tract), so neither depends on the other's engine.

use crate::class::ObjectClass;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Input preprocessing `(pixel · input_scale − mean[c]) / std[c]`, RGB (the fields of
/// `roadtrack_cnn::window::Preprocessing`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Preprocessing {
    /// Multiplier of the 0–255 value.
    pub input_scale: f32,
    /// Per-channel mean.
    pub mean: [f32; 3],
    /// Per-channel divisor.
    pub std: [f32; 3],
}

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

/// Channel widths of the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerWeights {
    /// Weight values, row-major in [`LayerSpec::weight_dims`] order.
    pub weight: Vec<f32>,
    /// Bias, one per output channel.
    pub bias: Vec<f32>,
}

/// A trained network: its shape, weights by layer (in [`CenterNetShape::layers`] order)
/// and its input preprocessing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CenterNetWeights {
    /// Channel widths.
    pub shape: CenterNetShape,
    /// One entry per layer.
    pub layers: Vec<LayerWeights>,
    /// `(pixel · input_scale − mean) / std`, RGB.
    pub preprocessing: Preprocessing,
}

impl CenterNetWeights {
    /// The weights as JSON (what [`CenterNetWeights::from_json`] reads).
    ///
    /// # Errors
    /// Never in practice (serialisation of plain numbers).
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string(self).map_err(|e| Error::Invalid(format!("weights to JSON: {e}")))
    }

    /// Weights from the JSON `roadtrack-learn` writes ([`CenterNetWeights::to_json`]).
    ///
    /// # Errors
    /// Malformed JSON or weights that do not match the shape.
    pub fn from_json(text: &str) -> Result<Self> {
        let w: Self = serde_json::from_str(text)
            .map_err(|e| Error::Invalid(format!("detector weights JSON: {e}")))?;
        w.validate()?;
        Ok(w)
    }

    /// The element-wise mean of networks of one shape and preprocessing: a "model soup"
    /// (Wortsman et al. 2022, uniform soup) of fine-tunes started from the same weights.
    /// Summed in f64, in the order given.
    ///
    /// # Errors
    /// No networks, or networks whose shapes or preprocessing differ.
    pub fn average(nets: &[Self]) -> Result<Self> {
        let first = nets
            .first()
            .ok_or_else(|| Error::Invalid("averaging weights: no networks given".into()))?;
        for (i, n) in nets.iter().enumerate() {
            n.validate()?;
            if n.shape != first.shape || n.preprocessing != first.preprocessing {
                return Err(Error::Invalid(format!(
                    "averaging weights: network {} has shape {:?} and preprocessing {:?}, \
                     the first {:?} and {:?}",
                    i + 1,
                    n.shape,
                    n.preprocessing,
                    first.shape,
                    first.preprocessing
                )));
            }
        }
        let k = nets.len() as f64;
        let mean = |get: &dyn Fn(&Self) -> &[f32], len: usize| -> Vec<f32> {
            (0..len)
                .map(|j| (nets.iter().map(|n| f64::from(get(n)[j])).sum::<f64>() / k) as f32)
                .collect()
        };
        let layers = (0..first.layers.len())
            .map(|l| LayerWeights {
                weight: mean(&|n| &n.layers[l].weight, first.layers[l].weight.len()),
                bias: mean(&|n| &n.layers[l].bias, first.layers[l].bias.len()),
            })
            .collect();
        Ok(Self {
            shape: first.shape,
            layers,
            preprocessing: first.preprocessing,
        })
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
