//! End to end over the tiny fixed-output detectors of scripts/make_tiny_detectors.py: each
//! layout decodes to the same boxes in image px after the letterbox undo.

use super::*;
use image::Rgb;
use roadtrack::detect::Detector;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// A 128×64 frame (letterboxed into 64×64: scale ½, 16 rows of padding above): grey with
/// a red block where box a/c lands (image x 48..80, y 24..40).
fn frame() -> Frame {
    let mut image = RgbImage::from_pixel(128, 64, Rgb([10, 20, 30]));
    for y in 24..40 {
        for x in 48..80 {
            image.put_pixel(x, y, Rgb([200, 0, 0]));
        }
    }
    Frame {
        index: 3,
        time_s: 0.3,
        image,
    }
}

type Expected = (ObjectClass, [f64; 4], f64);

/// The boxes the fixtures give at the default settings (see the script's table):
/// a (person 0.9), c (car 0.7), f (bus 0.6, clipped); b lost to NMS, d below the
/// threshold, e (dog) dropped.
fn expected_default() -> Vec<Expected> {
    vec![
        (ObjectClass::Pedestrian, [48.0, 24.0, 32.0, 16.0], 0.9),
        (ObjectClass::Car, [48.0, 24.0, 32.0, 16.0], 0.7),
        (ObjectClass::Bus, [104.0, 48.0, 24.0, 16.0], 0.6),
    ]
}

fn check(found: &FrameDetections, expected: &[Expected]) {
    let got: Vec<(ObjectClass, [f64; 4], f64)> = found
        .detections
        .iter()
        .map(|d| {
            let b = d.bbox().expect("box");
            (
                d.class.clone().expect("class"),
                [b.left, b.top, b.width, b.height],
                d.score.expect("score"),
            )
        })
        .collect();
    assert_eq!(got.len(), expected.len(), "{got:?}");
    for (g, e) in got.iter().zip(expected) {
        assert_eq!(g.0, e.0, "{got:?}");
        for k in 0..4 {
            assert!((g.1[k] - e.1[k]).abs() < 1e-3, "{got:?} vs {expected:?}");
        }
        assert!((g.2 - e.2).abs() < 1e-5, "{got:?}");
    }
}

#[test]
fn every_layout_decodes_to_the_same_boxes_in_image_pixels() -> Result<()> {
    for (file, layout) in [
        ("tiny_yolo.onnx", Layout::Yolo),
        ("tiny_yolo_t.onnx", Layout::YoloT),
        ("tiny_yolox.onnx", Layout::Yolox),
        ("tiny_detr.onnx", Layout::Detr),
    ] {
        // Auto finds the layout, and naming it gives the same.
        for asked in [Layout::Auto, layout] {
            let config = OnnxDetectorConfig {
                layout: asked,
                ..Default::default()
            };
            let mut det = OnnxDetector::load(&fixture(file), &config)?;
            assert_eq!(det.layout(), layout, "{file}");
            assert_eq!(det.input_size(), (64, 64));
            let found = det.detect(&frame())?;
            check(&found, &expected_default());
            let first = &found.detections[0];
            assert_eq!((first.frame, first.id), (3, 1));
            assert_eq!(first.pos_px, roadtrack::geometry::Point::new(64.0, 32.0));
            assert_eq!(first.colour_rgb, Some([200.0, 0.0, 0.0]), "{file}");
            assert_eq!(found.detections[2].id, 3);
        }
    }
    Ok(())
}

#[test]
fn thresholds_and_other_classes_change_what_is_kept() -> Result<()> {
    let config = OnnxDetectorConfig {
        min_score: 0.15,
        iou_threshold: 0.95,
        keep_other_classes: true,
        ..Default::default()
    };
    let mut det = OnnxDetector::load(&fixture("tiny_yolo.onnx"), &config)?;
    let mut expected = vec![
        (
            ObjectClass::Other("dog".into()),
            [92.0, 40.0, 16.0, 16.0],
            0.95,
        ),
        (ObjectClass::Pedestrian, [48.0, 24.0, 32.0, 16.0], 0.9),
        // b survives NMS at IoU 0.95.
        (ObjectClass::Pedestrian, [50.0, 24.0, 32.0, 16.0], 0.8),
        (ObjectClass::Car, [48.0, 24.0, 32.0, 16.0], 0.7),
        (ObjectClass::Bus, [104.0, 48.0, 24.0, 16.0], 0.6),
        (ObjectClass::Truck, [12.0, 0.0, 16.0, 16.0], 0.2),
    ];
    check(&det.detect(&frame())?, &expected);
    // An explicit class map keeps only its indices, under its names.
    let config = OnnxDetectorConfig {
        classes: Some("0=pedestrian,16=car".into()),
        ..Default::default()
    };
    let mut det = OnnxDetector::load(&fixture("tiny_yolo.onnx"), &config)?;
    expected = vec![
        (ObjectClass::Car, [92.0, 40.0, 16.0, 16.0], 0.95),
        (ObjectClass::Pedestrian, [48.0, 24.0, 32.0, 16.0], 0.9),
    ];
    check(&det.detect(&frame())?, &expected);
    // YOLOX's objectness multiplies: box g (0.1 × 1.0) comes in at 0.05.
    let config = OnnxDetectorConfig {
        min_score: 0.05,
        ..Default::default()
    };
    let mut det = OnnxDetector::load(&fixture("tiny_yolox.onnx"), &config)?;
    let found = det.detect(&frame())?;
    let g = found
        .detections
        .iter()
        .find(|d| d.score.is_some_and(|s| (s - 0.1).abs() < 1e-6))
        .expect("box g");
    assert_eq!(g.pos_px, roadtrack::geometry::Point::new(40.0, 48.0));
    Ok(())
}

#[test]
fn letterbox_pads_with_grey_and_scales_the_frame() {
    let config = OnnxDetectorConfig::default();
    let (input, placement) = letterbox(&frame().image, (64, 64), &config);
    assert_eq!(placement.offset, (0.0, 16.0));
    let plane = 64 * 64;
    let at = |c: usize, x: usize, y: usize| input[c * plane + y * 64 + x];
    // Padding rows above and below: 114 / 255.
    assert!((at(0, 5, 2) - 114.0 / 255.0).abs() < 1e-6);
    assert!((at(2, 60, 63) - 114.0 / 255.0).abs() < 1e-6);
    // The red block (image 48..80 × 24..40) at input 24..40 × 28..36.
    assert!((at(0, 30, 30) - 200.0 / 255.0).abs() < 1e-6);
    assert!(at(1, 30, 30).abs() < 1e-6);
    // Background (10, 20, 30).
    assert!((at(2, 5, 20) - 30.0 / 255.0).abs() < 1e-6);
    // BGR swaps the planes; input_scale 1 gives 0..255.
    let bgr = OnnxDetectorConfig {
        channels: Channels::Bgr,
        preprocessing: Preprocessing {
            input_scale: 1.0,
            ..Default::default()
        },
        resize: Resize::LetterboxTopLeft,
        ..Default::default()
    };
    let (input, placement) = letterbox(&frame().image, (64, 64), &bgr);
    assert_eq!(placement.offset, (0.0, 0.0));
    assert_eq!(input[2 * plane + 15 * 64 + 30], 200.0);
    assert_eq!(input[20 * 64 + 5], 30.0);
    assert_eq!(input[40 * 64 + 5], 114.0);
}

#[test]
fn non_detectors_and_unknown_layouts_are_errors_naming_the_file() {
    for (file, needle) in [
        ("tiny_classifier.onnx", "[1, 2]"),
        ("tiny_unknown.onnx", "[1, 2, 3, 4]"),
    ] {
        let err = OnnxDetector::load(&fixture(file), &OnnxDetectorConfig::default())
            .expect_err(file)
            .to_string();
        assert!(
            err.contains(file) && err.contains(needle) && err.contains("not a detector"),
            "{err}"
        );
    }
    let err = OnnxDetector::load(
        &fixture("tiny_yolo.onnx"),
        &OnnxDetectorConfig {
            layout: Layout::Detr,
            ..Default::default()
        },
    )
    .expect_err("not detr")
    .to_string();
    assert!(
        err.contains("tiny_yolo.onnx") && err.contains("[1, 6, 84]"),
        "{err}"
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let text = dir.path().join("model.onnx");
    std::fs::write(&text, "no model here\n").expect("write");
    let err = OnnxDetector::load(&text, &OnnxDetectorConfig::default()).expect_err("text");
    assert!(err.to_string().contains("model.onnx"), "{err}");
    let bad = OnnxDetectorConfig {
        iou_threshold: 1.5,
        ..Default::default()
    };
    let err = OnnxDetector::load(&fixture("tiny_yolo.onnx"), &bad).expect_err("iou");
    assert!(err.to_string().contains("iou_threshold"), "{err}");
}
