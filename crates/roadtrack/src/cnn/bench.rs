//! CNN throughput measurements for `roadtrack bench` and docs/PERFORMANCE.md "CNN".
//!
//! The budget (METHODS.md §3, issue 7): ≥ 30 frames/s at 640×480 with 10 targets ×
//! 70 particles. Per-window scoring runs the network 700 times a frame; dense mode runs it
//! once and looks 700 positions up in the [`ScoreMap`](super::ScoreMap).

use std::time::Instant;

use image::RgbImage;

use super::onnx::OnnxClassifier;
use super::ssd::SsdPersonDetector;
use crate::bench::StageResult;
use crate::error::Result;
use crate::geometry::Point;

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
