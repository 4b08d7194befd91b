//! The learned detector's network in roadtrack's kernels against tract: the same outputs
//! on random and parity-width networks and on the shipped model, the input read from the
//! image, the instruction sets, and which graphs fall back to tract.

use super::tests::{held_out_aerial_frame, parity_weights, shipped};
use super::*;
use image::RgbImage;
use roadtrack::error::Error;
use std::path::PathBuf;

/// The detector of the model at `path` run natively and the same run by tract; asserts
/// that the first is native and the second not.
fn native_and_tract(
    path: &Path,
    config: &CenterNetConfig,
) -> Result<(CenterNetDetector, CenterNetDetector)> {
    let native = CenterNetDetector::load(path, config)?;
    assert!(native.is_native());
    let tract = CenterNetDetector::load(path, config)?.whole_in_tract();
    assert!(!tract.is_native());
    Ok((native, tract))
}

/// A default-shape network with reproducible random weights, written as ONNX into `dir`.
fn random_default_net(dir: &Path) -> Result<PathBuf> {
    let path = dir.join("random.onnx");
    write_onnx(&path, &random_default_weights())?;
    Ok(path)
}

/// A default-shape network with reproducible random weights.
fn random_default_weights() -> CenterNetWeights {
    let shape = CenterNetShape::default();
    let layers = shape
        .layers()
        .iter()
        .enumerate()
        .map(|(i, s)| {
            // Scaled so the activations neither vanish nor blow up through ten layers.
            let fan_in = (s.cin * s.k * s.k) as f32;
            let scale = 2.0 * (3.0 / fan_in).sqrt();
            LayerWeights {
                weight: native::tests::values(s.weight_len(), 100 + i as u64)
                    .iter()
                    .map(|v| v * scale)
                    .collect(),
                bias: native::tests::values(s.cout, 200 + i as u64),
            }
        })
        .collect();
    CenterNetWeights {
        shape,
        layers,
        preprocessing: roadtrack::detect::centernet::Preprocessing {
            input_scale: 1.0 / 255.0,
            mean: [0.5; 3],
            std: [0.25; 3],
        },
    }
}

/// The AVX2 and AVX-512 kernels sum the same products in the same order with fused
/// multiply-adds, so their outputs are the same bits; the portable loop (separate multiply
/// and add) agrees within rounding. Where the CPU lacks an instruction set, its kernels
/// fall back and the comparison holds trivially.
#[test]
fn the_native_network_gives_the_same_bits_with_avx2_and_avx512() {
    use native::{Isa, NativeNet};
    let net = NativeNet::new(&random_default_weights()).expect("default shape");
    let (h, w) = (96, 208);
    let input = native::tests::values(3 * h * w, 21);
    let portable = net.run(&input, h, w, Isa::Portable);
    let avx2 = net.run(&input, h, w, Isa::Avx2);
    let avx512 = net.run(&input, h, w, Isa::Avx512);
    assert!(
        avx2.0 == avx512.0 && avx2.1 == avx512.1,
        "AVX2 and AVX-512 differ"
    );
    assert_same_outputs(&portable, &avx512, "portable vs vector kernels", 0.01);
}

#[test]
fn the_native_network_gives_what_tract_gives() -> Result<()> {
    let dir = tempfile::tempdir().map_err(|e| Error::io("tempdir", e))?;
    let path = random_default_net(dir.path())?;
    let (native, whole) = native_and_tract(&path, &CenterNetConfig::default())?;
    for (h, w) in [(16, 16), (48, 80), (96, 64)] {
        let input = native::tests::values(3 * h * w, (h * w) as u64);
        let a = native.forward(input.clone(), h, w)?;
        let b = whole.forward(input, h, w)?;
        assert_same_outputs(&a, &b, &format!("{h} x {w}"), 0.1);
    }
    Ok(())
}

/// The native path reads its input straight from the image, mirrored per view; tract's
/// path builds the planar input and its mirrored copies. On a frame whose sides are not
/// multiples of 16 (padding on the right and bottom, moved by the mirrors), with both
/// flips, the heat and box maps agree.
#[test]
fn the_native_input_from_the_image_is_the_planar_input() -> Result<()> {
    let dir = tempfile::tempdir().map_err(|e| Error::io("tempdir", e))?;
    let path = random_default_net(dir.path())?;
    let config = CenterNetConfig {
        flip: true,
        flip_vertical: true,
        ..CenterNetConfig::default()
    };
    let (native, tract) = native_and_tract(&path, &config)?;
    let values = native::tests::values(3 * 53 * 37, 9);
    let image = RgbImage::from_fn(53, 37, |x, y| {
        let i = 3 * (y * 53 + x) as usize;
        image::Rgb(std::array::from_fn(|k| {
            ((values[i + k] + 0.5) * 255.0) as u8
        }))
    });
    let (a, b) = (native.heat_maps(&image)?, tract.heat_maps(&image)?);
    assert_eq!((a.rows, a.cols), (b.rows, b.cols));
    assert_same_outputs(
        &(a.heat, a.boxes),
        &(b.heat, b.boxes),
        "53 x 37, flipped both ways",
        0.01,
    );
    Ok(())
}

#[test]
fn the_shipped_model_finds_the_same_boxes_native_or_in_tract() -> Result<()> {
    let image = held_out_aerial_frame()?;
    let native = CenterNetDetector::load(&shipped(), &CenterNetConfig::default())?;
    assert!(native.is_native());
    let whole = CenterNetDetector::load(&shipped(), &CenterNetConfig::default())?.whole_in_tract();
    let a = native.detect_boxes(&image)?;
    let b = whole.detect_boxes(&image)?;
    assert!(a.len() > 5, "{} boxes", a.len());
    assert_eq!(a.len(), b.len());
    for ((ba, ca, sa), (bb, cb, sb)) in a.iter().zip(&b) {
        assert_eq!(ca, cb);
        assert!((sa - sb).abs() < 1e-4, "score {sa} vs {sb}");
        for (p, q) in [
            (ba.left, bb.left),
            (ba.top, bb.top),
            (ba.width, bb.width),
            (ba.height, bb.height),
        ] {
            assert!((p - q).abs() < 1e-2, "{ba:?} vs {bb:?}");
        }
    }
    Ok(())
}

/// `a` and `b` (heat map, box map) equal within 1e-4, and `b`'s box map not trivially
/// small (some value above `min_spread`).
fn assert_same_outputs(
    a: &(Vec<f32>, Vec<f32>),
    b: &(Vec<f32>, Vec<f32>),
    what: &str,
    min_spread: f32,
) {
    let spread = b.1.iter().fold(0f32, |m, v| m.max(v.abs()));
    assert!(
        spread > min_spread,
        "{what}: trivially small outputs ({spread})"
    );
    for (name, x, y) in [("heatmap", &a.0, &b.0), ("boxes", &a.1, &b.1)] {
        assert_eq!(x.len(), y.len());
        for (i, (p, q)) in x.iter().zip(y).enumerate() {
            assert!((p - q).abs() < 1e-4, "{what} {name}[{i}]: {p} vs {q}");
        }
    }
}

/// Widths that are not multiples of 8 (4, 6, 8, 8, 8): the native kernels' portable path
/// for those layers, the vector one for the others.
#[test]
fn a_network_of_other_widths_runs_natively_as_tract_runs_it() -> Result<()> {
    let dir = tempfile::tempdir().map_err(|e| Error::io("tempdir", e))?;
    let path = dir.path().join("parity.onnx");
    write_onnx(&path, &parity_weights()?)?;
    let (native, tract) = native_and_tract(&path, &CenterNetConfig::default())?;
    let (h, w) = (64, 208);
    let input = native::tests::values(3 * h * w, 5);
    let a = native.forward(input.clone(), h, w)?;
    let b = tract.forward(input, h, w)?;
    assert_same_outputs(&a, &b, "parity widths", 0.01);
    Ok(())
}

/// A graph that is not node for node the one roadtrack writes (here one `Identity` more)
/// runs in tract, as written.
#[test]
fn a_graph_edited_by_hand_runs_in_tract() -> Result<()> {
    let dir = tempfile::tempdir().map_err(|e| Error::io("tempdir", e))?;
    let net = parity_weights()?;
    let mut proto = onnx_model(&net)?;
    let graph = proto.graph.as_mut().expect("graph");
    let last = graph
        .node
        .iter_mut()
        .find(|n| n.output == ["boxes"])
        .expect("boxes node");
    last.output = vec!["boxes_raw".into()];
    last.name = "boxes_raw".into();
    graph.node.push(crate::export::node(
        "Identity",
        &["boxes_raw"],
        "boxes",
        vec![],
    ));
    let edited = dir.path().join("edited.onnx");
    let bytes = prost::Message::encode_to_vec(&proto);
    std::fs::write(&edited, bytes).map_err(|e| Error::io(&edited, e))?;
    let det = CenterNetDetector::load(&edited, &CenterNetConfig::default())?;
    assert!(!det.is_native());
    let ours = dir.path().join("ours.onnx");
    write_onnx(&ours, &net)?;
    let native = CenterNetDetector::load(&ours, &CenterNetConfig::default())?;
    let input = native::tests::values(3 * 32 * 48, 6);
    let a = det.forward(input.clone(), 32, 48)?;
    let b = native.forward(input, 32, 48)?;
    assert_same_outputs(&a, &b, "edited graph", 0.01);
    Ok(())
}
