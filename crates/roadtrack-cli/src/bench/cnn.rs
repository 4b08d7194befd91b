//! CNN throughput measurements for `roadtrack bench` and docs/PERFORMANCE.md "CNN".
//!
//! The budget (METHODS.md §3, issue 7): ≥ 30 frames/s at 640×480 with 10 targets ×
//! 70 particles. Per-window scoring runs the network 700 times a frame; dense mode runs it
//! once and looks 700 positions up in the [`ScoreMap`](roadtrack_cnn::ScoreMap).
//! [`bench_cnn`] ([`bench_cnn_stages`] and [`bench_phd_cnn`]) is what `roadtrack bench --stages cnn`
//! runs: the network stages alone, and a whole PHD tracking step with a CNN likelihood,
//! per stage.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use image::RgbImage;
use rand::RngExt as _;

use super::StageResult;
use super::filters::{FilterBenchConfig, StageReport, bench_phd_with};
use roadtrack::error::{Error, Result};
use roadtrack::geometry::{BBox, Point};
use roadtrack::rng::{Stream, rng_for};
use roadtrack_cnn::export::write_onnx;
use roadtrack_cnn::likelihood::{OnnxDense, SsdDense, dense_likelihood};
use roadtrack_cnn::onnx::{CnnConfig, OnnxClassifier};
use roadtrack_cnn::ssd::{SsdConfig, SsdPersonDetector};
use roadtrack_cnn::train::{Patches, TrainConfig, train, training_preprocessing};

/// A deterministic textured 640×480 frame (the papers' frame size).
pub fn test_frame(width: u32, height: u32) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        let v = (x * 37 + y * 91 + (x * y) % 53) % 256;
        image::Rgb([
            v as u8,
            ((v * 3 + y) % 256) as u8,
            ((x * 7 + 11) % 256) as u8,
        ])
    })
}

/// `n` particle positions spread over the frame (deterministic).
pub fn particle_positions(width: u32, height: u32, n: usize) -> Vec<Point> {
    (0..n)
        .map(|i| {
            let t = i as f64 * 0.618_033_988_75;
            Point::new(
                t.fract() * f64::from(width),
                ((i as f64 + 0.5) / n as f64) * f64::from(height),
            )
        })
        .collect()
}

fn label(model: &str, w: u32, h: u32) -> String {
    format!("{model} on {w}×{h}")
}

/// Per-window scoring: `n_patches` windows on a 640×480 frame; items = patches.
pub fn bench_window_scoring(
    model: &OnnxClassifier,
    name: &str,
    n_patches: usize,
) -> Result<StageResult> {
    let frame = test_frame(640, 480);
    let pos = particle_positions(640, 480, n_patches);
    let mut out = vec![0.0; n_patches];
    model.score_windows(
        &frame,
        &pos[..n_patches.min(8)],
        &mut out[..n_patches.min(8)],
    )?;
    let t = Instant::now();
    model.score_windows(&frame, &pos, &mut out)?;
    Ok(StageResult::new(
        "cnn window scoring",
        &label(name, 640, 480),
        n_patches as u64,
        "patches",
        t.elapsed().as_secs_f64(),
    ))
}

/// Dense mode: `n_frames` score maps of a 640×480 frame at `stride_px`, plus `particles`
/// lookups per frame; items = frames.
pub fn bench_score_map(
    model: &OnnxClassifier,
    name: &str,
    stride_px: u32,
    particles: usize,
    n_frames: usize,
) -> Result<StageResult> {
    let frame = test_frame(640, 480);
    let pos = particle_positions(640, 480, particles);
    let mut out = vec![0.0; particles];
    model.score_map(&frame, stride_px)?; // builds and caches the dense plan
    let t = Instant::now();
    for _ in 0..n_frames {
        let map = model.score_map(&frame, stride_px)?;
        map.lookup(&pos, &mut out)?;
    }
    Ok(StageResult::new(
        &format!("cnn dense map, stride {stride_px} px, {particles} lookups"),
        &label(name, 640, 480),
        n_frames as u64,
        "frames",
        t.elapsed().as_secs_f64(),
    ))
}

/// SSD dense mode: `n_frames` whole-frame passes + score map at `stride_px` + `particles`
/// lookups on `frame`; items = frames.
pub fn bench_ssd_score_map(
    det: &SsdPersonDetector,
    frame: &RgbImage,
    stride_px: u32,
    particles: usize,
    n_frames: usize,
) -> Result<StageResult> {
    let (w, h) = frame.dimensions();
    let pos = particle_positions(w, h, particles);
    let mut out = vec![0.0; particles];
    det.score_map(frame, stride_px)?;
    let t = Instant::now();
    for _ in 0..n_frames {
        let map = det.score_map(frame, stride_px)?;
        map.lookup(&pos, &mut out)?;
    }
    Ok(StageResult::new(
        &format!("ssd dense map, stride {stride_px} px, {particles} lookups"),
        &label("SSDLite-MobileNetV2", w, h),
        n_frames as u64,
        "frames",
        t.elapsed().as_secs_f64(),
    ))
}

/// Trains the network `roadtrack train --preset person` writes (64×32 input) for a few
/// epochs on the filter benchmark's scene ([`square_scene`](roadtrack_sim::testkit::square_scene)): positives are 32×64 px windows
/// centred (±2 px) on the first frame's targets, negatives windows at least 30 px from
/// every target. Writes it as ONNX to `path` (window scale 1: a 32×64 px window around
/// the 24 px targets) and returns the test accuracy. A seeded few-second training, so the
/// PHD benchmark tracks with a likelihood that means something.
///
/// # Errors
/// When training or writing fails.
pub fn train_bench_classifier(cfg: &FilterBenchConfig, path: &Path) -> Result<f64> {
    let (frames, detections) = roadtrack_sim::testkit::square_scene(&cfg.scene());
    let Some(first) = frames.first() else {
        return Err(Error::Invalid("benchmark scene without frames".into()));
    };
    let tc = TrainConfig {
        epochs: 6,
        batch_size: 32,
        seed: cfg.seed,
        ..TrainConfig::default()
    };
    let prep = training_preprocessing();
    let mut patches = Patches {
        height: tc.input_height,
        width: tc.input_width,
        ..Default::default()
    };
    let (ww, wh) = (tc.input_width as f64, tc.input_height as f64);
    let mut r = rng_for(cfg.seed, Stream::Synthetic, 0xC22);
    for d in &detections {
        for _ in 0..20 {
            let c = Point::new(
                d.pos_px.x + r.random_range(-2.0..2.0),
                d.pos_px.y + r.random_range(-2.0..2.0),
            );
            patches.push_stretched(&first.image, BBox::from_centre(c, ww, wh), 1, &prep);
        }
    }
    let (w, h) = (f64::from(cfg.width), f64::from(cfg.height));
    let mut negatives = 0;
    while negatives < 2 * 20 * detections.len().max(1) {
        let c = Point::new(r.random_range(0.0..w), r.random_range(0.0..h));
        if detections.iter().all(|d| d.pos_px.distance(c) >= 30.0) {
            patches.push_stretched(&first.image, BBox::from_centre(c, ww, wh), 0, &prep);
            negatives += 1;
        }
    }
    let (net, report) = train(&patches, &tc, &mut |_| {})?;
    write_onnx(path, &net, &prep, Some(1.0))?;
    Ok(report.test_accuracy)
}

/// What `roadtrack bench --stages cnn` runs, with the classifier trained once: the network
/// stages alone ([`bench_cnn_stages`]) and a whole PHD step per stage ([`bench_phd_cnn`]),
/// on the filter benchmark's scene `cfg`; the SSD rows when `ssd_model` is given.
/// `progress` gets `(PHD runs done, PHD runs)`.
///
/// # Errors
/// When training, a model or a tracker fails.
pub fn bench_cnn(
    cfg: &FilterBenchConfig,
    ssd_model: Option<&Path>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(Vec<StageResult>, Vec<StageReport>)> {
    let dir = tempfile::tempdir().map_err(|e| Error::io("temporary folder", e))?;
    let path = dir.path().join("person.onnx");
    train_bench_classifier(cfg, &path)?;
    let stages = bench_cnn_stages(&path, ssd_model)?;
    let phd = bench_phd_cnn(cfg, &path, ssd_model, progress)?;
    Ok((stages, phd))
}

/// The CNN stages on a 640×480 frame: per-window scoring of 700 patches and dense maps
/// (stride 8 px) + 700 lookups for the classifier at `classifier` (the trained-size CNN of
/// [`train_bench_classifier`] in `roadtrack bench`), and the SSD's dense map when
/// `ssd_model` is given.
///
/// # Errors
/// When a model fails to load or run.
pub fn bench_cnn_stages(classifier: &Path, ssd_model: Option<&Path>) -> Result<Vec<StageResult>> {
    let model = OnnxClassifier::load(classifier, &CnnConfig::default())?;
    let name = "trained-size CNN 64×32";
    let mut out = vec![
        bench_window_scoring(&model, name, 700)?,
        bench_score_map(&model, name, 8, 700, 10)?,
    ];
    if let Some(p) = ssd_model {
        let det = SsdPersonDetector::load(p, &SsdConfig::default())?;
        out.push(bench_ssd_score_map(
            &det,
            &test_frame(640, 480),
            8,
            700,
            10,
        )?);
    }
    Ok(out)
}

/// A whole PHD tracking step with a network likelihood, per stage, on the filter
/// benchmark's scene (`cfg`: 640×480, 10 targets × 70 particles by default): the
/// classifier at `classifier` (in `roadtrack bench` the trained-size CNN of
/// [`train_bench_classifier`], trained on that scene) per particle window (`phd_cnn_window`)
/// and dense at `cfg.dense_stride_px` (`phd_cnn_dense`), and the SSD dense at the same
/// stride when `ssd_model` is given (`phd_ssd_dense`; the scene has no people, so its
/// labels die and only the per-frame map cost is meaningful). `progress` gets
/// `(runs done, runs)`.
///
/// # Errors
/// When a model fails to load or run, or a tracker fails.
pub fn bench_phd_cnn(
    cfg: &FilterBenchConfig,
    classifier: &Path,
    ssd_model: Option<&Path>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<StageReport>> {
    let model = Arc::new(OnnxClassifier::load(classifier, &CnnConfig::default())?);
    let runs = 2 + u64::from(ssd_model.is_some());
    let mut out = vec![bench_phd_with(
        cfg,
        "phd_cnn_window",
        Box::new(OnnxClassifier::load(classifier, &CnnConfig::default())?),
    )?];
    progress(1, runs);
    out.push(bench_phd_with(
        cfg,
        "phd_cnn_dense",
        Box::new(dense_likelihood(OnnxDense {
            model,
            stride_px: cfg.dense_stride_px,
        })),
    )?);
    progress(2, runs);
    if let Some(p) = ssd_model {
        let det = Arc::new(SsdPersonDetector::load(p, &SsdConfig::default())?);
        out.push(bench_phd_with(
            cfg,
            "phd_ssd_dense",
            Box::new(dense_likelihood(SsdDense {
                detector: det,
                stride_px: cfg.dense_stride_px,
            })),
        )?);
        progress(3, runs);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use roadtrack::likelihood::Likelihood;

    #[test]
    fn the_bench_classifier_learns_the_scene_targets() -> Result<()> {
        let cfg = FilterBenchConfig {
            targets: 4,
            frames: 2,
            ..Default::default()
        };
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let path = dir.path().join("m.onnx");
        let acc = train_bench_classifier(&cfg, &path)?;
        assert!(acc >= 0.9, "test accuracy {acc}");
        let model = OnnxClassifier::load(&path, &CnnConfig::default())?;
        assert_eq!(model.window_size_px(), (32.0, 64.0));
        let (frames, dets) = roadtrack_sim::testkit::square_scene(&cfg.scene());
        let far = Point::new(5.0, 5.0);
        assert!(dets.iter().all(|d| d.pos_px.distance(far) > 40.0));
        let mut out = [0.0; 2];
        model.evaluate(&frames[0].image, &[dets[0].pos_px, far], &mut out)?;
        assert!(out[0] > 0.5 && out[1] < 0.5, "{out:?}");
        Ok(())
    }
}
