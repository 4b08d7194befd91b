//! `--detector onnx` on the command line, with the tiny fixed-output detectors of
//! scripts/make_tiny_detectors.py (crates/roadtrack-cnn/tests/fixtures/).

mod common;
use common::{bin, fixture, stderr};
use std::path::{Path, PathBuf};

fn model(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../roadtrack-cnn/tests/fixtures")
        .join(name)
}

#[cfg(feature = "cnn")]
#[test]
fn detect_with_an_onnx_detector_writes_its_boxes_in_image_pixels() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("d.csv");
    let o = bin()
        .arg("detect")
        .arg(fixture("tiny_sequence"))
        .args(["--detector", "onnx", "--model"])
        .arg(model("tiny_yolo_t.onnx"))
        .arg("-o")
        .arg(&out)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", stderr(&o));
    let dets = roadtrack::io::detections::read_detections(&out).expect("read output");
    // 96×72 frames letterboxed into 64×64: scale 2/3, 8 rows of padding above. Per frame:
    // person 0.9 and car 0.7 on the same box, bus 0.6 clipped at the right edge.
    assert_eq!(dets.len(), 30, "3 boxes × 10 frames");
    for d in dets.iter().filter(|d| d.frame == 4) {
        let b = d.bbox().expect("box");
        let class = d.class.as_ref().expect("class").name().to_owned();
        let want = match class.as_str() {
            "pedestrian" | "car" => [36.0, 30.0, 24.0, 12.0],
            "bus" => [78.0, 48.0, 18.0, 12.0],
            other => panic!("class {other}"),
        };
        let got = [b.left, b.top, b.width, b.height];
        assert!(
            got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-3),
            "{class}: {got:?}"
        );
        assert!(d.colour_rgb.is_some() && d.score.is_some());
    }
    // --classes and --min-score reach the detector.
    let o = bin()
        .arg("detect")
        .arg(fixture("tiny_sequence"))
        .args(["--detector", "onnx", "--detector-model"])
        .arg(model("tiny_yolo.onnx"))
        .args([
            "--classes",
            "16=dog",
            "--min-score",
            "0.5",
            "--end",
            "2",
            "-o",
        ])
        .arg(&out)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", stderr(&o));
    let dets = roadtrack::io::detections::read_detections(&out).expect("read output");
    assert_eq!(dets.len(), 2);
    assert!(
        dets.iter()
            .all(|d| d.class.as_ref().is_some_and(|c| c.name() == "dog"))
    );
}

#[cfg(feature = "cnn")]
#[test]
fn a_classifier_or_unknown_layout_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (file, shape) in [
        ("tiny_classifier.onnx", "[1, 2]"),
        ("tiny_unknown.onnx", "[1, 2, 3, 4]"),
    ] {
        let o = bin()
            .arg("detect")
            .arg(fixture("tiny_sequence"))
            .args(["--detector", "onnx", "--model"])
            .arg(model(file))
            .arg("-o")
            .arg(dir.path().join("d.csv"))
            .output()
            .expect("run");
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(file) && err.contains(shape), "{err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(!dir.path().join("d.csv").exists());
}

#[cfg(feature = "cnn")]
#[test]
fn track_takes_the_onnx_detector_through_model() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("t.txt");
    let o = bin()
        .arg("track")
        .arg(fixture("tiny_sequence"))
        .args(["--method", "relaxation", "--detector", "onnx", "--model"])
        .arg(model("tiny_detr.onnx"))
        .args(["--confirm-hits", "1", "-o"])
        .arg(&out)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).expect("tracks");
    assert!(text.lines().count() >= 10, "{text}");
}

#[test]
fn onnx_flags_are_usage_errors_elsewhere_and_the_model_is_required() {
    let seq = fixture("tiny_sequence");
    for args in [
        vec!["--detector", "background", "--min-score", "0.5"],
        vec!["--layout", "yolo"],
        vec!["--detector", "onnx"],
        vec!["--detector", "onnx", "--min-score", "2"],
    ] {
        let o = bin()
            .arg("detect")
            .arg(&seq)
            .args(&args)
            .args(["-o", "-"])
            .output()
            .expect("run");
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    }
    let o = bin()
        .arg("detect")
        .arg(&seq)
        .args(["--detector", "onnx", "--min-area", "5", "--model"])
        .arg(model("tiny_yolo.onnx"))
        .args(["-o", "-"])
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--min-area"), "{}", stderr(&o));
}

#[cfg(not(feature = "cnn"))]
#[test]
fn without_the_cnn_feature_the_onnx_detector_is_a_clear_error() {
    let o = bin()
        .arg("detect")
        .arg(fixture("tiny_sequence"))
        .args(["--detector", "onnx", "--model"])
        .arg(model("tiny_yolo.onnx"))
        .args(["-o", "-"])
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("`cnn` feature"), "{}", stderr(&o));
}
