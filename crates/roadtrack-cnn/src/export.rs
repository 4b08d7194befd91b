//! Writing a trained [`TinyCnn`] as an ONNX file, so the tracker loads it through the same
//! tract loader as any user model ([`super::OnnxClassifier`]).
//!
//! The graph is `Conv → Relu → MaxPool → Conv → Relu → MaxPool → GlobalAveragePool →
//! Flatten → Gemm → Softmax` (opset 13), input `input` of shape `N×3×H×W`, output
//! `probabilities` `N×2` (class 1 = target). The preprocessing, the target class, the
//! output kind and the window scale go into the model's metadata (`roadtrack.*` keys),
//! which the loader takes as defaults.

use std::path::Path;

use prost::Message as _;
use tract_onnx::pb;

use super::net::TinyCnn;
use super::onnx::float_tensor;
use super::window::Preprocessing;
use roadtrack::error::Result;

/// An ONNX attribute holding a list of integers (also used by `centernet`).
pub(crate) fn ints(name: &str, v: &[i64]) -> pb::AttributeProto {
    pb::AttributeProto {
        name: name.into(),
        r#type: pb::attribute_proto::AttributeType::Ints as i32,
        ints: v.to_vec(),
        ..Default::default()
    }
}

fn int(name: &str, v: i64) -> pb::AttributeProto {
    pb::AttributeProto {
        name: name.into(),
        r#type: pb::attribute_proto::AttributeType::Int as i32,
        i: v,
        ..Default::default()
    }
}

/// An ONNX node with one output, named after it (also used by `centernet`).
pub(crate) fn node(
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

/// A float tensor's value info: `dims` fixed where `Some`, symbolic otherwise, named in turn
/// from `params` ("N" once they run out).
pub(crate) fn value_info(name: &str, dims: &[Option<i64>], params: &[&str]) -> pb::ValueInfoProto {
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

/// The ONNX model of `net` with `prep` and `window_scale` recorded in its metadata.
pub fn onnx_model(
    net: &TinyCnn,
    prep: &Preprocessing,
    window_scale: Option<f64>,
) -> pb::ModelProto {
    let s = net.shape;
    let v = net.views();
    let (c1, c2) = (s.c1, s.c2);
    let initializer = vec![
        float_tensor("conv1.w", &[c1, 3, 3, 3], v.conv1_w),
        float_tensor("conv1.b", &[c1], v.conv1_b),
        float_tensor("conv2.w", &[c2, c1, 3, 3], v.conv2_w),
        float_tensor("conv2.b", &[c2], v.conv2_b),
        float_tensor("fc.w", &[2, c2], v.fc_w),
        float_tensor("fc.b", &[2], v.fc_b),
    ];
    let pool = || vec![ints("kernel_shape", &[2, 2]), ints("strides", &[2, 2])];
    let nodes = vec![
        node(
            "Conv",
            &["input", "conv1.w", "conv1.b"],
            "c1",
            vec![ints("kernel_shape", &[3, 3])],
        ),
        node("Relu", &["c1"], "r1", vec![]),
        node("MaxPool", &["r1"], "p1", pool()),
        node(
            "Conv",
            &["p1", "conv2.w", "conv2.b"],
            "c2",
            vec![ints("kernel_shape", &[3, 3])],
        ),
        node("Relu", &["c2"], "r2", vec![]),
        node("MaxPool", &["r2"], "p2", pool()),
        node("GlobalAveragePool", &["p2"], "gap", vec![]),
        node("Flatten", &["gap"], "flat", vec![int("axis", 1)]),
        node(
            "Gemm",
            &["flat", "fc.w", "fc.b"],
            "logits",
            vec![int("transB", 1)],
        ),
        node(
            "Softmax",
            &["logits"],
            "probabilities",
            vec![int("axis", 1)],
        ),
    ];
    let triple = |t: [f32; 3]| format!("{},{},{}", t[0], t[1], t[2]);
    let mut meta = vec![
        ("roadtrack.target_class", "1".to_string()),
        ("roadtrack.output", "probabilities".to_string()),
        ("roadtrack.input_scale", prep.input_scale.to_string()),
        ("roadtrack.mean", triple(prep.mean)),
        ("roadtrack.std", triple(prep.std)),
    ];
    if let Some(ws) = window_scale {
        meta.push(("roadtrack.window_scale", format!("{ws}")));
    }
    opset13_model(
        "roadtrack train",
        pb::GraphProto {
            node: nodes,
            name: "roadtrack_tiny_cnn".into(),
            initializer,
            input: vec![value_info(
                "input",
                &[None, Some(3), Some(s.height as i64), Some(s.width as i64)],
                &[],
            )],
            output: vec![value_info("probabilities", &[None, Some(2)], &[])],
            ..Default::default()
        },
        meta,
    )
}

/// An opset-13 ONNX model (IR 8) of `graph` with `meta` as its metadata (the `roadtrack.*`
/// keys the loaders read), produced by `producer` of this version.
pub(crate) fn opset13_model(
    producer: &str,
    graph: pb::GraphProto,
    meta: Vec<(&str, String)>,
) -> pb::ModelProto {
    pb::ModelProto {
        ir_version: 8,
        opset_import: vec![pb::OperatorSetIdProto {
            domain: String::new(),
            version: 13,
        }],
        producer_name: producer.into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        graph: Some(graph),
        metadata_props: meta
            .into_iter()
            .map(|(k, v)| pb::StringStringEntryProto {
                key: k.into(),
                value: v,
            })
            .collect(),
        ..Default::default()
    }
}

/// Writes `net` as ONNX to `path` (atomically).
pub fn write_onnx(
    path: &Path,
    net: &TinyCnn,
    prep: &Preprocessing,
    window_scale: Option<f64>,
) -> Result<()> {
    let bytes = onnx_model(net, prep, window_scale).encode_to_vec();
    roadtrack::io::atomic::write_bytes_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::onnx::{CnnConfig, OnnxClassifier};
    use crate::train::{TrainConfig, synthetic_patches, train, training_preprocessing};

    #[test]
    fn trained_network_round_trips_through_onnx_and_tract() -> Result<()> {
        let cfg = TrainConfig {
            epochs: 2,
            batch_size: 8,
            learning_rate: 1e-2,
            input_height: 20,
            input_width: 14,
            conv1_channels: 4,
            conv2_channels: 6,
            ..TrainConfig::default()
        };
        let data = synthetic_patches(16, 20, 14, 9);
        let (net, _) = train(&data, &cfg, &mut |_| {})?;
        let dir = tempfile::tempdir().map_err(|e| roadtrack::Error::io("tempdir", e))?;
        let path = dir.path().join("trained.onnx");
        write_onnx(&path, &net, &training_preprocessing(), Some(2.5))?;
        let loaded = OnnxClassifier::load(&path, &CnnConfig::default())?;
        assert_eq!(loaded.input_size(), (20, 14));
        assert_eq!(*loaded.preprocessing(), training_preprocessing());
        assert_eq!(loaded.window_size_px(), (35.0, 50.0));
        for i in 0..data.len() {
            let x = data.patch(i);
            let tract = loaded.raw_outputs(x)?;
            let mut cache = crate::net::Cache::default();
            net.forward(x, &mut cache);
            for (k, (t, m)) in tract.iter().zip(cache.probs).enumerate() {
                assert!(
                    (t - m).abs() < 1e-5,
                    "patch {i} class {k}: tract {t} vs in-memory {m}"
                );
            }
        }
        Ok(())
    }
}
