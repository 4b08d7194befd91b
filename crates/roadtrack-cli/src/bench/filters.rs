//! Per-stage timings of the filters on a synthetic scene, for `roadtrack bench` and
//! docs/PERFORMANCE.md: `targets` coloured squares moving at constant velocity over a
//! textured `width × height` background, tracked by the PHD filter (colour likelihood per
//! particle, and in dense mode) and the basic particle filter.

use roadtrack::detection::Detection;
use roadtrack::error::Result;
use roadtrack::frame::Frame;
use roadtrack::geometry::BBox;
use roadtrack::likelihood::{
    BorderPolicy, ColourLikelihood, ColourLikelihoodConfig, DenseLikelihood, GridScorer,
    Likelihood, Window,
};
use roadtrack::track::filter::particle::{ParticleFilterConfig, ParticleFilterTracker};
use roadtrack::track::filter::phd::{FilterStageTimes, PhdConfig, PhdTracker};
use roadtrack_sim::testkit::{SquareSceneConfig, square_scene};
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

impl FilterBenchConfig {
    /// The scene part.
    pub fn scene(&self) -> SquareSceneConfig {
        SquareSceneConfig {
            width: self.width,
            height: self.height,
            targets: self.targets,
            frames: self.frames,
            seed: self.seed,
        }
    }
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

/// Runs the PHD filter with `likelihood` on the synthetic scene ([`square_scene`]) and
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
    let (frames, detections) = square_scene(&cfg.scene());
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
    let (frames, detections) = square_scene(&cfg.scene());
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
