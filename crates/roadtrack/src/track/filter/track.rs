//! Image trackers end to end (`roadtrack track --method pf|phd`): foreground detection
//! ([`Detector`]) for track starts and births, the particle filter or the labelled SMC-PHD
//! filter (METHODS.md §3) with the colour-histogram likelihood or a network (a CNN
//! classifier or the SSD pedestrian detector, [`load_model_likelihood`]), per particle
//! window or in dense mode.
//!
//! - [`track_source`]: a video, image folder or MOTChallenge sequence (two passes: the
//!   first samples frames for the background, as `roadtrack detect`).
//! - [`track_frames`]: any frame iterator with a bootstrapped detector (in-memory frames,
//!   the simulator).
//!
//! Per frame: detect → filter step (PF: start objects at new detections; PHD: birth
//! particles around detections no label explains) → end tracks that no detection has
//! supported for a while → give each estimate the box of its nearest detection.

use super::particle::{LikelihoodFactory, ParticleFilterConfig, ParticleFilterTracker};
use super::phd::{FilterStageTimes, PhdConfig, PhdTracker};
use crate::detect::background::{Detector, DetectorConfig};
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::geometry::{BBox, Point};
use crate::io::source::{self, SourceOptions};
use crate::likelihood::{
    BorderPolicy, ColourHistogram, ColourLikelihood, ColourLikelihoodConfig, DenseLikelihood,
    GridScorer, Likelihood, Window,
};
use crate::track_point::TrackPoint;
use image::{GrayImage, RgbImage};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, RwLock};

/// Which filter tracks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FilterMethod {
    /// The basic particle filter, `ρ` particles per object ([`ParticleFilterTracker`]).
    Pf,
    /// The labelled SMC-PHD filter ([`PhdTracker`]).
    Phd,
}

impl std::str::FromStr for FilterMethod {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "pf" => Ok(Self::Pf),
            "phd" => Ok(Self::Phd),
            _ => Err(Error::Invalid(format!(
                "unknown filter method {s:?}: expected pf or phd"
            ))),
        }
    }
}

/// Where the colour likelihood's reference histogram comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ColourReference {
    /// Each PF object's own start detection (the classic colour tracker, Pérez et al.
    /// 2002). The PHD filter, which needs one class likelihood, always uses `shared`.
    #[default]
    PerObject,
    /// The mean histogram of the detections of the first
    /// [`TrackLikelihoodConfig::reference_frames`] frames that have any: one "class"
    /// likelihood for every object, as the paper's CNN.
    Shared,
}

/// Where the PHD filter's birth particles go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BirthSource {
    /// Around the detections no label explains ([`super::LabelledPhd::add_births_at`]).
    #[default]
    Detections,
    /// The paper's fixed grid of [`PhdConfig::birth_grid_points`] points.
    Grid,
    /// Both.
    Both,
}

/// What the trackers' likelihood `h(y | x)` measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LikelihoodKind {
    /// The colour-histogram likelihood alone.
    #[default]
    Colour,
    /// The fraction of the window that the foreground detector marks as moving, divided
    /// by [`TrackLikelihoodConfig::foreground_full`] and capped at 1: the detector's mask
    /// as a dense score map (an integral image, O(1) per particle).
    Foreground,
    /// The product of the two.
    ColourForeground,
}

/// The likelihood of the image trackers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackLikelihoodConfig {
    /// What `h` measures. Default colour.
    pub kind: LikelihoodKind,
    /// Foreground fraction of a window that counts as a whole object (`h = 1`). Default 0.5.
    // Choice: a window matched to an object's box is about half covered by its mask (boxes
    // of oblique vehicles and of pedestrians are far from filled).
    pub foreground_full: f64,
    /// Histogram bins per RGB channel. Default 8.
    pub bins_per_channel: u32,
    /// Sample every `pixel_step`-th row and column of the window. Default 2.
    pub pixel_step: u32,
    /// `λ` in `h = exp(−λ·(1 − BC))`. Default 5.
    // Choice: 5, not Pérez's 20: the PHD update needs h near 1 on an object for its weight
    // to stay above the report threshold (docs/FILTERS.md, "Properties of the paper's
    // update"); with λ = 20 a window slightly off the object already scores < 0.05.
    pub sharpness: f64,
    /// The window is the detection's box (PF, per object) or the median detection box of
    /// the reference frames (shared) times this. Default 1.
    pub window_scale: f64,
    /// Smallest window side, px. Default 8.
    pub min_window_px: u32,
    /// Border handling of the window. Default clamp.
    pub border: BorderPolicy,
    /// Where the reference histogram comes from (PF). Default per object.
    pub reference: ColourReference,
    /// Frames with detections whose boxes make the shared reference (and the shared window
    /// size). Default 10. Frames before the reference is complete are buffered and then
    /// tracked as every other frame.
    pub reference_frames: u32,
    /// Dense mode: score a grid of this spacing once per frame and answer particles by
    /// bilinear lookup ([`DenseLikelihood`] over [`GridScorer`]); 0 = score every particle's
    /// window. Applies to a shared likelihood only. Default 0.
    pub dense_stride_px: u32,
}

impl Default for TrackLikelihoodConfig {
    fn default() -> Self {
        Self {
            kind: LikelihoodKind::Colour,
            foreground_full: 0.5,
            bins_per_channel: 8,
            pixel_step: 2,
            sharpness: 5.0,
            window_scale: 1.0,
            min_window_px: 8,
            border: BorderPolicy::Clamp,
            reference: ColourReference::PerObject,
            reference_frames: 10,
            dense_stride_px: 0,
        }
    }
}

impl TrackLikelihoodConfig {
    /// The colour likelihood config for a window of `size` px (before scaling).
    fn colour(&self, size: (f64, f64)) -> ColourLikelihoodConfig {
        let side = |v: f64| {
            let v = (v * self.window_scale).round();
            if v.is_finite() {
                (v as u32).max(self.min_window_px)
            } else {
                self.min_window_px
            }
        };
        ColourLikelihoodConfig {
            bins_per_channel: self.bins_per_channel,
            window: Window::new(side(size.0), side(size.1), self.border),
            pixel_step: self.pixel_step,
            sharpness: self.sharpness,
        }
    }
}

/// Everything `roadtrack track --method pf|phd` needs besides the input and the seed
/// (`--config F.toml`: tables `[detector]`, `[pf]`, `[phd]`, `[likelihood]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FilterTrackConfig {
    /// Foreground extraction (track starts, births, support, box sizes).
    pub detector: DetectorConfig,
    /// The particle filter (Table 5 defaults).
    pub pf: ParticleFilterConfig,
    /// The labelled SMC-PHD filter (Table 9 defaults).
    pub phd: PhdConfig,
    /// The colour likelihood.
    pub likelihood: TrackLikelihoodConfig,
    /// Where PHD births go. Default detections.
    // Choice: the paper's grid births rely on a classifier that scores background ≈ 0; a
    // colour histogram scores background windows of similar colour well above α_mesh, so
    // grid births there start phantom labels. `grid` and `both` are available.
    pub births: BirthSource,
    /// Birth particles per detection. Default 70 (`ρ`).
    pub birth_particles_per_detection: usize,
    /// Spread of birth particles around a detection, px. Default 4.
    pub birth_spread_px: f64,
    /// A detection within this distance of a label's predicted position is explained by
    /// it and seeds no birth, px. Default 30 (the PF's new-object gate).
    pub birth_gate_px: f64,
    /// A track is supported in a frame when a detection lies within this distance, px.
    /// Default 30.
    pub support_gate_px: f64,
    /// A track (PF object or PHD label) without support for more frames than this ends;
    /// 0 disables the rule. Default 20 (2 s at 10 frames/s).
    // Choice: the paper gives no rule for ending tracks besides the likelihood and border
    // rules. With a colour likelihood a track that slid onto similar background keeps a
    // high likelihood forever; the foreground detector is independent evidence.
    pub max_frames_without_detection: u32,
    /// Give each estimate the box size of its nearest detection within
    /// [`FilterTrackConfig::support_gate_px`] (else its last size, else the window).
    /// Default true.
    // Choice: the filters estimate a position only; box-based metrics (IoU) need a size.
    pub box_from_detections: bool,
}

impl Default for FilterTrackConfig {
    fn default() -> Self {
        Self {
            detector: DetectorConfig::default(),
            pf: ParticleFilterConfig::default(),
            phd: PhdConfig::default(),
            likelihood: TrackLikelihoodConfig::default(),
            births: BirthSource::Detections,
            birth_particles_per_detection: 70,
            birth_spread_px: 4.0,
            birth_gate_px: 30.0,
            support_gate_px: 30.0,
            max_frames_without_detection: 20,
            box_from_detections: true,
        }
    }
}

impl FilterTrackConfig {
    /// Checks every range, nested configs included.
    pub fn validate(&self) -> Result<()> {
        let c = "FilterTrackConfig";
        self.detector.validate()?;
        self.pf.validate()?;
        self.phd.validate()?;
        self.likelihood.colour((32.0, 32.0)).validate()?;
        let l = &self.likelihood;
        if !(l.window_scale.is_finite() && l.window_scale > 0.0) {
            return Err(Error::config(c, "likelihood.window_scale", "must be > 0"));
        }
        if !(l.foreground_full > 0.0 && l.foreground_full <= 1.0) {
            return Err(Error::config(
                c,
                "likelihood.foreground_full",
                "must be in (0, 1]",
            ));
        }
        if l.min_window_px == 0 {
            return Err(Error::config(c, "likelihood.min_window_px", "must be ≥ 1"));
        }
        if l.reference_frames == 0 {
            return Err(Error::config(
                c,
                "likelihood.reference_frames",
                "must be ≥ 1",
            ));
        }
        for (v, f) in [
            (self.birth_spread_px, "birth_spread_px"),
            (self.birth_gate_px, "birth_gate_px"),
            (self.support_gate_px, "support_gate_px"),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::config(
                    c,
                    f,
                    format!("must be finite and ≥ 0, got {v}"),
                ));
            }
        }
        Ok(())
    }

    /// Reads a TOML file (missing fields take the defaults) and validates it.
    ///
    /// # Errors
    /// When the file cannot be read or parsed, or a value is out of range.
    pub fn from_toml_file(path: &Path) -> Result<Self> {
        let cfg: Self = crate::config::load_toml(path)?;
        cfg.validate()?;
        Ok(cfg)
    }
}

/// Per-frame summary of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrameCount {
    /// Frame number.
    pub frame: u32,
    /// Expected number of objects: the PHD filter's weight sum, the PF's object count.
    pub expected: f64,
    /// Tracks reported in the frame.
    pub reported: usize,
    /// Detections in the frame.
    pub detections: usize,
}

/// What a run produced.
#[derive(Debug, Clone, Default)]
pub struct FilterTrackOutput {
    /// Track points, by frame then id (what `roadtrack track` writes).
    pub points: Vec<TrackPoint>,
    /// One entry per frame: expected and reported counts.
    pub counts: Vec<FrameCount>,
    /// The foreground detections used.
    pub detections: Vec<Detection>,
    /// Wall time per filter stage (detection not included).
    pub stage_times: FilterStageTimes,
    /// Wall time of foreground detection, s.
    pub detect_s: f64,
    /// The shared likelihood's window, px (`None` with per-object PF likelihoods).
    pub window_px: Option<(u32, u32)>,
}

/// Tracks `input` (video, image folder, MOTChallenge sequence) with `method`.
///
/// Opens the source twice: the first pass samples frames for the detector's background
/// (as `roadtrack detect`), the second tracks. `progress(done, total)` is called after
/// each tracked frame (`total` 0 when unknown).
///
/// # Errors
/// An invalid config, an unreadable source, a frame of another size, a likelihood error.
pub fn track_source(
    method: FilterMethod,
    cfg: &FilterTrackConfig,
    input: &Path,
    options: &SourceOptions,
    seed: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<FilterTrackOutput> {
    track_source_with_model(method, cfg, input, options, seed, None, progress)
}

/// [`track_source`] with `model` (e.g. from [`load_model_likelihood`]) as the class
/// likelihood instead of the colour histogram: one likelihood shared by every object (PF
/// and PHD). [`TrackLikelihoodConfig::kind`] still applies (`foreground` ignores the
/// model; `colour_foreground` multiplies the model by the foreground fraction); the
/// window and box sizes stay the median detection box of the reference frames.
///
/// # Errors
/// As [`track_source`].
pub fn track_source_with_model(
    method: FilterMethod,
    cfg: &FilterTrackConfig,
    input: &Path,
    options: &SourceOptions,
    seed: u64,
    model: Option<Box<dyn Likelihood>>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<FilterTrackOutput> {
    cfg.validate()?;
    let first = source::open(input, options)?;
    let total = first.info.selected_frames;
    let detector = Detector::bootstrap(cfg.detector.clone(), first, total)?;
    let frames = source::open(input, options)?;
    track_frames_with_model(
        method,
        cfg,
        detector,
        frames,
        total.map(u64::from),
        seed,
        model,
        progress,
    )
}

/// Tracks `frames` with `method`, detecting with `detector` (e.g.
/// `Detector::bootstrap(cfg.detector.clone(), frames.iter().cloned().map(Ok), None)`).
///
/// # Errors
/// As [`track_source`].
pub fn track_frames(
    method: FilterMethod,
    cfg: &FilterTrackConfig,
    detector: Detector,
    frames: impl Iterator<Item = Result<Frame>>,
    total: Option<u64>,
    seed: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<FilterTrackOutput> {
    track_frames_with_model(method, cfg, detector, frames, total, seed, None, progress)
}

/// [`track_frames`] with a network likelihood, as [`track_source_with_model`].
///
/// # Errors
/// As [`track_source`].
#[allow(clippy::too_many_arguments)]
pub fn track_frames_with_model(
    method: FilterMethod,
    cfg: &FilterTrackConfig,
    mut detector: Detector,
    frames: impl Iterator<Item = Result<Frame>>,
    total: Option<u64>,
    seed: u64,
    mut model: Option<Box<dyn Likelihood>>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<FilterTrackOutput> {
    cfg.validate()?;
    let shared = method == FilterMethod::Phd
        || cfg.likelihood.reference == ColourReference::Shared
        || model.is_some();
    let mut out = FilterTrackOutput::default();
    let mut runner: Option<Runner> = None;
    // Frames wait here until the shared reference is complete.
    let mut pending: Vec<(Frame, Vec<Detection>, GrayImage)> = Vec::new();
    let mut reference_frames = 0u32;
    let mut done = 0u64;
    for frame in frames {
        let frame = frame?;
        let t0 = std::time::Instant::now();
        let found = detector.process(&frame)?;
        let dets: Vec<Detection> = found
            .regions
            .iter()
            .enumerate()
            .map(|(i, r)| r.to_detection(frame.index, i as u64 + 1))
            .collect();
        out.detect_s += t0.elapsed().as_secs_f64();
        out.detections.extend(dets.iter().cloned());
        if let Some(r) = runner.as_mut() {
            r.step(&frame, &dets, &found.mask, &mut out)?;
        } else {
            if !dets.is_empty() {
                reference_frames += 1;
            }
            pending.push((frame, dets, found.mask));
            if !shared || reference_frames >= cfg.likelihood.reference_frames {
                let r = runner.insert(Runner::new(
                    method,
                    cfg,
                    &pending,
                    seed,
                    shared,
                    model.take(),
                )?);
                for (f, d, m) in pending.drain(..) {
                    r.step(&f, &d, &m, &mut out)?;
                }
            }
        }
        done += 1;
        progress(done, total.unwrap_or(0));
    }
    if runner.is_none() && !pending.is_empty() {
        // Fewer frames with detections than `reference_frames`: use what there is.
        let mut r = Runner::new(method, cfg, &pending, seed, shared, model.take())?;
        for (f, d, m) in pending.drain(..) {
            r.step(&f, &d, &m, &mut out)?;
        }
        runner = Some(r);
    }
    if let Some(r) = runner {
        out.stage_times = r.stage_times();
        out.window_px = r.window_px;
    }
    Ok(out)
}

enum Filter {
    Pf(Box<ParticleFilterTracker>),
    Phd(Box<PhdTracker>),
}

/// One run's filter with its bookkeeping.
struct Runner {
    cfg: FilterTrackConfig,
    filter: Filter,
    /// The current frame's foreground mask, read by foreground likelihoods.
    mask: SharedMask,
    window_px: Option<(u32, u32)>,
    /// Per track id: last frame with a detection within the support gate.
    last_support: BTreeMap<u64, u32>,
    /// Per track id: last box size.
    sizes: BTreeMap<u64, (f64, f64)>,
    /// The PF's estimates of the last frame.
    last_pf: Vec<Point>,
    default_size: (f64, f64),
}

impl Runner {
    fn new(
        method: FilterMethod,
        cfg: &FilterTrackConfig,
        pending: &[(Frame, Vec<Detection>, GrayImage)],
        seed: u64,
        shared: bool,
        model: Option<Box<dyn Likelihood>>,
    ) -> Result<Self> {
        let lc = cfg.likelihood;
        let mask: SharedMask = Arc::default();
        let (likelihood, window_px) = if shared {
            let (lik, win) = shared_likelihood(&lc, pending, &mask, model)?;
            (Some(lik), Some(win))
        } else {
            (None, None)
        };
        let default_size = window_px.map_or(
            (cfg.pf.object_width_px, cfg.pf.object_height_px),
            |(w, h)| (f64::from(w), f64::from(h)),
        );
        let filter = match method {
            FilterMethod::Pf => {
                let pf = match likelihood {
                    Some(lik) => ParticleFilterTracker::new(cfg.pf.clone(), lik, seed)?,
                    None => {
                        let mask = Arc::clone(&mask);
                        let factory: LikelihoodFactory =
                            Box::new(move |img: &RgbImage, d: &Detection| {
                                let size = d.size_px.unwrap_or((32.0, 32.0));
                                let b = BBox::from_centre(d.pos_px, size.0, size.1);
                                let colour = lc.colour(size);
                                let lik = ColourLikelihood::from_boxes(colour, img, &[b])?;
                                Ok(with_foreground(&lc, Box::new(lik), colour.window, &mask))
                            });
                        ParticleFilterTracker::with_object_likelihoods(
                            cfg.pf.clone(),
                            factory,
                            seed,
                        )?
                    }
                };
                Filter::Pf(Box::new(pf))
            }
            FilterMethod::Phd => {
                let lik = likelihood
                    .ok_or_else(|| Error::Invalid("PHD filter: no shared likelihood".to_owned()))?;
                let mut phd_cfg = cfg.phd.clone();
                phd_cfg.object_width_px = default_size.0;
                phd_cfg.object_height_px = default_size.1;
                let mut t = PhdTracker::new(phd_cfg, lik, seed)?;
                t.set_grid_births(matches!(cfg.births, BirthSource::Grid | BirthSource::Both));
                Filter::Phd(Box::new(t))
            }
        };
        Ok(Self {
            cfg: cfg.clone(),
            filter,
            mask,
            window_px,
            last_support: BTreeMap::new(),
            sizes: BTreeMap::new(),
            last_pf: Vec::new(),
            default_size,
        })
    }

    fn stage_times(&self) -> FilterStageTimes {
        match &self.filter {
            Filter::Pf(t) => t.stage_times(),
            Filter::Phd(t) => t.stage_times(),
        }
    }

    fn step(
        &mut self,
        frame: &Frame,
        dets: &[Detection],
        mask: &GrayImage,
        out: &mut FilterTrackOutput,
    ) -> Result<()> {
        if self.cfg.likelihood.kind != LikelihoodKind::Colour {
            let mut m = self
                .mask
                .write()
                .map_err(|_| Error::Invalid("foreground mask lock poisoned".to_owned()))?;
            m.set(mask);
        }
        let cfg = &self.cfg;
        let (mut points, expected, tracked) = match &mut self.filter {
            Filter::Pf(t) => {
                // Choice: a detection starts an object only when no object's last estimate
                // lies within half its box's longer side (at least the PF's own gate), so a
                // large nearby vehicle does not start a second object.
                let starts: Vec<Detection> = dets
                    .iter()
                    .filter(|d| {
                        let half = d.size_px.map_or(0.0, |(w, h)| w.max(h) / 2.0);
                        let gate = half.max(cfg.pf.new_object_gate_px);
                        self.last_pf.iter().all(|q| q.distance(d.pos_px) > gate)
                    })
                    .cloned()
                    .collect();
                let pts = t.step(frame, &starts)?;
                let tracked: Vec<(u64, Point)> =
                    pts.iter().map(|p| (p.id, p.bbox.centre())).collect();
                let n = t.n_objects() as f64;
                (pts, n, tracked)
            }
            Filter::Phd(t) => {
                let births: Vec<Point> = if matches!(cfg.births, BirthSource::Grid) {
                    Vec::new()
                } else {
                    // Labels predicted one frame ahead explain the detections near them.
                    let predicted: Vec<Point> = t.filter().map_or_else(Vec::new, |f| {
                        f.all_estimates()
                            .iter()
                            .map(|e| Point::new(e.pos.x + e.vel.x, e.pos.y + e.vel.y))
                            .collect()
                    });
                    dets.iter()
                        .map(|d| d.pos_px)
                        .filter(|p| predicted.iter().all(|q| q.distance(*p) > cfg.birth_gate_px))
                        .collect()
                };
                let pts = t.step_with_births(
                    frame,
                    &births,
                    cfg.birth_particles_per_detection,
                    cfg.birth_spread_px,
                )?;
                let tracked: Vec<(u64, Point)> = t.filter().map_or_else(Vec::new, |f| {
                    f.all_estimates()
                        .iter()
                        .map(|e| (u64::from(e.label), e.pos))
                        .collect()
                });
                (pts, t.expected_count(), tracked)
            }
        };

        // Support by detections; end tracks unsupported for too long.
        let near = |p: Point| -> Option<&Detection> {
            dets.iter()
                .map(|d| (d, d.pos_px.distance(p)))
                .filter(|(_, dist)| *dist <= cfg.support_gate_px)
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(d, _)| d)
        };
        let supported = one_to_one(&tracked, dets, cfg.support_gate_px);
        let mut ended = Vec::new();
        for &(id, _) in &tracked {
            let last = self.last_support.entry(id).or_insert(frame.index);
            if supported.contains(&id) {
                *last = frame.index;
            }
            let max = cfg.max_frames_without_detection;
            if max > 0 && frame.index.saturating_sub(*last) > max {
                ended.push(id);
            }
        }
        if !ended.is_empty() {
            match &mut self.filter {
                Filter::Pf(t) => t.end_objects(&ended),
                Filter::Phd(t) => {
                    let labels: Vec<u32> = ended
                        .iter()
                        .filter_map(|&id| u32::try_from(id).ok())
                        .collect();
                    t.remove_labels(&labels);
                }
            }
            points.retain(|p| !ended.contains(&p.id));
            for id in &ended {
                self.last_support.remove(id);
            }
        }
        let live: Vec<u64> = tracked.iter().map(|t| t.0).collect();
        self.last_support.retain(|id, _| live.contains(id));

        // Box sizes.
        if cfg.box_from_detections {
            for p in &mut points {
                let c = p.bbox.centre();
                if let Some(size) = near(c).and_then(|d| d.size_px) {
                    self.sizes.insert(p.id, size);
                }
                let (w, h) = self.sizes.get(&p.id).copied().unwrap_or(self.default_size);
                p.bbox = BBox::from_centre(c, w, h);
            }
            self.sizes.retain(|id, _| live.contains(id));
        }
        if let Filter::Pf(_) = self.filter {
            self.last_pf = points.iter().map(|p| p.bbox.centre()).collect();
        }
        out.counts.push(FrameCount {
            frame: frame.index,
            expected,
            reported: points.len(),
            detections: dets.len(),
        });
        out.points.extend(points);
        Ok(())
    }
}

/// Ids of the tracks that a detection supports: track–detection pairs within `gate`,
/// taken greedily from the closest, each track and detection at most once.
fn one_to_one(tracked: &[(u64, Point)], dets: &[Detection], gate: f64) -> Vec<u64> {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, (_, p)) in tracked.iter().enumerate() {
        for (j, d) in dets.iter().enumerate() {
            let dist = p.distance(d.pos_px);
            if dist <= gate {
                pairs.push((dist, i, j));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let (mut t_used, mut d_used) = (vec![false; tracked.len()], vec![false; dets.len()]);
    let mut out = Vec::new();
    for (_, i, j) in pairs {
        if !t_used[i] && !d_used[j] {
            t_used[i] = true;
            d_used[j] = true;
            out.push(tracked[i].0);
        }
    }
    out
}

/// The shared likelihood: `model` when given, else the colour likelihood with reference =
/// mean histogram of every detection box in `pending`, dense when configured; window =
/// median detection size.
fn shared_likelihood(
    lc: &TrackLikelihoodConfig,
    pending: &[(Frame, Vec<Detection>, GrayImage)],
    mask: &SharedMask,
    model: Option<Box<dyn Likelihood>>,
) -> Result<(Box<dyn Likelihood>, (u32, u32))> {
    let mut hists = Vec::new();
    let (mut ws, mut hs) = (Vec::new(), Vec::new());
    for (f, dets, _) in pending {
        for d in dets {
            if let Some(b) = d.bbox() {
                hists.push(ColourHistogram::of_box(&f.image, lc.bins_per_channel, &b));
                ws.push(b.width);
                hs.push(b.height);
            }
        }
    }
    let median = |v: &mut Vec<f64>| -> f64 {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(32.0)
    };
    let colour = lc.colour((median(&mut ws), median(&mut hs)));
    let window = (colour.window.width_px, colour.window.height_px);
    if let Some(model) = model {
        return Ok((with_foreground(lc, model, colour.window, mask), window));
    }
    // No detection at all: an empty reference (every window scores exp(−λ), nothing is
    // tracked).
    let reference = ColourHistogram::mean(&hists)
        .unwrap_or_else(|| ColourHistogram::zeros(lc.bins_per_channel));
    let lik = ColourLikelihood::new(colour, reference)?;
    let lik: Box<dyn Likelihood> = if lc.dense_stride_px > 0 {
        Box::new(DenseLikelihood::new(Box::new(GridScorer {
            inner: lik,
            stride_px: lc.dense_stride_px,
        })))
    } else {
        Box::new(lik)
    };
    Ok((with_foreground(lc, lik, colour.window, mask), window))
}

/// The foreground mask of the current frame as an integral image: `sums[(y·(w+1)) + x]`
/// counts the foreground pixels above and left of `(x, y)`.
#[derive(Debug, Default)]
struct MaskIntegral {
    width: usize,
    height: usize,
    sums: Vec<u32>,
}

type SharedMask = Arc<RwLock<MaskIntegral>>;

impl MaskIntegral {
    fn set(&mut self, mask: &GrayImage) {
        let (w, h) = (mask.width() as usize, mask.height() as usize);
        self.width = w;
        self.height = h;
        self.sums.clear();
        self.sums.resize((w + 1) * (h + 1), 0);
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += u32::from(mask.as_raw()[y * w + x] > 0);
                self.sums[(y + 1) * (w + 1) + x + 1] = self.sums[y * (w + 1) + x + 1] + row;
            }
        }
    }

    /// Fraction of the `window` centred on `p` (clipped to the image) that is foreground.
    fn fraction(&self, p: Point, window: &Window) -> f64 {
        if self.width == 0 || !(p.x.is_finite() && p.y.is_finite()) {
            return 0.0;
        }
        let clip = |v: f64, max: usize| v.round().clamp(0.0, max as f64) as usize;
        let (hw, hh) = (
            f64::from(window.width_px) / 2.0,
            f64::from(window.height_px) / 2.0,
        );
        let (x0, x1) = (clip(p.x - hw, self.width), clip(p.x + hw, self.width));
        let (y0, y1) = (clip(p.y - hh, self.height), clip(p.y + hh, self.height));
        if x1 <= x0 || y1 <= y0 {
            return 0.0;
        }
        let s = |x: usize, y: usize| f64::from(self.sums[y * (self.width + 1) + x]);
        (s(x1, y1) - s(x0, y1) - s(x1, y0) + s(x0, y0)) / ((x1 - x0) * (y1 - y0)) as f64
    }
}

/// `inner` as configured by [`TrackLikelihoodConfig::kind`]: alone, replaced by the
/// foreground fraction, or multiplied by it.
fn with_foreground(
    lc: &TrackLikelihoodConfig,
    inner: Box<dyn Likelihood>,
    window: Window,
    mask: &SharedMask,
) -> Box<dyn Likelihood> {
    match lc.kind {
        LikelihoodKind::Colour => inner,
        LikelihoodKind::Foreground => Box::new(ForegroundLikelihood {
            inner: None,
            mask: Arc::clone(mask),
            window,
            full: lc.foreground_full,
        }),
        LikelihoodKind::ColourForeground => Box::new(ForegroundLikelihood {
            inner: Some(inner),
            mask: Arc::clone(mask),
            window,
            full: lc.foreground_full,
        }),
    }
}

/// `h = inner · min(1, foreground fraction / full)` (`inner` = 1 when absent).
struct ForegroundLikelihood {
    inner: Option<Box<dyn Likelihood>>,
    mask: SharedMask,
    window: Window,
    full: f64,
}

impl Likelihood for ForegroundLikelihood {
    fn evaluate(&self, image: &RgbImage, positions_px: &[Point], out: &mut [f64]) -> Result<()> {
        match &self.inner {
            Some(inner) => inner.evaluate(image, positions_px, out)?,
            None => {
                crate::likelihood::check_lengths(positions_px, out)?;
                out.iter_mut().for_each(|o| *o = 1.0);
            }
        }
        let mask = self
            .mask
            .read()
            .map_err(|_| Error::Invalid("foreground mask lock poisoned".to_owned()))?;
        for (o, &p) in out.iter_mut().zip(positions_px) {
            *o *= (mask.fraction(p, &self.window) / self.full).min(1.0);
        }
        Ok(())
    }

    fn begin_frame(&mut self, image: &RgbImage) -> Result<()> {
        match &mut self.inner {
            Some(inner) => inner.begin_frame(image),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::class::ObjectClass;
    use roadtrack_sim::external::{ExternalTrajectories, TrajectorySample};
    use roadtrack_sim::{SceneKind, SimConfig, Simulation, TruthRow, ViewKind};

    /// Three cars of distinct colours driving along the crossing scene's road, well apart,
    /// for `frames` frames: the simulator's frames and truth.
    fn three_cars(frames: u32) -> Result<(Vec<Frame>, Vec<TruthRow>)> {
        let cfg = SimConfig {
            scene: SceneKind::Crossing,
            view: ViewKind::Oblique,
            frames,
            ..Default::default()
        };
        let mut samples = Vec::new();
        let cars = [
            (1u64, -1.75, -34.0, [200u8, 30, 30]),
            (2, 1.75, -14.0, [30, 60, 200]),
            (3, -1.75, 6.0, [230, 200, 40]),
        ];
        for (id, y, x0, rgb) in cars {
            for k in 0..=2 {
                let t = f64::from(k) * f64::from(frames) / 10.0 / 2.0;
                samples.push((
                    id,
                    TrajectorySample {
                        time_s: t,
                        class: ObjectClass::Car,
                        x_m: x0 + 6.0 * t,
                        y_m: y,
                        heading_deg: 0.0,
                        length_m: 4.5,
                        width_m: 1.8,
                        height_m: None,
                        rgb: Some(rgb),
                    },
                ));
            }
        }
        let ext = ExternalTrajectories::new(samples)?;
        let sim = Simulation::from_trajectories(&cfg, 3, ext, Some(frames))?;
        let (mut out, mut truth) = (Vec::new(), Vec::new());
        for step in sim {
            let step = step?;
            out.push(step.frame);
            truth.extend(step.truth);
        }
        Ok((out, truth))
    }

    fn run(
        method: FilterMethod,
        frames: &[Frame],
        cfg: &FilterTrackConfig,
    ) -> Result<FilterTrackOutput> {
        let detector = Detector::bootstrap(
            cfg.detector.clone(),
            frames.iter().cloned().map(Ok),
            Some(frames.len() as u32),
        )?;
        let mut calls = 0;
        let out = track_frames(
            method,
            cfg,
            detector,
            frames.iter().cloned().map(Ok),
            Some(frames.len() as u64),
            7,
            &mut |_, _| calls += 1,
        )?;
        assert_eq!(calls, frames.len());
        Ok(out)
    }

    #[test]
    fn phd_weight_sum_tracks_the_true_count_on_a_simulated_scene() -> Result<()> {
        let (frames, truth) = three_cars(30)?;
        let cfg = FilterTrackConfig::default();
        let out = run(FilterMethod::Phd, &frames, &cfg)?;
        assert_eq!(out.counts.len(), frames.len());
        let mut errors = Vec::new();
        for c in &out.counts[5..] {
            let n = truth
                .iter()
                .filter(|t| t.frame == c.frame && t.visibility >= 0.3)
                .count() as f64;
            errors.push((c.expected - n).abs());
        }
        let mae = errors.iter().sum::<f64>() / errors.len() as f64;
        assert!(
            mae < 0.8,
            "mean |Σw − true count| = {mae:.2}: {:?}",
            out.counts
        );
        Ok(())
    }

    #[test]
    fn pf_follows_each_car_and_track_source_on_a_folder_gives_the_same_tracks() -> Result<()> {
        let (frames, truth) = three_cars(24)?;
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        for f in &frames {
            let path = dir.path().join(format!("{:06}.png", f.index));
            f.image
                .save(&path)
                .map_err(|e| Error::Invalid(e.to_string()))?;
        }
        let cfg = FilterTrackConfig::default();
        let opts = SourceOptions {
            fps: Some(10.0),
            ..Default::default()
        };
        let from_dir = track_source(FilterMethod::Pf, &cfg, dir.path(), &opts, 7, &mut |_, _| {})?;
        let in_memory = run(FilterMethod::Pf, &frames, &cfg)?;
        assert_eq!(from_dir.points, in_memory.points);
        assert!(!in_memory.points.is_empty());
        // Reported centres lie on a car: inside a truth box of the frame. (The colour
        // histogram ignores where in the window the colours are, so a track may lag
        // inside a long car's box by tens of px.)
        let near = in_memory
            .points
            .iter()
            .filter(|p| {
                let c = p.bbox.centre();
                truth.iter().any(|t| {
                    let b = t.bbox;
                    t.frame == p.frame
                        && c.x >= b.left
                        && c.x <= b.left + b.width
                        && c.y >= b.top
                        && c.y <= b.top + b.height
                })
            })
            .count() as u32;
        let share = f64::from(near) / in_memory.points.len() as f64;
        assert!(
            share > 0.8,
            "{near} of {} points on a car",
            in_memory.points.len()
        );
        Ok(())
    }

    #[test]
    fn methods_parse_and_an_invalid_config_is_refused() {
        assert_eq!("pf".parse::<FilterMethod>().ok(), Some(FilterMethod::Pf));
        assert_eq!("phd".parse::<FilterMethod>().ok(), Some(FilterMethod::Phd));
        assert!("mrf".parse::<FilterMethod>().is_err());
        let mut cfg = FilterTrackConfig::default();
        assert!(cfg.validate().is_ok());
        cfg.likelihood.foreground_full = 0.0;
        assert!(cfg.validate().is_err());
        let text = "births = \"grid\"\n[likelihood]\nkind = \"colour_foreground\"\n";
        let parsed: std::result::Result<FilterTrackConfig, _> = toml::from_str(text);
        assert!(parsed.is_ok_and(|c| c.births == BirthSource::Grid
            && c.likelihood.kind == LikelihoodKind::ColourForeground));
        assert!(toml::from_str::<FilterTrackConfig>("bogus = 1").is_err());
    }
}
