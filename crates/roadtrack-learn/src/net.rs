//! The centre-point network in burn, following the layer list of [`crate::arch`]
//! exactly (so the ONNX export is a copy of the weights), with weights initialised from
//! roadtrack's own seeded RNG (He-uniform) rather than burn's global one: the same seed
//! gives the same network whatever else runs in the process.

use crate::arch::{
    CenterNetShape, CenterNetWeights, LayerKind, LayerSpec, LayerWeights, Preprocessing,
};
use burn::module::Param;
use burn::nn::Initializer;
use burn::nn::PaddingConfig2d;
use burn::nn::conv::{Conv2d, Conv2dConfig, ConvTranspose2d, ConvTranspose2dConfig};
use burn::prelude::*;
use burn::tensor::activation::{relu, sigmoid};
use rand::RngExt;

/// The network's outputs: heat-map logits `N × 4 × H/4 × W/4` and the box maps
/// `N × 4 × H/4 × W/4` (`ln(w/4)`, `ln(h/4)`, `dx`, `dy`).
#[derive(Debug)]
pub struct Outputs {
    /// Heat-map logits (sigmoid gives the probabilities the ONNX model outputs).
    pub heat_logits: Tensor<4>,
    /// Box size and offset maps.
    pub boxes: Tensor<4>,
}

/// The centre-point network (see `crate::arch::CenterNetShape::layers`).
#[derive(Module, Debug)]
pub struct CenterNet {
    /// `conv1..conv7`, `head`, `heat`, `box`, in layer-list order.
    convs: Vec<Conv2d>,
    /// `up1`, `up2`.
    ups: Vec<ConvTranspose2d>,
}

/// Prior probability of an object centre in a cell, for the heat head's bias
/// (CenterNet: −2.19 = logit(0.1)).
const HEAT_PRIOR: f64 = 0.1;

impl CenterNet {
    /// A network of `shape` with weights drawn from `rng` (He-uniform, biases 0, the heat
    /// head's bias at the logit of [`HEAT_PRIOR`]).
    pub fn init(shape: &CenterNetShape, rng: &mut impl rand::Rng, device: &Device) -> Self {
        let mut convs = Vec::new();
        let mut ups = Vec::new();
        for spec in shape.layers() {
            let fan_in = match spec.kind {
                LayerKind::Conv => spec.cin * spec.k * spec.k,
                // Each output of a non-overlapping 2×2 stride-2 deconvolution sees `cin` inputs.
                LayerKind::Deconv => spec.cin,
            } as f64;
            let bound = if spec.name == "heat" || spec.name == "box" {
                // Choice: small output heads start near their bias.
                0.01
            } else {
                (6.0 / fan_in).sqrt()
            };
            let weight: Vec<f32> = (0..spec.weight_len())
                .map(|_| rng.random_range(-bound..bound) as f32)
                .collect();
            let bias_value = if spec.name == "heat" {
                (HEAT_PRIOR / (1.0 - HEAT_PRIOR)).ln() as f32
            } else {
                0.0
            };
            let bias = vec![bias_value; spec.cout];
            let w = LayerWeights { weight, bias };
            match spec.kind {
                LayerKind::Conv => convs.push(conv_from(&spec, &w, device)),
                LayerKind::Deconv => ups.push(deconv_from(&spec, &w, device)),
            }
        }
        Self { convs, ups }
    }

    /// A network of `shape` holding `weights` (e.g. to evaluate an exported model in burn).
    pub fn from_weights(weights: &CenterNetWeights, device: &Device) -> Self {
        let mut convs = Vec::new();
        let mut ups = Vec::new();
        for (spec, w) in weights.shape.layers().iter().zip(&weights.layers) {
            match spec.kind {
                LayerKind::Conv => convs.push(conv_from(spec, w, device)),
                LayerKind::Deconv => ups.push(deconv_from(spec, w, device)),
            }
        }
        Self { convs, ups }
    }

    /// The forward pass on `N × 3 × H × W` (H, W multiples of 16).
    pub fn forward(&self, x: Tensor<4>) -> Outputs {
        let c = &self.convs;
        let r1 = relu(c[0].forward(x));
        let r2 = relu(c[1].forward(r1));
        let r3 = relu(c[2].forward(r2));
        let r4 = relu(c[3].forward(r3.clone()));
        let r5 = relu(c[4].forward(r4));
        let r6 = relu(c[5].forward(r5.clone()));
        let r7 = relu(c[6].forward(r6));
        let m1 = relu(self.ups[0].forward(r7) + r5);
        let m2 = relu(self.ups[1].forward(m1) + r3);
        let h = relu(c[7].forward(m2));
        Outputs {
            heat_logits: c[8].forward(h.clone()),
            boxes: c[9].forward(h),
        }
    }

    /// The heat-map probabilities (as the ONNX model's `heatmap`).
    pub fn heatmap(outputs: &Outputs) -> Tensor<4> {
        sigmoid(outputs.heat_logits.clone())
    }

    /// The weights in plain form, for the ONNX export (`roadtrack_cnn::centernet`).
    pub fn weights(&self, shape: &CenterNetShape, prep: Preprocessing) -> CenterNetWeights {
        let mut convs = self.convs.iter();
        let mut ups = self.ups.iter();
        let to_vec =
            |t: Tensor<4>| -> Vec<f32> { t.into_data().try_to_vec::<f32>().unwrap_or_default() };
        let to_vec1 =
            |t: Tensor<1>| -> Vec<f32> { t.into_data().try_to_vec::<f32>().unwrap_or_default() };
        let layers = shape
            .layers()
            .iter()
            .map(|spec| match spec.kind {
                LayerKind::Conv => {
                    let c = convs.next().expect("one conv per conv layer");
                    LayerWeights {
                        weight: to_vec(c.weight.val()),
                        bias: c
                            .bias
                            .as_ref()
                            .map(|b| to_vec1(b.val()))
                            .unwrap_or_default(),
                    }
                }
                LayerKind::Deconv => {
                    let u = ups.next().expect("one deconv per deconv layer");
                    LayerWeights {
                        weight: to_vec(u.weight.val()),
                        bias: u
                            .bias
                            .as_ref()
                            .map(|b| to_vec1(b.val()))
                            .unwrap_or_default(),
                    }
                }
            })
            .collect();
        CenterNetWeights {
            shape: *shape,
            layers,
            preprocessing: prep,
        }
    }
}

fn conv_from(spec: &LayerSpec, w: &LayerWeights, device: &Device) -> Conv2d {
    let mut conv = Conv2dConfig::new([spec.cin, spec.cout], [spec.k, spec.k])
        .with_stride([spec.stride, spec.stride])
        .with_padding(PaddingConfig2d::Explicit(
            spec.pad, spec.pad, spec.pad, spec.pad,
        ))
        .with_initializer(Initializer::Zeros)
        .init(device);
    conv.weight = Param::from_tensor(Tensor::from_data(
        TensorData::new(w.weight.clone(), spec.weight_dims()),
        device,
    ));
    conv.bias = Some(Param::from_tensor(Tensor::from_data(
        TensorData::new(w.bias.clone(), [spec.cout]),
        device,
    )));
    conv
}

fn deconv_from(spec: &LayerSpec, w: &LayerWeights, device: &Device) -> ConvTranspose2d {
    let mut up = ConvTranspose2dConfig::new([spec.cin, spec.cout], [spec.k, spec.k])
        .with_stride([spec.stride, spec.stride])
        .with_initializer(Initializer::Zeros)
        .init(device);
    up.weight = Param::from_tensor(Tensor::from_data(
        TensorData::new(w.weight.clone(), spec.weight_dims()),
        device,
    ));
    up.bias = Some(Param::from_tensor(Tensor::from_data(
        TensorData::new(w.bias.clone(), [spec.cout]),
        device,
    )));
    up
}
