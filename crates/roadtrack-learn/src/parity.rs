//! The burn ↔ tract parity fixture: a small random network, an input, and burn's outputs on
//! it, stored as JSON in `crates/roadtrack-cnn/tests/fixtures/centernet_parity.json`.
//! roadtrack-learn's test checks that burn still computes these outputs; roadtrack-cnn's
//! test checks that tract computes them from the exported ONNX (within 1e-4). Each crate
//! builds without the other's heavy dependency. Regenerate with
//! `cargo run -p roadtrack-learn --example parity_fixture`.

use burn::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};

use crate::arch::{CenterNetShape, CenterNetWeights, LayerWeights};
use crate::net::CenterNet;
use crate::train::training_preprocessing;

/// The fixture's contents.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParityFixture {
    /// The network.
    pub weights: CenterNetWeights,
    /// Input height.
    pub h: usize,
    /// Input width.
    pub w: usize,
    /// `3 × h × w` preprocessed input.
    pub input: Vec<f32>,
    /// burn's `heatmap` (sigmoid), `4 × h/4 × w/4`.
    pub heatmap: Vec<f32>,
    /// burn's `boxes`, `4 × h/4 × w/4`.
    pub boxes: Vec<f32>,
}

/// The tiny widths of the fixture's network.
pub fn tiny_shape() -> CenterNetShape {
    CenterNetShape {
        c1: 4,
        c2: 6,
        c3: 8,
        c4: 8,
        head: 8,
    }
}

/// burn's outputs `(heatmap, boxes)` of `weights` on `input` (`1 × 3 × h × w`).
pub fn burn_forward(
    weights: &CenterNetWeights,
    input: &[f32],
    h: usize,
    w: usize,
) -> (Vec<f32>, Vec<f32>) {
    let device = Device::flex();
    let net = CenterNet::from_weights(weights, &device);
    let out = net.forward(Tensor::from_data(
        TensorData::new(input.to_vec(), [1, 3, h, w]),
        &device,
    ));
    let heat = CenterNet::heatmap(&out)
        .into_data()
        .try_to_vec::<f32>()
        .unwrap_or_default();
    let boxes = out
        .boxes
        .into_data()
        .try_to_vec::<f32>()
        .unwrap_or_default();
    (heat, boxes)
}

/// A fixture from `seed`: weights uniform in ±0.4 (biases ±0.2), input uniform in ±2,
/// 48 × 64.
pub fn make_fixture(seed: u64) -> ParityFixture {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let shape = tiny_shape();
    let layers = shape
        .layers()
        .iter()
        .map(|s| LayerWeights {
            weight: (0..s.weight_len())
                .map(|_| rng.random_range(-0.4f32..0.4))
                .collect(),
            bias: (0..s.cout)
                .map(|_| rng.random_range(-0.2f32..0.2))
                .collect(),
        })
        .collect();
    let weights = CenterNetWeights {
        shape,
        layers,
        preprocessing: training_preprocessing(),
    };
    let (h, w) = (48, 64);
    let input: Vec<f32> = (0..3 * h * w)
        .map(|_| rng.random_range(-2.0f32..2.0))
        .collect();
    let (heatmap, boxes) = burn_forward(&weights, &input, h, w);
    ParityFixture {
        weights,
        h,
        w,
        input,
        heatmap,
        boxes,
    }
}
