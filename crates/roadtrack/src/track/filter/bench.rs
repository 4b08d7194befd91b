//! Per-stage timings of the filters on a synthetic scene, for `roadtrack bench` and
//! docs/PERFORMANCE.md: `targets` coloured squares moving at constant velocity over a
//! textured `width × height` background, tracked by the PHD filter (colour likelihood per
//! particle, and in dense mode) and the basic particle filter.

use super::particle::{ParticleFilterConfig, ParticleFilterTracker};
use super::phd::{FilterStageTimes, PhdConfig, PhdTracker};
use crate::detection::Detection;
use crate::error::Result;
use crate::frame::Frame;
use crate::geometry::{BBox, Point};
use crate::likelihood::{
    BorderPolicy, ColourLikelihood, ColourLikelihoodConfig, DenseLikelihood, GridScorer,
    Likelihood, Window,
};
use crate::rng::{Stream, rng_for};
use image::{Rgb, RgbImage};
use rand::RngExt as _;
use serde::Serialize;

/// Size of the benchmark.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterBenchConfig {
    /// Frame width, px. Default 640.
    pub width: u32,
    /// Frame height, px. Default 480.
    pub height: u32,
    /// Number of targets. Default 10.
    pub targets: usize,
    /// `ρ`. Default 70 (the paper's PHD setting).
    pub particles_per_object: usize,
    /// Frames timed. Default 30.
    pub frames: u32,
    /// Grid stride of dense mode, px. Default 8.
    pub dense_stride_px: u32,
    /// Seed.
    pub seed: u64,
}

impl Default for FilterBenchConfig {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            targets: 10,
            particles_per_object: 70,
            frames: 30,
            dense_stride_px: 8,
            seed: 0,
        }
    }
}

/// Mean wall time per frame of each stage of one filter run, ms.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageReport {
    /// What ran (`phd_colour`, `phd_dense`, `pf_colour`).
    pub name: String,
    /// Frames timed.
    pub frames: u64,
    /// Particles after the last step.
    pub particles: usize,
    /// Propagation and births.
    pub predict_ms: f64,
    /// Likelihood (for dense mode: the score map plus lookups).
    pub likelihood_ms: f64,
    /// Weight update.
    pub update_ms: f64,
    /// Label rules (particle filter: track start/end).
    pub labels_ms: f64,
    /// Resampling and estimates.
    pub resample_ms: f64,
    /// Sum of the stages.
    pub total_ms: f64,
    /// Frames per second from `total_ms`.
    pub fps: f64,
}

impl StageReport {
    fn new(name: &str, t: &FilterStageTimes, particles: usize) -> Self {
        let n = t.steps.max(1) as f64;
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3 / n;
        let total = ms(t.total());
        Self {
            name: name.into(),
            frames: t.steps,
            particles,
            predict_ms: ms(t.predict),
            likelihood_ms: ms(t.likelihood),
            update_ms: ms(t.update),
            labels_ms: ms(t.labels),
            resample_ms: ms(t.resample),
            total_ms: total,
            fps: if total > 0.0 {
                1e3 / total
            } else {
                f64::INFINITY
            },
        }
    }
}

/// The synthetic scene: frames and the first frame's detections.
pub fn bench_scene(cfg: &FilterBenchConfig) -> (Vec<Frame>, Vec<Detection>) {
    let mut rng = rng_for(cfg.seed, Stream::Synthetic, 0xBE7C);
    let (w, h) = (cfg.width, cfg.height);
    let background = RgbImage::from_fn(w, h, |x, y| {
        let v = 70 + ((x / 16 + y / 16) % 2) as u8 * 30;
        Rgb([v, v + 10, v])
    });
    let size = 24.0;
    let targets: Vec<(Point, Point, Rgb<u8>)> = (0..cfg.targets)
        .map(|k| {
            // One colour class (as one CNN class would be).
            let pos = Point::new(
                40.0 + rng.random::<f64>() * (f64::from(w) - 80.0),
                40.0 + rng.random::<f64>() * (f64::from(h) - 80.0),
            );
            let vel = Point::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            let _ = k;
            let colour = Rgb([200, 40, 40]);
            (pos, vel, colour)
        })
        .collect();
    let frames = (1..=cfg.frames)
        .map(|index| {
            let t = f64::from(index - 1);
            let mut img = background.clone();
            for (p, v, c) in &targets {
                let b = BBox::from_centre(Point::new(p.x + v.x * t, p.y + v.y * t), size, size);
                for y in b.top.max(0.0) as u32..(b.bottom().min(f64::from(h))) as u32 {
                    for x in b.left.max(0.0) as u32..(b.right().min(f64::from(w))) as u32 {
                        img.put_pixel(x, y, *c);
                    }
                }
            }
            Frame {
                index,
                time_s: t / 10.0,
                image: img,
            }
        })
        .collect();
    let detections = targets
        .iter()
        .enumerate()
        .map(|(k, (p, _, _))| Detection {
            size_px: Some((size, size)),
            ..Detection::at(1, k as u64 + 1, *p)
        })
        .collect();
    (frames, detections)
}

/// The PHD filter with `likelihood` on `frames`, started from `detections` (ρ =
/// `cfg.particles_per_object`), timed per stage.
fn run_phd(
    cfg: &FilterBenchConfig,
    frames: &[Frame],
    detections: &[Detection],
    name: &str,
    likelihood: Box<dyn Likelihood>,
) -> Result<StageReport> {
    let phd_cfg = PhdConfig {
        particles_per_object: cfg.particles_per_object,
        ..PhdConfig::default()
    };
    let mut t = PhdTracker::new(phd_cfg, likelihood, cfg.seed)?;
    t.start_from_detections(detections);
    for f in frames {
        t.step(f)?;
    }
    let n = t.filter().map_or(0, |f| f.particles().len());
    Ok(StageReport::new(name, &t.stage_times(), n))
}

/// Runs the PHD filter with `likelihood` on the synthetic scene ([`bench_scene`]) and
/// reports per-stage times (a whole tracking step: predict, likelihood — for dense
/// likelihoods the per-frame score map plus lookups — update, labels, resample).
///
/// # Errors
/// When the tracker or the likelihood fails.
pub fn bench_phd_with(
    cfg: &FilterBenchConfig,
    name: &str,
    likelihood: Box<dyn Likelihood>,
) -> Result<StageReport> {
    let (frames, detections) = bench_scene(cfg);
    run_phd(cfg, &frames, &detections, name, likelihood)
}

/// Runs the PHD filter (colour per particle, colour dense) and the particle filter on the
/// synthetic scene and reports per-stage times. `progress` gets `(runs done, 3)`.
///
/// # Errors
/// When a tracker fails (it should not on this scene).
pub fn bench_filters(
    cfg: &FilterBenchConfig,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<StageReport>> {
    let (frames, detections) = bench_scene(cfg);
    let Some(first) = frames.first() else {
        return Ok(Vec::new());
    };
    // The window matches the 24 px objects, and λ = 5 keeps h well above α_mesh a few px
    // off centre (with the default 32 px window and λ = 20 a 24 px object scores 0.007).
    let colour_cfg = ColourLikelihoodConfig {
        window: Window::new(24, 24, BorderPolicy::Clamp),
        sharpness: 5.0,
        ..ColourLikelihoodConfig::default()
    };
    // Reference from the inner 20 px of each box (no background pixels).
    let boxes: Vec<BBox> = detections
        .iter()
        .map(|d| BBox::from_centre(d.pos_px, 20.0, 20.0))
        .collect();
    let colour = ColourLikelihood::from_boxes(colour_cfg, &first.image, &boxes)?;
    let mut reports = Vec::new();
    let likelihoods: Vec<(&str, Box<dyn Likelihood>)> = vec![
        ("phd_colour", Box::new(colour.clone())),
        (
            "phd_dense",
            Box::new(DenseLikelihood::new(Box::new(GridScorer {
                inner: colour.clone(),
                stride_px: cfg.dense_stride_px,
            }))),
        ),
    ];
    for (name, lik) in likelihoods {
        reports.push(run_phd(cfg, &frames, &detections, name, lik)?);
        progress(reports.len() as u64, 3);
    }
    let pf_cfg = ParticleFilterConfig {
        particles_per_object: cfg.particles_per_object,
        ..ParticleFilterConfig::default()
    };
    let mut pf = ParticleFilterTracker::new(pf_cfg, Box::new(colour), cfg.seed)?;
    for f in &frames {
        let dets = if f.index == 1 { &detections[..] } else { &[] };
        pf.step(f, dets)?;
    }
    let n = pf.n_objects() * cfg.particles_per_object;
    reports.push(StageReport::new("pf_colour", &pf.stage_times(), n));
    progress(3, 3);
    Ok(reports)
}
