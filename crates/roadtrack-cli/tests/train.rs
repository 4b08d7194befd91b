//! End-to-end tests of `roadtrack train`: the real binary, patch folders and a tiny
//! MOTChallenge sequence; the written model is loaded back through the tracker's loader.
#![cfg(feature = "cnn")]

mod common;
use common::{bin, stderr};

use std::path::Path;

use roadtrack::geometry::{BBox, Point};
use roadtrack::io::mot::{MotGtRow, write_gt};
use roadtrack::io::seqinfo::SeqInfo;
use roadtrack_cnn::{CnnConfig, OnnxClassifier};

/// A bright upright bar on noise (positive) or noise only (negative), 24×12 px.
fn patch(positive: bool, k: u32) -> image::RgbImage {
    image::RgbImage::from_fn(12, 24, |x, y| {
        let n = ((x * 31 + y * 17 + k * 13) % 60) as u8 + 40;
        if positive && (4..8).contains(&x) && (3..21).contains(&y) {
            image::Rgb([230, 210, 190])
        } else {
            image::Rgb([n, n / 2 + 30, n])
        }
    })
}

#[test]
fn train_from_patch_folders_writes_a_loadable_accurate_model() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (pos, neg) = (dir.path().join("pos"), dir.path().join("neg"));
    std::fs::create_dir_all(&pos).expect("mkdir");
    std::fs::create_dir_all(&neg).expect("mkdir");
    for k in 0..30 {
        patch(true, k)
            .save(pos.join(format!("p{k}.png")))
            .expect("png");
        patch(false, k)
            .save(neg.join(format!("n{k}.png")))
            .expect("png");
    }
    let model = dir.path().join("person.onnx");
    let report = dir.path().join("report.json");
    let run = |out: &Path| {
        bin()
            .arg("train")
            .arg("--positives")
            .arg(&pos)
            .arg("--negatives")
            .arg(&neg)
            .args([
                "--epochs",
                "6",
                "--batch-size",
                "8",
                "--learning-rate",
                "0.01",
            ])
            .args(["--input-size", "24x12", "--seed", "3", "-o"])
            .arg(out)
            .arg("--report")
            .arg(&report)
            .output()
            .expect("run")
    };
    let o = run(&model);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("test accuracy"), "{}", stderr(&o));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
    assert_eq!(r["n_test"], 12);
    assert!(r["test_accuracy"].as_f64().expect("acc") >= 0.9, "{r}");
    assert_eq!(r["epochs"].as_array().expect("epochs").len(), 6);

    // Deterministic for a seed: byte-identical model.
    let again = dir.path().join("again.onnx");
    assert!(run(&again).status.success());
    assert_eq!(
        std::fs::read(&model).expect("read"),
        std::fs::read(&again).expect("read")
    );

    // The tracker's loader takes it and scores a positive above a negative.
    let clf = OnnxClassifier::load(&model, &CnnConfig::default()).expect("load");
    assert_eq!(clf.input_size(), (24, 12));
    let mut out = [0.0; 2];
    let c = Point::new(6.0, 12.0);
    clf.score_windows(&patch(true, 99), &[c], &mut out[..1])
        .expect("score");
    clf.score_windows(&patch(false, 99), &[c], &mut out[1..])
        .expect("score");
    assert!(out[0] > 0.5 && out[1] < 0.5, "{out:?}");
}

#[test]
fn train_from_a_sequence_uses_ground_truth_boxes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("SEQ-01");
    std::fs::create_dir_all(seq.join("img1")).expect("mkdir");
    std::fs::create_dir_all(seq.join("gt")).expect("mkdir");
    let (w, h) = (160u32, 120u32);
    let mut rows = Vec::new();
    for f in 1..=6u32 {
        let mut img = image::RgbImage::from_fn(w, h, |x, y| {
            let n = ((x * 7 + y * 13 + f * 5) % 50) as u8 + 60;
            image::Rgb([n, n, n / 2 + 40])
        });
        for k in 0..3u32 {
            let bx = BBox::new(
                f64::from(10 + k * 50 + f * 2),
                f64::from(20 + k * 10),
                12.0,
                30.0,
            );
            for y in bx.top as u32..(bx.top + bx.height) as u32 {
                for x in bx.left as u32..(bx.left + bx.width) as u32 {
                    img.put_pixel(x, y, image::Rgb([220, 60, 60]));
                }
            }
            rows.push(MotGtRow {
                frame: f,
                id: u64::from(k + 1),
                bbox: bx,
                consider: true,
                class: 1,
                visibility: 1.0,
            });
        }
        img.save(seq.join("img1").join(format!("{f:06}.png")))
            .expect("png");
    }
    write_gt(&seq.join("gt").join("gt.txt"), &rows).expect("gt");
    SeqInfo {
        name: "SEQ-01".into(),
        im_dir: "img1".into(),
        frame_rate: 10.0,
        seq_length: 6,
        im_width: w,
        im_height: h,
        im_ext: ".png".into(),
    }
    .write(&seq.join("seqinfo.ini"))
    .expect("seqinfo");
    let model = dir.path().join("m.onnx");
    let o = bin()
        .arg("train")
        .arg("--sequence")
        .arg(&seq)
        .args([
            "--epochs",
            "4",
            "--batch-size",
            "8",
            "--learning-rate",
            "0.01",
        ])
        .args(["--input-size", "20x10", "-o"])
        .arg(&model)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("54 patches (18 positive, 36 negative)"),
        "{err}"
    );
    let clf = OnnxClassifier::load(&model, &CnnConfig::default()).expect("load");
    // The window scale is the positives' median (boxes 12×30 into 10×20: 1.5).
    assert_eq!(clf.window_size_px(), (15.0, 30.0));
}

#[test]
fn train_without_data_is_a_usage_error() {
    let o = bin().arg("train").output().expect("run");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = bin()
        .args(["train", "--sequence", "/no/such/seq"])
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("/no/such/seq"), "{}", stderr(&o));
}

#[test]
fn detector_training_flags_without_detector_are_a_usage_error() {
    for flag in ["--motorcycle-share", "--heavy-share"] {
        let o = bin()
            .args(["train", "--sequence", "/no/such/seq", flag, "0.3"])
            .output()
            .expect("run");
        assert_eq!(o.status.code(), Some(2), "{flag}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("{flag}: only with --detector")),
            "{}",
            stderr(&o)
        );
    }
}
