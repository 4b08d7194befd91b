//! roadtrack's learned detector (`--detector cnn`): a small fully convolutional
//! centre-point network (CenterNet, Zhou et al. 2019, "Objects as Points") trained by
//! `roadtrack train --detector` on simulator renders (crate `roadtrack-learn`), stored as
//! ONNX and run here by roadtrack's own kernels ([`native`]), or through tract when the
//! graph is not the one roadtrack writes.
//!
//! The network ([`CenterNetShape::layers`]) takes `N × 3 × H × W` (H, W multiples of
//! [`INPUT_MULTIPLE`]) and returns, at stride [`STRIDE`]:
//! - `heatmap` `N × 4 × H/4 × W/4`: the sigmoid probability that an object of class
//!   [`CLASS_NAMES`]`[k]` has its box centre in the cell;
//! - `boxes` `N × 4 × H/4 × W/4`: `ln(w / 4)`, `ln(h / 4)` (box size, px) and the centre's
//!   sub-cell offset `dx`, `dy` in cells.
//!
//! This module holds the architecture (shared with the trainer), the ONNX writer
//! ([`onnx_model`]) and the detector ([`CenterNetDetector`], in `detector.rs`; its settings
//! in `config.rs`).

mod config;
mod detector;
#[cfg(test)]
mod level_tests;
pub mod native;
#[cfg(test)]
mod native_tests;
#[cfg(test)]
mod tests;
mod views;

pub use config::{
    BOX_GAIN_KEY, BOX_GAIN_REF_PX, BOX_GAIN_SIZE_RANGE_PX, CenterNetConfig, ClassMinScore, ZOOM,
    ZOOM_OVERLAP_IOU, ZoomMode, box_factor,
};
pub use detector::{CenterNetDense, CenterNetDetector, HeatMaps, default_model_path};
pub use views::{
    ZOOM_CAR_LENGTH_M, add_zoomed, average_flipped, decode_peaks, drop_nested, drop_second_peaks,
    flip_input, merge_levels, replace_small, score_map_of, shrink, zoom_rows,
};

use std::path::Path;

use prost::Message as _;
use tract_onnx::pb;

use super::export::{ints, node, opset13_model, value_info};
use super::onnx::float_tensor;
use roadtrack::error::Result;

pub use roadtrack::detect::centernet::{
    CLASS_NAMES, CLASSES, CenterNetShape, CenterNetWeights, INPUT_MULTIPLE, KIND, LayerKind,
    LayerSpec, LayerWeights, STRIDE, channel_class, class_channel,
};

/// Whether the ONNX file at `path` is a learned detector (`roadtrack.kind = centernet` in
/// its metadata); `false` for anything unreadable.
pub fn is_centernet_file(path: &Path) -> bool {
    std::fs::read(path)
        .ok()
        .and_then(|b| <pb::ModelProto as prost::Message>::decode(b.as_slice()).ok())
        .is_some_and(|m| super::onnx::metadata(&m, "roadtrack.kind") == Some(KIND))
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
    Ok(opset13_model(
        "roadtrack train --detector",
        pb::GraphProto {
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
        },
        meta,
    ))
}

/// The ONNX bytes of `net` ([`onnx_model`]).
///
/// # Errors
/// Weights that do not match the shape.
pub fn onnx_bytes(net: &CenterNetWeights) -> Result<Vec<u8>> {
    Ok(onnx_model(net)?.encode_to_vec())
}

/// The weights of a learned detector's ONNX file (what [`onnx_model`] wrote): the shape
/// from the initialisers' dims, each layer's `NAME.w` / `NAME.b`, the preprocessing from
/// the metadata. Lets a training stage start from a shipped model (`train --detector
/// --init models/detector.onnx`) and models be averaged (`--average`).
///
/// # Errors
/// The file cannot be read or decoded, is not a learned detector (`roadtrack.kind`), or
/// lacks a layer's weights or has them in the wrong size.
pub fn read_weights(path: &Path) -> Result<CenterNetWeights> {
    use super::onnx::model_error;
    let bytes = std::fs::read(path).map_err(|e| roadtrack::Error::io(path, e))?;
    let proto = pb::ModelProto::decode(bytes.as_slice())
        .map_err(|e| model_error(path, format!("not an ONNX file ({e})")))?;
    weights_of(&proto, path)
}

/// [`read_weights`] of a decoded model (`path` names it in errors).
pub(crate) fn weights_of(proto: &pb::ModelProto, path: &Path) -> Result<CenterNetWeights> {
    use super::onnx::model_error;
    if super::onnx::metadata(proto, "roadtrack.kind") != Some(KIND) {
        return Err(model_error(
            path,
            format!("not a learned detector (metadata roadtrack.kind is not {KIND:?})"),
        ));
    }
    let graph = proto
        .graph
        .as_ref()
        .ok_or_else(|| model_error(path, "no graph"))?;
    let tensor = |name: &str| -> Result<(Vec<usize>, Vec<f32>)> {
        let t = graph
            .initializer
            .iter()
            .find(|t| t.name == name)
            .ok_or_else(|| model_error(path, format!("no initialiser {name}")))?;
        let values = super::onnx::float_values(t)
            .ok_or_else(|| model_error(path, format!("initialiser {name} is not float data")))?;
        let dims = t
            .dims
            .iter()
            .map(|&d| usize::try_from(d).unwrap_or(0))
            .collect();
        Ok((dims, values))
    };
    // The widths are the output channels of the layers that set them.
    let cout = |name: &str| -> Result<usize> { Ok(tensor(&format!("{name}.b"))?.1.len()) };
    let shape = CenterNetShape {
        c1: cout("conv1")?,
        c2: cout("conv2")?,
        c3: cout("conv4")?,
        c4: cout("conv6")?,
        head: cout("head")?,
    };
    let mut layers = Vec::new();
    for s in shape.layers() {
        let (dims, weight) = tensor(&format!("{}.w", s.name))?;
        if dims != s.weight_dims() {
            return Err(model_error(
                path,
                format!(
                    "layer {} has weight dims {dims:?}, expected {:?}",
                    s.name,
                    s.weight_dims()
                ),
            ));
        }
        let (_, bias) = tensor(&format!("{}.b", s.name))?;
        layers.push(LayerWeights { weight, bias });
    }
    let p = super::onnx::preprocessing_from_metadata(proto);
    let net = CenterNetWeights {
        shape,
        layers,
        preprocessing: roadtrack::detect::centernet::Preprocessing {
            input_scale: p.input_scale,
            mean: p.mean,
            std: p.std,
        },
    };
    net.validate().map_err(|e| model_error(path, e))?;
    Ok(net)
}

/// Weights from a file: the trainer's JSON, or a learned detector's ONNX when the name
/// ends in `.onnx`.
///
/// # Errors
/// As [`read_weights`] or [`CenterNetWeights::from_json`], the file named.
pub fn read_weights_any(path: &Path) -> Result<CenterNetWeights> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("onnx"))
    {
        return read_weights(path);
    }
    let text = std::fs::read_to_string(path).map_err(|e| roadtrack::Error::io(path, e))?;
    CenterNetWeights::from_json(&text).map_err(|e| roadtrack::Error::format(path, e.to_string()))
}

/// The box gain of the model `proto` (at `path`): its [`BOX_GAIN_KEY`] metadata as the
/// terms `[a_w, b_w, a_h, b_h]` per heat-map channel, all 0 (factors of 1) without the key.
///
/// # Errors
/// [`roadtrack::Error::Format`] naming the file when the value is not what
/// [`parse_box_gain`] reads.
pub(crate) fn box_gain_of(proto: &pb::ModelProto, path: &Path) -> Result<[[f64; 4]; CLASSES]> {
    let Some(text) = super::onnx::metadata(proto, BOX_GAIN_KEY) else {
        return Ok([[0.0; 4]; CLASSES]);
    };
    parse_box_gain(text).map_err(|e| {
        super::onnx::model_error(path, format!("metadata `{BOX_GAIN_KEY}` = `{text}`: {e}"))
    })
}

/// The largest `|a|` or `|b|` a box gain may have: at the reference size a factor between
/// `e^-0.5` and `e^0.5` (0.61–1.65).
// Choice: a box off by more than that is not a calibration of the network but another
// network; the bound also catches factors given where their logarithms belong (1.1 for
// 0.095).
pub const BOX_GAIN_MAX_TERM: f64 = 0.5;

/// `a_w,b_w,a_h,b_h,…` (four terms per heat-map channel, [`box_factor`]) → the terms.
///
/// # Errors
/// As [`box_gain_terms`], and a message naming an item that is not a number.
pub fn parse_box_gain(text: &str) -> std::result::Result<[[f64; 4]; CLASSES], String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .map_err(|_| format!("`{}` is not a number within ±{BOX_GAIN_MAX_TERM}", t.trim()))
        })
        .collect::<std::result::Result<_, _>>()?;
    box_gain_terms(&v)
}

/// `4 × CLASSES` numbers, four per heat-map channel ([`box_factor`]) → the terms.
///
/// # Errors
/// A message when one is not finite and within ±[`BOX_GAIN_MAX_TERM`], or there are not
/// `4 × CLASSES` of them.
pub fn box_gain_terms(v: &[f64]) -> std::result::Result<[[f64; 4]; CLASSES], String> {
    if let Some(x) = v
        .iter()
        .find(|x| !(x.is_finite() && x.abs() <= BOX_GAIN_MAX_TERM))
    {
        return Err(format!("`{x}` is not a number within ±{BOX_GAIN_MAX_TERM}"));
    }
    if v.len() != 4 * CLASSES {
        return Err(format!(
            "expected {} numbers (a_w, b_w, a_h, b_h for each of {}), got {}",
            4 * CLASSES,
            CLASS_NAMES.join(", "),
            v.len()
        ));
    }
    Ok(std::array::from_fn(|k| {
        std::array::from_fn(|j| v[4 * k + j])
    }))
}

/// Copies the learned detector at `input` to `output` (atomically) with `gain` as its
/// [`BOX_GAIN_KEY`] metadata, replacing any it had; the network is untouched.
///
/// # Errors
/// `input` is not a learned detector ([`is_centernet_file`]) or unreadable; a term is not
/// finite and within ±[`BOX_GAIN_MAX_TERM`]; `output` cannot be written.
pub fn write_box_gain(input: &Path, output: &Path, gain: &[[f64; 4]; CLASSES]) -> Result<()> {
    box_gain_terms(gain.as_flattened())
        .map_err(|e| roadtrack::Error::Invalid(format!("box gain {gain:?}: {e}")))?;
    // `{}` of an f64 is the shortest text that parses back to the same value.
    let value = gain
        .iter()
        .flatten()
        .map(|g| format!("{g}"))
        .collect::<Vec<_>>()
        .join(",");
    let (mut proto, _) = super::onnx::read_image_model(input)?;
    if super::onnx::metadata(&proto, "roadtrack.kind") != Some(KIND) {
        return Err(super::onnx::model_error(
            input,
            "not a roadtrack learned detector (no `roadtrack.kind = centernet` metadata)",
        ));
    }
    proto.metadata_props.retain(|e| e.key != BOX_GAIN_KEY);
    proto.metadata_props.push(pb::StringStringEntryProto {
        key: BOX_GAIN_KEY.into(),
        value,
    });
    roadtrack::io::atomic::write_bytes_atomic(output, &proto.encode_to_vec())
}

/// Writes `net` as ONNX to `path` (atomically).
///
/// # Errors
/// Weights that do not match the shape; the file cannot be written.
pub fn write_onnx(path: &Path, net: &CenterNetWeights) -> Result<()> {
    roadtrack::io::atomic::write_bytes_atomic(path, &onnx_bytes(net)?)
}
